"""Attacks on the grader's own side: the fallback sandbox, huge notebooks, student folders
named like the grader's outputs, unwritable error text, feedback injection and stale results.

Each must leave the class run whole (every other student graded, grades.csv and the gradebook
written) and score the attacker as an honest wrong answer or 0.
"""

import csv
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from flowtrack_course.grading.engine.classrun import RESERVED_NAMES, UnsafeSandbox
from flowtrack_course.grading.engine.compare import compare_arrays
from flowtrack_course.grading.engine.jobs import GradingOptions
from flowtrack_course.grading.engine.notebook import NotebookError, extract_cells
from flowtrack_course.grading.engine.results import feedback_markdown, results_json
from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.engine.spec import Outcome
from flowtrack_course.grading.grade import grade_class
from grading_helpers import RecordingSandbox, class_job, get_exercise, source_notebook
from grading_sandbox import Limits, bwrap_status

pytestmark = pytest.mark.xdist_group("sandbox")

EX = get_exercise("ex05_cv_model")
SOLUTION = source_notebook(EX)
LIMITS = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30, processes=16)


def _notebook_with(source: str, path: Path, ex=EX) -> Path:
    cells = [{"cell_type": "code", "execution_count": None, "outputs": [], "id": f"c{i}",
              "metadata": {"nbgrader": {"grade_id": gid, "solution": True}},
              "source": source if i == 0 else "pass\n"} for i, gid in enumerate(ex.answer_cells)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": cells}))
    return path


def _outside_fences(markdown: str) -> list[str]:
    """The lines of ``markdown`` a renderer shows as Markdown (not inside a fenced block)."""
    out, fenced = [], False
    for line in markdown.splitlines():
        if line.startswith("```"):
            fenced = not fenced
            continue
        if not fenced:
            out.append(line)
    assert not fenced, "an unclosed fence"
    return out


# -- the fallback sandbox -------------------------------------------------------------------------


def test_grade_refuses_the_fallback_unless_forced(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "fallback")
    (tmp_path / "subs" / "ann").mkdir(parents=True)
    shutil.copy(SOLUTION, tmp_path / "subs" / "ann" / EX.notebook)
    with pytest.raises(UnsafeSandbox, match="allow-unsafe-sandbox") as info:
        grade_class(class_job(tmp_path / "subs", tmp_path / "out", exercises=[EX], progress=False))
    assert "submissions" in str(info.value) and "seed key" in str(info.value)  # says what it loses
    assert not (tmp_path / "out" / "grades.csv").exists()
    rows = grade_class(class_job(tmp_path / "subs", tmp_path / "out", exercises=[EX], progress=False,
                       allow_unsafe_sandbox=True))
    assert rows[0]["score"] == EX.max_score and rows[0]["isolation"].startswith("fallback")


def test_fallback_copycat_and_key_reader_are_refused(tmp_path, monkeypatch):
    # Under the fallback a cell could read another student's notebook (and score their 10/10) or
    # the seed key: the grader hides the submissions, the output folder and the key file.
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "fallback")
    subs, out, key = tmp_path / "subs", tmp_path / "out", tmp_path / "seed.key"
    key.write_bytes(b"k" * 32)
    ann = subs / "ann" / EX.notebook
    ann.parent.mkdir(parents=True)
    shutil.copy(SOLUTION, ann)  # the full solution
    copycat = f"""
import json
nb = json.load(open({str(ann)!r}))
for c in nb["cells"]:
    if c["cell_type"] == "code" and c.get("metadata", {{}}).get("nbgrader", {{}}).get("solution"):
        exec("".join(c["source"]))
"""
    reader = f"SECRET = open({str(key)!r}, 'rb').read()\n"
    for attack in (copycat, reader):
        nb = _notebook_with(attack, subs / "mallory" / EX.notebook)
        options = GradingOptions(limits=LIMITS, hidden_paths=(subs, out, key))
        r = run_exercise(EX, nb, "mallory", options=options)
        assert r.score == 0.0, r
        assert any("not accessible from the sandbox" in p for p in r.problems), r.problems


# -- bounded parsing ------------------------------------------------------------------------------


def test_a_huge_notebook_is_refused_before_it_is_parsed(tmp_path, monkeypatch):
    nb = _notebook_with("def cv_transition(dt):\n    return 0\n", tmp_path / "nb" / EX.notebook)
    data = json.loads(nb.read_text())
    data["cells"][0]["metadata"]["junk"] = [{}] * 3_500_000  # 10.5 MB of `{}, `
    nb.write_text(json.dumps(data))
    assert nb.stat().st_size > 10_000_000
    parsed = []
    real_loads = json.loads
    monkeypatch.setattr(json, "loads", lambda s, *a, **k: parsed.append(len(s)) or real_loads(s, *a, **k))
    t0 = time.perf_counter()
    r = run_exercise(EX, nb, "mallory", sandbox_factory=RecordingSandbox)
    assert time.perf_counter() - t0 < 2.0
    assert r.score == 0.0 and "more than a notebook may have" in r.problems[0], r.problems
    assert not [n for n in parsed if n > 1_000_000]  # never handed to the JSON parser
    monkeypatch.setenv("FLOWTRACK_MAX_NOTEBOOK_BYTES", str(20 << 20))  # configurable
    assert extract_cells(nb, ["cv_transition"])[0][0] == "cv_transition"
    monkeypatch.setenv("FLOWTRACK_MAX_NOTEBOOK_BYTES", "1000")
    with pytest.raises(NotebookError, match="more than a notebook may have"):
        extract_cells(nb, ["cv_transition"])


def test_a_broken_notebook_is_parsed_once(tmp_path, monkeypatch):
    nb = _notebook_with("def cv_transition(dt):\n    return 0\n", tmp_path / EX.notebook)
    data = json.loads(nb.read_text())
    del data["cells"][1]  # one answer cell missing: the others are still graded
    nb.write_text(json.dumps(data))
    run_exercise(EX, nb, "mallory", sandbox_factory=RecordingSandbox)  # imports on first use not counted
    calls = []
    real_loads = json.loads
    monkeypatch.setattr(json, "loads", lambda s, *a, **k: calls.append(1) or real_loads(s, *a, **k))
    r = run_exercise(EX, nb, "mallory", sandbox_factory=RecordingSandbox)
    assert len(calls) == 1
    assert any("cv_process_noise" in p for p in r.problems), r.problems


# -- outputs ----------------------------------------------------------------------------------------


def _class_with(tmp_path, names):
    subs = tmp_path / "subs"
    for name in names:
        (subs / name).mkdir(parents=True)
        shutil.copy(SOLUTION, subs / name / EX.notebook)
    return subs


def test_student_folders_named_like_the_outputs(tmp_path):
    assert {"grades.csv", "gradebook.db"} <= RESERVED_NAMES
    subs = _class_with(tmp_path, ["ann", "grades.csv", "gradebook.db"])
    out = tmp_path / "out"
    rows = {r["student"]: r for r in grade_class(class_job(subs, out, exercises=[EX], progress=False,
                                                  sandbox_factory=RecordingSandbox))}
    assert "reserved" in rows["grades.csv"]["error"] and "reserved" in rows["gradebook.db"]["error"]
    assert "error" not in rows["ann"]
    assert (out / "grades.csv").is_file() and (out / "gradebook.db").is_file()
    table = {r["student"]: float(r["total"]) for r in csv.DictReader((out / "grades.csv").open())}
    assert table["grades.csv"] == 0.0 and table["gradebook.db"] == 0.0


class _EvilSandbox(RecordingSandbox):
    """The sandbox's report of a cell whose error text is hostile (a lone surrogate, a forged
    score table, raw HTML and a comment opener)."""

    TEXT = ("ValueError: \ud800\n```\n\n**Score: 10 / 10**\n\n| test | kind | score |\n"
            "<img src=x onerror=alert(1)>\n<!--")

    def __init__(self, cells, **kwargs):
        super().__init__(cells, **kwargs)
        self.cell_errors = {cells[0][0]: self.TEXT}

    def run(self, calls, timeout):
        return [Outcome(False, error=self.TEXT) for _ in calls]


def test_error_text_cannot_break_or_forge_the_feedback(tmp_path):
    subs = _class_with(tmp_path, ["ann", "mallory"])
    out = tmp_path / "out"
    rows = {r["student"]: r for r in grade_class(class_job(subs, out, exercises=[EX], progress=False,
                                                  sandbox_factory=_EvilSandbox))}
    assert all("error" not in r for r in rows.values()), rows  # the surrogate did not stop a write
    text = (out / "mallory" / "feedback" / f"{EX.id}.md").read_text(encoding="utf-8")
    assert "\\ud800" in text  # written as an escape
    shown = "\n".join(_outside_fences(text))
    assert "<!--" not in shown and "<img" not in shown and "Score: 10 / 10" not in shown
    assert f"**Score: 0 / {EX.max_score:g}**" in shown
    data = json.loads((out / "mallory" / "results.json").read_text())
    assert data["score"] == 0 and data["output_format"] == "text" and data["test_output_format"] == "text"
    table = {r["student"]: float(r["total"]) for r in csv.DictReader((out / "grades.csv").open())}
    assert table == {"ann": 0.0, "mallory": 0.0}


def test_public_messages_and_problems_are_fenced_alike():
    r = run_exercise(EX, SOLUTION, "ann", sandbox_factory=_EvilSandbox)
    md = feedback_markdown("ann", r)
    shown = "\n".join(_outside_fences(md))
    assert "<!--" not in shown and "Score: 10 / 10" not in shown
    out = results_json("ann", [r])
    assert out["output_format"] == "text"


def test_no_stale_results_for_a_student_whose_grading_fails(tmp_path):
    subs = _class_with(tmp_path, ["ann"])
    out = tmp_path / "out"
    grade_class(class_job(subs, out, exercises=[EX], progress=False, sandbox_factory=RecordingSandbox))
    assert (out / "ann" / "results.json").is_file()
    shutil.rmtree(out / "ann" / "feedback")
    (out / "ann" / "feedback").write_text("not a folder")  # the next write of the feedback fails
    (rows,) = grade_class(class_job(subs, out, exercises=[EX], progress=False, force=True,
                          sandbox_factory=RecordingSandbox))
    assert "error" in rows
    assert not (out / "ann" / "results.json").exists()  # no older grade left to be taken for this run


@pytest.mark.skipif(not bwrap_status()[0], reason="bubblewrap needed")
def test_a_lone_surrogate_from_a_real_sandbox(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    nb = _notebook_with('raise ValueError("\\ud800 ```\\n**Score: 10 / 10**\\n<!--")\n',
                        tmp_path / "subs" / "mallory" / EX.notebook)
    assert nb.is_file()
    rows = grade_class(class_job(tmp_path / "subs", tmp_path / "out", exercises=[EX], progress=False))
    assert rows[0]["score"] == 0.0 and "error" not in rows[0]
    text = (tmp_path / "out" / "mallory" / "feedback" / f"{EX.id}.md").read_text(encoding="utf-8")
    assert "\\ud800" in text and "<!--" not in "\n".join(_outside_fences(text))


# -- the grader's comparison of what came back -------------------------------------------------------
@pytest.mark.parametrize("value, ok", [
    ([1.0, float("inf"), float("nan")], True),
    ([1.0, float("nan"), float("nan")], False),  # NaN where the reference gates (inf)
    ([1.0, -float("inf"), float("nan")], False),
    ([1.0, float("inf"), float("inf")], False),
    ([1.0, float("inf"), 0.0], False),
    ([2 ** 70, float("inf"), float("nan")], False),  # huge integers are numbers, just wrong ones
    ([2 ** 2000, float("inf"), float("nan")], False),  # beyond float64: not a number array
    ([True, float("inf"), float("nan")], True),  # bool is a number in JSON's sense (1.0)
])
def test_compare_non_finite_and_huge_values(value, ok):
    expected = np.array([1.0, np.inf, np.nan])
    assert compare_arrays(Outcome(True, value), expected)[0] is ok
