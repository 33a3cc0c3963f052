"""The Gradescope runner: one submission graded as ``run_autograder`` asks (:func:`run_submission`,
``python -m flowtrack_course.grading.grade.gradescope run``; the zip is
:mod:`~flowtrack_course.grading.export.gradescope`'s).

The hidden tests' inputs are seeded by the submitter's Gradescope id from
``submission_metadata.json`` (an error result when it is missing or names nobody), keyed by the
instructor's ``secret`` when the zip holds one. Students upload their notebooks in any folder layout
(they are found by file name). The course's grading modules are in the zip's ``course/``
(``--course``); they, the key, the metadata and the results folder must stay unreadable to the
sandbox, which is checked for real where student code runs as another uid (the setpriv mode).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

__all__ = ["MetadataError", "main", "run_submission", "student_from_metadata"]

_SAFE = re.compile(r"[^A-Za-z0-9_.@+\-]")


class MetadataError(ValueError):
    """``submission_metadata.json`` is missing or names no submitter."""


def student_from_metadata(path: str | os.PathLike | None) -> str:
    """The submitter's id from Gradescope's ``submission_metadata.json``.

    The first user's ``id`` (else ``email``), made safe for a folder name. Hidden-test inputs are
    seeded by it, so there is no silent default.

    Raises
    ------
    MetadataError
        No file, unreadable JSON, or no user id or e-mail in it.
    """
    if path is None:
        raise MetadataError("submission_metadata.json: no file given (--metadata or --student)")
    try:
        meta = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise MetadataError(f"submission_metadata.json: cannot read {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise MetadataError(f"submission_metadata.json: {path} is not JSON: {exc}") from None
    ident = None
    if isinstance(meta, dict):
        users = meta.get("users")
        if isinstance(users, list) and users and isinstance(users[0], dict):
            ident = users[0].get("id") or users[0].get("email")
    name = _SAFE.sub("_", str(ident))[:120] if ident not in (None, "") else ""
    if not name:
        raise MetadataError(f"submission_metadata.json: {path} names no submitter (users[0].id or email)")
    return name


def run_submission(
    submission: str | os.PathLike,
    results: str | os.PathLike,
    *,
    student: str = "submission",
    exercises=None,
    catalog=None,
    options=None,
) -> dict:
    """Grade one Gradescope submission folder and write ``results`` (Gradescope's results.json).

    ``exercises`` default to the ``catalog``'s for this submission (what the course's assignment
    gives this student: its notebooks and, where it assigns other languages, the answers in the
    student's; files beyond it are ignored with a note; ``catalog`` default: the course folder of
    ``$FLOWTRACK_COURSE``, else the current folder, with its ``assignment.toml``). ``options``
    (:class:`~..engine.jobs.GradingOptions`) carry the key and the paths to hide. Never raises
    because of the submission; an internal error still writes a results.json with score 0 and the
    error as output, so Gradescope shows something.
    """
    import tempfile
    from dataclasses import replace

    from ..engine.jobs import GradingOptions, StudentJob
    from ..engine.results import student_folder, write_atomic
    from ..engine.student import grade_student

    results = Path(results)
    try:
        notes: tuple[str, ...] = ()
        if exercises is None:
            if catalog is None:
                from ..sources import course_catalog

                catalog = course_catalog()
            # what the assignment gives this student: an upload beyond it is ignored (with a note),
            # never added to the total (which could then exceed 100 %)
            exercises = catalog.for_student(submission)
            notes = tuple(catalog.ignored(submission))
        options = replace(options or GradingOptions(), force=True)
        with tempfile.TemporaryDirectory(prefix="flowtrack-gs-") as tmp:
            job = StudentJob(student, Path(submission), Path(tmp), tuple(exercises), options.hiding(tmp),
                             notes=notes)
            summary = grade_student(job)
            results_file = Path(tmp) / student_folder(student) / "results.json"
            data = json.loads(results_file.read_text(encoding="utf-8"))
        if summary.get("isolation", "").startswith("fallback"):
            data["output"] += f"\n(sandbox isolation: {summary['isolation']})"
    except Exception as exc:  # Gradescope must get a results.json
        from grading_sandbox import SandboxConfigError

        from ..engine.spec import CannotGradeHere

        if isinstance(exc, (SandboxConfigError, CannotGradeHere)):  # the image, not the student's work
            message = f"autograder configuration error: {exc}"
        else:
            message = f"autograder error: {type(exc).__name__}: {exc}"
        data = _error_data(message)
    write_atomic(results, json.dumps(data, indent=1))
    return data


def main(argv: list[str] | None = None) -> int:
    """``python -m flowtrack_course.grading.grade.gradescope run --submission DIR --results FILE
    [--metadata F] [--course DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m flowtrack_course.grading.grade.gradescope")
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run", help="grade one Gradescope submission (what run_autograder calls)")
    run.add_argument("--submission", required=True, help="the submission folder")
    run.add_argument("--results", required=True, help="where to write results.json")
    run.add_argument("--metadata", default=None, help="Gradescope's submission_metadata.json")
    run.add_argument("--student", default=None, help="student id (default: from --metadata)")
    run.add_argument("--exercises", default=None, help="comma-separated exercise ids (default: all)")
    run.add_argument("--secret-file", default=None, help="the instructor's seed key (the zip's secret)")
    run.add_argument("--course", default=None,
                     help="the course folder with the exercises' grading modules (the zip's course/; "
                     "default: $FLOWTRACK_COURSE, else the current folder)")
    run.add_argument("--allow-unsafe-sandbox", action="store_true",
                     help="grade even when student code can only run in the fallback sandbox")
    args = parser.parse_args(argv)
    try:
        from ..engine.jobs import GradingOptions
        from ..sources import course_catalog

        student = args.student or student_from_metadata(args.metadata)
        catalog = course_catalog(args.course)
        exercises = None
        if args.exercises:
            exercises = [catalog.get(i) for i in catalog.resolve_ids(args.exercises)]
        secret = None
        if args.secret_file:
            from ..engine.seeds import read_secret

            secret = read_secret(args.secret_file)
    except Exception as exc:  # an explicit error result, never no results.json
        return _error_result(args.results, f"autograder configuration error: {type(exc).__name__}: {exc}")
    protect = [Path(args.results).resolve().parent, catalog.root / "exercises",
               *(Path(f) for f in (args.secret_file, args.metadata) if f), *_grader_packages()]
    problem = _isolation_problem([p for p in protect if p.exists()], args.allow_unsafe_sandbox)
    if problem:
        return _error_result(args.results, problem)
    from ..engine.results import format_score

    options = GradingOptions(secret=secret).hiding(args.submission, *protect, catalog.root)
    data = run_submission(args.submission, args.results, student=student, exercises=exercises,
                          catalog=catalog, options=options)
    print(f"flowtrack autograder: {student}: score {format_score(data.get('score', 0))}", file=sys.stderr)
    return 0


def _isolation_problem(protect: list[Path], allow_unsafe: bool) -> str:
    """Why student code cannot be isolated from the grader here ("" when it can).

    bubblewrap shows the sandbox none of the autograder's files. Without it (Docker's default seccomp
    profile forbids the namespaces), the setpriv mode runs student code as an unprivileged uid, which
    holds only while file permissions keep ``protect`` (results folder, key, tests, metadata) from
    it: checked for real. The fallback (no root, no setpriv) is refused unless ``allow_unsafe``.
    """
    from grading_sandbox import SandboxUnavailable, choose_mode, readable_by_sandbox

    try:
        mode, why = choose_mode()
    except SandboxUnavailable as exc:
        return f"autograder configuration error: {exc}"
    if mode == "fallback" and not allow_unsafe:
        return (f"autograder configuration error: student code cannot be isolated here ({why}); run "
                "the autograder as root (Gradescope does) with util-linux's setpriv, or pass "
                "--allow-unsafe-sandbox")
    if mode == "setpriv":
        exposed = readable_by_sandbox(protect)
        if exposed:
            return ("autograder configuration error: the sandbox's unprivileged uid could read "
                    + ", ".join(map(str, exposed)) + " (setup.sh makes the installed packages private and "
                    "run_autograder the rest: chmod -R go-rwx " + " ".join(map(str, exposed)) + ")")
    return ""


def _grader_packages() -> list[Path]:
    """The folders of the packages this grader runs from (the library, the grader, the sandbox):
    student code gets copies of what it may see, never these (they hold the reference code of the
    blocked modules and the grader's own)."""
    from grading_sandbox.runtime import package_dir

    from ..export.gradescope import PACKAGES

    out = []
    for name in PACKAGES:
        try:
            out.append(package_dir(name))
        except ValueError:
            continue
    return out


def _error_data(message: str) -> dict:
    """A Gradescope error result: score 0, the message shown, said not to be the student's doing."""
    from ..engine.results import FORMAT

    return {
        "score": 0.0,
        "output": message + "\nThis is not a problem with your work; please tell your instructor.",
        "visibility": "visible",
        "stdout_visibility": "hidden",
        "tests": [],
        "extra_data": {"flowtrack": {"format": FORMAT, "error": message}},
    }


def _error_result(results: str | os.PathLike, message: str) -> int:
    """Write a Gradescope error result (score 0, the message shown) and return exit status 1."""
    from ..engine.results import write_atomic

    write_atomic(Path(results), json.dumps(_error_data(message), indent=1))
    print(f"flowtrack autograder: {message}", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
