"""``flowtrack check NOTEBOOK``: a student's own run of an exercise's public tests.

The exercise is found from the notebook's file name; its answer cells run in the same sandbox and
with the same fixed seeds as in ``flowtrack grade``, so the public part of the grade is exactly what
``check`` shows. Hidden tests are not run (their inputs depend on the student and are not released).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TextIO

from .grade import ExerciseResult, run_exercise

__all__ = ["check_notebook", "format_report"]


def format_report(result: ExerciseResult, hidden_points: float = 0.0) -> str:
    """A plain-text table of the public tests' results followed by each test's message."""
    lines = [f"{result.exercise_id}: {result.title}  ({result.notebook})", ""]
    for p in result.problems:
        lines.append(f"PROBLEM: {p}")
    if result.problems:
        lines.append("")
    width = max([len(t.name) for t in result.tests] + [4])
    lines.append(f"{'test'.ljust(width)}  {'points':>11}  result")
    lines.append(f"{'-' * width}  {'-' * 11}  ------")
    for t in result.tests:
        pts = f"{t.score:g}/{t.max_score:g}"
        lines.append(f"{t.name.ljust(width)}  {pts:>11}  {'PASS' if t.passed else 'FAIL'}")
    lines.append("")
    for t in result.tests:
        if not t.passed:
            lines.append(f"{t.name}: {t.message}")
    seen: list[str] = []
    for t in result.tests:
        seen += [m for m in getattr(t, "mistakes", ()) if m not in seen]
    if seen:
        from .exercises.feedback import describe_mistakes

        lines += ["", *describe_mistakes(seen), ""]
    lines.append(f"public score: {result.score:g} / {result.max_score:g}")
    if hidden_points:
        lines.append(
            f"(hidden tests worth {hidden_points:g} more points use other inputs and are run when your "
            "work is graded)"
        )
    return "\n".join(lines)


def check_notebook(notebook: str | os.PathLike, *, stream: TextIO | None = None) -> int:
    """Run the public tests of the exercise ``notebook`` belongs to and print the report.

    Returns the exit status: 0 when every public test passes, 1 otherwise.

    Raises
    ------
    FileNotFoundError
        ``notebook`` does not exist.
    ValueError
        No exercise has that notebook's file name.
    """
    from .exercises import get_exercise

    stream = stream or sys.stdout
    path = Path(notebook)
    if not path.is_file():
        raise FileNotFoundError(f"notebook: no such file: {path}")
    from .languages import find_language_exercise  # hook (issue 19): C++ / Octave source files

    renamed_note = ""
    try:
        exercise = find_language_exercise(path) or get_exercise(str(path))
    except (KeyError, ValueError) as exc:
        # issue 18 hook: an LMS-renamed copy ("ex05_cv_model (1).ipynb") is checked, with the rename to make
        from .layout import suggest_rename

        found = suggest_rename(path)
        if found is None:
            raise ValueError(f"notebook: {path.name} is not one of the course's exercises ({exc})") from None
        exercise, renamed_note = found
    result = run_exercise(exercise, path, None, public_only=True)
    hidden = sum(float(t.points) for t in exercise.tests if t.hidden)
    print(format_report(result, hidden), file=stream)
    if result.isolation.startswith("fallback"):
        why = result.isolation.removeprefix("fallback: ")
        print(
            f"warning: bubblewrap is not available ({why}): your code ran in the fallback sandbox; "
            "the scores are the same, the isolation is weaker",
            file=stream,
        )
    ok = bool(result.tests) and all(t.passed for t in result.tests) and not result.problems
    if renamed_note:
        print(renamed_note, file=stream)
        ok = False
    return 0 if ok else 1
