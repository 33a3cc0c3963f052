"""Which exercises a run grades: a course's notebooks and extra sources of exercises (answers in
other languages), as far as the instructor's assignment says they count.

:class:`ExerciseSource` is what the engine needs of such a source; the layer above the engine
composes a :class:`Catalog` of the discovered course (:func:`~.discovery.discover`), its sources
and which notebooks are assigned (``assigned``). The engine itself never names an exercise nor a
source. What a class is graded on is fixed by the assignment, never by what students upload: the
columns (:meth:`Catalog.for_class`) are the assigned exercises; each student is graded on those
assigned to them (:meth:`Catalog.for_student`: a source may assign a student a part of its
exercises, e.g. the language they chose), and what they uploaded beyond that is ignored with a
note (:meth:`Catalog.ignored`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

from .discovery import ExerciseSet
from .spec import Exercise

__all__ = ["Catalog", "ExerciseSource"]


@runtime_checkable
class ExerciseSource(Protocol):
    """Exercises beside the course's notebooks, of which the assignment makes some count."""

    def exercises(self) -> Sequence[Exercise]:
        """Every exercise of the source (assigned or not: a student's own check may run any)."""
        ...

    def find(self, key: str | Path) -> Exercise | None:
        """The exercise with id ``key`` or whose student file is named like ``key``, else None."""
        ...

    def assigned(self) -> Sequence[Exercise]:
        """The exercises that count in the assignment (columns of the class's grades)."""
        ...

    def for_student(self, student_dir: Path) -> Sequence[Exercise]:
        """The assigned exercises one student is graded on (all of :meth:`assigned`, or those of the
        student's choice)."""
        ...

    def ignored(self, student_dir: Path) -> Sequence[str]:
        """One note per file of the student's folder this source knows but does not grade (outside
        the assignment), saying why."""
        ...


@dataclass(frozen=True)
class Catalog:
    """A course's exercises (:class:`~.discovery.ExerciseSet`) and its extra ``sources``;
    ``assigned`` the ids of the notebooks that count (None: all of them).

    Picklable when its sources are (a class run's workers receive it and look exercises up by id).
    """

    course: ExerciseSet
    sources: tuple[ExerciseSource, ...] = ()
    assigned: tuple[str, ...] | None = None

    @property
    def root(self) -> Path:
        """The course folder."""
        return self.course.root

    def default(self) -> tuple[Exercise, ...]:
        """The course's notebooks (all of them, assigned or not)."""
        return tuple(self.course.exercises)

    def notebooks(self) -> tuple[Exercise, ...]:
        """The notebooks the assignment counts."""
        if self.assigned is None:
            return self.default()
        return tuple(ex for ex in self.default() if ex.id in self.assigned)

    def for_class(self, submissions: str | os.PathLike | None = None) -> tuple[Exercise, ...]:
        """The exercises a class is graded on (the columns of its grades): the assigned notebooks and
        the sources' assigned exercises, whatever the students uploaded (``submissions`` is not
        read; kept for callers that pass it)."""
        return (*self.notebooks(), *(ex for s in self.sources for ex in s.assigned()))

    def for_student(self, folder: str | os.PathLike) -> tuple[Exercise, ...]:
        """The exercises one student is graded on: the assigned notebooks and what the sources
        assign this student."""
        return (*self.notebooks(), *(ex for s in self.sources for ex in s.for_student(Path(folder))))

    def ignored(self, folder: str | os.PathLike) -> list[str]:
        """Notes on what the student uploaded outside the assignment (the notebooks of exercises that
        are not assigned, the sources' files), for the student's feedback."""
        notes = []
        if self.assigned is not None:
            root = Path(folder)
            for ex in self.default():
                if ex.id not in self.assigned and any(root.rglob(Path(ex.notebook).name)):
                    notes.append(f"ignored {Path(ex.notebook).name}: {ex.id} is not part of this assignment")
        for s in self.sources:
            notes += list(s.ignored(Path(folder)))
        return notes

    def everything(self) -> tuple[Exercise, ...]:
        """Every exercise the catalog knows."""
        return (*self.default(), *(ex for s in self.sources for ex in s.exercises()))

    def find(self, key: str | os.PathLike) -> Exercise | None:
        """The exercise named by ``key`` (an id, a notebook's or a source file's path or name)."""
        for s in self.sources:
            found = s.find(os.fspath(key))
            if found is not None:
                return found
        return self.course.find(key)

    def get(self, key: str | os.PathLike) -> Exercise:
        """:meth:`find`, raising ``KeyError`` when nothing matches."""
        found = self.find(key)
        if found is None:
            return self.course.get(key)  # raises with the known ids
        return found

    def resolve_ids(self, spec: str | Sequence[str] | None) -> list[str]:
        """Exercise ids from a list or a comma-separated string of ids or their unique prefixes
        (``"ex05"`` for the one exercise whose id starts with ``ex05_``); ``[]`` for none.

        Raises
        ------
        ValueError
            A name matches no exercise, or a prefix more than one.
        """
        if spec is None:
            return []
        if isinstance(spec, str):
            spec = spec.split(",")
        out = []
        for key in (str(e).strip() for e in spec):
            if not key:
                continue
            found = self.find(key)
            if found is None:
                short = [ex.id for ex in self.default() if ex.id.startswith(key + "_")]
                if len(short) != 1:
                    known = ", ".join(ex.id for ex in self.default())
                    raise ValueError(f"exercises: no exercise {key!r}; known: {known}")
                out.append(short[0])
            else:
                out.append(found.id)
        return list(dict.fromkeys(out))
