"""``flowtrack gradescope --out autograder.zip``: a Gradescope autograder running flowtrack's grader.

The zip holds::

    setup.sh          Debian packages (python3, venv, bubblewrap, open3d's libraries) and
                      ``pip install ./flowtrack[grading]`` into /autograder/venv (PyPI only)
    run_autograder    grades /autograder/submission as one student and writes
                      /autograder/results/results.json
    flowtrack/        the package's source tree (pyproject.toml, README.md, reference_impl/flowtrack),
                      which carries the exercises' trusted test definitions

``run_autograder`` calls ``python -m flowtrack.grading.gradescope run`` (:func:`run_submission`); its
paths come from the environment so that it can be tried outside Gradescope: ``AUTOGRADER_ROOT``
(default ``/autograder``) and ``FLOWTRACK_PYTHON`` (default ``$AUTOGRADER_ROOT/venv/bin/python``).
The hidden tests' inputs are seeded by the submitter's Gradescope id from
``submission_metadata.json`` (``"submission"`` when it is absent), keyed by the instructor's
``secret`` when the zip holds one (``flowtrack gradescope --secret-file``). ``FLOWTRACK_EXERCISES`` (comma-
separated ids) restricts grading to some exercises (one assignment per exercise on Gradescope).
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

__all__ = ["build_autograder", "main", "run_submission", "student_from_metadata"]

SETUP_SH = """\
#!/usr/bin/env bash
# Gradescope runs this once, as root, when the autograder image is built.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq python3 python3-venv python3-pip bubblewrap libgomp1 libusb-1.0-0
# hook (issue 19): the toolchains of answers in C++, Octave and Java (Mathematica: mathics3, the ports extra)
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
/autograder/venv/bin/pip install -q "/autograder/source/flowtrack[grading,ports]"
# Student code runs as an unprivileged uid that must read the venv (numpy) but nothing else.
chmod o+x /autograder
chmod -R a+rX /autograder/venv
"""

RUN_AUTOGRADER = """\
#!/usr/bin/env bash
# Gradescope runs this for every submission. Paths can be overridden to try it elsewhere.
set -uo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
PY="${FLOWTRACK_PYTHON:-$ROOT/venv/bin/python}"
mkdir -p "$ROOT/results"
SECRET=()
if [ -f "$ROOT/source/secret" ]; then  # the instructor's seed key (flowtrack gradescope --secret-file)
    chmod 600 "$ROOT/source/secret"
    SECRET=(--secret-file "$ROOT/source/secret")
fi
exec "$PY" -m flowtrack.grading.gradescope run \\
    --submission "$ROOT/submission" \\
    --metadata "$ROOT/submission_metadata.json" \\
    --results "$ROOT/results/results.json" \\
    ${FLOWTRACK_EXERCISES:+--exercises "$FLOWTRACK_EXERCISES"} \\
    "${SECRET[@]}"
"""

_SAFE = re.compile(r"[^A-Za-z0-9_.@+\-]")


def _package_root() -> Path:
    """The source tree holding pyproject.toml and reference_impl/flowtrack."""
    root = Path(__file__).resolve().parents[3]
    if not (root / "pyproject.toml").is_file() or not (root / "reference_impl" / "flowtrack").is_dir():
        raise FileNotFoundError(
            f"source: flowtrack's source tree (pyproject.toml, reference_impl/) not found at {root}; "
            "build the autograder from a checkout of the course"
        )
    return root


def build_autograder(
    out: str | os.PathLike,
    *,
    source: str | os.PathLike | None = None,
    secret_file: str | os.PathLike | None = None,
) -> Path:
    """Write the Gradescope autograder zip to ``out`` (see the module docstring); returns its path.

    Only the package (``reference_impl/flowtrack``), ``pyproject.toml`` and ``README.md`` are copied:
    no exercises, solutions, lessons or caches. With ``secret_file`` (created if missing, see
    :func:`~flowtrack.grading.spec.read_secret`) the key is added as ``secret`` (mode 0600: the
    sandbox's unprivileged uid cannot read it, and it is not bound into the sandbox) and seeds the
    hidden tests.
    """
    secret = None
    if secret_file is not None:
        from .spec import read_secret

        secret = read_secret(secret_file, create=True)
    root = Path(source) if source is not None else _package_root()
    pkg = root / "reference_impl" / "flowtrack"
    if not pkg.is_dir():
        raise FileNotFoundError(f"source: no reference_impl/flowtrack in {root}")
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
        add(zf, "run_autograder", RUN_AUTOGRADER, 0o755)
        if secret is not None:
            add(zf, "secret", secret, 0o600)
        add(zf, "flowtrack/pyproject.toml", (root / "pyproject.toml").read_text(encoding="utf-8"))
        readme = root / "README.md"
        add(zf, "flowtrack/README.md", readme.read_text(encoding="utf-8") if readme.is_file() else "")
        for p in sorted(pkg.rglob("*")):
            if not p.is_file() or "__pycache__" in p.parts or p.suffix in (".pyc", ".so", ".o"):
                continue
            add(zf, f"flowtrack/{p.relative_to(root).as_posix()}", p.read_bytes())
    os.replace(tmp, out)
    return out


def student_from_metadata(path: str | os.PathLike | None) -> str:
    """The submitter's id from Gradescope's ``submission_metadata.json`` (``"submission"`` if none)."""
    if path is None:
        return "submission"
    try:
        meta = json.loads(Path(path).read_text(encoding="utf-8"))
        users = meta.get("users") or []
        ident = users[0].get("id") or users[0].get("email") if users else None
        ident = ident or meta.get("id")
    except (OSError, ValueError, AttributeError, IndexError, TypeError):
        return "submission"
    name = _SAFE.sub("_", str(ident)) if ident else ""
    return name[:120] or "submission"


def run_submission(
    submission: str | os.PathLike,
    results: str | os.PathLike,
    *,
    student: str = "submission",
    exercises=None,
    secret: bytes | None = None,
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
            from .languages import answered_exercises  # hook (issue 19)

            exercises = (*EXERCISES, *answered_exercises(submission))
        with tempfile.TemporaryDirectory(prefix="flowtrack-gs-") as tmp:
            summary = grade_student(student, submission, tuple(exercises), tmp, force=True, secret=secret)
            data = json.loads((Path(tmp) / student / "results.json").read_text(encoding="utf-8"))
        if summary.get("isolation", "").startswith("fallback"):
            data["output"] += f"\n(sandbox isolation: {summary['isolation']})"
    except Exception as exc:  # Gradescope must get a results.json
        data = {"score": 0.0, "output": f"autograder error: {type(exc).__name__}: {exc}", "tests": []}
    write_atomic(results, json.dumps(data, indent=1))
    return data


def main(argv: list[str] | None = None) -> int:
    """``python -m flowtrack.grading.gradescope run --submission DIR --results FILE [--metadata F]``."""
    parser = argparse.ArgumentParser(prog="python -m flowtrack.grading.gradescope")
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run", help="grade one Gradescope submission (what run_autograder calls)")
    run.add_argument("--submission", required=True, help="the submission folder")
    run.add_argument("--results", required=True, help="where to write results.json")
    run.add_argument("--metadata", default=None, help="Gradescope's submission_metadata.json")
    run.add_argument("--student", default=None, help="student id (default: from --metadata)")
    run.add_argument("--exercises", default=None, help="comma-separated exercise ids (default: all)")
    run.add_argument("--secret-file", default=None, help="the instructor's seed key (the zip's secret)")
    args = parser.parse_args(argv)
    student = args.student or student_from_metadata(args.metadata)
    exercises = None
    if args.exercises:
        from .exercises import get_exercise
        from .languages import find_language_exercise  # hook (issue 19)

        ids = [i.strip() for i in args.exercises.split(",") if i.strip()]
        exercises = [find_language_exercise(i) or get_exercise(i) for i in ids]
    secret = None
    if args.secret_file:
        from .spec import read_secret

        secret = read_secret(args.secret_file)
    data = run_submission(args.submission, args.results, student=student, exercises=exercises, secret=secret)
    print(f"flowtrack autograder: {student}: score {data.get('score', 0):g}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
