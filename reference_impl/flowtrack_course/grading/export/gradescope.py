"""``flowtrack gradescope --out autograder.zip``: a Gradescope autograder running flowtrack's grader.

The zip holds::

    setup.sh          Debian packages (python3, venv, bubblewrap), the ``grader`` extra's pinned
                      requirements (requirements-grader.txt: numpy, scipy, ... no open3d,
                      scikit-image or Jupyter) and ``pip install --no-deps ./flowtrack`` into
                      /autograder/venv (PyPI only); the installed packages and the source folder are
                      made private to root
    requirements-grader.txt   pyproject.toml's ``grader`` extra
    run_autograder    grades /autograder/submission as one student and writes
                      /autograder/results/results.json; when the grader itself fails
                      (flowtrack not importable, ...) it writes an error result instead
    flowtrack/        the packages' source tree (pyproject.toml, README.md, reference_impl/flowtrack,
                      reference_impl/flowtrack_course and reference_impl/grading_sandbox)
    course/exercises/<id>/   each exercise's grading files (its grading module; no notebook, worked
                      solution or test answers: :func:`~..engine.discovery.grading_files`)
    course/assignment.toml   what counts (:mod:`~..assignment`): the course's, or ``--assignment-file``;
                      absent when neither exists (every notebook exercise, no other language)

``run_autograder`` calls ``python -m flowtrack_course.grading.grade.gradescope run``
(:func:`~..grade.gradescope.run_submission`); its paths come from the environment so that it can be
tried outside Gradescope: ``AUTOGRADER_ROOT`` (default ``/autograder``) and ``FLOWTRACK_PYTHON``
(default ``$AUTOGRADER_ROOT/venv/bin/python``). ``flowtrack gradescope --exercises ex01,ex05`` sets
the exercises graded (the default of ``run_autograder``; the ``FLOWTRACK_EXERCISES`` environment
variable overrides it). Use a Gradescope base image with Python >= 3.11 (Ubuntu 24.04).
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

from ...course import course_root
from ..engine.discovery import EXERCISES_DIR, exercise_folders, grading_files

__all__ = ["PACKAGES", "RUN_AUTOGRADER", "SETUP_SH", "build_autograder", "grader_requirements"]

SETUP_SH = r"""#!/usr/bin/env bash
# Gradescope runs this once, as root, when the autograder image is built (AUTOGRADER_ROOT moves
# /autograder elsewhere, to try the bundle outside Gradescope).
set -euo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq python3 python3-venv python3-pip bubblewrap util-linux
# the toolchains of answers in C++, Octave and Java (Mathematica answers: mathics3, in the grader extra)
apt-get install -y -qq g++ libeigen3-dev nlohmann-json3-dev octave openjdk-17-jdk-headless \
    libgoogle-gson-java libejml-java
python3 - <<'PY'
import sys
if sys.version_info < (3, 11):
    sys.exit(f"flowtrack needs Python >= 3.11, this image has {sys.version.split()[0]}: "
             "choose the Ubuntu 24.04 base image")
PY
python3 -m venv "$ROOT/venv"
"$ROOT/venv/bin/pip" install -q --upgrade pip
# Only what grading imports (pyproject's `grader` extra, pinned in requirements-grader.txt): no open3d,
# scikit-image or Jupyter; then flowtrack itself without its dependencies.
"$ROOT/venv/bin/pip" install -q -r "$ROOT/source/requirements-grader.txt"
"$ROOT/venv/bin/pip" install -q --no-deps "$ROOT/source/flowtrack"
# Student code runs as a fresh unprivileged uid per sandbox: under bubblewrap where it can create
# namespaces, else (Docker's default seccomp profile) switched to with setpriv (util-linux), no
# capabilities, no_new_privs. That uid needs the Python runtime and numpy/scipy of the venv, and
# nothing of the grader: every top-level entry the flowtrack distribution installed (the library, of
# which the sandbox gets a filtered copy; the grader; the sandbox, whose runner the sandbox gets a
# copy of; their metadata) and $ROOT/source (the key, and the course's exercise grading modules in
# course/) are the grader's only. run_autograder refuses to grade while the sandbox could read them.
chmod o+x "$ROOT"
chmod -R a+rX "$ROOT/venv"
"$ROOT/venv/bin/python" - > "$ROOT/.flowtrack-private" <<'PY'
import importlib.metadata as md
from pathlib import Path

dist = md.distribution("flowtrack")
site = Path(dist.locate_file("")).resolve()
entries = {Path(f).parts[0] for f in dist.files or () if Path(f).parts and Path(f).parts[0] != ".."}
print("\n".join(str(site / e) for e in sorted(entries) if (site / e).exists()))
PY
while IFS= read -r d; do chmod -R go-rwx "$d"; done < "$ROOT/.flowtrack-private"
rm -f "$ROOT/.flowtrack-private"
chmod -R go-rwx "$ROOT/source"
"""

RUN_AUTOGRADER = r"""#!/usr/bin/env bash
# Gradescope runs this for every submission. Paths can be overridden to try it elsewhere.
# It always leaves a results.json: the grader's, or an error result when the grader itself failed.
set -uo pipefail
ROOT="${AUTOGRADER_ROOT:-/autograder}"
PY="${FLOWTRACK_PYTHON:-$ROOT/venv/bin/python}"
EXERCISES="${FLOWTRACK_EXERCISES:-@EXERCISES@}"  # flowtrack gradescope --exercises (empty: all)
RESULTS="$ROOT/results/results.json"
# the exercises' grading modules: the zip's course/ (Gradescope unpacks the zip into $ROOT/source and
# runs a copy of this script; tried elsewhere, the folder next to this script)
COURSE="$ROOT/source/course"
[ -d "$COURSE" ] || COURSE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/course"
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
"$PY" -m flowtrack_course.grading.grade.gradescope run \
    --course "$COURSE" \
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

#: the packages the zip installs: the library, the grader and the sandbox
PACKAGES = ("flowtrack", "flowtrack_course", "grading_sandbox")


def _package_root(course: str | os.PathLike | None = None) -> Path:
    """The course checkout holding pyproject.toml, the packages in reference_impl/ and exercises/
    (``--course``, else ``$FLOWTRACK_COURSE``, else the current folder)."""
    need = ("pyproject.toml", EXERCISES_DIR, *(f"reference_impl/{p}" for p in PACKAGES))
    return course_root(course, need=need)


def build_autograder(
    out: str | os.PathLike,
    *,
    source: str | os.PathLike | None = None,
    secret_file: str | os.PathLike | None = None,
    exercises: str | list[str] | tuple[str, ...] | None = None,
    assignment: str | os.PathLike | None = None,
) -> Path:
    """Write the Gradescope autograder zip to ``out`` (see the module docstring); returns its path.

    Only the packages (``reference_impl/flowtrack``, ``reference_impl/flowtrack_course``,
    ``reference_impl/grading_sandbox``), ``pyproject.toml``, ``README.md`` and the exercises' grading
    files are copied: no notebooks, solutions, lessons or caches. With ``secret_file`` (created if
    missing, see :func:`~..engine.seeds.read_secret`) the key is added as ``secret`` (mode 0600: the
    sandbox's unprivileged uid cannot read it, and it is not bound into the sandbox) and seeds the
    hidden tests. ``exercises`` (ids or their ``exNN`` prefixes, or a comma-separated string; default
    all) become ``run_autograder``'s default (one Gradescope assignment per exercise set).
    ``assignment`` (an ``assignment.toml``; default: the course's own, when it has one) goes into the
    zip as ``course/assignment.toml``: what each submission is graded on.
    """
    from ..assignment import FILE_NAME
    from ..sources import course_catalog

    root = _package_root(source)
    assignment_file = Path(assignment) if assignment is not None else root / FILE_NAME
    catalog = course_catalog(root, assignment if assignment is not None else None)  # checks it
    ex_ids = catalog.resolve_ids(exercises)
    secret = None
    if secret_file is not None:
        from ..engine.seeds import read_secret
        from ..grade.keys import check_key_file

        check_key_file(secret_file)  # refuse a key others can read
        secret = read_secret(secret_file, create=True)
    pkgs = [root / "reference_impl" / p for p in PACKAGES]
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
        # every exercise's grading files (an exercise may recognise a mistake another one defines)
        for folder in exercise_folders(root):
            for p in grading_files(folder):
                add(zf, f"course/{p.relative_to(root).as_posix()}", p.read_bytes())
        if assignment_file.is_file():
            add(zf, f"course/{FILE_NAME}", assignment_file.read_bytes())
    os.replace(tmp, out)
    return out


def grader_requirements(root: str | os.PathLike | None = None) -> str:
    """requirements.txt text of pyproject.toml's ``grader`` extra (what grading imports at run time)."""
    import tomllib

    root = Path(root) if root is not None else _package_root()
    meta = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    reqs = meta.get("project", {}).get("optional-dependencies", {}).get("grader")
    if not reqs:
        raise ValueError(f"pyproject.toml in {root} has no [project.optional-dependencies] grader extra")
    return "\n".join(reqs) + "\n"
