"""The instructor's side of the grader: layout checks, renamed copies, LMS export and
roster, seed-key handling, the Gradescope bundle, packaging metadata, misconceptions and class report.

Oracles: hand-written expected mappings for the LMS renames; the Canvas/Moodle files are read back
with the csv module and compared with the scores the test itself decided; the gradebook is read back
through nbgrader's own API; score statistics are checked against numpy; the wheel's METADATA
against the core-metadata fields of PEP 639 (License-Expression, License-File).
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest

nbformat = pytest.importorskip("nbformat")

from flowtrack_course.grading.engine import layout  # noqa: E402
from flowtrack_course.grading.engine.spec import Call, Exercise, GradedTest, Outcome  # noqa: E402
from flowtrack_course.grading.export import classreport, lms  # noqa: E402
from flowtrack_course.grading.grade.keys import InsecureKeyError, check_key_file  # noqa: E402
from grading_helpers import (  # noqa: E402
    StandInSandbox,
    get_exercise,
    run_grade_with,
    source_notebook,
)

pytestmark = pytest.mark.xdist_group("grading_instructor")

ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------------------------------
# a tiny course: two fake exercises graded by a double that never runs code


def _build(rng):
    return [Call("answer", (1.0,))], lambda outs: (float(outs[0].value), "ok" if outs[0].value else "wrong")


EXA = Exercise(
    "exa", "Vectors", "exa_vectors.ipynb", ("a1",), (), (GradedTest("t_a", "test_a", 2.0, False, _build),)
)
EXB = Exercise(
    "exb", "Model", "exb_model.ipynb", ("b1",), (), (GradedTest("t_b", "test_b", 3.0, True, _build),)
)
COURSE = (EXA, EXB)


class MarkerSandbox(StandInSandbox):
    """Scores 1 when an answer cell holds the text ``CORRECT``, else 0 (the cells are never run)."""

    isolation = "marker"

    def run(self, calls, timeout):
        correct = any("CORRECT" in src for _, src in self.cells)
        return [Outcome(True, 1.0 if correct else 0.0) for _ in calls]


def _nb(path: Path, ex: Exercise, text: str) -> Path:
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell(text)
    cell.metadata["nbgrader"] = {
        "grade_id": ex.answer_cells[0],
        "solution": True,
        "grade": False,
        "locked": False,
        "schema_version": 3,
        "task": False,
    }
    nb.cells.append(cell)
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    return path


def _run(subs, out, **kw):
    lines: list[str] = []
    kw.setdefault("exercises", COURSE)
    run = run_grade_with(subs, out, progress=False, log=lines.append, sandbox_factory=MarkerSandbox, **kw)
    return run, lines


def _rows(path: Path) -> list[dict]:
    return list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))


# --------------------------------------------------------------------------------------------------
# layout


@pytest.mark.parametrize(
    ("name", "canon", "copy"),
    [
        ("exa_vectors.ipynb", "exa_vectors", 0),
        ("exa_vectors (1).ipynb", "exa_vectors", 1),  # Canvas / browser download of a resubmission
        ("exa_vectors(12).ipynb", "exa_vectors", 12),
        ("exa_vectors-2.ipynb", "exa_vectors", 2),  # Canvas: "-N" for the N-th resubmission
        ("exa_vectors_3.ipynb", "exa_vectors", 3),
        ("EXA_Vectors.IPYNB", "exa_vectors", 0),
        ("exa_vectors - Copy.ipynb", "exa_vectors", 1),
        ("exa-vectors.ipynb", "exa_vectors", 0),
    ],
)
def test_canonical_names_of_lms_renames(name, canon, copy):
    assert layout.canonical(name) == canon
    assert layout.copy_number(name) == copy


def test_lms_prefixes_give_the_exercise_and_a_student_id():
    m = layout.match_exercise("doejane_LATE_123_4567_exa_vectors-1.ipynb", COURSE)
    assert m is not None and m[0] is EXA and layout.suggest_student_id(m[1]) == "doejane"
    m = layout.match_exercise("Jane Doe_4242_assignsubmission_file_exb_model.ipynb", COURSE)
    assert m is not None and m[0] is EXB and layout.suggest_student_id(m[1]) == "jane_doe"
    assert layout.match_exercise("exa_vectors.py", COURSE) is None
    assert layout.match_exercise("vectors.ipynb", COURSE) is None


def _class(root: Path) -> Path:
    subs = root / "subs"
    _nb(subs / "alice" / EXA.notebook, EXA, "CORRECT")
    _nb(subs / "alice" / EXB.notebook, EXB, "CORRECT")
    _nb(subs / "bob" / "exa_vectors (1).ipynb", EXA, "wrong first try")
    _nb(subs / "bob" / "exa_vectors (2).ipynb", EXA, "CORRECT")  # the latest resubmission
    _nb(subs / "bob" / EXB.notebook, EXB, "CORRECT")
    _nb(subs / "carol" / "EXA_Vectors.ipynb", EXA, "CORRECT")
    (subs / "carol" / "notes.txt").write_text("my notes")
    _nb(subs / "dave" / "sub" / "exb_model-2.ipynb", EXB, "CORRECT")
    return subs


def test_check_layout_reports_renamed_copies_and_unknown_files(tmp_path):
    subs = _class(tmp_path)
    rep = layout.check_layout(subs, COURSE)
    assert rep.students == ["alice", "bob", "carol", "dave"]
    assert {(r.student, r.exercise_id): r.found for r in rep.renamed} == {
        ("bob", "exa"): "exa_vectors (2).ipynb",
        ("carol", "exa"): "EXA_Vectors.ipynb",
        ("dave", "exb"): "sub/exb_model-2.ipynb",
    }
    assert rep.ambiguous == {("bob", "exa"): ["exa_vectors (1).ipynb"]}
    assert rep.unknown == {"carol": ["notes.txt"]}
    assert rep.missing == {"carol": ["exb"], "dave": ["exa"]}
    assert not rep.flat and not rep.blocking
    text = "\n".join(rep.messages(COURSE))
    assert "NOT graded" in text and "--accept-renamed" in text
    assert f"mv {subs / 'carol' / 'EXA_Vectors.ipynb'} {subs / 'carol' / EXA.notebook}" in text


def test_renamed_copies_score_zero_unless_accepted_and_feedback_says_so(tmp_path):
    subs = _class(tmp_path)
    run, lines = _run(subs, tmp_path / "out")
    assert run.status == 0 and any("NOT graded" in ln for ln in lines)
    scores = {r["student"]: float(r["total"]) for r in _rows(tmp_path / "out" / "grades.csv")}
    assert scores == {"alice": 5.0, "bob": 3.0, "carol": 0.0, "dave": 0.0}
    assert any("renamed notebook(s) were not graded" in s for s in run.summary)
    run, _ = _run(subs, tmp_path / "out", accept_renamed=True)
    scores = {r["student"]: float(r["total"]) for r in _rows(tmp_path / "out" / "grades.csv")}
    # bob's latest copy (2) is right, his first (1) wrong: 2 + 3 only if the best match was graded
    assert scores == {"alice": 5.0, "bob": 5.0, "carol": 2.0, "dave": 3.0}
    feedback = (tmp_path / "out" / "bob" / "feedback" / "exa.md").read_text()
    assert "exa_vectors (2).ipynb" in feedback and "--accept-renamed" in feedback
    assert "accept-renamed" not in (tmp_path / "out" / "alice" / "feedback" / "exa.md").read_text()
    data = json.loads((tmp_path / "out" / "dave" / "results.json").read_text())
    assert "sub/exb_model-2.ipynb" in data["output"]
    assert any("accepted 3 renamed" in s for s in run.summary)


def test_a_flat_layout_grades_nobody_and_says_why(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "doejane_123_4567_exa_vectors.ipynb", EXA, "CORRECT")
    _nb(subs / "roebob_LATE_124_4568_exb_model-1.ipynb", EXB, "CORRECT")
    (subs / "readme.pdf").write_text("x")
    run, lines = _run(subs, tmp_path / "out")
    assert run.status == 2 and "directly in SUBMISSIONS" in run.reason
    text = "\n".join(lines)
    assert f"mv {subs / 'doejane_123_4567_exa_vectors.ipynb'} {subs / 'doejane' / EXA.notebook}" in text
    assert f"{subs / 'roebob' / EXB.notebook}" in text
    assert "readme.pdf" in text and "<student>/" in text  # the expected layout is shown
    assert not (tmp_path / "out" / "grades.csv").exists()


def test_folders_without_any_expected_notebook_grade_nobody(tmp_path):
    subs = tmp_path / "subs"
    (subs / "ann").mkdir(parents=True)
    (subs / "ann" / "homework.py").write_text("print(1)")
    _nb(subs / "ben" / "exa_vectors (1).ipynb", EXA, "CORRECT")
    run, _ = _run(subs, tmp_path / "out")
    assert (
        run.status == 2
        and "none of the 2 student folder(s)" in run.reason
        and "--accept-renamed" in run.reason
    )
    run, _ = _run(subs, tmp_path / "out", accept_renamed=True)
    assert run.status == 0 and run.rows[1]["score"] == 2.0
    (tmp_path / "empty").mkdir()
    run, _ = _run(tmp_path / "empty", tmp_path / "out3")
    assert run.status == 2 and "no student folder" in run.reason


def test_moodle_folder_names_are_graded_as_ids_with_a_suggested_rename(tmp_path):
    subs = tmp_path / "subs"
    _nb(subs / "Jane Doe_4242_assignsubmission_file_" / EXA.notebook, EXA, "CORRECT")
    run, lines = _run(subs, tmp_path / "out")
    assert run.status == 0 and [r["student"] for r in run.rows] == ["Jane Doe_4242_assignsubmission_file_"]
    assert any(ln.endswith("/Jane Doe'") and "mv" in ln for ln in lines)  # the roster's id, spaces kept


def test_cli_grade_exits_nonzero_on_a_flat_layout(tmp_path, capsys):
    from flowtrack_course.cli import main

    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "ex05_cv_model.ipynb").write_text("{}")
    status = main(["grade", str(subs), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert status == 2 and "graded no student" in err and "ex05_cv_model.ipynb" in err


def test_check_suggests_the_rename_of_an_lms_copy(tmp_path, capsys):
    from flowtrack_course.grading.check import check as check_mod

    calls = []

    def fake_run(exercise, path, student, *, public_only=False, **kw):
        calls.append((exercise.id, Path(path).name, public_only))
        from flowtrack_course.grading.engine.results import ExerciseResult

        return ExerciseResult(exercise.id, exercise.title, exercise.notebook)

    copy = tmp_path / "ex05_cv_model (1).ipynb"
    copy.write_text("{}")
    orig = check_mod.run_exercise
    check_mod.run_exercise = fake_run
    try:
        status = check_mod.check_notebook(copy)
        with pytest.raises(ValueError, match="not one of the course's exercises"):
            (tmp_path / "homework.ipynb").write_text("{}")
            check_mod.check_notebook(tmp_path / "homework.ipynb")
    finally:
        check_mod.run_exercise = orig
    out = capsys.readouterr().out
    assert calls == [("ex05_cv_model", copy.name, True)]
    assert status == 1 and "renamed copy" in out and str(tmp_path / "ex05_cv_model.ipynb") in out


# --------------------------------------------------------------------------------------------------
# roster and LMS files

ROSTER = """Student ID,Full Name,E-mail,Section,SIS User ID,Canvas ID
alice,Alice Liddell,alice@uni.example,S1,A-001,101
bob,"Builder, Bob",bob@uni.example,S2,B-002,
carol,Carol,,S1,,
zoe,Zoe Zed,zoe@uni.example,S2,Z-009,109
"""


def _roster(tmp_path: Path) -> Path:
    p = tmp_path / "roster.csv"
    p.write_text(ROSTER)
    return p


def test_read_roster_maps_aliases_and_splits_names(tmp_path):
    r = lms.read_roster(_roster(tmp_path))
    assert list(r) == ["alice", "bob", "carol", "zoe"]
    assert (r["alice"].first_name, r["alice"].last_name, r["alice"].email) == (
        "Alice",
        "Liddell",
        "alice@uni.example",
    )
    assert (r["bob"].first_name, r["bob"].last_name) == ("Bob", "Builder")
    assert r["alice"].sis_user_id == "A-001" and r["alice"].lms_id == "101" and r["bob"].section == "S2"
    assert r["alice"].sortable_name == "Liddell, Alice"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("name,email\nA,a@b.c\n", "no student id column"),
        ("student,email\nann,a@b.c\nann,x@y.z\n", "row 3: duplicate"),
        ("student,email\nann,not-an-email\n", "row 2: email"),
        ("student,email\n,a@b.c\n", "row 2: empty student id"),
    ],
)
def test_read_roster_rejects_bad_rows(tmp_path, text, match):
    p = tmp_path / "r.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        lms.read_roster(p)
    with pytest.raises(FileNotFoundError, match="roster"):
        lms.read_roster(tmp_path / "nope.csv")


def _graded_class(tmp_path: Path, **kw):
    subs = _class(tmp_path)
    return _run(subs, tmp_path / "out", accept_renamed=True, **kw)


def test_canvas_export_per_exercise_and_total(tmp_path):
    _graded_class(tmp_path)
    roster = lms.read_roster(_roster(tmp_path))
    ids, rows = lms.read_grades_csv(tmp_path / "out" / "grades.csv")
    assert ids == ["exa", "exb"]
    text, warnings = lms.canvas_csv(
        rows, ids, points={"exa": 2.0, "exb": 3.0}, roster=roster, mode="exercises", assignment="HW1"
    )
    table = list(csv.reader(io.StringIO(text)))
    assert table[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "HW1: exa", "HW1: exb"]
    assert table[1][0].strip() == "Points Possible" and table[1][5:] == ["2", "3"]
    body = {r[0]: r for r in table[2:]}
    assert body["Liddell, Alice"][1:] == ["101", "A-001", "", "S1", "2", "3"]
    assert body["Builder, Bob"][1:] == ["", "B-002", "", "S2", "2", "3"]
    assert body["Carol"][1:] == ["", "", "carol", "S1", "2", "0"]  # login = folder name
    assert body["Zed, Zoe"][5:] == ["", ""]  # in the roster, nothing submitted: left blank
    assert body["dave"][3] == "dave" and body["dave"][5:] == ["0", "3"]  # graded, not in the roster
    assert any("not in the roster" in w and "dave" in w for w in warnings)
    assert any("without a graded submission" in w and "zoe" in w for w in warnings)
    text, _ = lms.canvas_csv(
        rows, ids, points={"exa": 2.0, "exb": 3.0}, roster=roster, assignment="HW1", assignment_id="777"
    )
    table = list(csv.reader(io.StringIO(text)))
    assert table[0][5:] == ["HW1 (777)"] and table[1][5:] == ["5"]
    assert {r[0]: r[5] for r in table[2:]}["Builder, Bob"] == "5"


def test_moodle_export_identifies_users_by_email_or_id_number(tmp_path):
    _graded_class(tmp_path)
    out = tmp_path / "moodle.csv"
    path, warnings = lms.export_lms(
        "moodle",
        tmp_path / "out" / "grades.csv",
        out,
        roster=_roster(tmp_path),
        mode="total",
        assignment="HW1",
        points={},
    )
    table = list(csv.DictReader(io.StringIO(path.read_text())))
    assert list(table[0]) == ["First name", "Last name", "ID number", "Email address", "HW1"]
    by = {r["First name"]: r for r in table}
    assert by["Alice"]["Email address"] == "alice@uni.example" and by["Alice"]["HW1"] == "5"
    assert by["Carol"]["ID number"] == "carol" and by["Carol"]["HW1"] == "2"
    assert by["Zoe"]["HW1"] == ""
    assert any("without e-mail or ID number" in w for w in warnings)
    with pytest.raises(ValueError, match="lms"):
        lms.export_lms("blackboard", tmp_path / "out" / "grades.csv", out)


def test_grade_with_roster_and_lms_fills_gradebook_and_writes_canvas_csv(tmp_path):
    pytest.importorskip("nbgrader")
    from nbgrader.api import Gradebook

    from flowtrack_course.grading.export.gradebook import _alembic_on_path

    run, _ = _graded_class(tmp_path, roster=_roster(tmp_path), lms="canvas", lms_mode="exercises")
    assert run.status == 0 and (tmp_path / "out" / "canvas.csv").is_file()
    with _alembic_on_path(), Gradebook(f"sqlite:///{tmp_path / 'out' / 'gradebook.db'}") as gb:
        alice = gb.find_student("alice")
        assert (alice.first_name, alice.last_name, alice.email, alice.lms_user_id) == (
            "Alice",
            "Liddell",
            "alice@uni.example",
            "101",
        )
        assert gb.find_student("dave").email is None
    assert any("not in the roster" in s and "dave" in s for s in run.summary)


def test_export_command_line(tmp_path, capsys):
    from flowtrack_course.cli import main

    _graded_class(tmp_path)
    out = tmp_path / "canvas.csv"
    status = main(
        [
            "export",
            "--lms",
            "canvas",
            "--grades",
            str(tmp_path / "out" / "grades.csv"),
            "--roster",
            str(_roster(tmp_path)),
            "--out",
            str(out),
        ]
    )
    assert status == 0 and "wrote" in capsys.readouterr().out
    table = list(csv.reader(io.StringIO(out.read_text())))
    assert table[0][5:] == ["flowtrack"] and table[1][5] == "5"  # the total of grades.csv
    assert (tmp_path / "out" / "grades.csv").read_text().splitlines()[0] == "student,exa,exb,total,max"


# --------------------------------------------------------------------------------------------------
# seed key


def test_a_key_others_can_read_is_refused_with_the_fix(tmp_path):
    key = tmp_path / "key"
    key.write_bytes(os.urandom(32))
    key.chmod(0o644)
    with pytest.raises(InsecureKeyError, match=r"chmod 600 .*key"):
        check_key_file(key)
    key.chmod(0o640)
    with pytest.raises(InsecureKeyError):
        check_key_file(key)
    key.chmod(0o600)
    check_key_file(key)
    check_key_file(tmp_path / "missing")  # created owner-only later


def test_gradescope_bundle_refuses_a_world_readable_key(tmp_path):
    from flowtrack_course.grading.export.gradescope import build_autograder

    key = tmp_path / "key"
    key.write_bytes(os.urandom(32))
    key.chmod(0o604)
    with pytest.raises(InsecureKeyError, match="chmod 600"):
        build_autograder(tmp_path / "ag.zip", secret_file=key)
    assert not (tmp_path / "ag.zip").exists()


def test_cli_refuses_a_world_readable_key(tmp_path, capsys):
    from flowtrack_course.cli import main

    key = tmp_path / "key"
    key.write_bytes(os.urandom(32))
    key.chmod(0o644)
    (tmp_path / "subs" / "ann").mkdir(parents=True)
    status = main(
        [
            "grade",
            str(tmp_path / "subs"),
            "--out",
            str(tmp_path / "out"),
            "--secret-file",
            str(key),
            "--no-progress",
        ]
    )
    assert status == 2 and "chmod 600" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_summary_says_why_students_are_regraded(tmp_path):
    subs = _class(tmp_path)
    out = tmp_path / "out"
    run, _ = _run(subs, out, secret=b"k" * 32)
    assert run.regraded == {} and not any("re-graded" in s for s in run.summary)
    run, _ = _run(subs, out, secret=b"k" * 32)
    assert run.regraded == {} and all(r["skipped"] for r in run.rows)
    run, _ = _run(subs, out, secret=b"j" * 32)
    assert run.regraded == {s: "seed key changed" for s in ("alice", "bob", "carol", "dave")}
    line = next(s for s in run.summary if s.startswith("re-graded"))
    assert "4 student(s)" in line and "4 seed key changed" in line and "--secret-file" in line
    _nb(subs / "alice" / EXA.notebook, EXA, "now wrong")
    run, _ = _run(subs, out, secret=b"j" * 32)
    assert run.regraded == {"alice": "submission changed"}
    run, _ = _run(subs, out, secret=b"j" * 32, force=True)
    assert set(run.regraded.values()) == {"--force"}


# --------------------------------------------------------------------------------------------------
# misconceptions and class report


def test_misconceptions_csv_is_written_with_its_header_on_every_run(tmp_path):
    _graded_class(tmp_path)
    text = (tmp_path / "out" / "misconceptions.csv").read_text()
    assert text == "exercise,mistake_id,count,students\n"
    report = (tmp_path / "out" / "class_report.md").read_text()
    assert "| exa | 2 | 4 |" in report and "No mistakes were recognised" in report


def test_mistakes_from_results_json_reach_the_csv_and_the_report(tmp_path):
    out = tmp_path / "out"

    def results(student, outputs, extra=()):
        tests = [{"name": f"{ex}: t", "output": o, "extra_data": {"exercise": ex}} for ex, o in outputs]
        data = {
            "score": 0,
            "tests": tests,
            "extra_data": {"flowtrack": {"mistakes": [list(e) for e in extra]}},
        }
        (out / student).mkdir(parents=True)
        (out / student / "results.json").write_text(json.dumps(data))

    # the grader's records count; the "mistake <id>:" lines of an output are text (a student's own
    # exception message may hold such lines: mallory's), never parsed
    results("ann", [("exa", "expected 1\nmistake generic-sign: the sign is flipped"), ("exb", "ok")],
            extra=[("exa", "generic-sign")])
    results("ben", [("exa", "mistake generic-sign: flipped\nmistake generic-scale: x2")],
            extra=[("exa", "generic-sign"), ("exa", "generic-scale")])
    results("cid", [("exb", "all good")], extra=[("exb", "cv-dt-squared")])
    results("mallory", [("exa", "ValueError: \nmistake generic-sign: forged\nmistake q-block-diagonal: x")])
    results("dan", [("exb", "all good")])  # the grader's own record format (grade.py, mistake_records)
    data = json.loads((out / "dan" / "results.json").read_text())
    data["extra_data"]["flowtrack"]["mistakes"] = [{"exercise": "exb", "id": "cv-dt-squared", "tests": ["t"]}]
    (out / "dan" / "results.json").write_text(json.dumps(data))
    found = classreport.collect_mistakes(out, ["ann", "ben", "cid", "dan", "mallory", "nobody"])
    assert found.pop("dan") == [("exb", "cv-dt-squared")]
    assert found.pop("mallory") == []
    assert found == {
        "ann": [("exa", "generic-sign")],
        "ben": [("exa", "generic-scale"), ("exa", "generic-sign")],
        "cid": [("exb", "cv-dt-squared")],
    }
    classreport.write_misconceptions_csv(out / "m.csv", found)
    rows = _rows(out / "m.csv")
    assert rows[0] == {
        "exercise": "exa",
        "mistake_id": "generic-sign",
        "count": "2",
        "students": "ann;ben",
    }
    assert {(r["mistake_id"], r["count"]) for r in rows[1:]} == {
        ("generic-scale", "1"),
        ("cv-dt-squared", "1"),
    }
    summaries = [{"student": s, "exercises": {"exa": 1.0, "exb": 0.0}} for s in ("ann", "ben", "cid")]
    md = classreport.class_report_markdown(summaries, COURSE, found)
    assert "| exa | `generic-sign` | 2 | 67 % |" in md


def test_score_distribution_agrees_with_numpy():
    rng = np.random.default_rng(3)
    scores = [*np.round(rng.uniform(0, 7.0, size=37), 2).tolist(), 0.0, 7.0, 7.0]
    d = classreport.score_distribution(scores, 7.0)
    hist, _ = np.histogram(scores, bins=np.linspace(0, 7.0, 11))
    assert d["histogram"] == hist.tolist()
    assert d["mean"] == pytest.approx(np.mean(scores), rel=1e-12)
    assert d["median"] == pytest.approx(np.median(scores), rel=1e-12)
    assert (d["min"], d["max"], d["n"]) == (min(scores), max(scores), len(scores))
    assert d["full"] == sum(1 for s in scores if s == 7.0) and d["zero"] == sum(1 for s in scores if s == 0.0)


# --------------------------------------------------------------------------------------------------
# Gradescope bundle


def _unpack(tmp_path: Path, **kw) -> Path:
    from flowtrack_course.grading.export.gradescope import build_autograder

    z = build_autograder(tmp_path / "ag.zip", **kw)
    dest = tmp_path / "source"
    with zipfile.ZipFile(z) as zf:
        zf.extractall(dest)
    for script in ("setup.sh", "run_autograder"):
        subprocess.run(["bash", "-n", str(dest / script)], check=True)
    return dest


def _grader_extra() -> list[str]:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return meta["project"]["optional-dependencies"]["grader"]


def test_setup_installs_only_the_grader_extra(tmp_path):
    src = _unpack(tmp_path)
    setup = (src / "setup.sh").read_text()
    assert "[grading]" not in setup and "--no-deps" in setup and "requirements-grader.txt" in setup
    reqs = (src / "requirements-grader.txt").read_text().split()
    assert reqs == _grader_extra()
    names = {r.split(">")[0].split("=")[0].split("<")[0].lower() for r in reqs}
    assert {"numpy", "scipy", "nbformat"} <= names
    assert not names & {
        "open3d",
        "scikit-image",
        "nbgrader",
        "jupytext",
        "ipykernel",
        "notebook",
        "matplotlib",
    }
    assert (src / "flowtrack" / "LICENSE").is_file()  # license-files of pyproject.toml


def test_bundle_exercises_option_is_the_run_default(tmp_path):
    src = _unpack(tmp_path, exercises="ex01,ex05_cv_model")
    script = (src / "run_autograder").read_text()
    assert 'EXERCISES="${FLOWTRACK_EXERCISES:-ex01_projection_jacobian,ex05_cv_model}"' in script
    with pytest.raises(ValueError, match="exercises"):
        _unpack(tmp_path / "bad", exercises="ex99")


def _fake_autograder(tmp_path: Path, metadata: dict | None) -> Path:
    ag = tmp_path / "autograder"
    (ag / "submission").mkdir(parents=True)
    if metadata is not None:
        (ag / "submission_metadata.json").write_text(json.dumps(metadata))
    return ag


def _run_autograder(src: Path, ag: Path, python: str, extra_env=None) -> dict:
    env = dict(
        os.environ,
        AUTOGRADER_ROOT=str(ag),
        FLOWTRACK_PYTHON=python,
        PYTHONPATH=str(src / "flowtrack" / "reference_impl"),
        **(extra_env or {}),
    )
    env.pop("FLOWTRACK_EXERCISES", None)
    proc = subprocess.run(
        ["bash", str(src / "run_autograder")], env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0
    return json.loads((ag / "results" / "results.json").read_text())


@pytest.mark.parametrize("python", ["/nonexistent/python", "broken"])
def test_run_autograder_writes_an_error_result_when_the_grader_cannot_run(tmp_path, python):
    src = _unpack(tmp_path)
    ag = _fake_autograder(tmp_path, {"users": [{"id": "42"}]})
    (ag / "results").mkdir()
    (ag / "results" / "results.json").write_text('{"score": 100}')  # stale: must not survive
    if python == "broken":  # an interpreter on which flowtrack cannot be imported
        python = str(tmp_path / "py")
        Path(python).write_text(
            f"#!/bin/sh\nexec {sys.executable} -I -c 'import flowtrack_missing_module' \"$@\"\n"
        )
        Path(python).chmod(0o755)
    data = _run_autograder(src, ag, python)
    assert data["score"] == 0 and data["tests"] == []
    assert data["output"].startswith("autograder error") and "not a problem with your work" in data["output"]
    assert ("ModuleNotFoundError" if python.endswith("/py") else "No such file") in data["output"]


def test_missing_metadata_is_an_explicit_error(tmp_path):
    src = _unpack(tmp_path, exercises="ex05")
    ag = _fake_autograder(tmp_path, None)
    data = _run_autograder(src, ag, sys.executable)
    assert data["score"] == 0 and "submission_metadata.json" in data["output"]
    assert data["extra_data"]["flowtrack"]["error"]
    from flowtrack_course.grading.grade.gradescope import MetadataError, student_from_metadata

    (tmp_path / "m.json").write_text(json.dumps({"users": []}))
    with pytest.raises(MetadataError, match="names no submitter"):
        student_from_metadata(tmp_path / "m.json")
    (tmp_path / "m.json").write_text(json.dumps({"users": [{"email": "a b@x.org"}]}))
    assert student_from_metadata(tmp_path / "m.json") == "a_b@x.org"


def test_bundle_grades_only_its_exercises(tmp_path):
    src = _unpack(tmp_path, exercises="ex05")
    ag = _fake_autograder(tmp_path, {"users": [{"id": "777"}]})
    nb = source_notebook(get_exercise("ex05_cv_model"))
    (ag / "submission" / nb.name).write_bytes(nb.read_bytes())
    data = _run_autograder(src, ag, sys.executable)
    info = data["extra_data"]["flowtrack"]
    assert list(info["exercises"]) == ["ex05_cv_model"] and info["student"] == "777"
    assert {t["extra_data"]["exercise"] for t in data["tests"]} == {"ex05_cv_model"}
    assert data["score"] == pytest.approx(info["max_score"])  # the instructor's solution


def _req_name(req: str) -> str:
    return re.split(r"[<>=!~;\[ ]", req, maxsplit=1)[0].lower().replace("_", "-")


def _closure(names: list[str], extras: bool = False) -> set[str]:
    """The distributions ``names`` need, recursively, as installed; with ``extras`` also their
    optional (extra) requirements, which a library may import when they happen to be installed."""
    from importlib.metadata import PackageNotFoundError, requires

    seen: set[str] = set()
    todo = list(names)
    while todo:
        n = todo.pop()
        if n in seen:
            continue
        seen.add(n)
        try:
            reqs = requires(n) or []
        except PackageNotFoundError:
            continue
        for r in reqs:
            if not extras and "extra" in r.split(";", 1)[-1] and ";" in r:
                continue
            todo.append(_req_name(r))
    return seen


PROBE = r"""
import json, sys, tempfile
from pathlib import Path
from flowtrack_course.grading.engine.jobs import GradingOptions, StudentJob
from flowtrack_course.grading.engine.student import grade_student
from flowtrack_course.grading.sources import course_catalog
sub = Path(sys.argv[1])
exercises = course_catalog().default()
with tempfile.TemporaryDirectory() as tmp:
    s = grade_student(StudentJob("probe", sub, Path(tmp), exercises, GradingOptions(force=True)))
top = sorted({m.split(".")[0] for m in sys.modules} - set(sys.stdlib_module_names))
print(json.dumps({"score": s["score"], "max": s["max_score"], "modules": top}))
"""


@pytest.mark.slow
def test_grading_imports_only_the_grader_extra(tmp_path):
    # Grade the instructor's solutions of every exercise and list the third-party modules the
    # grading process imported: each must come from a distribution of the `grader` extra.
    from importlib.metadata import packages_distributions

    sub = tmp_path / "sub"
    sub.mkdir()
    for nb in (ROOT / "exercises").glob("ex*/ex*.ipynb"):
        (sub / nb.name).write_bytes(nb.read_bytes())
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(sub)], capture_output=True, text=True, timeout=900, check=True
    )
    data = json.loads(proc.stdout.strip().splitlines()[-1])
    assert data["score"] == pytest.approx(data["max"])
    # (no sympy here: ex11's trusted scorer parses and compares the symbolic answers
    # with it in the grading process, and the grader extra lists it)
    assert "sympy" in {_req_name(r) for r in _grader_extra()}
    heavy = {"open3d", "skimage", "matplotlib", "IPython", "nbgrader", "jupytext", "sklearn", "tqdm"}
    assert not heavy & set(data["modules"])  # (sklearn: only on some clustering inputs)
    allowed = _closure([_req_name(r) for r in _grader_extra()])
    dists = packages_distributions()
    used = {}
    for mod in data["modules"]:
        # flowtrack itself; Cython's pseudo-module; scikit-sparse and pyamg (the `fast` extra) are
        # optional (guarded imports in flowtrack.sceneflow, which falls back to SuperLU/CG without them)
        if mod in ("flowtrack", "flowtrack_course", "grading_sandbox", "cython_runtime", "sksparse", "pyamg",
                   "__main__") \
                or mod.startswith("_"):
            continue
        names = {d.lower().replace("_", "-") for d in dists.get(mod, [mod])}
        used[mod] = names
    missing = {m: n for m, n in used.items() if not n & allowed}
    # jsonschema (under nbformat) imports its format checkers' optional packages when installed
    optional = _closure([_req_name(r) for r in _grader_extra()], extras=True)
    missing = {m: n for m, n in missing.items() if not n & optional}
    assert not missing, f"grading imports modules outside the grader extra: {missing}"


# --------------------------------------------------------------------------------------------------
# packaging


def test_pyproject_license_is_an_spdx_expression():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"
    for pattern in meta["project"]["license-files"]:
        assert list(ROOT.glob(pattern)), pattern
    req = next(r for r in meta["build-system"]["requires"] if r.startswith("setuptools"))
    assert req.replace(" ", "") in ("setuptools>=77", "setuptools>=77.0")


@pytest.mark.slow
def test_wheel_metadata_carries_the_license_expression(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", str(ROOT), "-w", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "license" not in proc.stderr.lower() or "deprecat" not in proc.stderr.lower()
    wheel = next(tmp_path.glob("flowtrack-*.whl"))
    with zipfile.ZipFile(wheel) as zf:
        meta = next(n for n in zf.namelist() if n.endswith(".dist-info/METADATA"))
        text = zf.read(meta).decode()
        names = zf.namelist()
    assert "License-Expression: MIT" in text and "License-File: LICENSE" in text
    assert any(n.endswith("licenses/LICENSE") for n in names)
