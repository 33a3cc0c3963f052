"""What a class's SUBMISSIONS folder holds on a first real run: resubmissions beside the first
submission, student folders named as people are (spaces, accents, other scripts), a name no output
could carry, a notebook left directly in SUBMISSIONS.

Oracles: the scores are decided here (a double scores 1 for an answer cell holding ``CORRECT``), the
CSV files are read back with the csv module, the gradebook through nbgrader's own API.
"""

from __future__ import annotations

import csv
import io
import json
import os
import time
import unicodedata
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")

from flowtrack_course.grading.engine.results import student_folder  # noqa: E402
from flowtrack_course.grading.engine.spec import Call, Exercise, GradedTest, Outcome  # noqa: E402
from grading_helpers import StandInSandbox, run_grade_with  # noqa: E402

pytestmark = pytest.mark.xdist_group("grading_instructor")


def _build(rng):
    return [Call("answer", (1.0,))], lambda outs: (float(outs[0].value), "ok" if outs[0].value else "wrong")


EXA = Exercise(
    "exa", "Vectors", "exa_vectors.ipynb", ("a1",), (), (GradedTest("t_a", "test_a", 2.0, False, _build),)
)


class MarkerSandbox(StandInSandbox):
    """Scores 1 when an answer cell holds the text ``CORRECT``, else 0 (the cells are never run)."""

    isolation = "marker"

    def run(self, calls, timeout):
        correct = any("CORRECT" in src for _, src in self.cells)
        return [Outcome(True, 1.0 if correct else 0.0) for _ in calls]


def _nb(path: Path, text: str, age: float = 0.0) -> Path:
    """A notebook of exercise ``exa`` whose answer cell holds ``text``, modified ``age`` s ago."""
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell(text)
    cell.metadata["nbgrader"] = {"grade_id": "a1", "solution": True, "grade": False, "locked": False,
                                 "schema_version": 3, "task": False}
    nb.cells.append(cell)
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    t = time.time() - age
    os.utime(path, (t, t))
    return path


def _run(subs, out, **kw):
    lines: list[str] = []
    run = run_grade_with(subs, out, exercises=(EXA,), progress=False, log=lines.append,
                         sandbox_factory=MarkerSandbox, **kw)
    return run, lines


def _rows(path: Path) -> list[dict]:
    return list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))


# --------------------------------------------------------------------------------------------------
# resubmissions


def test_the_newest_copy_is_graded_even_when_the_original_is_there(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "ann" / "exa_vectors.ipynb", "first try, wrong", age=600)
    _nb(subs / "ann" / "exa_vectors (1).ipynb", "second try, wrong", age=300)
    _nb(subs / "ann" / "exa_vectors (2).ipynb", "CORRECT", age=120)
    # the highest copy number wins over a newer file: (2) is the resubmission, whatever its mtime
    _nb(subs / "bob" / "exa_vectors.ipynb", "wrong, touched later", age=0)
    _nb(subs / "bob" / "exa_vectors-2.ipynb", "CORRECT", age=300)
    # the same copy number: the newest file
    _nb(subs / "cat" / "exa_vectors.ipynb", "older, wrong", age=300)
    _nb(subs / "cat" / "EXA_Vectors.ipynb", "CORRECT", age=10)
    run, lines = _run(subs, tmp_path / "out", accept_renamed=True)
    assert run.status == 0, run.summary
    scores = {r["student"]: float(r["total"]) for r in _rows(tmp_path / "out" / "grades.csv")}
    assert scores == {"ann": 2.0, "bob": 2.0, "cat": 2.0}
    feedback = (tmp_path / "out" / "ann" / "feedback" / "exa.md").read_text()
    assert "graded `exa_vectors (2).ipynb`" in feedback
    assert "ignored `exa_vectors (1).ipynb`, `exa_vectors.ipynb`" in feedback
    assert any("newer than the expected exa_vectors.ipynb" in ln for ln in lines)


def test_without_accept_renamed_the_feedback_names_the_file_graded_and_those_ignored(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "ann" / "exa_vectors.ipynb", "first try, wrong", age=600)
    _nb(subs / "ann" / "exa_vectors (1).ipynb", "CORRECT", age=60)
    _nb(subs / "dan" / "exa_vectors (1).ipynb", "CORRECT", age=60)  # no original: not submitted
    run, lines = _run(subs, tmp_path / "out")
    scores = {r["student"]: float(r["total"]) for r in _rows(tmp_path / "out" / "grades.csv")}
    assert scores == {"ann": 0.0, "dan": 0.0}
    feedback = (tmp_path / "out" / "ann" / "feedback" / "exa.md").read_text()
    assert "graded `exa_vectors.ipynb`; ignored `exa_vectors (1).ipynb`" in feedback
    assert "--accept-renamed" in feedback
    feedback = (tmp_path / "out" / "dan" / "feedback" / "exa.md").read_text()
    assert "not submitted under its expected name; ignored `exa_vectors (1).ipynb`" in feedback
    text = "\n".join(lines)
    assert "ann/exa_vectors (1).ipynb -> ann/exa_vectors.ipynb" in text and "graded instead" in text
    assert any("2 renamed notebook(s) were not graded" in s for s in run.summary)


# --------------------------------------------------------------------------------------------------
# student ids


def test_any_folder_name_is_an_id_kept_in_every_output_and_joined_with_the_roster(tmp_path):
    from nbgrader.api import Gradebook

    subs = tmp_path / "subs"
    names = ["José Müller", "李雷", "ann"]
    _nb(subs / names[0] / "exa_vectors.ipynb", "CORRECT")
    _nb(subs / names[1] / "exa_vectors.ipynb", "wrong")
    _nb(subs / names[2] / "exa_vectors.ipynb", "CORRECT")
    roster = tmp_path / "roster.csv"
    # the roster spells the accent as a letter and a combining mark (as macOS names files)
    nfd = unicodedata.normalize("NFD", names[0])
    roster.write_text(f"student,name,email\n{nfd},José Müller,jose@uni.edu\n李雷,Li Lei,li@uni.edu\n"
                      "ann,Ann Lee,ann@uni.edu\n", encoding="utf-8")
    out = tmp_path / "out"
    run, lines = _run(subs, out, roster=str(roster), lms="canvas")
    assert run.status == 0, (run.reason, run.summary, lines)
    rows = _rows(out / "grades.csv")
    assert {r["student"]: float(r["total"]) for r in rows} == {names[0]: 2.0, names[1]: 0.0, names[2]: 2.0}
    for name in names:
        folder = out / student_folder(name)
        assert json.loads((folder / "results.json").read_text())["extra_data"]["flowtrack"]["student"] == name
        assert f"Student: `{name}`" in (folder / "feedback" / "exa.md").read_text()
    assert student_folder(names[0]).isascii() and student_folder(names[1]) != student_folder(names[0])
    canvas = list(csv.reader(io.StringIO((out / "canvas.csv").read_text(encoding="utf-8"))))
    by_name = {row[0]: row for row in canvas[2:]}
    assert by_name["Müller, José"][-1] == "2" and by_name["Lei, Li"][-1] == "0"
    assert not any("not in the roster" in s for s in run.summary)
    with Gradebook(f"sqlite:///{out / 'gradebook.db'}") as gb:
        assert sorted(s.id for s in gb.students) == sorted(names)
        assert gb.find_student(names[0]).email == "jose@uni.edu"
    # moodle, from the same grades.csv
    from flowtrack_course.grading.export.lms import export_lms

    path, warnings = export_lms("moodle", out / "grades.csv", tmp_path / "moodle.csv", roster=roster)
    moodle = list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))
    assert {r["Email address"]: r["flowtrack"] for r in moodle} == {
        "jose@uni.edu": "2", "li@uni.edu": "0", "ann@uni.edu": "2"}
    assert not warnings


def test_a_name_that_cannot_be_an_id_skips_that_student_only(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "ann" / "exa_vectors.ipynb", "CORRECT")
    _nb(subs / "bad\nname" / "exa_vectors.ipynb", "CORRECT")
    os.mkdir(os.fsencode(subs) + b"/caf\xe9")  # Latin-1 bytes: not UTF-8 text
    _nb(Path(os.fsdecode(os.fsencode(subs) + b"/caf\xe9")) / "exa_vectors.ipynb", "CORRECT")
    run, lines = _run(subs, tmp_path / "out")
    assert run.status == 1
    assert [r["student"] for r in _rows(tmp_path / "out" / "grades.csv")] == ["ann"]
    text = "\n".join(lines)
    assert "'bad\\nname': it holds control characters" in text and "not UTF-8" in text
    assert any("2 student folder(s) not graded" in s for s in run.summary)


def test_a_notebook_left_directly_in_submissions_fails_the_run_unless_ignored(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "ann" / "exa_vectors.ipynb", "CORRECT")
    _nb(subs / "bob_123_456_exa_vectors.ipynb", "CORRECT")
    run, lines = _run(subs, tmp_path / "out")
    assert run.status == 1 and [r["student"] for r in run.rows] == ["ann"]
    assert any("1 file(s) directly in" in s and "--ignore-flat" in s for s in run.summary)
    assert any(f"{subs / 'bob' / 'exa_vectors.ipynb'}" in ln for ln in lines)  # the move to make
    run, _ = _run(subs, tmp_path / "out", ignore_flat=True)
    assert run.status == 0 and any("left out (--ignore-flat)" in s for s in run.summary)
