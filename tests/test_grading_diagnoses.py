"""Diagnoses that describe the error, and public tests that can see it.

A generic diagnosis (``generic-scale``, ``-sign``, ``-transpose``, ``-permutation``) says little on
one call (every wrong number is a multiple of the right one), so a test names it only when two
calls or more show it with the same relation; a wrong shape is reported as the shapes (with the
hint when the last two axes are swapped); held-out mistakes the catalogue does not know get no id.
The expected values come from the trusted reference (flowtrack) and numpy; the answers run in this
process (the in-process runner), as in tests/test_mistakes.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtrack_course.grading.engine.authoring import Outcome, array_check, per_call, tuple_check
from flowtrack_course.grading.engine.mistakes import generic_relation, mistakes_of
from grading_helpers import exercise_module
from test_mistakes import _body, _named, _run, _solution

# --------------------------------------------------------------------------------------------------
# the rule


def _scorer(expected: list[np.ndarray]):
    return per_call([f"f({k})" for k in range(len(expected))], [array_check(e) for e in expected])


E1 = np.array([[1.0, 2.0], [3.0, 4.0]])
E2 = np.array([[0.5, -1.0], [2.0, 7.0]])


@pytest.mark.parametrize(
    "outputs, named",
    [
        ([2 * E1, 2 * E2], ["generic-scale"]),  # two calls, one factor
        ([2 * E1], []),  # one call is a hint, not evidence
        ([2 * E1, 3 * E2], []),  # two factors: no constant one
        ([2 * E1, E2 + 1.0], []),  # the other call fails another way
        ([-E1, -E2], ["generic-sign"]),
        ([E1.T, E2.T], ["generic-transpose"]),
        ([E1.T, E2], []),  # a passing call does not confirm, one transposed call is no evidence
    ],
)
def test_a_generic_id_needs_two_calls_with_the_same_relation(outputs, named):
    expected = [E1, E2][: len(outputs)]
    _, report = _scorer(expected)([Outcome(True, o.tolist()) for o in outputs])
    assert list(mistakes_of(report)) == named


def test_one_number_is_a_multiple_of_any_other_and_proves_no_scale():
    assert generic_relation(np.array([[7e9]]), np.array([[1.0]])) is None
    assert generic_relation(np.array([0.0, 3.0]), np.array([0.0, 1.0])) is None  # one nonzero entry
    scorer = _scorer([np.array([[1.0]]), np.array([[2.0]])])
    _, report = scorer([Outcome(True, [[5.0]]), Outcome(True, [[10.0]])])
    assert not mistakes_of(report)


def test_the_parts_of_one_result_are_one_call():
    check = tuple_check([array_check(E1), array_check(E2)], ("x", "P"))
    _, one = per_call(["f()"], [check])([Outcome(True, [(2 * E1).tolist(), (2 * E2).tolist()])])
    assert not mistakes_of(one)  # x and P of the same call: not two independent calls
    _, two = per_call(["f()", "g()"], [check, check])(
        [Outcome(True, [(2 * E1).tolist(), (2 * E2).tolist()])] * 2)
    assert list(mistakes_of(two)) == ["generic-scale"]


# --------------------------------------------------------------------------------------------------
# the course's exercises

JOSEPH_WITHOUT_KRK = """
S = H @ P @ H.T + R
K = np.linalg.solve(S, H @ P).T
x = x + K @ (z - H @ x)
IKH = np.eye(len(x)) - K @ H
P = IKH @ P @ IKH.T
return x, 0.5 * (P + P.T)
"""

GAIN_WITH_S_NOT_ITS_INVERSE = """
S = H @ P @ H.T + R
K = P @ H.T @ S
x = x + K @ (z - H @ x)
IKH = np.eye(len(x)) - K @ H
P = IKH @ P @ IKH.T + K @ R @ K.T
return x, 0.5 * (P + P.T)
"""


@pytest.mark.parametrize("body", [JOSEPH_WITHOUT_KRK, GAIN_WITH_S_NOT_ITS_INVERSE],
                         ids=["joseph-without-KRK", "gain-with-S"])
def test_held_out_kalman_mistakes_get_no_id(body):
    """Two mistakes the catalogue does not define: no catalogued id fits them, and no generic one
    describes them (P is no multiple of the right one, x neither)."""
    for student in ("ana", "ben", "cy"):
        results = _run("ex06_kalman_predict_update", _body("ex06_kalman_predict_update", "kf_update", body),
                       student=student)
        update = [r for r in results if r[0].startswith("update")]
        assert all(r[1] < r[2] for r in update), update  # they are wrong
        assert not _named(results), (student, results)


def test_a_transposed_jacobian_is_reported_as_shapes_with_the_hint():
    src = _solution("ex01_projection_jacobian")
    src["projection_jacobian"] = src["projection_jacobian"].replace(
        "def projection_jacobian(X, fx, fy):", "def _right(X, fx, fy):") + (
        "\n\ndef projection_jacobian(X, fx, fy):\n    return np.swapaxes(_right(X, fx, fy), 1, 2)\n")
    results = {r[0]: r for r in _run("ex01_projection_jacobian", src)}
    public = results["Jacobian: three points, fx = fy and fx != fy"]
    assert "got shape (3, 3, 2)" in public[3] and "expected an array of shape (3, 2, 3)" in public[3]
    assert "transposed?" in public[3] and "could not check" not in public[3]
    hidden = results["Jacobian: random points and focal lengths"]
    assert "transposed?" in hidden[3] and "mistake generic-transpose:" in hidden[3]
    assert "the results differ from the expected ones" not in hidden[3]


@pytest.mark.parametrize("answer", ["dt*(a + v*dt - b) - 2*lam*Lv", "4*dt*(a + v*dt - b) - 2*lam*Lv",
                                    "2*dt*(a + v*dt - b) - lam*Lv"])
def test_el_half_factor_is_named_in_either_form(answer):
    results = _run("ex11_concepts", _body("ex11_concepts", "euler_lagrange", f'return "{answer}"'))
    el = [r for r in results if r[0].startswith("Euler-Lagrange")]
    assert el and el[0][1] == 0.0 and "mistake el-half-factor:" in el[0][3]


def test_pairs_given_as_column_row_fail_a_public_test():
    src = _solution("ex08_hungarian")
    src["hungarian"] = src["hungarian"].replace("def hungarian(cost):", "def _right(cost):") + (
        "\n\ndef hungarian(cost):\n    return _right(cost)[:, ::-1]\n")
    results = {r[0]: r for r in _run("ex08_hungarian", src)}
    small = next(r for name, r in results.items() if name.startswith("small matrices"))
    assert small[1] < small[2], small
    assert "not a minimal one (total 18, the minimum is 6)" in small[3] and "mistake " not in small[3]
    # what a hidden test says of it: in words that read, without the answer's total (the student's choice)
    module = exercise_module("ex08_hungarian")
    C = np.array([[9.0, 2.0, 6.0], [5.0, 9.0, 1.0], [3.0, 7.0, 9.0]])
    _, report = module.assignment_check(C)(Outcome(True, [[1, 0], [2, 1], [0, 2]]))
    assert report.safe == "a valid assignment but not a minimal one (its total exceeds the minimum)"


@pytest.mark.parametrize("source, kind", [("def def f(dt):\n    return dt\n", "SyntaxError"),
                                          ("def f(dt):\nreturn dt\n", "IndentationError")])
def test_a_cell_that_does_not_compile_is_reported_on_one_readable_line(source, kind):
    """The child's text of a syntax error (as it really formats it) reads as the error, where it
    is and the offending line, with no escaped newlines in between."""
    from flowtrack_course.grading.engine.feedback import cell_problems
    from grading_sandbox.errors import exception_text

    try:
        compile(source, "<cell f>", "exec")
    except SyntaxError as exc:
        text = exception_text(exc, cell=True)
    else:
        raise AssertionError("the source compiled")
    (line,) = cell_problems({"f": text}, ["f"])
    assert "\\n" not in line and line.startswith(f"cell 'f' failed to run: {kind}: "), line
    assert "(at <cell f> line " in line
    assert ("def def f(dt):" if kind == "SyntaxError" else "return dt") in line
