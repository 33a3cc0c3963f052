"""The autograder's sub-commands of ``flowtrack``: ``release``, ``check``, ``grade``, ``export``,
``gradescope``.

Only argument parsing lives here (imports stay light: ``flowtrack --help`` imports this module);
the work is done by the commands' folders (the packages ``assign``, ``check``, ``grade`` and
``export`` of :mod:`flowtrack_course.grading`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..argtypes import positive_int

__all__ = ["register"]


def _cmd_release(args: argparse.Namespace) -> int:
    from .assign.release import release

    info = release(args.out, source=args.source, force=args.force)
    print(
        f"wrote {info['out']}: {len(info['lessons'])} lessons, {len(info['exercises'])} exercises "
        "(no solutions, hidden tests or outputs)"
    )
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from .check.check import check_notebook

    return check_notebook(args.notebook, course=args.course)


def _secret(path: str | None) -> bytes | None:
    """The instructor's seed key of ``--secret-file`` (created if missing), or None with a warning."""
    from .engine.seeds import read_secret

    if path is None:
        print(
            "warning: no --secret-file: hidden-test inputs are seeded from student and test names only, "
            "so a student who has the course package can predict them",
            file=sys.stderr,
        )
        return None
    from .grade.keys import check_key_file

    check_key_file(path)  # refuse a key others can read (InsecureKeyError, a ValueError)
    existed = Path(path).exists()
    secret = read_secret(path, create=True)
    if not existed:
        print(f"created the seed key {path} (owner-only; reuse it for this class)", file=sys.stderr)
    return secret


def _add_secret_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--secret-file",
        metavar="FILE",
        default=None,
        help="the instructor's seed key for hidden-test inputs (created with 32 random bytes if missing; "
        "keep it away from students and reuse it for every run of a class)",
    )


def _cmd_grade(args: argparse.Namespace) -> int:
    # layout checks, re-grade reasons, class report and LMS export: grade.command.run_grade
    from ..course import use_course
    from .engine.classrun import UnsafeSandbox
    from .engine.jobs import ClassJob, GradingOptions
    from .grade.command import run_grade
    from .sources import course_catalog

    # the course of this run, also for the worker processes (their fork server reads the variable)
    course = use_course(args.course, need=("exercises",))

    options = GradingOptions(
        secret=_secret(args.secret_file),
        hidden_paths=(args.secret_file,) if args.secret_file else (),
        hidden_visibility=args.hidden_visibility,
        force=args.force,
    )
    from .assignment import assignment_of

    assignment = assignment_of(course, args.assignment_file)
    catalog = course_catalog(course, assignment)
    print(f"assignment ({assignment.source or 'default: no assignment.toml'}): {assignment.describe()}",
          file=sys.stderr)
    job = ClassJob(
        args.submissions, args.out, catalog=catalog, jobs=args.jobs, options=options,
        allow_unsafe_sandbox=args.allow_unsafe_sandbox, progress=not args.no_progress,
    )
    try:
        run = run_grade(
            job,
            assignment=args.assignment,
            accept_renamed=args.accept_renamed,
            roster=args.roster,
            lms=args.lms,
            lms_mode="exercises" if args.lms_per_exercise else "total",
            ignore_flat=args.ignore_flat,
        )
    except UnsafeSandbox as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if run.reason:
        print(f"error: {run.reason}", file=sys.stderr)
    for line in run.summary:
        print(line)
    return run.status


def _cmd_export(args: argparse.Namespace) -> int:
    from .export.lms import export_lms

    path, warnings = export_lms(
        args.lms, args.grades, args.out, roster=args.roster,
        mode="exercises" if args.per_exercise else "total", assignment=args.assignment,
        assignment_id=args.canvas_assignment_id,
    )
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"wrote {path} ({args.lms} gradebook import)")
    return 0


def _cmd_gradescope(args: argparse.Namespace) -> int:
    from .export.gradescope import build_autograder

    _secret(args.secret_file)  # creates a missing key (and says so), or warns that there is none
    path = build_autograder(
        args.out, source=args.course, secret_file=args.secret_file, exercises=args.exercises,
        assignment=args.assignment_file,
    )
    print(f"wrote {path} (upload it as the assignment's autograder; Ubuntu 24.04 base image)")
    return 0


def _add_assignment_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--assignment-file", metavar="FILE", default=None,
        help="what counts: which exercises and which other languages (an assignment.toml; default: the "
        "course's assignment.toml, else every notebook exercise and no other language). Uploads outside "
        "it are ignored with a note and never change anyone's maximum",
    )


def _add_instructor_options(p: argparse.ArgumentParser) -> None:
    """``flowtrack grade``'s options for what an LMS delivers and takes: renamed copies, roster, LMS
    export."""
    p.add_argument(
        "--accept-renamed",
        action="store_true",
        help="grade the newest copy of each notebook ('name (1).ipynb', 'name-2.ipynb', case changes: how "
        "Canvas and Moodle rename resubmissions; the highest copy number, then the newest file), also when "
        "the original is there, and name the file graded and those ignored in the student's feedback",
    )
    p.add_argument(
        "--ignore-flat",
        action="store_true",
        help="leave out notebooks put directly in SUBMISSIONS (reported, not graded) without making the "
        "run's exit status 1",
    )
    p.add_argument(
        "--roster",
        metavar="FILE",
        default=None,
        help="CSV with a header: student (the folder name), name or first_name/last_name, email, "
        "optional section, sis_user_id, sis_login_id, canvas_id; fills names and e-mails in the gradebook "
        "and the LMS files",
    )
    p.add_argument(
        "--lms", choices=("canvas", "moodle"), default=None,
        help="also write OUT/canvas.csv or OUT/moodle.csv for the LMS gradebook's CSV import",
    )
    p.add_argument(
        "--lms-per-exercise", action="store_true",
        help="one LMS column per exercise instead of one assignment total",
    )


def _add_export_command(subparsers) -> None:
    p = subparsers.add_parser(
        "export",
        help="LMS gradebook import file (Canvas, Moodle) from a grade run's grades.csv",
        description=(
            "Writes the CSV the LMS gradebook imports: Canvas (Student, ID, SIS User ID, SIS Login ID, "
            "Section, assignment columns, Points Possible row) or Moodle (First name, Last name, ID number, "
            "Email address, grade item columns). --roster maps student ids to names, e-mails and LMS ids."
        ),
    )
    p.add_argument("--lms", required=True, choices=("canvas", "moodle"), help="the LMS")
    p.add_argument("--grades", required=True, help="grades.csv of a flowtrack grade run")
    p.add_argument("--roster", default=None, help="roster CSV (see flowtrack grade --help)")
    p.add_argument("--out", required=True, help="the CSV to write")
    p.add_argument("--per-exercise", action="store_true", help="one column per exercise (default: total)")
    p.add_argument("--assignment", default="flowtrack", help="assignment (column) name in the LMS")
    p.add_argument(
        "--canvas-assignment-id", default=None,
        help="Canvas assignment id: the column becomes 'NAME (ID)' and updates that assignment",
    )
    p.set_defaults(func=_cmd_export)


def register(subparsers) -> None:
    """Add ``release``, ``check``, ``grade`` and ``gradescope`` to ``flowtrack``'s sub-commands."""
    p = subparsers.add_parser(
        "release",
        help="write the student bundle (lessons, exercises without solutions or hidden tests)",
        description=(
            "Student bundle: OUT/README.md, OUT/lessons/*.ipynb (from the jupytext sources, no "
            "outputs), OUT/exercises/*.ipynb made with nbgrader's preprocessors (solutions replaced "
            "by stubs, hidden tests and outputs removed). The bundle is scanned before it is written."
        ),
    )
    p.add_argument("--out", required=True, help="bundle folder (replaced if it is an earlier bundle)")
    p.add_argument(
        "--course", "--source", dest="source", metavar="DIR", default=None,
        help="the course folder with exercises/ and lessons/ (default: $FLOWTRACK_COURSE, else the "
        "current folder)",
    )
    p.add_argument("--force", action="store_true", help="replace OUT even if it is not an earlier bundle")
    p.add_argument(
        "--with-checks", action="store_true",
        help="accepted for older scripts: every bundle holds each exercise's grading module "
        "(OUT/exercises/<id>/grading.py), which `flowtrack check` runs",
    )
    p.set_defaults(func=_cmd_release)

    p = subparsers.add_parser(
        "check",
        help="run an exercise notebook's public tests (a student's own check)",
        description=(
            "Runs the public tests of the exercise NOTEBOOK belongs to (found by its file name) in the "
            "grader's sandbox with the grader's inputs; prints each test's result and the public "
            "score. Exit status 0 when every public test passes, 1 otherwise."
        ),
    )
    p.add_argument("notebook", help="the exercise notebook, e.g. exercises/ex01_projection_jacobian.ipynb")
    p.add_argument(
        "--course", metavar="DIR", default=None,
        help="the course folder (or bundle) with exercises/ (default: $FLOWTRACK_COURSE, else the current "
        "folder, else the folder above NOTEBOOK that holds exercises/)",
    )
    p.set_defaults(func=_cmd_check)

    p = subparsers.add_parser(
        "grade",
        help="grade a class: SUBMISSIONS/<student>/<exercise notebooks>",
        description=(
            "Grades every student folder of SUBMISSIONS. Writes OUT/grades.csv, "
            "OUT/<student>/results.json (Gradescope format), OUT/<student>/feedback/ and the nbgrader "
            "gradebook OUT/gradebook.db. Finished students are kept on a re-run unless --force."
        ),
    )
    p.add_argument("submissions", help="folder with one sub-folder per student")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--jobs", type=positive_int, default=1, help="students graded in parallel (default: 1)")
    p.add_argument("--force", action="store_true", help="re-grade students whose results are up to date")
    p.add_argument(
        "--hidden-visibility",
        default="after_published",
        choices=("hidden", "after_due_date", "after_published"),
        help="Gradescope visibility of hidden tests (default: after_published)",
    )
    p.add_argument("--assignment", default="flowtrack", help="assignment name in the gradebook")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    p.add_argument(
        "--allow-unsafe-sandbox",
        action="store_true",
        help="grade even where bubblewrap cannot run: student code then runs in the fallback sandbox, "
        "whose in-process guard a determined student can get around (other students' work, the output "
        "folder and the seed key become readable)",
    )
    p.add_argument(
        "--course", metavar="DIR", default=None,
        help="the course folder with exercises/ (default: $FLOWTRACK_COURSE, else the current folder)",
    )
    _add_secret_option(p)
    _add_assignment_option(p)
    _add_instructor_options(p)
    p.set_defaults(func=_cmd_grade)
    _add_export_command(subparsers)

    p = subparsers.add_parser(
        "gradescope",
        help="build a Gradescope autograder zip running the same grader",
        description=(
            "Writes a Gradescope autograder bundle: setup.sh (Debian packages and pip install of "
            "flowtrack from the included source tree), run_autograder (grades /autograder/submission "
            "into /autograder/results/results.json) and the flowtrack package."
        ),
    )
    p.add_argument("--out", default="autograder.zip", help="zip to write (default: autograder.zip)")
    p.add_argument(
        "--exercises", default=None, metavar="IDS",
        help="comma-separated exercise ids graded by this autograder, e.g. ex01_projection_jacobian,"
        "ex05_cv_model (default: all)",
    )
    p.add_argument(
        "--course", metavar="DIR", default=None,
        help="the course checkout holding pyproject.toml, reference_impl/ and exercises/ (default: "
        "$FLOWTRACK_COURSE, else the current folder)",
    )
    _add_secret_option(p)
    _add_assignment_option(p)
    p.set_defaults(func=_cmd_gradescope)


if __name__ == "__main__":  # pragma: no cover
    print("use: flowtrack release|check|grade|gradescope --help", file=sys.stderr)
