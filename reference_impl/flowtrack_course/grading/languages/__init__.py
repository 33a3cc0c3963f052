"""Students answer in C++ (Eigen), Java, Octave and Mathematica (Mathics3) too, graded by the same grader.

- :mod:`.exercises`: one :class:`LanguageExercise` per (problem, language), the scoring, the stubs and
  the bundle's files;
- :mod:`.driver`: the trusted driver the sandboxed child executes.

The problems, their public and seeded hidden inputs, the Python reference's expected values and the
catalogued mistakes are in :mod:`flowtrack_course.polyglot.problems`; how each language is built and
run in the sandbox, and the cached harness objects, in its :mod:`flowtrack_course.polyglot`
toolchain (the ports use the same stack). Instructor sources:
``exercises/<lang>/<problem>/<problem>.<ext>`` with ``BEGIN SOLUTION`` / ``END SOLUTION`` blocks.
"""

from __future__ import annotations

from ...polyglot.base import ToolchainMissing
from ...polyglot.problems import GRADED_PROBLEMS as PROBLEMS
from ...polyglot.toolchains import TOOLCHAINS
from .exercises import (
    LANGUAGE_EXERCISES,
    LanguageExercise,
    answered_exercises,
    find_language_exercise,
    materialise,
    public_vectors,
    release_languages,
    strip_solutions,
    submitted_exercises,
)

__all__ = [
    "answered_exercises",
    "LANGUAGE_EXERCISES",
    "LanguageExercise",
    "PROBLEMS",
    "TOOLCHAINS",
    "ToolchainMissing",
    "find_language_exercise",
    "materialise",
    "public_vectors",
    "release_languages",
    "strip_solutions",
    "submitted_exercises",
]
