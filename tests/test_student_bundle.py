"""The student bundle works on its own and poses the problems instead of answering them.

Worked answers to the syllabus' problems are tagged cells of the lessons: the book and the
instructors' copy keep them, ``flowtrack release`` replaces them by a note; the stripped lessons
still define every name their later cells use (checked statically, without running them). Links
between lessons point to the bundle's notebooks; the README says how to install the light
``student`` extra, which has no open3d and no book stack, and ``flowtrack check`` runs without them.
Exercise texts do not print another exercise's answer.
"""

from __future__ import annotations

import ast
import json
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import nbformat
import pytest

from flowtrack_course.grading.assign.release import WORKED_ANSWER_TAG, bundle_links, release, student_lesson
from flowtrack_course.notebooks import read_notebook

ROOT = Path(__file__).resolve().parents[1]
LESSONS = sorted(p for p in (ROOT / "lessons").glob("*.md") if p.name != "README.md")


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("student") / "bundle"
    release(out, source=ROOT)
    return out


def _tagged(cell) -> bool:
    return WORKED_ANSWER_TAG in cell.metadata.get("tags", [])


def _names(src: str) -> tuple[set[str], set[str]]:
    """(names assigned, names loaded) by a code cell (IPython magics and `!` lines skipped)."""
    lines = [ln for ln in src.splitlines() if not ln.lstrip().startswith(("%", "!"))]
    tree = ast.parse("\n".join(lines))
    stored, loaded = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            (stored if isinstance(node.ctx, ast.Store) else loaded).add(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            stored.add(node.name)
        elif isinstance(node, ast.arg):  # a parameter is defined inside its function
            stored.add(node.arg)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            stored |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return stored, loaded


def test_problems_are_posed_and_their_worked_answers_tagged():
    tagged = {}
    for p in LESSONS:
        nb = read_notebook(p)
        tagged[p.stem] = [c for c in nb.cells if _tagged(c)]
    for stem in (
        "01_camera_geometry",
        "02_variational_scene_flow",
        "04_bayes_and_kalman",
        "05_multi_object_tracking",
        "06_flow_to_tracks",
        "07_five_languages",
    ):
        assert tagged[stem], stem
    for k, stem in enumerate(
        (
            "01_camera_geometry",
            "02_variational_scene_flow",
            "04_bayes_and_kalman",
            "05_multi_object_tracking",
            "06_flow_to_tracks",
        ),
        start=1,
    ):
        text = (ROOT / "lessons" / f"{stem}.md").read_text(encoding="utf-8")
        assert f"**Problem {k} (syllabus).**" in text, stem
        # the statement is a visible (untagged) cell of the lesson
        statement = [
            c
            for c in read_notebook(ROOT / "lessons" / f"{stem}.md").cells
            if f"**Problem {k} (syllabus).**" in c.source
        ]
        assert statement and not any(_tagged(c) for c in statement), stem


#: Text of each lesson's worked answers that the bundle must not contain (and the course must).
WITHHELD_TEXT = {
    "01_camera_geometry": ["J_syllabus"],
    "04_bayes_and_kalman": ["sp.kronecker_product(Q1d, sp.eye(2))           # Q1d ⊗ I2"],
    "05_multi_object_tracking": [
        r"\sum_{j} y_{ij}\le 1",  # Problem 4's constraints
        "C_def = np.array([[(z - zp) @ np.linalg.inv(Si) @ (z - zp)",  # ex07's cost, written out
        "def assignment_constraints(M, N):",
    ],
    "06_flow_to_tracks": ["Assumptions this rests on", "This lesson's answer, step by step"],
    "07_five_languages": [
        "Q_text = sp.kronecker_product(Q1d, sp.eye(2))",  # the derivation of Q for [px, py, vx, vy]
        "assert Pi * Q_derived * Pi.T == Q_listings",  # blkdiag is right for [px, vx, py, vy]
        "N_mat = sp.Matrix([[-2 / dt, 1, 0, 0], [0, 0, -2 / dt, 1]])",  # what the listings' Q cannot excite
        "n_1^\\top x = p_y - 2p_x/\\Delta t",
    ],
}


def test_worked_answers_of_lessons_5_to_7_are_withheld(bundle):
    for stem, needles in WITHHELD_TEXT.items():
        course = (ROOT / "lessons" / f"{stem}.md").read_text(encoding="utf-8")
        student = json.dumps(nbformat.read(bundle / "lessons" / f"{stem}.ipynb", as_version=4))
        student_text = "".join(
            c.source for c in nbformat.read(bundle / "lessons" / f"{stem}.ipynb", as_version=4).cells
        )
        for needle in needles:
            assert needle in course, (stem, needle)
            assert needle not in student_text, (stem, needle)
        assert "**Your turn.**" in student, stem


@pytest.mark.parametrize("lesson", LESSONS, ids=[p.stem for p in LESSONS])
def test_stripped_lesson_defines_what_its_later_cells_use(lesson):
    nb = read_notebook(lesson)
    only_in_tagged: set[str] = set()
    kept: set[str] = set()
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        stored, loaded = _names(cell.source)
        if _tagged(cell):
            only_in_tagged |= stored - kept
            continue
        missing = (loaded & only_in_tagged) - stored
        assert not missing, (lesson.name, missing, cell.source[:200])
        kept |= stored
        only_in_tagged -= stored


def test_release_withholds_worked_answers_and_links_inside_the_bundle(bundle):
    for p in LESSONS:
        nb = nbformat.read(bundle / "lessons" / f"{p.stem}.ipynb", as_version=4)
        assert not any(_tagged(c) for c in nb.cells)
        n_runs = sum(
            1
            for i, c in enumerate(read_notebook(p).cells)
            if _tagged(c) and (i == 0 or not _tagged(read_notebook(p).cells[i - 1]))
        )
        assert sum("**Your turn.**" in c.source for c in nb.cells) == n_runs
        for c in nb.cells:
            if c.cell_type != "markdown":
                continue
            for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", c.source):
                if target.startswith(("http://", "https://", "mailto:")):
                    continue
                assert not target.endswith(".md") or target.startswith("http"), (p.name, target)
                assert (bundle / "lessons" / target).resolve().exists(), (p.name, target)
    # the worked Jacobian of Problem 1 is printed in the course, not in the bundle's lesson 1
    assert "J_syllabus" in (ROOT / "lessons" / "01_camera_geometry.md").read_text(encoding="utf-8")
    assert "J_syllabus" not in (bundle / "lessons" / "01_camera_geometry.ipynb").read_text(encoding="utf-8")


def test_student_readmes_say_how_to_install_and_check(bundle):
    readme = (bundle / "README.md").read_text(encoding="utf-8")
    assert 'pip install "flowtrack[student]"' in readme and "flowtrack check exercises/" in readme
    assert "mistake <id>" in readme
    lessons_readme = (bundle / "lessons" / "README.md").read_text(encoding="utf-8")
    assert "instructor's copy" not in lessons_readme and "jupytext" not in lessons_readme
    for target in re.findall(r"\]\(([^)#\s]+)\)", lessons_readme):
        assert (bundle / "lessons" / target).is_file(), target


def test_bundle_links_rewrites_lesson_sources_and_drops_outside_links():
    md = (
        "[L3](03_graph_scene_flow.md) [L4](../lessons/04_bayes_and_kalman.md#3) [src](../reference_impl/x.py)"
    )
    assert (
        bundle_links(md) == "[L3](03_graph_scene_flow.ipynb) [L4](../lessons/04_bayes_and_kalman.ipynb#3) src"
    )
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_markdown_cell("a"),
        nbformat.v4.new_code_cell("x = 1", metadata={"tags": [WORKED_ANSWER_TAG]}),
        nbformat.v4.new_markdown_cell("b", metadata={"tags": [WORKED_ANSWER_TAG]}),
        nbformat.v4.new_markdown_cell("c"),
    ]
    out = student_lesson(nb)
    assert [c.source[:3] for c in out.cells] == ["a", "> *", "c"]


def test_student_extra_is_light():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    heavy = ("open3d", "sphinx", "myst", "selenium", "mathics", "bdsim", "scikit-sparse")
    assert not any(d.startswith(heavy) for d in meta["dependencies"])
    student = meta["optional-dependencies"]["student"]
    assert not any(d.startswith(heavy) for d in student)
    # the full installs keep open3d
    for extra in ("pipeline", "dev", "lessons"):
        assert any(d.startswith("open3d") for d in meta["optional-dependencies"][extra])


def test_check_runs_without_open3d_nbgrader_or_the_book_stack():
    code = (
        "import sys\n"
        "for m in ('open3d', 'nbgrader', 'jupytext', 'sphinx', 'myst_nb', 'nbclient'):\n"
        "    sys.modules[m] = None\n"
        "from flowtrack_course.grading.check import check_notebook\n"
        f"sys.exit(check_notebook({str(ROOT / 'exercises' / 'ex05_cv_model' / 'ex05_cv_model.ipynb')!r}))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "public score: 3 / 3" in r.stdout


def test_exercise_texts_do_not_print_another_exercises_answer():
    text = {
        nb.parent.name: "\n".join(
            "".join(c["source"])
            for c in json.loads(nb.read_text(encoding="utf-8"))["cells"]
            if c["cell_type"] == "markdown"
        )
        for nb in sorted((ROOT / "exercises").glob("ex*/ex*.ipynb"))
    }
    assert len(text) >= 12
    jacobian = re.compile(r"-\s*f_x\s*X\s*/\s*Z\^2")  # ex01's answer, written out
    assert not any(jacobian.search(t) for k, t in text.items()), [
        k for k, t in text.items() if jacobian.search(t)
    ]
    q_kron = re.compile(r"Q\s*=\s*Q_\{1D\}\s*\\otimes\s*I_2\b")
    assert not any(q_kron.search(t) for k, t in text.items() if k != "ex05_cv_model")
    # ex11's unexcited combinations (p_y - 2 p_x / dt, v_y - 2 v_x / dt) and its Q for [px, vx, py, vy]
    unexcited = re.compile(r"[pv]_y\s*-\s*2\s*[pv]_x\s*/")
    assert not any(unexcited.search(t) for t in text.values())
    other_order = re.compile(r"\[p_x,\s*v_x,\s*p_y,\s*v_y\][^.]*(\bis\b|=)\s*\$?\\?(operatorname\{)?blkdiag")
    assert not any(other_order.search(t) for k, t in text.items() if k != "ex11_concepts")


def _check_in(folder: Path, target: str) -> subprocess.CompletedProcess:
    """``flowtrack check TARGET`` run from ``folder`` as a student would (no course around)."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "FLOWTRACK_COURSE"}
    code = f"import sys\nfrom flowtrack_course.cli import main\nsys.exit(main(['check', {target!r}]))\n"
    return subprocess.run([sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True,
                          timeout=300)


def test_the_default_bundle_checks_its_exercises_on_its_own(bundle, tmp_path):
    """A student's `flowtrack check` in a bundle made by a plain `flowtrack release` (no course
    checkout around, no $FLOWTRACK_COURSE) finds the exercise's grading module there, for a notebook
    and for an answer in another language; the bundle holds each exercise's grading files and
    nothing else of the course's exercise folders (no notebook with its solutions, worked solution,
    test answers or source in another language). ``--with-checks`` is an alias kept for scripts."""
    from flowtrack_course.cli import main

    ids = sorted(p.parent.name for p in (ROOT / "exercises").glob("ex*/grading.py"))
    assert ids and all((bundle / "exercises" / i / "grading.py").is_file() for i in ids)
    kept = [p for p in (bundle / "exercises").glob("ex*/**/*") if p.is_file()]
    leaked = [p for p in kept if p.suffix in (".ipynb", ".md") or p.name == "cases.py"
              or b"SOLUTION" in p.read_bytes()]
    assert not leaked, leaked
    assert list((ROOT / "exercises").glob("ex*/cpp/*.cpp"))  # ... though the course keeps them there

    r = _check_in(bundle, "exercises/ex05_cv_model.ipynb")
    assert r.returncode == 1, r.stdout + r.stderr  # the released stub fails its public tests ...
    assert "public score: 0 / 3" in r.stdout  # ... graded by the bundle's own copy of the tests
    r = _check_in(bundle, "exercises/octave/cv_model/cv_model.m")
    assert r.returncode == 1, r.stdout + r.stderr  # the stub of the Octave answer, in the sandbox
    assert "public score: 0 / 1" in r.stdout

    alias = tmp_path / "alias"
    assert main(["release", "--course", str(ROOT), "--out", str(alias), "--with-checks"]) == 0
    files = sorted(p.relative_to(alias) for p in alias.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(bundle) for p in bundle.rglob("*") if p.is_file())

    # a bundle whose tests were deleted says what is missing
    bare = tmp_path / "bare"
    shutil.copytree(bundle, bare)
    for i in ids:
        shutil.rmtree(bare / "exercises" / i)
    r = _check_in(bare, "exercises/ex05_cv_model.ipynb")
    assert r.returncode == 2 and "holds no exercise's grading module" in r.stderr, r.stderr
