"""Students answer in C++ (Eigen), Java, Octave and Mathematica (Mathics3) too, graded by the same
grader (issue 19).

- :mod:`.problems`: the language-neutral problems, their public and seeded hidden inputs, the Python
  reference's expected values and the catalogued mistakes;
- :mod:`.toolchains`: how each language is built and run in the sandbox, and the cached harness
  objects;
- :mod:`.driver`: the trusted driver the sandboxed child executes;
- :mod:`.exercises`: one :class:`LanguageExercise` per (problem, language), the scoring, the stubs and
  the bundle's files.

Instructor sources: ``exercises/<lang>/<problem>/<problem>.<ext>`` with ``BEGIN SOLUTION`` /
``END SOLUTION`` blocks.
"""

from __future__ import annotations

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
from .problems import PROBLEMS
from .toolchains import LANGUAGES, TOOLCHAINS, ToolchainMissing

__all__ = [
    "answered_exercises",
    "LANGUAGES",
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
