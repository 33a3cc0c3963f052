"""The Gradescope autograder as Gradescope runs it without namespaces: root in a container where
bubblewrap cannot create namespaces (Docker's default seccomp profile; here ``$FLOWTRACK_BWRAP``
points at a stub that fails the same way). Student code then runs in the setpriv mode, as a fresh
unprivileged uid: it can neither read the key, the tests or the metadata, nor write results.json,
even going around the in-process audit hook with ctypes; results.json is the grader's.

The Sandbox-level attack suites (tests/test_grading_attacks*.py) run in this mode too (their
``mode`` fixtures include ``"setpriv"``).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import nbformat
import pytest

from flowtrack_course.grading.assign.release import release_notebook
from flowtrack_course.grading.export.gradescope import build_autograder
from grading_helpers import get_exercise, source_notebook, use_sandbox_mode
from grading_sandbox import readable_by_sandbox

pytestmark = [
    pytest.mark.xdist_group("sandbox"),
    pytest.mark.skipif(os.geteuid() != 0, reason="a Gradescope container runs the autograder as root"),
]

REPO = Path(__file__).resolve().parents[1]
EX = get_exercise("ex05_cv_model")

ATTACK = """
import errno, os, signal
ROOT = {root!r}
# Around the in-process audit hook: it resolves a relative path against the cwd, not against dir_fd,
# so these opens reach the kernel unchecked; only the uid and the file modes can stop them.
top = os.open("/", os.O_RDONLY)
report = []
for p in [ROOT + "/source/secret", ROOT + "/submission_metadata.json",
          ROOT + "/source/course/exercises/ex05_cv_model/grading.py",
          ROOT + "/results/results.json"]:
    try:
        fd = os.open(p.lstrip("/"), os.O_RDONLY, dir_fd=top)
        report.append("READ " + p + " " + repr(os.read(fd, 64)))
    except OSError as exc:
        report.append(errno.errorcode[exc.errno])
for p in [ROOT + "/results/results.json", ROOT + "/results/forged.json", ROOT + "/forged.json",
          ROOT + "/source/forged.json"]:
    try:
        fd = os.open(p.lstrip("/"), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666, dir_fd=top)
        os.write(fd, b'{{"score": 1000, "tests": []}}')
        report.append("WROTE " + p)
    except OSError as exc:
        report.append(errno.errorcode[exc.errno])
for pid in (os.getppid(), 1, -1):
    try:
        os.kill(pid, signal.SIGKILL)
    except OSError as exc:
        report.append("kill " + type(exc).__name__)
raise RuntimeError("ATTACK RAN " + ",".join(report))
"""


def _snapshot(root: Path) -> dict:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*")) if "results" not in p.relative_to(root).parts}


@pytest.fixture
def autograder(tmp_path, monkeypatch, tmp_path_factory):
    """/autograder as the Gradescope image has it, in a folder other users can traverse (as / is)."""
    use_sandbox_mode("setpriv", monkeypatch, tmp_path_factory)
    root = Path(tempfile.mkdtemp(prefix="flowtrack-autograder-"))
    os.chmod(root, 0o755)
    try:
        key = tmp_path / "key"
        key.write_bytes(b"k" * 32)
        key.chmod(0o600)
        zpath = build_autograder(tmp_path / "autograder.zip", secret_file=key, exercises="ex05")
        with zipfile.ZipFile(zpath) as zf:
            zf.extractall(root / "source")
            for info in zf.infolist():  # zipfile drops the modes
                os.chmod(root / "source" / info.filename, (info.external_attr >> 16) & 0o777)
        for d in (root / "source").rglob("*"):  # as unzip leaves them: readable by everyone
            if d.is_dir():
                d.chmod(0o755)
        os.chmod(root / "source", 0o755)
        sub = root / "submission"
        sub.mkdir(mode=0o755)
        stub = release_notebook(nbformat.read(source_notebook(EX), as_version=4))
        for c in stub.cells:
            if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == EX.answer_cells[0]:
                c.source = ATTACK.format(root=str(root)) + "".join(c.source)
        nbformat.write(stub, sub / Path(EX.notebook).name)
        meta = {"users": [{"id": "4242", "email": "a@b"}]}
        (root / "submission_metadata.json").write_text(json.dumps(meta))
        os.chmod(root / "submission_metadata.json", 0o644)
        yield root
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_gradescope_without_namespaces_isolates_by_uid(autograder):
    root = autograder
    before = _snapshot(root)
    env = dict(os.environ, AUTOGRADER_ROOT=str(root), FLOWTRACK_PYTHON=sys.executable,
               # the grader imports the zip's flowtrack (private after run_autograder), as after setup.sh
               PYTHONPATH=str(root / "source" / "flowtrack" / "reference_impl"))
    r = subprocess.run(["bash", str(root / "source" / "run_autograder")], env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((root / "results" / "results.json").read_text())
    info = data["extra_data"]["flowtrack"]
    assert info["format"] == "flowtrack-results/1" and "error" not in info, data["output"][:2000]
    assert info["student"] == "4242" and info["isolation"] == "setpriv"
    assert data["score"] == 0.0 and data["tests"] and all(t["score"] == 0 for t in data["tests"])
    text = json.dumps(data)
    # the attack ran to its end, and the kernel refused every open (EACCES), not the audit hook
    ran = re.search(r"ATTACK RAN [A-Za-z, ]*", text).group(0)  # the attack's own report, once
    assert ran.count("EACCES") == 8 and "READ" not in ran and "WROTE" not in ran, ran
    assert "kkkk" not in text and "1000" not in text
    assert sorted(p.name for p in (root / "results").iterdir()) == ["results.json"]
    assert _snapshot(root) == before  # nothing written outside (the attack's targets included)
    assert (root / "results").stat().st_mode & 0o077 == 0


def test_gradescope_refuses_to_grade_when_the_sandbox_could_read_the_key(autograder, tmp_path):
    root = autograder
    secret = root / "source" / "secret"
    exposed = root / "exposed-key"
    shutil.copy(secret, exposed)
    os.chmod(exposed, 0o644)
    assert readable_by_sandbox([exposed, secret]) == [str(exposed)]  # 0600 root: unreadable
    results = tmp_path / "results.json"
    r = subprocess.run(
        [sys.executable, "-m", "flowtrack_course.grading.grade.gradescope", "run", "--submission",
         str(root / "submission"), "--results", str(results), "--student", "4242", "--exercises", "ex05",
         "--secret-file", str(exposed)],
        capture_output=True, text=True, timeout=300, env=dict(os.environ),
    )
    assert r.returncode == 1
    data = json.loads(results.read_text())
    assert data["score"] == 0.0 and "could read" in data["output"] and str(exposed) in data["output"]
