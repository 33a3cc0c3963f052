"""``flowtrack release`` leaves no exercise answer in what a student reads.

The bundle is made once, as an instructor makes it (:func:`flowtrack_course.grading.assign.release.release`),
and every file a student reads is searched: the lessons, the exercise notebooks, the READMEs and the
stubs and guides of the other languages (notebooks by their cells' sources). The exercises' grading
modules (``exercises/<id>/grading.py``) are left out: they are the grader's code, which computes the
expected values with the reference implementation, as the installed package does.

Two searches, both after the notation is normalised as in ``test_lessons_release``:

* the answer formulas: Problems 1–5 (``test_lessons_release.ANSWERS``) and the answers the exercises
  grade that no lesson teaches as such (:data:`EXERCISE_ANSWERS`);
* the worked solutions themselves: every line of an exercise's solution cells that computes
  something (an operator on the right of ``=`` or after ``return``, 20 characters or more once
  spaces are removed) or is 28 characters long must not appear anywhere in that text, except the
  few lines a lesson teaches on its own account (:data:`TAUGHT_IN_LESSONS`).
"""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import pytest

from test_lessons_release import ANSWERS, normalise

ROOT = Path(__file__).resolve().parents[1]

#: exercise -> [(what, regex on the normalised text)]: answers the exercises grade beyond Problems
#: 1-5 whose derivation is the exercise (a lesson teaches the ideas, not these results)
EXERCISE_ANSWERS: dict[str, list[tuple[str, str]]] = {
    "ex11_concepts": [
        ("the Euler-Lagrange residual, as the text answer", r"dt\*\(a\+v\*dt-b\)-lam\*L"),
        ("the steady-state error variance of a mistuned filter",
         r"\(1(\.0)?-K\)\*\*2\*q_true\+K\*\*2\*r"),
        ("the projection Jacobian taken by sympy", r"rho\.jacobian\(\[X,Y,Z\]\)"),
    ],
    "ex12_rgbd_data_term": [
        ("the null-space dimension counted from the eigenvalues", r"np\.sum\(ev<=1e-9\*ev\[-1\]\)"),
    ],
}

#: normalised solution lines a lesson teaches itself (the exercise practises them): (line, lesson)
TAUGHT_IN_LESSONS = {
    "G=sp.Matrix([dt**2/2,dt])": "04_bayes_and_kalman: the noise gain of the constant-velocity model",
}

_COMPUTES = re.compile(r"(=|^return).*[-+*/@]")


def _flat(text: str) -> str:
    return re.sub(r"\s+", "", text)


@pytest.fixture(scope="module")
def bundle(tmp_path_factory) -> Path:
    from flowtrack_course.grading.assign.release import release

    out = tmp_path_factory.mktemp("bundle") / "course"
    release(out, source=ROOT)
    return out


def student_texts(bundle: Path) -> dict[str, str]:
    """What a student reads in the bundle, file by file (a notebook as its cells' sources)."""
    texts = {}
    for p in sorted(bundle.rglob("*")):
        rel = p.relative_to(bundle)
        if not p.is_file() or rel.parts[0].startswith("."):
            continue
        if len(rel.parts) == 3 and rel.parts[0] == "exercises" and p.name == "grading.py":
            continue  # the grader's code (see the module docstring)
        try:
            text = p.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue
        if p.suffix == ".ipynb":
            text = "\n".join(c.source for c in nbformat.reads(text, as_version=4).cells)
        texts[str(rel)] = text
    return texts


def solution_lines() -> dict[str, list[str]]:
    """Each exercise's computing solution lines, normalised (spaces removed, comments dropped)."""
    out = {}
    for nb_path in sorted((ROOT / "exercises").glob("ex*/ex*.ipynb")):
        nb = nbformat.read(nb_path, as_version=4)
        lines = []
        for cell in nb.cells:
            for block in re.findall(r"### BEGIN SOLUTION\n(.*?)### END SOLUTION", cell.source, re.S):
                for line in block.splitlines():
                    flat = _flat(line.split("  #")[0])
                    if flat.startswith(("#", "import", "from", "def")):
                        continue
                    if len(flat) >= 28 or (len(flat) >= 20 and _COMPUTES.search(flat)):
                        lines.append(flat)
        out[nb_path.parent.name] = lines
    return out


def formula_leaks(texts: dict[str, str]) -> list[str]:
    found = []
    for name, text in texts.items():
        flat = normalise(text)
        for problem, patterns in ANSWERS.items():
            found += [f"{name}: Problem {problem}, {what}" for what, pat in patterns if re.search(pat, flat)]
        for ex, patterns in EXERCISE_ANSWERS.items():
            found += [f"{name}: {ex}, {what}" for what, pat in patterns if re.search(pat, flat)]
    return found


def _graded_functions() -> set[str]:
    from grading_helpers import EXERCISES

    return {gid for ex in EXERCISES for gid in ex.answer_cells}


def _interface_only(line: str, graded: set[str]) -> bool:
    """A bare call of a graded function (``C=mahalanobis_cost(z_pred,S,Z)``): its interface, which
    the public tests show, not its answer."""
    m = re.fullmatch(r"(?:[\w,]+=)?(\w+)\([\w,.]*\)", line)
    return bool(m) and m.group(1) in graded


def solution_leaks(texts: dict[str, str], lines: dict[str, list[str]]) -> list[str]:
    flats = {name: _flat(text) for name, text in texts.items()}
    graded = _graded_functions()
    return [f"{name}: a line of {ex}'s solution, {line!r}"
            for ex, ex_lines in lines.items() for line in ex_lines
            if line not in TAUGHT_IN_LESSONS and not _interface_only(line, graded)
            for name, flat in flats.items() if line in flat]


def test_the_bundle_holds_no_answer_formula(bundle):
    texts = student_texts(bundle)
    assert sum(n.startswith("lessons/") and n.endswith(".ipynb") for n in texts) == 7
    assert sum(n.startswith("exercises/ex") and n.endswith(".ipynb") for n in texts) >= 12
    assert formula_leaks(texts) == []


def test_the_bundle_holds_no_line_of_a_worked_solution(bundle):
    lines = solution_lines()
    assert all(lines.values()), [ex for ex, v in lines.items() if not v]  # every exercise is searched
    assert solution_leaks(student_texts(bundle), lines) == []


def test_the_lessons_teach_what_the_exceptions_say():
    """Each allowed line is in the lesson named, so an exception cannot outlive its reason."""
    for line, why in TAUGHT_IN_LESSONS.items():
        lesson = why.split(":")[0]
        assert line in _flat((ROOT / "lessons" / f"{lesson}.md").read_text(encoding="utf-8")), line


@pytest.mark.parametrize("ex", sorted(EXERCISE_ANSWERS))
def test_every_exercise_pattern_finds_its_worked_solution(ex):
    """A pattern that matches nothing would pass for nothing: each matches the instructor's notebook."""
    nb = nbformat.read(ROOT / "exercises" / ex / f"{ex}.ipynb", as_version=4)
    flat = normalise("\n".join(c.source for c in nb.cells))
    missing = [what for what, pat in EXERCISE_ANSWERS[ex] if not re.search(pat, flat)]
    assert missing == []


def test_a_planted_answer_is_found(bundle):
    """A solution line or a formula copied into untagged text of the bundle is reported."""
    texts = student_texts(bundle)
    lines = solution_lines()
    planted = dict(texts)
    name = "exercises/ex06_kalman_predict_update.ipynb"
    planted[name] = texts[name] + "\nHint: `K = np.linalg.solve(S, H @ P).T`"
    assert solution_leaks(planted, lines) == [f"{name}: a line of ex06_kalman_predict_update's solution, "
                                              "'K=np.linalg.solve(S,H@P).T'"]
    planted = dict(texts)
    planted[name] = texts[name] + r"\n$$\Delta t^2\, v - \lambda\,\Delta v = \Delta t\,(b - a)$$"
    assert formula_leaks(planted) == [f"{name}: Problem 2, the Euler-Lagrange equation"]
