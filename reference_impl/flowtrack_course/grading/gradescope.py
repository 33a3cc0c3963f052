"""``flowtrack gradescope --out autograder.zip``: a Gradescope autograder running flowtrack's grader.

The zip holds::

    setup.sh          Debian packages (python3, venv, bubblewrap), the ``grader`` extra's pinned
                      requirements (requirements-grader.txt: numpy, scipy, ... no open3d,
                      scikit-image or Jupyter) and ``pip install --no-deps ./flowtrack`` into
                      /autograder/venv (PyPI only)
    requirements-grader.txt   pyproject.toml's ``grader`` extra
    run_autograder    grades /autograder/submission as one student and writes
                      /autograder/results/results.json; when the grader itself fails
                      (flowtrack not importable, ...) it writes an error result instead
    flowtrack/        the packages' source tree (pyproject.toml, README.md, reference_impl/flowtrack and
                      reference_impl/flowtrack_course),
                      which carries the exercises' trusted test definitions

``run_autograder`` calls ``python -m flowtrack_course.grading.gradescope run`` (:func:`run_submission`); its
paths come from the environment so that it can be tried outside Gradescope: ``AUTOGRADER_ROOT``
(default ``/autograder``) and ``FLOWTRACK_PYTHON`` (default ``$AUTOGRADER_ROOT/venv/bin/python``).
The hidden tests' inputs are seeded by the submitter's Gradescope id from
``submission_metadata.json`` (an error result when it is missing or names nobody), keyed by the instructor's
``secret`` when the zip holds one (``flowtrack gradescope --secret-file``). ``flowtrack gradescope
--exercises ex01,ex05`` sets the exercises graded (the default of ``run_autograder``; the
``FLOWTRACK_EXERCISES`` environment variable overrides it).
Use a Gradescope base image with Python >= 3.11 (Ubuntu 24.04).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import zipfile
from pathlib import Path

from ..course import course_root

__all__ = ["MetadataError", "build_autograder", "grader_requirements", "main", "run_submission",
           "student_from_metadata"]

SETUP_SH = """\
#!/usr/bin/env bash
# Gradescope runs this once, as root, when the autograder image is built.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq python3 python3-venv python3-pip bubblewrap util-linux
# the toolchains of answers in C++, Octave and Java (Mathematica answers: mathics3, in the grader extra)
apt-get install -y -qq g++ libeigen3-dev nlohmann-json3-dev octave openjdk-17-jdk-headless \
    libgoogle-gson-java libejml-java
python3 - <<'EOF'
import sys
if sys.version_info < (3, 11):
    sys.exit(f"flowtrack needs Python >= 3.11, this image has {sys.version.split()[0]}: "
             "choose the Ubuntu 24.04 base image")
EOF
python3 -m venv /autograder/venv
/autograder/venv/bin/pip install -q --upgrade pip
# Only what grading imports (pyproject's `grader` extra, pinned in requirements-grader.txt): no open3d,
# scikit-image or Jupyter; then flowtrack itself without its dependencies.
/autograder/venv/bin/pip install -q -r /autograder/source/requirements-grader.txt
/autograder/venv/bin/pip install -q --no-deps "/autograder/source/flowtrack"
# Student code runs as a fresh unprivileged uid per sandbox: under bubblewrap where it can create
# namespaces, else (Docker's default seccomp profile) switched to with setpriv (util-linux), no
# capabilities, no_new_privs. That uid needs the Python runtime and numpy/scipy of the venv, and
# nothing of the grader: the installed flowtrack (its grading package holds the tests; the sandbox
# gets a filtered copy) and /autograder/source (the key) are the grader's only.
chmod o+x /autograder
chmod -R a+rX /autograder/venv
FT_DIR="$(/autograder/venv/bin/python -c 'import flowtrack, os; print(os.path.dirname(flowtrack.__file__))')"
chmod -R go-rwx "$FT_DIR" /autograder/source
"""

RUN_AUTOGRADER = r"""#!/usr/bin/env bash
# Gradescope runs this for every submission. Paths can be overridden to try it elsewhere.
# It always leaves a results.json: the grader's, or an error result when the grader itself failed.
set -uo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
PY="${FLOWTRACK_PYTHON:-$ROOT/venv/bin/python}"
EXERCISES="${FLOWTRACK_EXERCISES:-@EXERCISES@}"  # flowtrack gradescope --exercises (empty: all)
RESULTS="$ROOT/results/results.json"
mkdir -p "$ROOT/results"
rm -f "$RESULTS"
# Only the grader (root) may read or write these; the student's code runs as another uid.
chmod 700 "$ROOT/results"
chmod -R go-rwx "$ROOT/source" "$ROOT/submission" 2>/dev/null
[ -f "$ROOT/submission_metadata.json" ] && chmod go-rwx "$ROOT/submission_metadata.json"
SECRET=()
if [ -f "$ROOT/source/secret" ]; then  # the instructor's seed key (flowtrack gradescope --secret-file)
    chmod 600 "$ROOT/source/secret"
    SECRET=(--secret-file "$ROOT/source/secret")
fi
ERR="$(mktemp)"
"$PY" -m flowtrack_course.grading.gradescope run \
    --submission "$ROOT/submission" \
    --metadata "$ROOT/submission_metadata.json" \
    --results "$RESULTS" \
    ${EXERCISES:+--exercises "$EXERCISES"} \
    "${SECRET[@]}" 2>"$ERR"
STATUS=$?
cat "$ERR" >&2
if [ ! -s "$RESULTS" ]; then
    # The grader could not run (flowtrack not importable, no interpreter, killed): an error result.
    DETAIL="$(tail -c 1500 "$ERR" | tr -d '\000-\011\013-\037' \
        | sed -e 's/\\/\\\\/g' -e 's/"/\\"/g' | awk '{printf "%s\\n", $0}')"
    cat > "$RESULTS" <<EOF
{"score": 0.0, "visibility": "visible", "stdout_visibility": "hidden", "tests": [],
 "output": "autograder error: the grader failed before grading (exit status $STATUS); this is \
not a problem with your work, please tell your instructor.\n$DETAIL",
 "extra_data": {"flowtrack": {"format": "flowtrack-results/1", "error": "grader failed", "status": $STATUS}}}
EOF
fi
rm -f "$ERR"
exit 0
"""

_SAFE = re.compile(r"[^A-Za-z0-9_.@+\-]")


_PACKAGES = ("flowtrack", "flowtrack_course")  # the library and the grader that the zip installs


def _package_root(course: str | os.PathLike | None = None) -> Path:
    """The course checkout holding pyproject.toml and reference_impl/flowtrack{,_course}
    (``--course``, else ``$FLOWTRACK_COURSE``, else the current folder)."""
    return course_root(course, need=("pyproject.toml", *(f"reference_impl/{p}" for p in _PACKAGES)))


def build_autograder(
    out: str | os.PathLike,
    *,
    source: str | os.PathLike | None = None,
    secret_file: str | os.PathLike | None = None,
    exercises: str | list[str] | tuple[str, ...] | None = None,
) -> Path:
    """Write the Gradescope autograder zip to ``out`` (see the module docstring); returns its path.

    Only the packages (``reference_impl/flowtrack``, ``reference_impl/flowtrack_course``),
    ``pyproject.toml`` and ``README.md`` are copied:
    no exercises, solutions, lessons or caches. With ``secret_file`` (created if missing, see
    :func:`~flowtrack_course.grading.spec.read_secret`) the key is added as ``secret`` (mode 0600: the
    sandbox's unprivileged uid cannot read it, and it is not bound into the sandbox) and seeds the
    hidden tests. ``exercises`` (ids, or a comma-separated string; default all) become
    ``run_autograder``'s default (one Gradescope assignment per exercise set).
    """
    ex_ids = _exercise_ids(exercises)
    secret = None
    if secret_file is not None:
        from .keys import check_key_file
        from .spec import read_secret

        check_key_file(secret_file)  # issue 18 hook: refuse a key others can read
        secret = read_secret(secret_file, create=True)
    root = _package_root(source)
    pkgs = [root / "reference_impl" / p for p in _PACKAGES]
    for pkg in pkgs:
        if not pkg.is_dir():
            raise FileNotFoundError(f"source: no reference_impl/{pkg.name} in {root}")
    out = Path(out)
    if out.suffix != ".zip":
        raise ValueError(f"out must name a .zip file, got {out}")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp")

    def add(zf: zipfile.ZipFile, name: str, data: str | bytes, mode: int = 0o644) -> None:
        info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
        info.external_attr = (0o100000 | mode) << 16
        info.compress_type = zipfile.ZIP_DEFLATED
        zf.writestr(info, data)

    with zipfile.ZipFile(tmp, "w") as zf:
        add(zf, "setup.sh", SETUP_SH, 0o755)
        add(zf, "run_autograder", RUN_AUTOGRADER.replace("@EXERCISES@", ",".join(ex_ids)), 0o755)
        add(zf, "requirements-grader.txt", grader_requirements(root))
        if secret is not None:
            add(zf, "secret", secret, 0o600)
        add(zf, "flowtrack/pyproject.toml", (root / "pyproject.toml").read_text(encoding="utf-8"))
        lic = root / "LICENSE"  # pyproject's license-files: the build fails without it
        if lic.is_file():
            add(zf, "flowtrack/LICENSE", lic.read_text(encoding="utf-8"))
        readme = root / "README.md"
        add(zf, "flowtrack/README.md", readme.read_text(encoding="utf-8") if readme.is_file() else "")
        for p in sorted(f for pkg in pkgs for f in pkg.rglob("*")):
            if not p.is_file() or "__pycache__" in p.parts or p.suffix in (".pyc", ".so", ".o"):
                continue
            add(zf, f"flowtrack/{p.relative_to(root).as_posix()}", p.read_bytes())
    os.replace(tmp, out)
    return out


def _exercise_ids(exercises) -> list[str]:
    """Validated exercise ids from a list or a comma-separated string (``[]``: all)."""
    if exercises is None:
        return []
    if isinstance(exercises, str):
        exercises = exercises.split(",")
    ids = [str(e).strip() for e in exercises if str(e).strip()]
    from .exercises import EXERCISES, get_exercise
    from .languages import find_language_exercise

    out = []
    for i in ids:
        lang = find_language_exercise(i)
        if lang is not None:
            out.append(lang.id)
            continue
        try:
            out.append(get_exercise(i).id)
        except KeyError as exc:
            short = [ex.id for ex in EXERCISES if ex.id.startswith(i + "_")]  # "ex05" -> "ex05_cv_model"
            if len(short) != 1:
                raise ValueError(f"exercises: {exc.args[0]}") from None
            out.append(short[0])
    return list(dict.fromkeys(out))


def grader_requirements(root: str | os.PathLike | None = None) -> str:
    """requirements.txt text of pyproject.toml's ``grader`` extra (what grading imports at run time)."""
    import tomllib

    root = Path(root) if root is not None else _package_root()
    meta = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    reqs = meta.get("project", {}).get("optional-dependencies", {}).get("grader")
    if not reqs:
        raise ValueError(f"pyproject.toml in {root} has no [project.optional-dependencies] grader extra")
    return "\n".join(reqs) + "\n"


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
    secret: bytes | None = None,
    hidden_paths=(),
) -> dict:
    """Grade one Gradescope submission folder and write ``results`` (Gradescope's results.json).

    Never raises because of the submission; an internal error still writes a results.json with
    score 0 and the error as output, so Gradescope shows something.
    """
    import tempfile

    from .grade import grade_student, write_atomic

    results = Path(results)
    try:
        if exercises is None:
            from .exercises import EXERCISES
            from .languages import answered_exercises  # answers in C++, Java, Octave, Mathematica

            exercises = (*EXERCISES, *answered_exercises(submission))
        with tempfile.TemporaryDirectory(prefix="flowtrack-gs-") as tmp:
            summary = grade_student(student, submission, tuple(exercises), tmp, force=True, secret=secret,
                                    hidden_paths=(*hidden_paths, tmp))
            data = json.loads((Path(tmp) / student / "results.json").read_text(encoding="utf-8"))
        if summary.get("isolation", "").startswith("fallback"):
            data["output"] += f"\n(sandbox isolation: {summary['isolation']})"
    except Exception as exc:  # Gradescope must get a results.json
        data = {"score": 0.0, "output": f"autograder error: {type(exc).__name__}: {exc}", "tests": []}
    write_atomic(results, json.dumps(data, indent=1))
    return data


def main(argv: list[str] | None = None) -> int:
    """``python -m flowtrack_course.grading.gradescope run --submission DIR --results FILE
    [--metadata F]``."""
    parser = argparse.ArgumentParser(prog="python -m flowtrack_course.grading.gradescope")
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run", help="grade one Gradescope submission (what run_autograder calls)")
    run.add_argument("--submission", required=True, help="the submission folder")
    run.add_argument("--results", required=True, help="where to write results.json")
    run.add_argument("--metadata", default=None, help="Gradescope's submission_metadata.json")
    run.add_argument("--student", default=None, help="student id (default: from --metadata)")
    run.add_argument("--exercises", default=None, help="comma-separated exercise ids (default: all)")
    run.add_argument("--secret-file", default=None, help="the instructor's seed key (the zip's secret)")
    run.add_argument("--allow-unsafe-sandbox", action="store_true",
                     help="grade even when student code can only run in the fallback sandbox")
    args = parser.parse_args(argv)
    try:
        student = args.student or student_from_metadata(args.metadata)
        exercises = None
        if args.exercises:
            from .exercises import get_exercise
            from .languages import find_language_exercise

            exercises = [find_language_exercise(i) or get_exercise(i) for i in _exercise_ids(args.exercises)]
        secret = None
        if args.secret_file:
            from .spec import read_secret

            secret = read_secret(args.secret_file)
    except Exception as exc:  # issue 18: an explicit error result, never no results.json
        return _error_result(args.results, f"autograder configuration error: {type(exc).__name__}: {exc}")
    protect = [Path(args.results).resolve().parent, Path(__file__).resolve().parent / "exercises",
               *(Path(f) for f in (args.secret_file, args.metadata) if f)]
    problem = _isolation_problem([p for p in protect if p.exists()], args.allow_unsafe_sandbox)
    if problem:
        return _error_result(args.results, problem)
    hidden = [args.submission, *protect]
    data = run_submission(args.submission, args.results, student=student, exercises=exercises, secret=secret,
                          hidden_paths=hidden)
    print(f"flowtrack autograder: {student}: score {data.get('score', 0):g}", file=sys.stderr)
    return 0


def _isolation_problem(protect: list[Path], allow_unsafe: bool) -> str:
    """Why student code cannot be isolated from the grader here ("" when it can).

    bubblewrap shows the sandbox none of the autograder's files. Without it (Docker's default seccomp
    profile forbids the namespaces), the setpriv mode runs student code as an unprivileged uid, which
    holds only while file permissions keep ``protect`` (results folder, key, tests, metadata) from
    it: checked for real. The fallback (no root, no setpriv) is refused unless ``allow_unsafe``.
    """
    from .isolation import SandboxUnavailable, choose_mode, readable_by_sandbox

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
                    + ", ".join(map(str, exposed)) + " (run_autograder makes them private: chmod go-rwx)")
    return ""


def _error_result(results: str | os.PathLike, message: str) -> int:
    """Write a Gradescope error result (score 0, the message shown) and return exit status 1."""
    from .grade import FORMAT, write_atomic

    data = {
        "score": 0.0,
        "output": message + "\nThis is not a problem with your work; please tell your instructor.",
        "visibility": "visible",
        "stdout_visibility": "hidden",
        "tests": [],
        "extra_data": {"flowtrack": {"format": FORMAT, "error": message}},
    }
    write_atomic(Path(results), json.dumps(data, indent=1))
    print(f"flowtrack autograder: {message}", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
