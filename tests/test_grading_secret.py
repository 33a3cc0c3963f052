"""The instructor's seed key: hidden-test inputs keyed by a secret the students do not have.

Without a key the hidden inputs of a student are sha256 of public names, so anyone with the course
package can draw them. These tests check that a key changes every hidden input (and no public one),
that the same key reproduces them, that a re-run with another key re-grades instead of keeping the
old results, and that the key reaches the grader from the command line and from the Gradescope zip.
A recording sandbox stands in for bubblewrap (what is checked is the inputs sent, not the isolation).
"""

from __future__ import annotations

import dataclasses
import json
import stat
import zipfile
from pathlib import Path

import numpy as np
import pytest

nbformat = pytest.importorskip("nbformat")

from flowtrack_course.grading.engine.jobs import GradingOptions  # noqa: E402
from flowtrack_course.grading.engine.run import run_exercise  # noqa: E402
from flowtrack_course.grading.engine.seeds import MIN_SECRET_BYTES, read_secret, secret_id, student_seed  # noqa: E402
from flowtrack_course.grading.grade import grade_class  # noqa: E402
from grading_helpers import (  # noqa: E402
    RecordingSandbox,
    class_job,
    get_exercise,
    source_notebook,
)

ROOT = Path(__file__).resolve().parents[1]
EX = get_exercise("ex02_optical_flow")
KEY_A = bytes(range(32))
KEY_B = bytes(range(1, 33))


def _inputs(student, secret, hidden):
    """The arguments sent for ``student``'s hidden (or public) tests of EX under ``secret``."""
    nb = source_notebook(EX)
    RecordingSandbox.sent = []
    tests = [t for t in EX.tests if t.hidden == hidden]
    assert tests, "EX needs hidden and public tests for this check"
    sub = dataclasses.replace(EX, tests=tuple(tests))
    run_exercise(sub, nb, student, sandbox_factory=RecordingSandbox, options=GradingOptions(secret=secret))
    return list(RecordingSandbox.sent)


def test_a_key_changes_every_hidden_input_and_no_public_one():
    plain = _inputs("ana", None, hidden=True)
    keyed = _inputs("ana", KEY_A, hidden=True)
    assert plain and len(plain) == len(keyed)
    assert all(p != k for p, k in zip(plain, keyed))  # each hidden call gets new inputs
    assert _inputs("ana", KEY_A, hidden=True) == keyed  # reproducible with the same key
    assert _inputs("ana", KEY_B, hidden=True) != keyed
    assert _inputs("ana", KEY_A, hidden=False) == _inputs("ana", None, hidden=False)


def test_keyed_seeds_are_spread_and_unlinkable_to_the_unkeyed_ones():
    names = [f"s{i:03d}" for i in range(200)]
    keyed = {student_seed(n, EX.id, "t", KEY_A) for n in names}
    plain = {student_seed(n, EX.id, "t") for n in names}
    assert len(keyed) == len(names) and not keyed & plain
    assert all(0 <= s < 2**63 for s in keyed)
    # bits look uniform: mean of the top bit over 200 seeds within 5 sigma of 1/2
    top = np.array([s >> 62 for s in keyed])
    assert abs(top.mean() - 0.5) < 5 * 0.5 / np.sqrt(len(top))


def test_read_secret_creates_an_owner_only_key_and_rejects_short_ones(tmp_path):
    path = tmp_path / "course" / "seed.key"
    with pytest.raises(FileNotFoundError, match="secret file"):
        read_secret(path)
    key = read_secret(path, create=True)
    assert len(key) == 32 and stat.S_IMODE(path.stat().st_mode) == 0o600
    assert read_secret(path) == key and read_secret(path, create=True) == key  # never overwritten
    assert read_secret(tmp_path / "other.key", create=True) != key
    short = tmp_path / "short.key"
    short.write_bytes(b"x" * (MIN_SECRET_BYTES - 1))
    with pytest.raises(ValueError, match="at least 16 bytes"):
        read_secret(short)
    with pytest.raises(TypeError, match="secret must be bytes"):
        student_seed("a", "b", "c", secret="a text key is not bytes")
    assert secret_id(None) == "" and secret_id(KEY_A) != secret_id(KEY_B)
    assert KEY_A.hex() not in secret_id(KEY_A)


def test_a_rerun_with_another_key_regrades_and_the_same_key_keeps(tmp_path):
    subs, out = tmp_path / "subs", tmp_path / "out"
    (subs / "ana").mkdir(parents=True)
    (subs / "ana" / EX.notebook).write_bytes(source_notebook(EX).read_bytes())

    def run(secret):
        rows = grade_class(class_job(subs, out, exercises=[EX], progress=False,
                                     sandbox_factory=RecordingSandbox, secret=secret))
        return rows[0]["skipped"], json.loads((out / "ana" / "results.json").read_text())

    skipped, data = run(KEY_A)
    assert not skipped and data["extra_data"]["flowtrack"]["secret_id"] == secret_id(KEY_A)
    assert run(KEY_A)[0]  # same key, same files: kept
    skipped, data = run(KEY_B)
    assert not skipped and data["extra_data"]["flowtrack"]["secret_id"] == secret_id(KEY_B)
    skipped, data = run(None)
    assert not skipped and data["extra_data"]["flowtrack"]["secret_id"] == ""


def test_the_command_line_creates_and_uses_the_key(tmp_path, capsys):
    # real sandbox, one student with the solution notebook: full marks with a key, key file created
    from flowtrack_course.cli import main

    subs, out, key = tmp_path / "subs", tmp_path / "out", tmp_path / "seed.key"
    (subs / "ana").mkdir(parents=True)
    (subs / "ana" / EX.notebook).write_bytes(source_notebook(EX).read_bytes())
    args = ["grade", str(subs), "--out", str(out), "--no-progress"]
    assert main([*args, "--secret-file", str(key)]) == 0
    assert "created the seed key" in capsys.readouterr().err and key.is_file()
    info = json.loads((out / "ana" / "results.json").read_text())["extra_data"]["flowtrack"]
    assert info["secret_id"] == secret_id(key.read_bytes())
    assert info["exercises"][EX.id]["score"] == EX.max_score
    assert main([*args, "--secret-file", str(key)]) == 0
    assert "created" not in capsys.readouterr().err  # the existing key is reused
    assert main(args) == 0
    assert "no --secret-file" in capsys.readouterr().err  # without a key: graded, with a warning


def test_the_gradescope_zip_carries_the_key_to_the_grader(tmp_path):
    from flowtrack_course.grading.export.gradescope import build_autograder

    key = tmp_path / "seed.key"
    zpath = build_autograder(tmp_path / "autograder.zip", secret_file=key)
    with zipfile.ZipFile(zpath) as zf:
        info = zf.getinfo("secret")
        assert zf.read("secret") == key.read_bytes()
        assert stat.S_IMODE(info.external_attr >> 16) == 0o600
        run_script = zf.read("run_autograder").decode()
    assert '--secret-file "$ROOT/source/secret"' in run_script
    with zipfile.ZipFile(build_autograder(tmp_path / "plain.zip")) as zf:
        assert "secret" not in zf.namelist()


def test_the_gradescope_command_creates_the_key_once(tmp_path, capsys):
    from flowtrack_course.cli import main

    key, zpath = tmp_path / "seed.key", tmp_path / "ag.zip"
    assert main(["gradescope", "--out", str(zpath), "--secret-file", str(key)]) == 0
    assert "created the seed key" in capsys.readouterr().err
    with zipfile.ZipFile(zpath) as zf:
        assert zf.read("secret") == key.read_bytes()
    assert main(["gradescope", "--out", str(zpath), "--secret-file", str(key)]) == 0
    assert "created" not in capsys.readouterr().err
    assert main(["gradescope", "--out", str(zpath)]) == 0
    assert "no --secret-file" in capsys.readouterr().err
