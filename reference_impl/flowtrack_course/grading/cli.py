"""The autograder's sub-commands of ``flowtrack``: ``release``, ``check``, ``grade``, ``gradescope``.

Only argument parsing lives here (imports stay light: ``flowtrack --help`` imports this module);
the work is done by :mod:`.release`, :mod:`.check`, :mod:`.grade` and :mod:`.gradescope`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..argtypes import positive_int

__all__ = ["register"]


def _cmd_release(args: argparse.Namespace) -> int:
    from .release import release

    info = release(args.out, source=args.source, force=args.force)
    print(
        f"wrote {info['out']}: {len(info['lessons'])} lessons, {len(info['exercises'])} exercises "
        "(no solutions, hidden tests or outputs)"
    )
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from .check import check_notebook

    return check_notebook(args.notebook)


def _secret(path: str | None) -> bytes | None:
    """The instructor's seed key of ``--secret-file`` (created if missing), or None with a warning."""
    from .spec import read_secret

    if path is None:
        print(
            "warning: no --secret-file: hidden-test inputs are seeded from student and test names only, "
            "so a student who has the course package can predict them",
            file=sys.stderr,
        )
        return None
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
    from .grade import grade_class

    secret = _secret(args.secret_file)
    rows = grade_class(
        args.submissions,
        args.out,
        jobs=args.jobs,
        force=args.force,
        hidden_visibility=args.hidden_visibility,
        assignment=args.assignment,
        progress=not args.no_progress,
        secret=secret,
    )
    graded = sum(1 for r in rows if not r.get("skipped") and "error" not in r)
    skipped = sum(1 for r in rows if r.get("skipped"))
    errors = sum(1 for r in rows if "error" in r)
    out = Path(args.out)
    print(
        f"graded {graded} students, kept {skipped} finished ones, {errors} errors; wrote "
        f"{out / 'grades.csv'}, {out / 'gradebook.db'} and {out}/<student>/results.json, feedback/"
    )
    return 1 if errors else 0


def _cmd_gradescope(args: argparse.Namespace) -> int:
    from .gradescope import build_autograder

    _secret(args.secret_file)  # creates a missing key (and says so), or warns that there is none
    path = build_autograder(args.out, source=args.course, secret_file=args.secret_file)
    print(f"wrote {path} (upload it as the assignment's autograder; Ubuntu 24.04 base image)")
    return 0


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
    p.add_argument("notebook", help="the exercise notebook, e.g. exercises/01_projection_jacobian.ipynb")
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
    _add_secret_option(p)
    p.set_defaults(func=_cmd_grade)

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
        "--course", metavar="DIR", default=None,
        help="the course checkout holding pyproject.toml and reference_impl/ (default: "
        "$FLOWTRACK_COURSE, else the current folder)",
    )
    _add_secret_option(p)
    p.set_defaults(func=_cmd_gradescope)


if __name__ == "__main__":  # pragma: no cover
    print("use: flowtrack release|check|grade|gradescope --help", file=sys.stderr)
