"""What a grading run is asked to do, as data: :class:`GradingOptions` (how every exercise is run),
:class:`StudentJob` (one student's folder) and :class:`ClassJob` (a class).

These replace long parameter lists: a class run hands each worker a :class:`StudentJob` (picklable
when the options hold no sandbox stand-in), which :func:`~.student.grade_student` grades.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .spec import Exercise

if TYPE_CHECKING:
    from .catalog import Catalog

__all__ = ["VISIBILITIES", "ClassJob", "GradingOptions", "StudentJob"]

#: Gradescope's visibilities of a test
VISIBILITIES = ("hidden", "after_due_date", "after_published", "visible")


@dataclass(frozen=True)
class GradingOptions:
    """How exercises are run and reported, the same for every student of a run.

    Attributes
    ----------
    secret : bytes or None
        The instructor's seed key of the hidden tests (:func:`~.seeds.read_secret`); None seeds them
        from public names only.
    hidden_paths : tuple of str
        What the sandbox's fallback must refuse to open (the class's submissions, the output
        folder, the key file, the course); bubblewrap shows none of them anyway.
    hidden_visibility : str
        Gradescope visibility of hidden tests in ``results.json``.
    force : bool
        Re-grade students whose results are up to date.
    reuse_sandboxes : bool
        Run a student's exercises in zygote sandboxes (:class:`grading_sandbox.SandboxPool`)
        instead of a fresh sandbox each; the scores are the same.
    limits : grading_sandbox.Limits or None
        Resource limits of the sandboxes (their defaults when None).
    sandbox_factory : callable or None
        A ``Sandbox``-like class (tests' stand-ins); default :class:`grading_sandbox.Sandbox`.
    """

    secret: bytes | None = None
    hidden_paths: tuple[str, ...] = ()
    hidden_visibility: str = "after_published"
    force: bool = False
    reuse_sandboxes: bool = True
    limits: Any = None
    sandbox_factory: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        if self.hidden_visibility not in VISIBILITIES:
            raise ValueError(
                f"hidden_visibility must be a Gradescope visibility, got {self.hidden_visibility!r}"
            )
        object.__setattr__(self, "hidden_paths", tuple(str(p) for p in self.hidden_paths))

    def hiding(self, *paths: str | os.PathLike) -> GradingOptions:
        """These options with ``paths`` (resolved) added to :attr:`hidden_paths`."""
        more = tuple(str(Path(p).resolve()) for p in paths)
        return replace(self, hidden_paths=tuple(dict.fromkeys((*self.hidden_paths, *more))))


@dataclass(frozen=True)
class StudentJob:
    """One student's folder to grade into ``out/<student>/``.

    ``student`` is the student's id (the folder's name, whatever its letters; the outputs go to
    ``out/<student_folder(student)>/``); ``exercises`` are the exercises to grade; ``exercises_hash``
    (computed when None) identifies them in ``results.json``; ``renamed`` (``{exercise id: path in
    the folder}``) grades accepted renamed copies (``--accept-renamed``: a missing notebook's, or
    one newer than the notebook under its expected name); ``ignored`` (``{exercise id: [paths]}``)
    are the other files standing for an exercise, which the feedback names; ``notes`` are told the
    student (e.g. the files of their folder outside the assignment, which are not graded).
    """

    student: str
    folder: Path
    out: Path
    exercises: tuple[Exercise, ...]
    options: GradingOptions = field(default_factory=GradingOptions)
    exercises_hash: str | None = None
    renamed: Mapping[str, str] = field(default_factory=dict)
    ignored: Mapping[str, Sequence[str]] = field(default_factory=dict)
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class ClassJob:
    """A class to grade: every student folder of ``submissions`` into ``out``.

    Attributes
    ----------
    submissions, out : Path
        ``SUBMISSIONS/<student>/...`` and the output folder.
    catalog : Catalog or None
        Where the exercises come from (:class:`~.catalog.Catalog`); needed when ``exercises`` is
        None, and for ``jobs > 1`` (the workers look the exercises up by id in it).
    exercises : tuple of Exercise or None
        The exercises graded (the columns of ``grades.csv``); None: the catalog's assigned ones
        (:meth:`~.catalog.Catalog.for_class`). With a catalog, each student is graded on those of
        them the catalog assigns that student (:meth:`~.catalog.Catalog.for_student`; exercises
        the catalog does not know are graded for everyone).
    jobs : int
        Students graded in parallel (worker processes).
    options : GradingOptions
        How each exercise is run.
    renamed : mapping
        ``{student: {exercise id: path}}`` of accepted renamed copies.
    ignored : mapping
        ``{student: {exercise id: [paths]}}`` of the files standing for an exercise that are not
        graded (named in the feedback).
    allow_unsafe_sandbox : bool
        Grade even where bubblewrap cannot isolate student code.
    progress : bool
        Show a progress bar.
    log : callable or None
        Where warnings go (default: standard error).
    """

    submissions: Path
    out: Path
    catalog: Catalog | None = None
    exercises: tuple[Exercise, ...] | None = None
    jobs: int = 1
    options: GradingOptions = field(default_factory=GradingOptions)
    renamed: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    ignored: Mapping[str, Mapping[str, Sequence[str]]] = field(default_factory=dict)
    allow_unsafe_sandbox: bool = False
    progress: bool = True
    log: Callable[[str], None] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "submissions", Path(self.submissions))
        object.__setattr__(self, "out", Path(self.out))
        if self.exercises is not None:
            object.__setattr__(self, "exercises", tuple(self.exercises))

    def resolved(self) -> tuple[Exercise, ...]:
        """The exercises of this run: ``exercises``, else the catalog's for this class."""
        if self.exercises is not None:
            return tuple(self.exercises)
        if self.catalog is None:
            raise ValueError("a ClassJob needs exercises or a catalog")
        return tuple(self.catalog.for_class(self.submissions))

    def with_exercises(self, exercises: Sequence[Exercise]) -> ClassJob:
        return replace(self, exercises=tuple(exercises))
