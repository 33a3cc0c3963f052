"""The Gradescope autograder as Gradescope installs and runs it, without bubblewrap.

``setup.sh`` runs as written (as root, in a folder standing for ``/autograder``; only ``apt-get`` is a
stub, the machine has the Debian packages): it makes a virtual environment, installs the grader's
requirements and the zip's flowtrack into it, and makes the grader private. ``run_autograder`` then
grades with that environment, not with this checkout: no ``PYTHONPATH``, no ``FLOWTRACK_PYTHON``.
bubblewrap cannot create namespaces (as under Docker's default seccomp profile), so student code runs
in the setpriv mode, as an unprivileged uid that must read numpy and nothing of the grader.

One slow test: the pip install is most of its time.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

import pytest

from flowtrack_course.grading.export.gradescope import build_autograder
from grading_helpers import get_exercise, source_notebook, use_sandbox_mode
from grading_sandbox import readable_by_sandbox

pytestmark = [
    pytest.mark.slow,
    pytest.mark.xdist_group("sandbox"),
    pytest.mark.skipif(os.geteuid() != 0, reason="Gradescope installs and runs the autograder as root"),
]

EX = get_exercise("ex05_cv_model")


def _run(cmd, env, timeout):
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)


def test_installed_bundle_grades_in_setpriv_mode_without_bubblewrap(tmp_path, monkeypatch):
    use_sandbox_mode("setpriv", monkeypatch)  # FLOWTRACK_BWRAP: a bwrap that cannot make namespaces
    root = Path(tempfile.mkdtemp(prefix="flowtrack-installed-"))  # other users may traverse it, as /
    os.chmod(root, 0o755)
    try:
        key = tmp_path / "key"
        key.write_bytes(b"k" * 32)
        key.chmod(0o600)
        zpath = build_autograder(tmp_path / "autograder.zip", secret_file=key, exercises="ex05")
        with zipfile.ZipFile(zpath) as zf:  # as Gradescope unpacks it
            zf.extractall(root / "source")
            for info in zf.infolist():
                os.chmod(root / "source" / info.filename, (info.external_attr >> 16) & 0o777)
        for d in [root / "source", *(p for p in (root / "source").rglob("*") if p.is_dir())]:
            d.chmod(0o755)
        stubs = tmp_path / "bin"
        stubs.mkdir()
        (stubs / "apt-get").write_text(f"#!/bin/sh\necho \"$*\" >> {tmp_path / 'apt.log'}\n")
        (stubs / "apt-get").chmod(0o755)
        env = {k: v for k, v in os.environ.items()
               if k not in ("PYTHONPATH", "FLOWTRACK_PYTHON", "FLOWTRACK_SANDBOX", "VIRTUAL_ENV")}
        env.update(AUTOGRADER_ROOT=str(root), PATH=f"{stubs}:{env.get('PATH', '/usr/bin:/bin')}")
        setup = _run(["bash", str(root / "source" / "setup.sh")], env, 1800)
        assert setup.returncode == 0, setup.stderr[-3000:]
        assert "bubblewrap" in (tmp_path / "apt.log").read_text()
        site = next((root / "venv" / "lib").glob("python3*/site-packages"))
        installed = sorted(p for p in site.iterdir() if p.name.split("-")[0] in
                           ("flowtrack", "flowtrack_course", "grading_sandbox"))
        assert {p.name for p in installed} >= {"flowtrack", "flowtrack_course", "grading_sandbox"}
        # every installed package of the grader (and its metadata) is private; numpy is not
        assert readable_by_sandbox([*installed, root / "source"]) == []
        assert readable_by_sandbox([site / "numpy"]) == [str(site / "numpy")]

        (root / "submission").mkdir(mode=0o755)
        shutil.copy(source_notebook(EX), root / "submission" / Path(EX.notebook).name)
        (root / "submission_metadata.json").write_text(json.dumps({"users": [{"id": "4242"}]}))

        def run_autograder() -> dict:
            r = _run(["bash", str(root / "source" / "run_autograder")], env, 900)
            assert r.returncode == 0, r.stderr[-2000:]
            return json.loads((root / "results" / "results.json").read_text())

        data = run_autograder()
        info = data["extra_data"]["flowtrack"]
        assert "error" not in info, data["output"][:2000]
        assert info["isolation"] == "setpriv" and info["student"] == "4242"
        mine = [t for t in data["tests"] if t["name"].startswith(EX.id)]
        assert mine and all(t["score"] == t["max_score"] for t in mine), data["output"][:2000]
        assert data["score"] == pytest.approx(EX.max_score)

        # A setup.sh that left the grader readable (as one that made only `flowtrack` private did):
        # the autograder refuses to grade and says what to make private.
        for p in installed:
            if p.name == "flowtrack_course":
                subprocess.run(["chmod", "-R", "go+rX", str(p)], check=True)
        data = run_autograder()
        assert data["score"] == 0 and not data["tests"]
        assert "could read" in data["output"] and "flowtrack_course" in data["output"]
        assert "not a problem with your work" in data["output"]
    finally:
        shutil.rmtree(root, ignore_errors=True)
