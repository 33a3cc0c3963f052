"""A fractional score reads the same in every output: the feedback, grades.csv and the LMS files
print the digits of results.json's rounded value (before, ``:g`` cut them to six significant
digits in some files: 23.1667 beside 23.166667)."""

from __future__ import annotations

import csv
import io
import json
from types import SimpleNamespace

from flowtrack_course.grading.engine.classrun import _write_grades_csv
from flowtrack_course.grading.engine.results import (
    ExerciseResult,
    feedback_markdown,
    format_score,
    results_json,
)
from flowtrack_course.grading.engine.results import TestResult as Result  # not a pytest class
from flowtrack_course.grading.export.lms import canvas_csv, moodle_csv

SCORE = 139 / 6  # 23.1666...: more digits than six significant ones


def test_format_score_keeps_six_decimals_and_drops_trailing_zeros():
    assert format_score(SCORE) == "23.166667" and format_score(23.0) == "23" and format_score(2.5) == "2.5"
    assert format_score(-0.0) == "0" and format_score(1e-12) == "0"


def test_every_output_prints_the_same_digits(tmp_path):
    tests = [Result("a", "g", SCORE, 30.0, False, "ok"), Result("b", "g", 0.0, 1.0, True, "")]
    r = ExerciseResult("ex01", "title", "ex01.ipynb", tests)
    expected = format_score(SCORE)
    # results.json holds the rounded number itself
    data = json.loads(json.dumps(results_json("s1", [r])))
    assert f"{data['score']:.6f}".rstrip("0") == expected
    md = feedback_markdown("s1", r)
    assert f"{expected} / 31" in md and "23.1667 " not in md
    ex = SimpleNamespace(id="ex01", max_score=31.0)
    rows = [{"student": "s1", "exercises": {"ex01": SCORE}, "score": SCORE}]
    _write_grades_csv(tmp_path / "grades.csv", rows, [ex])
    (row,) = list(csv.DictReader(io.StringIO((tmp_path / "grades.csv").read_text())))
    assert row["ex01"] == expected and row["total"] == expected and row["max"] == "31"
    lms_rows = [{"student": "s1", "exercises": {"ex01": SCORE}, "score": SCORE, "max": 31.0}]
    for made in (canvas_csv(lms_rows, ["ex01"]), moodle_csv(lms_rows, ["ex01"])):
        text = made[0] if isinstance(made, tuple) else made  # (csv text, notes)
        assert expected in text and "23.1667," not in text and "23.1667\n" not in text
