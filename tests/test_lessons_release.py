"""The student bundle's lessons give away none of the syllabus' Problems 1–5.

``flowtrack release`` replaces every lesson cell tagged ``worked-answer`` by a note
(:func:`flowtrack_course.grading.assign.release.student_lesson`); anything untagged reaches the student. Each
problem's answer formulas, written from its worked solution in ``solutions/problem*.md``, are searched
for in the released text of every lesson (Markdown and code cells), after the notation is normalised
(spaces and LaTeX spacing removed, ``\\frac{a}{b}`` and ``\\tfrac{a}{b}`` read as ``a/b``), so that
rewording the spacing does not hide a formula from the test.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Problem -> [(what, regex on the normalised text)]; the answer each worked solution derives
ANSWERS: dict[int, list[tuple[str, str]]] = {
    1: [  # solutions/problem1_projection_jacobian.md: the Jacobian's entries
        ("the Jacobian's first row", r"f_x/Z&0&-f_xX/Z\^2"),
        ("the Jacobian's depth column", r"-\(?f_xX/Z\^2"),
        ("the Jacobian's depth column, as code", r"-fx\*X/Z\*\*2"),
    ],
    2: [  # solutions/problem2_euler_lagrange.md: first variation and Euler-Lagrange equation
        ("the Euler-Lagrange equation", r"\\Deltat\^2v-\\lambda\\Deltav=\\Deltat\(b-a\)"),
        ("the Euler-Lagrange equation, unsimplified", r"2\\Deltat\(a\+v\\Deltat-b\)-2\\lambda\\Deltav"),
        ("the first variation", r"\\nablav\\cdot\\nabla\\eta"),
        ("the Euler-Lagrange equation, as code", r"dt\*\*2\*v-lam\*laplacian"),
        ("the Euler-Lagrange equation, unsimplified, as code", r"2\*dt\*\(a\+v\*dt-b\)-2\*lam\*laplacian"),
    ],
    3: [  # solutions/problem3_gaussian_posterior.md: the completed square
        ("the posterior precision, scalar", r"1/p\+h\^2/r"),
        ("the posterior N(beta/alpha, 1/alpha)", r"\\mathcal\{?N\}?\(\\beta/\\alpha,?1/\\alpha\)"),
        ("the posterior precision, matrix", r"P\^\{-1\}\+H\^\\top\{?R\}?\^\{-1\}H"),
    ],
    4: [  # solutions/problem4_assignment.md: the assignment constraints
        ("each track at most one detection", r"\\sum_\{?j(=1)?\}?(\^\{?[0-9A-Za-z]+\}?)?y_\{ij\}\\le"),
        ("each detection at most one track", r"\\sum_\{?i(=1)?\}?(\^\{?[0-9A-Za-z]+\}?)?y_\{ij\}\\le"),
    ],
    5: [  # solutions/problem5_motion_clustering.md: the normalised cut and its relaxation
        ("the normalised cut", r"\\mathrm\{cut\}\(A,B\)/\\mathrm\{vol\}\(A\)"),
        ("the Rayleigh quotient of the cut", r"y\^\\topLy/y\^\\topDy"),
    ],
}


def normalise(text: str) -> str:
    """Notation-insensitive text: no whitespace, no LaTeX spacing or sizing, fractions as a/b."""
    t = re.sub(r"\\(?:,|;|!|:|quad|qquad|left|right|big|Big|bigg|Bigg)(?![A-Za-z])", "", text)
    t = re.sub(r"\s+", "", t)
    frac = re.compile(r"\\[td]?frac\{([^{}]*)\}\{([^{}]*)\}")
    while frac.search(t):
        t = frac.sub(r"\1/\2", t)
    return re.sub(r"\\[td]?frac(\w)(\w)", r"\1/\2", t)  # \tfrac1p


def released_lessons() -> dict[str, str]:
    """Each lesson's text as ``flowtrack release`` writes it: every cell's source, in order."""
    from flowtrack_course.grading.assign.release import student_lesson
    from flowtrack_course.notebooks import read_notebook, strip_outputs

    out = {}
    for src in sorted((ROOT / "lessons").glob("[0-9][0-9]_*.md")):
        nb = student_lesson(strip_outputs(read_notebook(src)))
        out[src.name] = "\n".join(cell.source for cell in nb.cells)
    return out


def leaks(texts: dict[str, str]) -> list[str]:
    found = []
    for name, text in texts.items():
        flat = normalise(text)
        for problem, patterns in ANSWERS.items():
            for what, pattern in patterns:
                if re.search(pattern, flat):
                    found.append(f"{name}: Problem {problem}, {what}")
    return found


def test_the_released_lessons_hold_no_answer_to_problems_1_to_5():
    texts = released_lessons()
    assert len(texts) == 7
    assert leaks(texts) == []


@pytest.mark.parametrize("problem", sorted(ANSWERS))
def test_every_answer_pattern_finds_its_worked_solution(problem):
    """A pattern that matches nothing would pass the test above for nothing: each problem's worked
    solution must contain one of its answer formulas."""
    (src,) = (ROOT / "solutions").glob(f"problem{problem}_*.md")
    found = leaks({src.name: src.read_text(encoding="utf-8")})
    assert found, f"no answer pattern of Problem {problem} matches {src.name}"


def test_the_instructors_lessons_still_hold_the_answers():
    """The worked answers are withheld from the bundle, not deleted from the lessons."""
    full = {p.name: p.read_text(encoding="utf-8") for p in (ROOT / "lessons").glob("0[12]_*.md")}
    problems = {f.split(": Problem ")[1].split(",")[0] for f in leaks(full)}
    assert {"1", "2"} <= problems


def test_normalise_reads_fractions_and_spacing_alike():
    flat = r"\Deltat^2v-\lambda\Deltav=\Deltat(b-a)"
    assert normalise(r"\Delta t^2\, v - \lambda\,\Delta v = \Delta t\,(b - a)") == flat
    assert normalise(r"\alpha = \tfrac1p + \tfrac{h^2}{r}") == r"\alpha=1/p+h^2/r"
    assert normalise(r"\frac{f_x X}{Z^2}") == "f_xX/Z^2"
