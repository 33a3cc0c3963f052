"""Students answer in C++ (Eigen), Java, Octave and Mathematica (Mathics3) too, graded by the same grader.

- :mod:`.exercises`: one :class:`LanguageExercise` per (problem, language) a course declares, the
  scoring, the stubs and the bundle's files of one exercise;
- :mod:`.source`: a course's language exercises as a source of exercises
  (:class:`LanguageSource`: found by the files submitted; the instructor's sources; the bundle);
- :mod:`.driver`: the trusted driver the sandboxed child executes.

The problems, their public and seeded hidden inputs, the Python reference's expected values and the
wrong answers that recognise their mistakes are in :mod:`flowtrack_course.polyglot.problems`; how
each language is built and run in the sandbox, and the cached harness objects, in its
:mod:`flowtrack_course.polyglot` toolchain (the ports use the same stack). The mistakes' messages
are the course's: those of the notebooks, and the few only other languages show in the grading
module of the exercise they belong to. This package imports nothing of the ports.
"""

from __future__ import annotations

from ...polyglot.base import ToolchainMissing
from ...polyglot.problems import GRADED_PROBLEMS as PROBLEMS
from ...polyglot.toolchains import TOOLCHAINS
from .exercises import (
    LanguageExercise,
    language_catalogue,
    language_exercises,
    materialise,
    public_vectors,
    strip_solutions,
)
from .source import LanguageSource

__all__ = [
    "LanguageExercise",
    "LanguageSource",
    "PROBLEMS",
    "TOOLCHAINS",
    "ToolchainMissing",
    "language_catalogue",
    "language_exercises",
    "materialise",
    "public_vectors",
    "strip_solutions",
]
