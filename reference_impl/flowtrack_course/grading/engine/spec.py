"""What an exercise is, for the grader: trusted test definitions and trusted comparisons.

An :class:`Exercise` names its notebook, the nbgrader ``grade_id`` of the answer cells whose code
the sandboxed child executes, the modules the child may not import, its :class:`GradedTest`\\ s and
the :class:`~.mistakes.Mistake`\\ s they recognise. A test's ``build(rng)`` returns the
:class:`~grading_sandbox.Call`\\ s to make in the child and a scorer; the scorer receives one
:class:`~grading_sandbox.Outcome` per call (plain data only, converted by the grader) and returns
the fraction of the points earned and a message. Expected values are computed here, by the trusted
reference, and never sent to the child.

What makes one kind of exercise different from another (a notebook, a source file in another
language) is a method of :class:`Exercise`: :meth:`~Exercise.extract_cells`, :attr:`~Exercise.spawns`,
:meth:`~Exercise.source_files` and :meth:`~Exercise.environment_problem`, which a subclass overrides
(:class:`Gradable` is the interface the engine relies on).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from grading_sandbox import Call, Outcome

from .compare import as_float_array, compare_arrays
from .mistakes import Mistake
from .notebook import answer_cells

if TYPE_CHECKING:
    from .mistakes import Catalogue

__all__ = [
    "Call",
    "CannotGradeHere",
    "Dependency",
    "Exercise",
    "Gradable",
    "GradedTest",
    "Outcome",
    "Scorer",
    "as_float_array",
    "compare_arrays",
]


Scorer = Callable[[Sequence[Outcome]], tuple[float, str]]


class CannotGradeHere(RuntimeError):
    """This machine lacks what grading an exercise needs (a compiler, an interpreter): the
    installation's problem, said as such, never a student's score (:meth:`Exercise.environment_problem`)."""


@dataclass(frozen=True)
class GradedTest:
    """A test: ``build(rng) -> (calls, scorer)``; ``scorer(outcomes) -> (fraction in [0, 1], message)``.

    ``hidden`` tests are reported to students by name and score only. ``grade_id`` is the nbgrader id
    of the notebook's test cell this test stands for (the notebook's own test cells are never run by
    the grader: students can edit them).
    """

    name: str
    grade_id: str
    points: float
    hidden: bool
    build: Callable[[np.random.Generator], tuple[Sequence[Call], Scorer]]
    timeout: float = 10.0


@dataclass(frozen=True)
class Dependency:
    """Test cell ``test`` checks a function (``builds``) built on the one test cell ``on`` checks
    (``function``): when both fail, the dependent test's message says which function to fix first."""

    test: str
    on: str
    function: str
    builds: str


@dataclass(frozen=True)
class Exercise:
    """One exercise and its tests.

    ``notebook`` is the path of the student's file relative to the bundle's ``exercises/`` (and to
    a student's submission folder); ``answer_cells`` the grade_ids of the cells (in notebook order)
    the child executes; ``blocked`` the modules the child cannot import (e.g. ``"mylib.camera"``,
    ``"scipy.optimize"``); ``allowed`` what the student may import besides the standard library
    (the notebook's "You may import" line; ``numpy`` always): the sandbox then holds only the
    packages these need and refuses importing any other. Empty: no allowlist (everything installed,
    minus ``blocked``). ``packages`` the course's packages the sandbox shows (a read-only copy each,
    ``blocked`` modules stubbed out). ``mistakes`` the catalogued wrong answers its tests recognise
    (their ``Variant``\\ s name them), with their messages; ``depends`` which tests build on others.
    ``catalogue`` is set when the exercise is discovered in a course: every mistake of the course
    (an exercise may recognise one another exercise defines) and the generic ones.
    """

    id: str
    title: str
    notebook: str
    answer_cells: tuple[str, ...]
    blocked: tuple[str, ...]
    tests: tuple[GradedTest, ...]
    allowed: tuple[str, ...] = ()
    packages: tuple[str, ...] = ()
    mistakes: tuple[Mistake, ...] = ()
    depends: tuple[Dependency, ...] = ()
    catalogue: Catalogue | None = field(default=None, compare=False, repr=False)

    @property
    def max_score(self) -> float:
        return float(sum(t.points for t in self.tests))

    def extract_cells(self, path: Path) -> tuple[list[tuple[str, str]], list[str]]:
        """The answer cells of the student's file ``path`` that can be extracted, and one message
        for each problem (a missing or broken notebook breaks every cell; a missing cell only the
        functions it defines)."""
        return answer_cells(Path(path), self.answer_cells)

    @property
    def spawns(self) -> bool:
        """True when the exercise's own (trusted) code starts programs in the sandbox (an answer in
        another language is compiled and run there)."""
        return False

    def source_files(self) -> list[Path]:
        """Files the grading depends on beyond its tests' modules (hashed with the tests, so that a
        change re-grades finished students)."""
        return []

    def environment_problem(self) -> str:
        """What this machine lacks to grade the exercise, with how to install it ("" when nothing:
        a notebook needs only the sandbox)."""
        return ""


@runtime_checkable
class Gradable(Protocol):
    """What the engine needs of an exercise (:class:`Exercise` and its subclasses have it)."""

    id: str
    title: str
    notebook: str
    answer_cells: tuple[str, ...]
    blocked: tuple[str, ...]
    tests: tuple[GradedTest, ...]
    allowed: tuple[str, ...]
    packages: tuple[str, ...]

    @property
    def max_score(self) -> float: ...

    @property
    def spawns(self) -> bool: ...

    def extract_cells(self, path: Path) -> tuple[list[tuple[str, str]], list[str]]: ...

    def source_files(self) -> list[Path]: ...

    def environment_problem(self) -> str: ...
