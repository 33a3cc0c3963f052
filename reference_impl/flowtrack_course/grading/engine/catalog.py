"""Which exercises a run grades: a course's notebooks (always) and extra sources of exercises that
are graded when a student answered them (answers in other languages).

:class:`ExerciseSource` is what the engine needs of such a source; the layer above the engine
composes a :class:`Catalog` of the discovered course (:func:`~.discovery.discover`) and its
sources. The engine itself never names an exercise nor a source.
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
    """Exercises graded only when a student answered them (found by the files submitted)."""

    def exercises(self) -> Sequence[Exercise]:
        """Every exercise of the source."""
        ...

    def find(self, key: str | Path) -> Exercise | None:
        """The exercise with id ``key`` or whose student file is named like ``key``, else None."""
        ...

    def answered(self, student_dir: Path) -> Sequence[Exercise]:
        """The exercises one student's folder holds an answer to."""
        ...

    def submitted(self, submissions: Path) -> Sequence[Exercise]:
        """The exercises at least one student folder of ``submissions`` holds an answer to."""
        ...


@dataclass(frozen=True)
class Catalog:
    """A course's exercises (:class:`~.discovery.ExerciseSet`) and its extra ``sources``.

    Picklable when its sources are (a class run's workers receive it and look exercises up by id).
    """

    course: ExerciseSet
    sources: tuple[ExerciseSource, ...] = ()

    @property
    def root(self) -> Path:
        """The course folder."""
        return self.course.root

    def default(self) -> tuple[Exercise, ...]:
        """The exercises every run grades: the course's notebooks."""
        return tuple(self.course.exercises)

    def for_class(self, submissions: str | os.PathLike) -> tuple[Exercise, ...]:
        """The notebooks, and the sources' exercises someone in the class answered."""
        extra = [ex for s in self.sources for ex in s.submitted(Path(submissions))]
        return (*self.default(), *extra)

    def for_student(self, folder: str | os.PathLike) -> tuple[Exercise, ...]:
        """The notebooks, and the sources' exercises this student answered."""
        extra = [ex for s in self.sources for ex in s.answered(Path(folder))]
        return (*self.default(), *extra)

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
