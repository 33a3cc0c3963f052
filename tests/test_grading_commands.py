"""The autograder's commands: release, check, grade (class, restart, gradebook) and gradescope.

Oracles: the bundle is scanned for the markers and for the distinctive lines of every solution and
hidden test read from the source notebooks; expected scores are the exercises' point totals
(solutions full, stubs zero); the gradebook is read back with nbgrader's own CSV exporter and its
grade cells compared with the points written in the notebooks' nbgrader metadata.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
pytest.importorskip("nbgrader")

from flowtrack_course.grading.assign.release import release, release_notebook  # noqa: E402
from flowtrack_course.grading.check import check_notebook  # noqa: E402
from flowtrack_course.grading.engine.discovery import grading_files  # noqa: E402
from flowtrack_course.grading.engine.seeds import public_seed, student_seed  # noqa: E402
from flowtrack_course.grading.export.gradebook import grade_cells, notebook_name  # noqa: E402
from flowtrack_course.grading.grade import grade_class  # noqa: E402
from grading_helpers import COURSE_SET, EXERCISES, class_job, get_exercise, source_notebook  # noqa: E402

pytestmark = pytest.mark.xdist_group("grading_commands")

ROOT = Path(__file__).resolve().parents[1]
EXDIR = ROOT / "exercises"
# Two quick exercises: one answer cell (ex02), two answer cells (ex05, for partial credit).
SUBSET_IDS = ("ex02_optical_flow", "ex05_cv_model")
SUBSET = tuple(get_exercise(i) for i in SUBSET_IDS)
SOL_BLOCK = re.compile(r"### BEGIN SOLUTION\n(.*?)### END SOLUTION", re.DOTALL)
HIDDEN_BLOCK = re.compile(r"### BEGIN HIDDEN TESTS\n(.*?)### END HIDDEN TESTS", re.DOTALL)


def _source_nb(ex):
    return nbformat.read(source_notebook(ex), as_version=4)


def _write(nb, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)


def _answer_cell(nb, grade_id):
    return next(c for c in nb.cells if c.metadata.get("nbgrader", {}).get("grade_id") == grade_id)


def _test_cells(nb):
    return [c for c in nb.cells if c.metadata.get("nbgrader", {}).get("grade")]


# --------------------------------------------------------------------------------------------------
# release


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("release") / "bundle"
    info = release(out, source=ROOT)
    return out, info


def _secret_lines():
    """Distinctive lines of every solution and hidden-test block (not shown elsewhere in the course)."""
    public_text = "".join(p.read_text(encoding="utf-8") for p in (ROOT / "lessons").glob("*.md"))
    secrets = {}
    for ex in EXERCISES:
        nb = _source_nb(ex)
        cells = ["".join(c.source) for c in nb.cells]
        blocks = [b for src in cells for b in SOL_BLOCK.findall(src) + HIDDEN_BLOCK.findall(src)]
        outside = "\n".join(HIDDEN_BLOCK.sub("", SOL_BLOCK.sub("", src)) for src in cells)
        lines = {ln.strip() for b in blocks for ln in b.splitlines()}
        secrets[ex.id] = sorted(
            ln for ln in lines if len(ln) >= 20 and ln not in outside and ln not in public_text
        )
    return secrets


def test_release_bundle_has_no_solutions_hidden_tests_or_outputs(bundle):
    out, info = bundle
    assert (out / "README.md").is_file() and "flowtrack check" in (out / "README.md").read_text()
    assert sorted(info["exercises"]) == sorted(ex.notebook for ex in EXERCISES)
    lessons = sorted(p.stem for p in (ROOT / "lessons").glob("*.md") if p.name != "README.md")
    assert sorted(Path(n).stem for n in info["lessons"]) == lessons
    for ex in EXERCISES:
        assert (out / "exercises" / ex.notebook).is_file()
    # the grading modules are the instructor's test code (what `flowtrack check` runs; they were in the
    # installed package before exercises had folders): their reference computations are no leak
    tests = {out / "exercises" / ex.id / p.relative_to(COURSE_SET.folder(ex.id))
             for ex in EXERCISES for p in grading_files(COURSE_SET.folder(ex.id))}
    assert tests and all(p.is_file() for p in tests)
    text = {}
    for p in out.rglob("*"):
        assert "solutions" not in p.relative_to(out).parts
        if p.is_file():
            text[p] = p.read_text(encoding="utf-8")
    for marker in ("BEGIN SOLUTION", "END SOLUTION", "BEGIN HIDDEN TESTS", "END HIDDEN TESTS"):
        assert marker not in "\n".join(text.values())
    # nothing else of the exercises' folders: no notebook with its solutions, worked solution, test
    # answers or source in another language
    assert {p for p in text if p.parent.parent == out / "exercises" and p.parent.name in
            {ex.id for ex in EXERCISES}} == tests
    everything = "\n".join(v for p, v in text.items() if p not in tests)
    for p in out.rglob("*.ipynb"):
        nb = json.loads(text[p])
        for cell in nb["cells"]:
            assert not cell.get("outputs") and not cell.get("execution_count"), p
    secrets = _secret_lines()
    assert sum(len(v) for v in secrets.values()) >= 2 * len(EXERCISES)  # the scan has teeth
    for ex_id, lines in secrets.items():
        leaked = [ln for ln in lines if ln in everything]
        assert not leaked, (ex_id, leaked[:3])


def test_release_keeps_public_tests_and_stubs(bundle):
    out, _ = bundle
    for ex in EXERCISES:
        released = nbformat.read(out / "exercises" / ex.notebook, as_version=4)
        for gid in ex.answer_cells:
            assert "raise NotImplementedError()" in "".join(_answer_cell(released, gid).source)
        src_tests = [HIDDEN_BLOCK.sub("", "".join(c.source)).strip() for c in _test_cells(_source_nb(ex))]
        rel_tests = ["".join(c.source).strip() for c in _test_cells(released)]
        assert rel_tests == src_tests


def test_release_notebook_removes_a_planted_solution():
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell(
        "def f():\n    ### BEGIN SOLUTION\n    return 'SECRET-42'\n    ### END SOLUTION\n"
    )
    cell.metadata["nbgrader"] = {"grade": False, "grade_id": "a", "locked": False, "schema_version": 3,
                                 "solution": True, "task": False}
    cell.outputs = [nbformat.v4.new_output("stream", text="SECRET-43")]
    nb.cells.append(cell)
    out = release_notebook(nb)
    assert "SECRET-42" not in json.dumps(out) and "SECRET-43" not in json.dumps(out)


def test_release_refuses_to_overwrite_a_foreign_folder(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="out"):
        release(tmp_path, source=ROOT)
    assert (tmp_path / "keep.txt").read_text() == "mine"


def test_release_never_replaces_the_course_or_its_sources(tmp_path):
    # `flowtrack release --out . --force` from the course folder must not delete the course.
    course = tmp_path / "course"
    for d in ("exercises", "lessons", "solutions"):
        (course / d).mkdir(parents=True)
        (course / d / "keep.md").write_text("mine")
    for out in (course, tmp_path, course / "exercises", course / "solutions" / "bundle"):
        with pytest.raises(ValueError, match="out"):
            release(out, source=course, force=True)
    assert all((course / d / "keep.md").read_text() == "mine" for d in ("exercises", "lessons", "solutions"))


def test_release_has_no_dead_links_into_solutions(bundle):
    out, _ = bundle
    src = "".join(p.read_text(encoding="utf-8") for p in (ROOT / "lessons").glob("*.md"))
    assert "](../solutions/" in src  # the lessons do link there: the check below has teeth
    for p in out.rglob("*"):
        if p.is_file():
            assert "](../solutions/" not in p.read_text(encoding="utf-8"), p


# --------------------------------------------------------------------------------------------------
# check


def test_check_solution_passes_and_stub_fails(bundle, capsys):
    out, _ = bundle
    ex = SUBSET[1]
    assert check_notebook(source_notebook(ex)) == 0
    text = capsys.readouterr().out
    public = [t for t in ex.tests if not t.hidden]
    assert f"public score: {sum(t.points for t in public):g} / {sum(t.points for t in public):g}" in text
    assert all(t.name in text for t in public) and "FAIL" not in text
    assert check_notebook(out / "exercises" / ex.notebook) == 1
    text = capsys.readouterr().out
    assert "FAIL" in text and f"public score: 0 / {sum(t.points for t in public):g}" in text
    assert all(t.name not in text for t in ex.tests if t.hidden)


def test_check_unknown_notebook_is_a_value_error(tmp_path):
    p = tmp_path / "not_an_exercise.ipynb"
    p.write_text("{}")
    with pytest.raises(ValueError, match="notebook"):
        check_notebook(p)


# --------------------------------------------------------------------------------------------------
# grade: a tiny class


def _stub_nb(ex, bundle_dir):
    return nbformat.read(bundle_dir / "exercises" / ex.notebook, as_version=4)


def _make_class(root: Path, bundle_dir: Path) -> dict[str, float]:
    """Students with every kind of submission; returns the expected total of the exact cases."""
    a, b = SUBSET
    sub = root / "subs"
    for ex in SUBSET:
        _write(_source_nb(ex), sub / "sol" / ex.notebook)
        _write(_stub_nb(ex, bundle_dir), sub / "stub" / ex.notebook)
    # partial: solution of a, only the first answer cell of b solved
    _write(_source_nb(a), sub / "partial" / a.notebook)
    nb = _stub_nb(b, bundle_dir)
    _answer_cell(nb, b.answer_cells[0]).source = _answer_cell(_source_nb(b), b.answer_cells[0]).source
    _write(nb, sub / "partial" / b.notebook)
    # malformed: a is not JSON, b is a solution
    (sub / "notjson").mkdir(parents=True)
    (sub / "notjson" / a.notebook).write_text("this is not a notebook {")
    _write(_source_nb(b), sub / "notjson" / b.notebook)
    # missing: a's answer cell lost its id, b not submitted at all
    nb = _source_nb(a)
    _answer_cell(nb, a.answer_cells[0]).metadata["nbgrader"]["grade_id"] = "renamed-cell"
    _write(nb, sub / "missing" / a.notebook)
    # renamed function in b's first answer cell; syntax error in a
    nb = _source_nb(b)
    cell = _answer_cell(nb, b.answer_cells[0])
    fname = re.search(r"def (\w+)\(", "".join(cell.source)).group(1)
    cell.source = "".join(cell.source).replace(f"def {fname}(", f"def {fname}_v2(")
    _write(nb, sub / "renamed" / b.notebook)
    nb = _source_nb(a)
    _answer_cell(nb, a.answer_cells[0]).source += "\ndef oops(:\n"
    _write(nb, sub / "renamed" / a.notebook)
    # edited public test cells (and their points): solution still full, stub still zero
    for who, make in (("edited_sol", _source_nb), ("edited_stub", lambda ex: _stub_nb(ex, bundle_dir))):
        for ex in SUBSET:
            nb = make(ex)
            for c in _test_cells(nb):
                c.source = "assert True  # all good"
                c.metadata["nbgrader"]["points"] = 1000
            _write(nb, sub / who / ex.notebook)
    full = a.max_score + b.max_score
    return {"sol": full, "stub": 0.0, "notjson": b.max_score, "edited_sol": full, "edited_stub": 0.0}


@pytest.fixture(scope="module")
def graded(bundle, tmp_path_factory):
    root = tmp_path_factory.mktemp("class")
    exact = _make_class(root, bundle[0])
    rows = grade_class(class_job(root / "subs", root / "out", jobs=2, exercises=SUBSET, progress=False))
    return root, exact, {r["student"]: r for r in rows}


def _csv(path):
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_grade_scores_every_kind_of_submission(graded):
    root, exact, rows = graded
    a, b = SUBSET
    assert all("error" not in r for r in rows.values())
    for who, total in exact.items():
        assert rows[who]["score"] == pytest.approx(total), who
    assert 0 < rows["partial"]["score"] < exact["sol"]
    assert rows["partial"]["exercises"][a.id] == pytest.approx(a.max_score)
    assert 0 < rows["partial"]["exercises"][b.id] < b.max_score
    assert rows["missing"]["score"] < a.max_score and rows["missing"]["exercises"][b.id] == 0
    assert rows["renamed"]["exercises"][a.id] < a.max_score
    assert 0 < rows["renamed"]["exercises"][b.id] < b.max_score
    fb = (root / "out" / "notjson" / "feedback" / f"{a.id}.md").read_text()
    assert "not valid JSON" in fb or "not a notebook" in fb
    assert "not submitted" in (root / "out" / "missing" / "feedback" / f"{b.id}.md").read_text()


def test_grades_csv_and_results_json_schema(graded):
    root, _, rows = graded
    table = _csv(root / "out" / "grades.csv")
    assert list(table[0]) == ["student", *SUBSET_IDS, "total", "max"]
    assert [r["student"] for r in table] == sorted(rows)
    max_total = sum(ex.max_score for ex in SUBSET)
    for r in table:
        assert float(r["max"]) == pytest.approx(max_total)
        assert float(r["total"]) == pytest.approx(sum(float(r[i]) for i in SUBSET_IDS))
        data = json.loads((root / "out" / r["student"] / "results.json").read_text())
        assert data["score"] == pytest.approx(float(r["total"]))
        assert data["score"] == pytest.approx(sum(t["score"] for t in data["tests"]))
        assert len(data["tests"]) == sum(len(ex.tests) for ex in SUBSET)
        for t in data["tests"]:
            assert set(t) >= {"name", "score", "max_score", "status", "output", "visibility"}
            assert 0 <= t["score"] <= t["max_score"]
            assert t["status"] == ("passed" if t["score"] == t["max_score"] else "failed")
            if t["extra_data"]["hidden"]:
                assert t["visibility"] == "after_published"
                # the score line, then why a failed hidden test failed and its mistake lines
                first = t["output"].split("\n")[0]
                assert re.fullmatch(r"hidden test .+: [0-9.e+-]+ / [0-9.e+-]+", first), t["output"]
            else:
                assert t["visibility"] == "visible"
        for ex in SUBSET:
            assert (root / "out" / r["student"] / "feedback" / f"{ex.id}.md").is_file()


def test_feedback_shows_hidden_tests_by_name_and_score_only(graded):
    root, _, _ = graded
    ex = SUBSET[1]
    fb = (root / "out" / "stub" / "feedback" / f"{ex.id}.md").read_text()
    public_section = fb.split("## Public tests in detail")[1].split("## Hidden tests that failed")[0]
    for t in ex.tests:
        assert t.name in fb
        if t.hidden:
            assert f"### {t.name}" not in public_section


def test_hidden_inputs_are_seeded_per_student_and_public_ones_fixed():
    ex = SUBSET[0]
    t = next(t for t in ex.tests if t.hidden)
    assert student_seed("s1", ex.id, t.name) != student_seed("s2", ex.id, t.name)
    assert public_seed(ex.id, t.name) == public_seed(ex.id, t.name)
    assert public_seed(ex.id, t.name) not in {student_seed(s, ex.id, t.name) for s in ("s1", "s2")}


def test_gradebook_exports_through_nbgrader(graded, tmp_path):
    from nbgrader.api import Gradebook
    from nbgrader.plugins import CsvExportPlugin

    from flowtrack_course.grading.export.gradebook import _alembic_on_path

    root, _, _ = graded
    dest = tmp_path / "export.csv"
    with _alembic_on_path(), Gradebook(f"sqlite:///{root / 'out' / 'gradebook.db'}") as gb:
        CsvExportPlugin(to=str(dest)).export(gb)
        for ex in SUBSET:
            nb_cells = {
                c.metadata["nbgrader"]["grade_id"]: float(c.metadata["nbgrader"]["points"])
                for c in _test_cells(_source_nb(ex))
            }
            db_nb = gb.find_notebook(notebook_name(ex), "flowtrack")
            db_cells = {c.name: c.max_score for c in db_nb.grade_cells}
            assert db_cells == nb_cells == grade_cells(ex)
    exported = {r["student_id"]: r for r in _csv(dest)}
    for r in _csv(root / "out" / "grades.csv"):
        assert float(exported[r["student"]]["score"]) == pytest.approx(float(r["total"]))
        assert float(exported[r["student"]]["max_score"]) == pytest.approx(float(r["max"]))


def test_gradebook_is_stamped_with_nbgraders_alembic_head():
    """The revision read from nbgrader's migration files is the one ``alembic heads`` reports."""
    import nbgrader.api

    from flowtrack_course.grading.export.gradebook import _alembic_head

    exe = Path(sys.executable).parent / "alembic"
    if not exe.exists():
        pytest.skip("the alembic command is not installed beside this interpreter")
    with nbgrader.api._temp_alembic_ini("sqlite:////nonexistent.db") as ini:
        heads = subprocess.run([str(exe), "-c", ini, "heads"], capture_output=True, text=True, check=True,
                               timeout=120).stdout
    assert heads.split()[0] == _alembic_head()


# --------------------------------------------------------------------------------------------------
# idempotence and restart


def test_regrade_is_idempotent_and_restart_keeps_finished_students(bundle, tmp_path):
    ex = SUBSET[1]
    subs, out = tmp_path / "subs", tmp_path / "out"
    for who in ("ann", "ben", "cat"):
        make = _source_nb if who != "ben" else (lambda e: _stub_nb(e, bundle[0]))
        _write(make(ex), subs / who / ex.notebook)
    # a run killed halfway: ann finished, ben's results.json truncated, a stray temp file
    only_ann = tmp_path / "only_ann"
    shutil.copytree(subs / "ann", only_ann / "ann")
    grade_class(class_job(only_ann, out, exercises=[ex], progress=False))
    (out / "ben").mkdir()
    (out / "ben" / "results.json").write_text('{"score": 99, "tes')
    (out / "cat" / "feedback").mkdir(parents=True)
    (out / "cat" / ".results.json.x.tmp").write_text("partial")
    ann_before = (out / "ann" / "results.json").read_bytes()
    rows = {r["student"]: r for r in grade_class(class_job(subs, out, exercises=[ex], progress=False))}
    assert rows["ann"]["skipped"] and not rows["ben"]["skipped"] and not rows["cat"]["skipped"]
    assert (out / "ann" / "results.json").read_bytes() == ann_before
    assert rows["ben"]["score"] == 0 and rows["cat"]["score"] == ex.max_score
    snapshot = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.suffix != ".db"}
    again = grade_class(class_job(subs, out, exercises=[ex], progress=False))
    assert all(r["skipped"] for r in again)
    assert {p: p.read_bytes() for p in snapshot} == snapshot
    # a changed submission is re-graded; --force re-grades everyone
    _write(_source_nb(ex), subs / "ben" / ex.notebook)
    rows = {r["student"]: r for r in grade_class(class_job(subs, out, exercises=[ex], progress=False))}
    assert not rows["ben"]["skipped"] and rows["ben"]["score"] == ex.max_score and rows["ann"]["skipped"]
    again = grade_class(class_job(subs, out, exercises=[ex], force=True, progress=False))
    assert not any(r["skipped"] for r in again)


def test_grade_command_line_on_all_exercises(bundle, tmp_path, capsys):
    from flowtrack_course.cli import main

    ex = SUBSET[0]
    _write(_source_nb(ex), tmp_path / "subs" / "zoe" / "nested" / ex.notebook)  # found by file name
    (tmp_path / "subs" / "yan").mkdir()  # submitted nothing
    assert main(["grade", str(tmp_path / "subs"), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    assert "graded 2 students" in capsys.readouterr().out
    table = {r["student"]: r for r in _csv(tmp_path / "out" / "grades.csv")}
    assert list(table["zoe"]) == ["student", *(e.id for e in EXERCISES), "total", "max"]
    assert float(table["zoe"]["total"]) == float(table["zoe"][ex.id]) == ex.max_score
    assert float(table["yan"]["total"]) == 0
    assert float(table["yan"]["max"]) == sum(e.max_score for e in EXERCISES)


@pytest.mark.parametrize("command", ["release", "check", "grade", "gradescope"])
def test_every_command_has_help(command, capsys):
    from flowtrack_course.cli import main

    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0 and "usage: flowtrack " + command in capsys.readouterr().out


ATTACK = """
import os, pathlib
for target in {targets!r}:
    try:
        pathlib.Path(target).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(target).write_text('{{"score": 1000}}')
    except Exception:
        pass
import numpy
numpy.allclose = lambda *a, **k: True


def {name}(*args, **kwargs):
    os._exit(0)
"""


def test_an_attacking_student_cannot_forge_grades_or_stop_the_run(tmp_path):
    ex = SUBSET[0]
    subs, out = tmp_path / "subs", tmp_path / "out"
    _write(_source_nb(ex), subs / "ann" / ex.notebook)
    nb = _source_nb(ex)
    cell = _answer_cell(nb, ex.answer_cells[0])
    name = re.search(r"def (\w+)\(", "".join(cell.source)).group(1)
    targets = [str(out / "grades.csv"), str(out / "ann" / "results.json"),
               str(out / "mallory" / "results.json"), str(subs / "ann" / ex.notebook)]
    cell.source = ATTACK.format(targets=targets, name=name)
    _write(nb, subs / "mallory" / ex.notebook)
    before = (subs / "ann" / ex.notebook).read_bytes()
    rows = {r["student"]: r for r in grade_class(class_job(subs, out, exercises=[ex], progress=False))}
    assert rows["mallory"]["score"] == 0 and rows["ann"]["score"] == ex.max_score
    table = {r["student"]: float(r["total"]) for r in _csv(out / "grades.csv")}
    assert table == {"ann": ex.max_score, "mallory": 0.0}
    assert json.loads((out / "mallory" / "results.json").read_text())["score"] == 0
    assert json.loads((out / "ann" / "results.json").read_text())["score"] == ex.max_score
    assert (subs / "ann" / ex.notebook).read_bytes() == before


def test_grade_warns_when_the_sandbox_falls_back(tmp_path):
    from grading_sandbox import Sandbox

    class FallbackSandbox(Sandbox):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.isolation = "fallback: pretend bubblewrap is missing"

    ex = SUBSET[0]
    _write(_source_nb(ex), tmp_path / "subs" / "ann" / ex.notebook)
    lines = []
    rows = grade_class(class_job(tmp_path / "subs", tmp_path / "out", exercises=[ex], progress=False,
                                 log=lines.append, sandbox_factory=FallbackSandbox))
    assert rows[0]["score"] == ex.max_score
    assert [ln for ln in lines if ln.startswith("warning:") and "pretend bubblewrap" in ln]


def test_grade_rejects_bad_arguments(tmp_path):
    with pytest.raises(FileNotFoundError, match="submissions"):
        grade_class(class_job(tmp_path / "nope", tmp_path / "out", progress=False))
    (tmp_path / "subs" / "bad\nname").mkdir(parents=True)  # not an id: left out, never the class's error
    assert grade_class(class_job(tmp_path / "subs", tmp_path / "out", progress=False)) == []
    with pytest.raises(ValueError, match="jobs"):
        grade_class(class_job(tmp_path / "subs", tmp_path / "out", jobs=0, progress=False))


# --------------------------------------------------------------------------------------------------
# gradescope


def test_gradescope_zip_runs_the_same_grader(tmp_path):
    from flowtrack_course.grading.export.gradescope import build_autograder

    zpath = build_autograder(tmp_path / "autograder.zip")
    unpacked = tmp_path / "source"
    with zipfile.ZipFile(zpath) as zf:
        names = zf.namelist()
        zf.extractall(unpacked)
        modes = {i.filename: (i.external_attr >> 16) for i in zf.infolist()}
    assert {"setup.sh", "run_autograder", "flowtrack/pyproject.toml"} <= set(names)
    assert modes["setup.sh"] & stat.S_IXUSR and modes["run_autograder"] & stat.S_IXUSR
    # no course folder (exercise notebooks, solutions) in the zip; the exercises' grading modules
    # (the trusted tests) are what the zip is for, and nothing else of their folders
    course = ("exercises/", "solutions/", "flowtrack/exercises/", "flowtrack/solutions/")
    assert not any(n.startswith(course) or n.endswith(".ipynb") for n in names)
    assert {f"course/exercises/{ex.id}/grading.py" for ex in EXERCISES} <= set(names)
    assert not any(n.endswith((".md", "/cases.py")) for n in names if n.startswith("course/"))
    assert any(n.startswith("flowtrack/reference_impl/grading_sandbox/") for n in names)
    setup = (unpacked / "setup.sh").read_text()
    assert "bubblewrap" in setup
    # student code runs as an unprivileged uid: it must be able to read the venv (numpy)
    assert 'chmod -R a+rX "$ROOT/venv"' in setup and 'ROOT="${AUTOGRADER_ROOT:-/autograder}"' in setup
    for script in ("setup.sh", "run_autograder"):
        subprocess.run(["bash", "-n", str(unpacked / script)], check=True)  # valid bash
    # a fake /autograder: the grader comes from the zip's source tree, not from this checkout
    ag = tmp_path / "autograder"
    for ex in SUBSET:
        _write(_source_nb(ex), ag / "submission" / ex.notebook)
    (ag / "submission_metadata.json").write_text(json.dumps({"users": [{"id": "12345", "name": "X"}]}))
    env = dict(
        os.environ,
        AUTOGRADER_ROOT=str(ag),
        FLOWTRACK_PYTHON=sys.executable,
        FLOWTRACK_EXERCISES=",".join(SUBSET_IDS),
        PYTHONPATH=str(unpacked / "flowtrack" / "reference_impl"),
    )
    probe = subprocess.run(
        [sys.executable, "-c", "import flowtrack_course.grading.grade as g; print(g.__file__)"],
        env=env, capture_output=True, text=True, check=True,
    )
    assert Path(probe.stdout.strip()).is_relative_to(unpacked)
    subprocess.run(["bash", str(unpacked / "run_autograder")], env=env, check=True, timeout=600)
    data = json.loads((ag / "results" / "results.json").read_text())
    assert data["score"] == pytest.approx(sum(ex.max_score for ex in SUBSET))
    assert all(t["status"] == "passed" for t in data["tests"])
    assert data["extra_data"]["flowtrack"]["student"] == "12345"


def test_a_submitted_link_leading_outside_the_submission_is_not_read(tmp_path):
    # bob's "notebook" is a link to alice's (or to a file of the grading machine): never graded as
    # his; a link inside his own folder is fine.
    from flowtrack_course.grading.engine.student import locate_notebook

    ex = get_exercise("ex02_optical_flow")
    alice, bob, carol = (tmp_path / n for n in ("alice", "bob", "carol"))
    for d in (alice, bob, carol):
        d.mkdir()
    shutil.copy(source_notebook(ex), alice / ex.notebook)
    (bob / ex.notebook).symlink_to(alice / ex.notebook)
    (bob / "sub").mkdir()
    (bob / "sub" / ex.notebook).symlink_to("/etc/hostname")
    (carol / "real.ipynb").write_text("{}")
    (carol / ex.notebook).symlink_to(carol / "real.ipynb")
    assert locate_notebook(alice, ex) == alice / ex.notebook
    found = locate_notebook(bob, ex)
    assert not found.exists() and "outside" in found.name
    assert locate_notebook(carol, ex) == carol / ex.notebook


def test_hidden_inputs_cannot_leak_through_a_later_public_test(tmp_path):
    # The student's function remembers every input and raises them in its next call: a public test
    # run after a hidden one would show the hidden inputs in its message.
    from flowtrack_course.grading.engine.run import run_exercise
    from flowtrack_course.grading.engine.spec import Call, Exercise, GradedTest

    def build(values):
        def b(rng):
            x = [float(v) for v in (values if values is not None else rng.normal(size=3) + 1000.0)]
            calls = [Call("f", (x,))]
            return calls, lambda outs: ((1.0, "ok") if outs[0].ok else (0.0, outs[0].error))
        return b

    tests = tuple(
        GradedTest(name, "t", 1.0, hidden, build(None if hidden else [1.0, 2.0, 3.0]))
        for name, hidden in (("public 1", False), ("hidden 1", True), ("public 2", False), ("hidden 2", True))
    )
    ex = Exercise("leak", "leak", "leak.ipynb", ("answer",), (), tests)
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell(
        "SEEN = []\ndef f(x):\n    SEEN.append(list(x))\n    if len(SEEN) > 1:\n"
        "        raise ValueError(repr(SEEN))\n    return 0\n"
    )
    cell.metadata["nbgrader"] = {"grade_id": "answer", "solution": True, "grade": False, "locked": False}
    nb.cells.append(cell)
    _write(nb, tmp_path / "leak.ipynb")
    result = run_exercise(ex, tmp_path / "leak.ipynb", "alice")
    assert [t.name for t in result.tests] == ["public 1", "hidden 1", "public 2", "hidden 2"]
    shown = " ".join(t.message for t in result.tests if not t.hidden) + " ".join(result.problems)
    assert "[1.0, 2.0, 3.0]" in shown  # the leak channel works for public inputs ...
    assert "100" not in shown  # ... but no hidden input (all near 1000) ever reaches a shown message
