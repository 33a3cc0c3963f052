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

from grading_sandbox import SandboxConfigError

from ..engine.results import ExerciseResult, format_score
from ..engine.run import run_exercise
from ..engine.spec import CannotGradeHere

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
        pts = f"{format_score(t.score)}/{format_score(t.max_score)}"
        lines.append(f"{t.name.ljust(width)}  {pts:>11}  {'PASS' if t.passed else 'FAIL'}")
    lines.append("")
    for t in result.tests:
        if not t.passed:
            lines.append(f"{t.name}: {t.message}")
    seen: list[str] = []
    for t in result.tests:
        seen += [m for m in getattr(t, "mistakes", ()) if m not in seen]
    if seen:
        lines += ["", *result.catalogue.lines(seen), ""]
    lines.append(f"public score: {format_score(result.score)} / {format_score(result.max_score)}")
    if hidden_points:
        lines.append(
            f"(hidden tests worth {format_score(hidden_points)} more points use other inputs and are run "
            "when your work is graded)"
        )
    return "\n".join(lines)


def check_notebook(
    notebook: str | os.PathLike, *, course: str | os.PathLike | None = None, stream: TextIO | None = None
) -> int:
    """Run the public tests of the exercise ``notebook`` belongs to and print the report.

    The exercise is looked up in the course folder ``course`` (else ``$FLOWTRACK_COURSE``, else the
    current folder, else the folder above ``notebook`` that holds ``exercises/``:
    :func:`~flowtrack_course.grading.sources.course_near`). Returns the exit status: 0 when every
    public test passes, 1 otherwise, 3 when the sandbox cannot import what the exercise allows (the
    installation's problem, printed with the fix instead of a score).

    Raises
    ------
    FileNotFoundError
        ``notebook`` does not exist.
    ValueError
        No exercise has that notebook's file name.
    """
    from ..engine.jobs import GradingOptions
    from ..engine.layout import suggest_rename
    from ..sources import course_near

    stream = stream or sys.stdout
    path = Path(notebook)
    if not path.is_file():
        raise FileNotFoundError(f"notebook: no such file: {path}")
    catalog = course_near(path, course)
    if not catalog.default():
        raise ValueError(
            f"notebook: the course folder {catalog.root} holds no exercise's grading module "
            "(exercises/<id>/grading.py): pass --course DIR (a checkout of the course), or ask your "
            "instructor for a bundle made by `flowtrack release`"
        )
    renamed_note = ""
    try:
        exercise = catalog.get(path)  # a notebook, or a source file in another language
    except KeyError as exc:
        # an LMS-renamed copy ("exNN_name (1).ipynb") is checked, with the rename to make
        found = suggest_rename(path, catalog.default())
        if found is None:
            raise ValueError(f"notebook: {path.name} is not one of the course's exercises ({exc})") from None
        exercise, renamed_note = found
    options = GradingOptions().hiding(catalog.root)
    try:
        result = run_exercise(exercise, path, None, public_only=True, options=options)
    except (SandboxConfigError, CannotGradeHere) as exc:  # the installation, not the student's work
        print(f"{exercise.id}: NOT CHECKED\n\n{exc}", file=stream)
        return 3
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
