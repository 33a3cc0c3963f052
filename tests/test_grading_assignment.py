"""Only assigned exercises count: what a class is graded on is the instructor's assignment
(``assignment.toml``), never what the students upload.

The attack: one student uploads the answer files of every exercise in every other language. Oracle:
the assignment's own maximum, the sum of the assigned exercises' points computed here from the
exercise definitions; the class's ``max`` column, Canvas' "Points Possible" and Gradescope's total
must be it for every student, whatever anyone uploaded. The sandbox is a stand-in (what is tested is
which exercises are graded, not how).
"""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import pytest

from flowtrack_course.grading.assignment import Assignment, parse_assignment, read_assignment
from flowtrack_course.grading.engine.jobs import GradingOptions
from flowtrack_course.grading.grade.gradescope import run_submission
from flowtrack_course.grading.sources import course_catalog
from grading_helpers import (
    COURSE,
    EXERCISES,
    LANGUAGE_EXERCISES,
    RecordingSandbox,
    run_grade_with,
    source_notebook,
)

NOTEBOOK_MAX = sum(ex.max_score for ex in EXERCISES)


def _student(root: Path, name: str, notebooks=True, languages=()) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    if notebooks:
        for ex in EXERCISES:
            shutil.copy(source_notebook(ex), folder / ex.notebook)
    for ex in languages:  # a file of the right name is all the grader looks for
        path = folder / "exercises" / ex.notebook
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("// an answer\n")
    return folder


def _graded(run):
    """The run graded everyone: its only complaint may be that the stand-in sandbox, the same for
    every student, failed an exercise the same way for all (which a real class run must report)."""
    same_way = any("failed it the same way" in s for s in run.summary)
    assert run.status == 0 or (run.status == 3 and same_way), run


def test_uploads_in_unassigned_languages_change_nobodys_maximum(tmp_path):
    assert len(LANGUAGE_EXERCISES) >= 19
    subs = tmp_path / "subs"
    _student(subs, "ann")
    _student(subs, "ben")
    _student(subs, "mallory", languages=LANGUAGE_EXERCISES)  # every language file there is
    out = tmp_path / "out"
    run = run_grade_with(subs, out, catalog=course_catalog(COURSE), progress=False,
                         sandbox_factory=RecordingSandbox, lms="canvas")
    _graded(run)
    rows = list(csv.DictReader((out / "grades.csv").open()))
    assert list(rows[0])[1:-2] == [ex.id for ex in EXERCISES]  # no column for what mallory uploaded
    assert {float(r["max"]) for r in rows} == {NOTEBOOK_MAX}
    canvas = list(csv.reader(io.StringIO((out / "canvas.csv").read_text())))
    assert canvas[1][0].strip() == "Points Possible" and float(canvas[1][-1]) == NOTEBOOK_MAX
    results = json.loads((out / "mallory" / "results.json").read_text())
    assert results["extra_data"]["flowtrack"]["max_score"] == NOTEBOOK_MAX
    notes = [line for line in results["output"].splitlines() if line.startswith("note: ignored")]
    assert len(notes) == len(LANGUAGE_EXERCISES) and "not part of this assignment" in notes[0], notes
    page = (out / "mallory" / "feedback" / f"{EXERCISES[0].id}.md").read_text()
    assert "Notes on your submission" in page


def test_gradescope_never_grades_beyond_the_assignment(tmp_path):
    sub = _student(tmp_path, "submission", languages=LANGUAGE_EXERCISES)
    data = run_submission(sub, tmp_path / "results.json", student="mallory", catalog=course_catalog(COURSE),
                          options=GradingOptions(sandbox_factory=RecordingSandbox))
    assert data["extra_data"]["flowtrack"]["max_score"] == NOTEBOOK_MAX
    assert sum(t["max_score"] for t in data["tests"]) == pytest.approx(NOTEBOOK_MAX)
    assert data["score"] <= NOTEBOOK_MAX
    assert "note: ignored" in data["output"]


def _language(language: str, exercise: str):
    return next(ex for ex in LANGUAGE_EXERCISES if ex.language == language and ex.exercise == exercise)


def test_one_language_of_each_students_choice(tmp_path):
    # ex05 and ex06 in Octave or Mathematica, the student's choice: every student's maximum is the
    # notebooks' plus one language's items, the other language's cells are blank
    toml = tmp_path / "assignment.toml"
    toml.write_text('exercises = ["ex05", "ex06"]\nlanguages = ["octave", "mathics"]\n')
    assignment = read_assignment(toml)
    catalog = course_catalog(COURSE, toml)
    notebooks = [ex for ex in EXERCISES if ex.id.startswith(("ex05", "ex06"))]
    items = {lang: [_language(lang, e.id) for e in notebooks] for lang in assignment.languages}
    want = sum(ex.max_score for ex in notebooks) + sum(ex.max_score for ex in items["octave"])
    assert want == sum(ex.max_score for ex in notebooks) + sum(ex.max_score for ex in items["mathics"])
    subs = tmp_path / "subs"
    for name, langs in (("oli", items["octave"]), ("max", items["mathics"]), ("nia", []),
                        ("both", [items["octave"][0], *items["mathics"]]),
                        ("extra", [*items["octave"], _language("cpp", "ex05_cv_model")])):
        folder = _student(subs, name, notebooks=False, languages=langs)
        for ex in notebooks:
            shutil.copy(source_notebook(ex), folder / ex.notebook)
        shutil.copy(source_notebook(EXERCISES[0]), folder / EXERCISES[0].notebook)  # not assigned
    out = tmp_path / "out"
    run = run_grade_with(subs, out, catalog=catalog, progress=False, sandbox_factory=RecordingSandbox)
    _graded(run)
    rows = {r["student"]: r for r in csv.DictReader((out / "grades.csv").open())}
    columns = [*(ex.id for ex in notebooks), *(ex.id for lang in assignment.languages for ex in items[lang])]
    assert list(rows["oli"])[1:-2] == columns
    assert {float(r["max"]) for r in rows.values()} == {want}
    chosen = {"oli": "octave", "max": "mathics", "nia": "octave", "both": "mathics", "extra": "octave"}
    for student, lang in chosen.items():
        other = "mathics" if lang == "octave" else "octave"
        assert all(rows[student][ex.id] != "" for ex in items[lang]), (student, rows[student])
        assert all(rows[student][ex.id] == "" for ex in items[other]), (student, rows[student])
    output = json.loads((out / "both" / "results.json").read_text())["output"]
    assert "yours is Octave" not in output and "ignored exercises/octave/" in output, output
    output = json.loads((out / "extra" / "results.json").read_text())["output"]
    assert "ignored exercises/cpp/cv_model/cv_model.cpp: answers in C++" in output, output
    assert f"ignored {EXERCISES[0].notebook}: {EXERCISES[0].id} is not part of this assignment" in output


def test_the_assignment_file_is_checked_and_explained(tmp_path):
    assert Assignment().describe() == "every exercise of the course; no other languages"
    a = parse_assignment('exercises = ["ex05"]\nlanguages = ["cpp", "java"]\nlanguage_choice = "all"\n')
    assert a.describe() == "ex05; each of them also answered in each of cpp, java"
    for text, what in (('exercise = ["ex05"]', "unknown key"), ('languages = "cpp"', "must be a list"),
                       ('language_choice = "two"', "'one' or 'all'"), ("exercises = [", "not a TOML")):
        with pytest.raises(ValueError, match=what):
            parse_assignment(text)
    for assignment, what in ((Assignment(exercises=("ex99",)), "ex99"),
                             (Assignment(languages=("cobol",)), "cobol"),
                             (Assignment(languages=("cpp",), language_exercises=("ex02",)), "ex02"),
                             (Assignment(languages=("cpp", "mathics")), "not set in mathics")):
        with pytest.raises(ValueError, match=what):
            course_catalog(COURSE, assignment)
    # the course's own file is the default; without one, every notebook and no other language
    assert [ex.id for ex in course_catalog(COURSE).for_class()] == [ex.id for ex in EXERCISES]
