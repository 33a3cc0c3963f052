"""``flowtrack grade``: a class graded as an instructor runs it.

:func:`grade_class` grades a class (:func:`~..engine.classrun.run_class`) and writes the nbgrader
gradebook (:mod:`..export.gradebook`). :func:`run_grade` is the command around it:

1. :func:`~..engine.layout.check_layout` on SUBMISSIONS: flat layouts, renamed copies and unknown
   files are reported with the expected layout and suggested ``mv`` commands; with
   ``accept_renamed`` the best renamed copy of a missing notebook is graded (and the feedback says so);
2. the students that will be re-graded and why (:func:`~.keys.regrade_reasons`);
3. grading, with the roster's names and e-mails in the nbgrader gradebook;
4. ``OUT/misconceptions.csv`` and ``OUT/class_report.md`` (:mod:`..export.classreport`), and with
   ``lms`` ``OUT/canvas.csv`` or ``OUT/moodle.csv`` (:mod:`..export.lms`).

A run that grades no student (no student folder, or no folder holding any expected notebook) ends
with exit status 2 and the reason; an error grading a student gives 1.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..engine.classrun import OUTPUT_FILES, run_class
from ..engine.jobs import ClassJob

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
) -> GradeRun:
    """Check the layout, grade, and write the class outputs (see the module docstring).

    ``job`` says what to grade and how (its ``renamed`` is filled from the layout check when
    ``accept_renamed``); ``roster`` is the roster CSV's path; ``lms`` ``"canvas"`` or ``"moodle"``.
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
    if report.bad_folders:
        return GradeRun(
            2,
            reason=(
                f"graded no student: {len(report.bad_folders)} folder name(s) in {submissions} are not "
                "usable student ids (see the suggested renames above)"
            ),
        )
    if not report.students:
        why = (
            "the notebooks are directly in SUBMISSIONS (see the suggested moves above)"
            if (report.flat or report.flat_unmatched)
            else "SUBMISSIONS holds no student folder"
        )
        return GradeRun(2, reason=f"graded no student: {why}")
    renamed = report.renamed_map() if accept_renamed else {}
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
        notebooks, _ = locate_notebooks(Path(submissions) / s, exercises, renamed.get(s))
        sub_hashes[s] = submission_hash(notebooks)
    reasons = regrade_reasons(
        job.out,
        report.students,
        exercises_hash=ex_hash,
        submission_hashes=sub_hashes,
        key_id=secret_id(job.options.secret),
        force=job.options.force,
    )
    job = replace(job, exercises=exercises, renamed=renamed, log=log)
    rows = grade_class(job, assignment=assignment, roster=roster_map)
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
    empty = [s for s in report.students if s not in usable]
    if empty:
        summary.append(
            f"warning: {len(empty)} student folder(s) hold no expected notebook (scored 0): "
            + ", ".join(empty[:10])
        )
    summary.append(f"wrote {files['misconceptions']} and {files['class_report']}")
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
        unknown = [r["student"] for r in rows if r["student"] not in roster_map]
        if unknown:
            summary.append(f"warning: {len(unknown)} student(s) not in the roster: {', '.join(unknown[:10])}")
    return GradeRun(1 if errors else 0, rows, summary, "", reasons, files)
