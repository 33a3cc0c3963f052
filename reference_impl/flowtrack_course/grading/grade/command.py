"""``flowtrack grade``: a class graded as an instructor runs it.

:func:`grade_class` grades a class (:func:`~..engine.classrun.run_class`) and writes the nbgrader
gradebook (:mod:`..export.gradebook`). :func:`run_grade` is the command around it:

1. :func:`~..engine.layout.check_layout` on SUBMISSIONS: flat layouts, renamed copies and unknown
   files are reported with the expected layout and suggested ``mv`` commands; with
   ``accept_renamed`` the best copy of a notebook is graded, the original's place taken by a newer
   resubmission too (the feedback names the file graded and those ignored);
2. the students that will be re-graded and why (:func:`~.keys.regrade_reasons`);
3. grading, with the roster's names and e-mails in the nbgrader gradebook;
4. ``OUT/misconceptions.csv`` and ``OUT/class_report.md`` (:mod:`..export.classreport`), and with
   ``lms`` ``OUT/canvas.csv`` or ``OUT/moodle.csv`` (:mod:`..export.lms`).

A run that grades no student (no student folder, or no folder holding any expected notebook) ends
with exit status 2 and the reason; an error grading a student gives 1; a grader whose sandbox cannot
import what an exercise allows (checked before any student is graded:
:func:`~..engine.run.check_environment`), or a class whose every student failed an exercise the same
way (:func:`~..engine.classrun.uniform_failures`), gives 3 and says so; so does an environment
without nbgrader (a student install), before anyone is graded.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

from grading_sandbox import SandboxConfigError

from ..engine.classrun import OUTPUT_FILES, run_class, uniform_failures
from ..engine.jobs import ClassJob
from ..engine.spec import CannotGradeHere

__all__ = ["GradeRun", "grade_class", "run_grade"]


def grade_class(job: ClassJob, *, assignment: str = "flowtrack", roster: dict | None = None) -> list[dict]:
    """Grade the class ``job`` (:func:`~..engine.classrun.run_class`: ``grades.csv``, each student's
    ``results.json`` and feedback) and write ``OUT/gradebook.db``, an nbgrader gradebook (assignment
    ``assignment``, one notebook per exercise; ``roster`` (:func:`~..export.lms.read_roster`) fills
    names and e-mails). Returns one summary per student (sorted by student).
    """
    from ..export.gradebook import write_gradebook

    rows, exercises, students = run_class(job)
    write_gradebook(job.out / OUTPUT_FILES["gradebook"], exercises, job.out, students, assignment=assignment,
                    roster=roster)
    return rows


def _have_nbgrader() -> bool:
    """Whether the gradebook's nbgrader can be imported (without importing it: that takes a second)."""
    if "nbgrader" in sys.modules:
        return sys.modules["nbgrader"] is not None
    return importlib.util.find_spec("nbgrader") is not None


@dataclass
class GradeRun:
    """Outcome of :func:`run_grade`: exit status, the per-student rows and the summary lines."""

    status: int
    rows: list[dict] = field(default_factory=list)
    summary: list[str] = field(default_factory=list)
    reason: str = ""
    regraded: dict[str, str] = field(default_factory=dict)
    files: dict[str, Path] = field(default_factory=dict)


def run_grade(
    job: ClassJob,
    *,
    assignment: str = "flowtrack",
    accept_renamed: bool = False,
    roster: str | os.PathLike | None = None,
    lms: str | None = None,
    lms_mode: str = "total",
    ignore_flat: bool = False,
) -> GradeRun:
    """Check the layout, grade, and write the class outputs (see the module docstring).

    ``job`` says what to grade and how (its ``renamed`` and ``ignored`` are filled from the layout
    check: with ``accept_renamed`` the newest copy of each notebook is graded); ``roster`` is the
    roster CSV's path; ``lms`` ``"canvas"`` or ``"moodle"``. A student folder whose name cannot be an
    id is left out with a message, and so are files directly in SUBMISSIONS; both make the exit status
    1 (the latter unless ``ignore_flat``).
    """
    from ..engine.layout import check_layout
    from ..engine.seeds import secret_id
    from ..engine.student import exercises_hash, locate_notebooks, submission_hash
    from ..export.classreport import write_class_outputs
    from .keys import describe_regrades, regrade_reasons

    log = job.log or (lambda msg: print(msg, file=sys.stderr))
    if lms not in (None, "canvas", "moodle"):
        raise ValueError(f"lms must be 'canvas' or 'moodle', got {lms!r}")
    if lms_mode not in ("total", "exercises"):
        raise ValueError(f"lms_mode must be 'total' or 'exercises', got {lms_mode!r}")
    submissions = job.submissions
    exercises = job.resolved()  # the notebooks, and the language items someone in the class answered
    roster_map = None
    if roster is not None:
        from ..export.lms import read_roster

        roster_map = read_roster(roster)
    report = check_layout(submissions, exercises)
    for msg in report.messages(exercises, accept_renamed=accept_renamed):
        log(msg)
    if not report.students:
        if report.flat or report.flat_unmatched:
            why = "the notebooks are directly in SUBMISSIONS (see the suggested moves above)"
        elif report.unusable:
            why = f"the {len(report.unusable)} folder name(s) in {submissions} cannot be student ids (above)"
        else:
            why = "SUBMISSIONS holds no student folder"
        return GradeRun(2, reason=f"graded no student: {why}")
    renamed = report.renamed_map() if accept_renamed else {}
    ignored = report.ignored_map(accept_renamed=accept_renamed)
    usable = [s for s in report.students if report.found.get(s) or renamed.get(s)]
    if not usable:
        hint = " (renamed copies were found: rename them or use --accept-renamed)" if report.renamed else ""
        return GradeRun(
            2,
            reason=(
                f"graded no student: none of the {len(report.students)} student folder(s) holds an expected "
                f"notebook{hint}"
            ),
        )
    # why earlier results are re-graded (the same comparison grade_student makes)
    ex_hash = exercises_hash(exercises)
    sub_hashes = {}
    for s in report.students:
        notebooks, _ = locate_notebooks(Path(submissions) / s, exercises, renamed.get(s), ignored.get(s))
        sub_hashes[s] = submission_hash(notebooks)
    reasons = regrade_reasons(
        job.out,
        report.students,
        exercises_hash=ex_hash,
        submission_hashes=sub_hashes,
        key_id=secret_id(job.options.secret),
        force=job.options.force,
    )
    job = replace(job, exercises=exercises, renamed=renamed, ignored=ignored, log=log)
    if not _have_nbgrader():  # the gradebook is written last: say so before grading anyone
        return GradeRun(3, reason=(
            "flowtrack grade writes an nbgrader gradebook, and nbgrader is not installed in this "
            "environment (a student install?): python -m pip install 'flowtrack[grading]' "
            "(graded no student: nothing was written)"))
    try:
        rows = grade_class(job, assignment=assignment, roster=roster_map)
    except (SandboxConfigError, CannotGradeHere) as exc:  # found before any student was graded
        return GradeRun(3, reason=f"{exc}\n(graded no student: nothing was written)")
    out = job.out
    files = {"grades": out / OUTPUT_FILES["grades"], "gradebook": out / OUTPUT_FILES["gradebook"]}
    files["misconceptions"], files["class_report"] = write_class_outputs(out, rows, exercises)
    summary = []
    graded = sum(1 for r in rows if not r.get("skipped") and "error" not in r)
    skipped = sum(1 for r in rows if r.get("skipped"))
    errors = sum(1 for r in rows if "error" in r)
    summary.append(
        f"graded {graded} students, kept {skipped} finished ones, {errors} errors; wrote "
        f"{out / 'grades.csv'}, {out / 'gradebook.db'} and {out}/<student>/results.json, feedback/"
    )
    reasons = {
        s: why for s, why in reasons.items() if any(r["student"] == s and not r.get("skipped") for r in rows)
    }
    if reasons:
        summary.append(describe_regrades(reasons))
    if accept_renamed and report.renamed:
        summary.append(
            f"accepted {len(report.renamed)} renamed notebook(s) (noted in those students' feedback)"
        )
    elif report.renamed:
        summary.append(
            f"warning: {len(report.renamed)} renamed notebook(s) were not graded "
            "(see above; --accept-renamed)"
        )
    stray = len(report.flat) + len(report.flat_unmatched)
    if stray and not ignore_flat:
        summary.append(
            f"error: {stray} file(s) directly in {submissions} were not graded (notebooks go in one folder "
            "per student: see the suggested moves above); move them and grade again, or pass --ignore-flat "
            "to leave them out"
        )
    elif stray:
        summary.append(f"warning: {stray} file(s) directly in {submissions} left out (--ignore-flat)")
    if report.unusable:
        summary.append(
            f"error: {len(report.unusable)} student folder(s) not graded: their names cannot be student ids "
            f"({', '.join(ascii(n) for n in sorted(report.unusable)[:10])}; see above)"
        )
    empty = [s for s in report.students if s not in usable]
    if empty:
        summary.append(
            f"warning: {len(empty)} student folder(s) hold no expected notebook (scored 0): "
            + ", ".join(empty[:10])
        )
    summary.append(f"wrote {files['misconceptions']} and {files['class_report']}")
    uniform = uniform_failures(rows, exercises)
    summary += [f"error: {line}" for line in uniform]
    config = any(r.get("config_error") for r in rows)
    if lms:
        from ..export.lms import export_lms

        path, warnings = export_lms(
            lms,
            files["grades"],
            out / OUTPUT_FILES[lms],
            roster=roster_map,
            mode=lms_mode,
            assignment=assignment,
        )
        files["lms"] = path
        summary.append(f"wrote {path} ({lms} gradebook import, {lms_mode})")
        summary += [f"warning: {w}" for w in warnings]
    if roster_map is not None and not lms:  # (the LMS export reports the same)
        from ..export.lms import roster_entry

        unknown = [r["student"] for r in rows if roster_entry(roster_map, r["student"]) is None]
        if unknown:
            summary.append(f"warning: {len(unknown)} student(s) not in the roster: {', '.join(unknown[:10])}")
    problems = errors or report.unusable or (stray and not ignore_flat)
    status = 3 if (uniform or config) else 1 if problems else 0
    return GradeRun(status, rows, summary, "", reasons, files)
