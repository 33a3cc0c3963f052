"""Adding an exercise is adding a folder: nothing else of the course or of the grader is edited.

A throw-away exercise (``exercises/ex99_dot/``: its notebook and its grading module, with a mistake
and its message) is put in an otherwise empty course folder; that folder is then released, checked
and graded with the commands instructors and students run, the grader finding the exercise by
itself (the class in two worker processes, which find it again by its id).
"""

from __future__ import annotations

import csv
import json
import os
import textwrap
from pathlib import Path

import nbformat
import pytest

from flowtrack_course.cli import main
from flowtrack_course.grading.assign.release import release
from flowtrack_course.grading.check import check_notebook
from flowtrack_course.grading.engine.discovery import discover

pytestmark = pytest.mark.xdist_group("sandbox")

GRADING = '''
"""ex99: the dot product (a throw-away exercise of the course's tests)."""

import numpy as np

from flowtrack_course.grading.engine.authoring import Exercise, Mistake, Variant, array_check, graded_test


def _variants(a, b):
    return [Variant("dot-of-sums", np.array(np.sum(a) * np.sum(b)))]


@graded_test("dot of two fixed vectors", "test_dot", 2.0, hidden=False)
def _public(rng):
    a, b = np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0])
    return [("dot", (a, b), {}, array_check(np.dot(a, b), variants=_variants(a, b)))]


@graded_test("dot of random vectors", "test_dot", 3.0, hidden=True)
def _hidden(rng):
    out = []
    for n in (2, 5, 9):
        a, b = rng.normal(size=n), rng.normal(size=n)
        out.append(("dot", (a, b), {}, array_check(np.dot(a, b), variants=_variants(a, b))))
    return out


EXERCISE = Exercise(
    id="ex99_dot",
    title="The dot product",
    notebook="ex99_dot.ipynb",
    answer_cells=("dot",),
    blocked=(),
    allowed=("numpy",),
    tests=(_public, _hidden),
    mistakes=(Mistake("dot-of-sums", "the sums are multiplied: the dot product sums the products a_i b_i"),),
)
'''

ANSWER = """import numpy as np


def dot(a, b):
    \"\"\"The dot product of two vectors of the same length n.

    Returns
    -------
    float
        sum_i a_i b_i (shape ()).
    \"\"\"
    ### BEGIN SOLUTION
    return float(np.dot(a, b))
    ### END SOLUTION
"""

TEST = """assert abs(dot([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]) - 32.0) < 1e-9
### BEGIN HIDDEN TESTS
assert abs(dot([1.0, 0.0], [0.0, 1.0])) < 1e-9
### END HIDDEN TESTS
"""


def _meta(grade_id: str, *, solution: bool, points: float | None = None) -> dict:
    m = {"grade": points is not None, "grade_id": grade_id, "locked": points is not None,
         "schema_version": 3, "solution": solution, "task": False}
    if points is not None:
        m["points"] = points
    return {"nbgrader": m}


@pytest.fixture(scope="module")
def course(tmp_path_factory) -> Path:
    """A course folder with one exercise folder, and nothing else the commands need."""
    root = tmp_path_factory.mktemp("course")
    (root / "lessons").mkdir()
    folder = root / "exercises" / "ex99_dot"
    folder.mkdir(parents=True)
    (folder / "grading.py").write_text(textwrap.dedent(GRADING).lstrip())
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells = [
        nbformat.v4.new_markdown_cell("# The dot product\n\n**You may import:** numpy."),
        nbformat.v4.new_code_cell(ANSWER, metadata=_meta("dot", solution=True)),
        nbformat.v4.new_code_cell(TEST, metadata=_meta("test_dot", solution=False, points=5.0)),
    ]
    nbformat.write(nb, folder / "ex99_dot.ipynb")
    return root


def _student(subs: Path, name: str, source: Path, body: str | None = None) -> None:
    nb = nbformat.read(source, as_version=4)
    if body is not None:
        cell = next(c for c in nb.cells if c.metadata.get("nbgrader", {}).get("grade_id") == "dot")
        cell.source = f"import numpy as np\n\n\ndef dot(a, b):\n    {body}\n"
    (subs / name).mkdir(parents=True)
    nbformat.write(nb, subs / name / "ex99_dot.ipynb")


def test_the_new_folder_is_found(course):
    (ex,) = discover(course).exercises
    assert ex.id == "ex99_dot" and ex.max_score == 5.0 and ex.catalogue is not None
    assert [m.exercise for m in ex.mistakes] == ["ex99_dot"]


def test_release_check_and_grade_a_new_exercise(course, tmp_path, capsys, monkeypatch):
    # `flowtrack grade --course` makes its course this process's (for its workers): undone afterwards
    monkeypatch.setenv("FLOWTRACK_COURSE", os.environ.get("FLOWTRACK_COURSE", ""))
    # release: the student's notebook at exercises/<notebook>, its grading files beside it
    bundle = tmp_path / "bundle"
    info = release(bundle, source=course, with_checks=True)
    assert info["exercises"] == ["ex99_dot.ipynb"]
    stub = bundle / "exercises" / "ex99_dot.ipynb"
    assert "raise NotImplementedError" in stub.read_text() and "BEGIN SOLUTION" not in stub.read_text()
    assert (bundle / "exercises" / "ex99_dot" / "grading.py").is_file()
    # check: the instructor's solution passes, the student's stub fails, each against its course
    assert check_notebook(course / "exercises" / "ex99_dot" / "ex99_dot.ipynb", course=course) == 0
    assert "public score: 2 / 2" in capsys.readouterr().out
    assert check_notebook(stub, course=bundle) == 1
    assert "public score: 0 / 2" in capsys.readouterr().out
    # grade: a class, with `flowtrack grade --course` in two worker processes
    subs = tmp_path / "subs"
    source = course / "exercises" / "ex99_dot" / "ex99_dot.ipynb"
    _student(subs, "ann", source)
    _student(subs, "ben", source, "return float(np.sum(a) * np.sum(b))")
    _student(subs, "cy", stub)
    out = tmp_path / "out"
    status = main(["grade", str(subs), "--out", str(out), "--course", str(course), "--jobs", "2",
                   "--no-progress"])
    assert status == 0, capsys.readouterr().err
    table = {r["student"]: r for r in csv.DictReader((out / "grades.csv").open())}
    assert list(table["ann"]) == ["student", "ex99_dot", "total", "max"]
    assert {s: float(r["total"]) for s, r in table.items()} == {"ann": 5.0, "ben": 0.0, "cy": 0.0}
    feedback = (out / "ben" / "feedback" / "ex99_dot.md").read_text()
    assert "mistake dot-of-sums: the sums are multiplied" in feedback
    data = json.loads((out / "ben" / "results.json").read_text())
    (record,) = data["extra_data"]["flowtrack"]["mistakes"]
    assert record["exercise"] == "ex99_dot" and record["id"] == "dot-of-sums"
    rows = list(csv.DictReader((out / "misconceptions.csv").open()))
    assert [(r["exercise"], r["mistake_id"], r["students"]) for r in rows] == [
        ("ex99_dot", "dot-of-sums", "ben")
    ]
