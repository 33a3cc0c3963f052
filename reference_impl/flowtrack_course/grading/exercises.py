r"""The exercise registry: trusted test definitions of the ten exercise notebooks in ``exercises/``.

Every :class:`~flowtrack_course.grading.spec.Exercise` here names its notebook, the nbgrader
``grade_id``\ s of the answer cells a student fills in, the modules the student's code may not import, and its
:class:`~flowtrack_course.grading.spec.GradedTest`\ s. A test's ``build(rng)`` returns the
:class:`~flowtrack_course.grading.spec.Call`\ s to make and a scorer; expected values are computed in
``build`` by the trusted reference (``flowtrack`` itself, or scipy for the Hungarian algorithm) on the
grader's side and never sent to the student's code. Public tests use small fixed inputs (the ones the
notebook's visible asserts show) and get ``rng`` seeded with the fixed
:func:`~flowtrack_course.grading.grade.public_seed`; hidden tests draw other inputs from ``rng``, which the
grader seeds per student with :func:`~flowtrack_course.grading.spec.student_seed`. Every scorer gives partial
credit: the fraction of calls (or checks) that pass.

``run_in_process`` runs the same tests on functions found in a namespace dict (the notebook's
``globals()``): it converts inputs and results to plain data exactly as the sandboxed child does,
seeds public tests with the same fixed seed as ``flowtrack grade`` and ``flowtrack check`` (a student
sees the same public inputs in every path), and applies the same scorers with the same clipping (a
NaN or infinite fraction earns 0). It is what the notebooks' own hidden-test blocks call, so that
``nbgrader autograde`` also grades these notebooks (with partial credit). It executes student code
in the calling process and is therefore **not secure**: flowtrack's grader runs student code only in
:mod:`flowtrack_course.grading.sandbox`.

Examples
--------
>>> ex = get_exercise("ex05_cv_model")
>>> ex.notebook, ex.answer_cells, ex.max_score
('ex05_cv_model.ipynb', ('cv_transition', 'cv_process_noise'), 10.0)
>>> import numpy as np
>>> ns = {"cv_transition": lambda dt: np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])}
>>> [(name, earned) for name, earned, _, _ in run_in_process(ex, ns, cell="test_F")]
[('F: dt = 0.5', 1.0), ('F: random dt', 2.0)]
"""

from __future__ import annotations

import contextlib
import json
import math
import signal
import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .spec import Call, Exercise, GradedTest, Outcome, Scorer, as_float_array, compare_arrays, student_seed

__all__ = [
    "EXERCISES",
    "get_exercise",
    "plain_data",
    "run_in_process",
]

Check = Callable[[Outcome], tuple[float, str]]


# ==================================================================================================
# scoring helpers
# ==================================================================================================
def _per_call(labels: Sequence[str], checks: Sequence[Check]) -> Scorer:
    """A scorer awarding the mean over calls of each call's check fraction (in [0, 1])."""
    labels = list(labels)
    checks = list(checks)

    def scorer(outcomes: Sequence[Outcome]) -> tuple[float, str]:
        if len(outcomes) != len(checks):
            return 0.0, f"expected {len(checks)} results, got {len(outcomes)}"
        fractions = []
        problems = []
        for label, check, outcome in zip(labels, checks, outcomes):
            try:
                f, msg = check(outcome)
            except Exception as exc:  # a trusted check must never crash the grader on odd data
                f, msg = 0.0, f"could not check the result ({type(exc).__name__})"
            f = float(min(max(f, 0.0), 1.0)) if math.isfinite(f) else 0.0
            fractions.append(f)
            if f < 1.0:
                problems.append(f"{label}: {msg}")
        score = sum(fractions) / len(fractions) if fractions else 0.0
        if score >= 1.0:
            return 1.0, f"all {len(checks)} checks passed"
        n_ok = sum(f >= 1.0 for f in fractions)
        shown = "; ".join(problems[:3]) + (" ..." if len(problems) > 3 else "")
        return score, f"{n_ok}/{len(checks)} checks passed. {shown}"

    return scorer


def _array_check(expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9) -> Check:
    def check(outcome: Outcome) -> tuple[float, str]:
        ok, msg = compare_arrays(outcome, expected, rtol=rtol, atol=atol)
        return (1.0 if ok else 0.0), msg

    return check


def _tuple_check(parts: Sequence[Check], names: Sequence[str]) -> Check:
    """A result that is a tuple of ``len(parts)`` items, each checked separately (equal weights)."""

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        value = outcome.value
        if type(value) not in (list, tuple) or len(value) != len(parts):
            return 0.0, f"expected a tuple ({', '.join(names)}) of {len(parts)} items"
        total = 0.0
        msgs = []
        for name, part, item in zip(names, parts, value):
            f, msg = part(Outcome(True, item))
            total += f
            if f < 1.0:
                msgs.append(f"{name}: {msg}")
        return total / len(parts), "; ".join(msgs) or "ok"

    return check


def _fmt(x: Any) -> str:
    if isinstance(x, np.ndarray):
        return f"array{x.shape}"
    if isinstance(x, float):
        return f"{x:.4g}"
    if isinstance(x, list):
        return f"list of {len(x)}"
    return repr(x)


def _label(function: str, args: Sequence[Any], kwargs: Mapping[str, Any] | None = None) -> str:
    parts = [_fmt(a) for a in args] + [f"{k}={_fmt(v)}" for k, v in (kwargs or {}).items()]
    return f"{function}({', '.join(parts)})"


def _calls_and_checks(
    entries: Sequence[tuple[str, tuple[Any, ...], dict[str, Any], Check]],
) -> tuple[list[Call], Scorer]:
    calls = [Call(fn, args, kw) for fn, args, kw, _ in entries]
    labels = [_label(fn, args, kw) for fn, args, kw, _ in entries]
    return calls, _per_call(labels, [c for *_, c in entries])


def _test(name: str, grade_id: str, points: float, hidden: bool, timeout: float = 10.0):
    """Decorator turning ``build(rng) -> entries`` into a :class:`GradedTest`."""

    def wrap(fn: Callable[[np.random.Generator], Sequence[tuple]]) -> GradedTest:
        def build(rng: np.random.Generator) -> tuple[Sequence[Call], Scorer]:
            return _calls_and_checks(fn(rng))

        build.__doc__ = fn.__doc__
        return GradedTest(
            name=name, grade_id=grade_id, points=points, hidden=hidden, build=build, timeout=timeout
        )

    return wrap


# ==================================================================================================
# ex01: the projection Jacobian
# ==================================================================================================
def _ex01_points(rng: np.random.Generator, n: int) -> np.ndarray:
    X = rng.uniform(-1.0, 1.0, size=(n, 3))
    X[:, 2] = rng.uniform(0.5, 4.0, size=n)
    return X


def _cam(fx, fy, cx=0.0, cy=0.0):
    from flowtrack.camera import PinholeCamera

    return PinholeCamera(float(fx), float(fy), float(cx), float(cy))


_EX01_X = np.array([[1.0, 2.0, 4.0], [0.0, 0.0, 1.0], [-0.5, 0.25, 2.0]])


@_test("project: three points", "test_project", 1.0, hidden=False)
def _ex01_project_public(rng):
    from flowtrack.camera import project

    return [
        (
            "project",
            (_EX01_X, 100.0, 100.0, 50.0, 40.0),
            {},
            _array_check(project(_EX01_X, _cam(100, 100, 50, 40))),
        )
    ]


@_test("project: random points and intrinsics", "test_project", 2.0, hidden=True)
def _ex01_project_hidden(rng):
    from flowtrack.camera import project

    out = []
    for n in (1, 5, 20):
        X = _ex01_points(rng, n)
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        cx, cy = (float(v) for v in rng.uniform(100.0, 400.0, 2))
        out.append(("project", (X, fx, fy, cx, cy), {}, _array_check(project(X, _cam(fx, fy, cx, cy)))))
    return out


def _jacobian_check(expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9) -> Check:
    """Per-entry credit: the share of the six Jacobian entries right at every point."""

    def check(outcome: Outcome) -> tuple[float, str]:
        ok, msg = compare_arrays(outcome, expected, rtol=rtol, atol=atol)
        if ok:
            return 1.0, "ok"
        got = as_float_array(outcome.value, expected.shape) if outcome.ok else None
        if got is None:
            return 0.0, msg
        good = [
            (i, j)
            for i in range(2)
            for j in range(3)
            if np.allclose(got[:, i, j], expected[:, i, j], rtol=rtol, atol=atol)
        ]
        wrong = [f"J[:, {i}, {j}]" for i in range(2) for j in range(3) if (i, j) not in good]
        return len(good) / 6.0, f"wrong entries {', '.join(wrong)}"

    return check


@_test("Jacobian: three points", "test_jacobian", 2.0, hidden=False)
def _ex01_jac_public(rng):
    from flowtrack.camera import projection_jacobian

    J = projection_jacobian(_EX01_X, _cam(100.0, 100.0))
    return [("projection_jacobian", (_EX01_X, 100.0, 100.0), {}, _jacobian_check(J))]


@_test("Jacobian: random points and focal lengths", "test_jacobian", 5.0, hidden=True)
def _ex01_jac_hidden(rng):
    from flowtrack.camera import projection_jacobian

    out = []
    for n in (1, 7, 30):
        X = _ex01_points(rng, n)
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        out.append(
            ("projection_jacobian", (X, fx, fy), {}, _jacobian_check(projection_jacobian(X, _cam(fx, fy))))
        )
    return out


# ==================================================================================================
# ex02: optical flow from scene flow
# ==================================================================================================
_EX02_X = np.array([[0.0, 0.0, 2.0], [1.0, -1.0, 4.0]])
_EX02_V = np.array([[1.0, 0.0, 0.0], [0.0, 0.5, -1.0]])


def _ex02_expected(X, V, dt, fx, fy):
    from flowtrack.camera import optical_flow_from_scene_flow

    return optical_flow_from_scene_flow(X, V, dt, _cam(fx, fy))


@_test("optical flow: two points", "test_optical_flow", 3.0, hidden=False)
def _ex02_public(rng):
    return [
        (
            "optical_flow",
            (_EX02_X, _EX02_V, 0.1, 500.0, 500.0),
            {},
            _array_check(_ex02_expected(_EX02_X, _EX02_V, 0.1, 500, 500)),
        ),
        (
            "optical_flow",
            (_EX02_X, _EX02_V, 1.0, 100.0, 200.0),
            {},
            _array_check(_ex02_expected(_EX02_X, _EX02_V, 1.0, 100, 200)),
        ),
    ]


@_test("optical flow: random points, velocities and time steps", "test_optical_flow", 7.0, hidden=True)
def _ex02_hidden(rng):
    out = []
    for n, dt in ((1, 1.0), (6, float(rng.uniform(0.01, 0.2))), (25, float(rng.uniform(0.5, 2.0)))):
        X = _ex01_points(rng, n)
        V = rng.normal(size=(n, 3))
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        out.append(("optical_flow", (X, V, dt, fx, fy), {}, _array_check(_ex02_expected(X, V, dt, fx, fy))))
    # motion along the viewing ray produces no optical flow (first order)
    X = _ex01_points(rng, 5)
    V = X * rng.uniform(-2.0, 2.0, size=(5, 1))
    out.append(("optical_flow", (X, V, 0.1, 400.0, 400.0), {}, _array_check(np.zeros((5, 2)), atol=1e-9)))
    return out


# ==================================================================================================
# ex03: red-black Gauss-Seidel
# ==================================================================================================
def _ex03_sweep_expected(v, rhs, c, lam):
    from flowtrack.variational import red_black_sweep

    return red_black_sweep(np.array(v, dtype=np.float64), rhs, c, lam)


def _ex03_solve_expected(a, b, dt, lam):
    from flowtrack.variational import solve_component

    return solve_component(a, b, dt, lam, method="dct")


def _ex03_solve_check(a, b, dt, lam) -> Check:
    d = (b - a) / dt
    # the solver stops at a relative residual < 1e-10, so |v - v*| <= 1e-10 |d|_F (M = I)
    return _array_check(
        _ex03_solve_expected(a, b, dt, lam), rtol=1e-6, atol=1e-7 * float(np.abs(d).max() + 1e-300)
    )


_EX03_V0 = np.zeros((3, 4))
_EX03_RHS = np.arange(12.0).reshape(3, 4)
_EX03_C = np.full((3, 4), 1.0)
_EX03_A = np.zeros((3, 4))
_EX03_B = np.array([[0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0]])


@_test("sweep: one sweep from zero on a 3x4 grid", "test_sweep", 2.0, hidden=False)
def _ex03_sweep_public(rng):
    return [
        (
            "red_black_sweep",
            (_EX03_V0, _EX03_RHS, _EX03_C, 0.0),
            {},
            _array_check(_ex03_sweep_expected(_EX03_V0, _EX03_RHS, _EX03_C, 0.0)),
        ),
        (
            "red_black_sweep",
            (_EX03_V0, _EX03_RHS, _EX03_C, 1.0),
            {},
            _array_check(_ex03_sweep_expected(_EX03_V0, _EX03_RHS, _EX03_C, 1.0)),
        ),
    ]


@_test("sweep: random grids, iterates and weights", "test_sweep", 3.0, hidden=True)
def _ex03_sweep_hidden(rng):
    out = []
    for H, W in ((1, 5), (4, 4), (5, 7), (8, 6)):
        v = rng.normal(size=(H, W))
        rhs = rng.normal(size=(H, W))
        c = rng.uniform(0.1, 2.0, size=(H, W))
        lam = float(rng.uniform(0.1, 3.0))
        out.append(
            ("red_black_sweep", (v, rhs, c, lam), {}, _array_check(_ex03_sweep_expected(v, rhs, c, lam)))
        )
    return out


@_test("solver: a step edge on a 3x4 grid", "test_solver", 2.0, hidden=False)
def _ex03_solve_public(rng):
    return [
        (
            "solve_gauss_seidel",
            (_EX03_A, _EX03_B, 0.5, 0.1),
            {},
            _ex03_solve_check(_EX03_A, _EX03_B, 0.5, 0.1),
        )
    ]


@_test("solver: random components", "test_solver", 3.0, hidden=True, timeout=20.0)
def _ex03_solve_hidden(rng):
    out = []
    for H, W in ((2, 3), (6, 5), (8, 10)):
        a = rng.normal(size=(H, W))
        b = a + rng.normal(scale=0.1, size=(H, W))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(0.5, 5.0)) * dt**2
        out.append(("solve_gauss_seidel", (a, b, dt, lam), {}, _ex03_solve_check(a, b, dt, lam)))
    return out


# ==================================================================================================
# ex04: kNN graph Laplacian and graph scene flow
# ==================================================================================================
def _ex04_L(P, k, sigma):
    from flowtrack.sceneflow import graph_laplacian, knn_graph

    return graph_laplacian(knn_graph(P, k=k, sigma=sigma)).toarray()


def _ex04_flow(P, Y, dt, lam, k, sigma):
    from flowtrack.sceneflow import graph_scene_flow

    return graph_scene_flow(P, Y, dt, lam, k=k, sigma=sigma, solver="splu")


_EX04_P = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 1.0, 0.0]])
_EX04_Y = _EX04_P + np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.2, 0.0]])


@_test("Laplacian: four points", "test_laplacian", 2.0, hidden=False)
def _ex04_L_public(rng):
    return [
        ("knn_laplacian", (_EX04_P, 1, 1.0), {}, _array_check(_ex04_L(_EX04_P, 1, 1.0))),
        ("knn_laplacian", (_EX04_P, 2, 2.0), {}, _array_check(_ex04_L(_EX04_P, 2, 2.0))),
    ]


@_test("Laplacian: random clouds", "test_laplacian", 3.0, hidden=True)
def _ex04_L_hidden(rng):
    out = []
    for n, k in ((6, 5), (12, 2), (30, 4), (40, 6)):
        P = rng.normal(size=(n, 3))
        sigma = float(rng.uniform(0.3, 1.5))
        out.append(("knn_laplacian", (P, k, sigma), {}, _array_check(_ex04_L(P, k, sigma))))
    return out


@_test("graph scene flow: four points", "test_graph_flow", 2.0, hidden=False)
def _ex04_flow_public(rng):
    return [
        (
            "graph_scene_flow",
            (_EX04_P, _EX04_Y, 0.1, 0.0, 1, 1.0),
            {},
            _array_check(_ex04_flow(_EX04_P, _EX04_Y, 0.1, 0.0, 1, 1.0)),
        ),
        (
            "graph_scene_flow",
            (_EX04_P, _EX04_Y, 0.1, 0.01, 1, 1.0),
            {},
            _array_check(_ex04_flow(_EX04_P, _EX04_Y, 0.1, 0.01, 1, 1.0)),
        ),
    ]


@_test("graph scene flow: random clouds", "test_graph_flow", 3.0, hidden=True)
def _ex04_flow_hidden(rng):
    out = []
    for n, k in ((8, 3), (25, 4), (40, 6)):
        P = rng.normal(size=(n, 3))
        Y = P + 0.05 * rng.normal(size=(n, 3))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(0.1, 2.0)) * dt**2
        sigma = float(rng.uniform(0.5, 1.5))
        out.append(
            (
                "graph_scene_flow",
                (P, Y, dt, lam, k, sigma),
                {},
                _array_check(_ex04_flow(P, Y, dt, lam, k, sigma)),
            )
        )
    return out


# ==================================================================================================
# ex05: constant-velocity model
# ==================================================================================================
def _ex05_F(dt):
    from flowtrack.kalman import constant_velocity_model

    return constant_velocity_model(dt, 1.0, 1.0, dim=2)[0]


def _ex05_Q(dt, q):
    from flowtrack.kalman import white_noise_acceleration_Q

    return white_noise_acceleration_Q(dt, q, dim=2)


@_test("F: dt = 0.5", "test_F", 1.0, hidden=False)
def _ex05_F_public(rng):
    return [("cv_transition", (0.5,), {}, _array_check(_ex05_F(0.5)))]


@_test("F: random dt", "test_F", 2.0, hidden=True)
def _ex05_F_hidden(rng):
    return [
        ("cv_transition", (dt,), {}, _array_check(_ex05_F(dt))) for dt in rng.uniform(0.01, 2.0, 3).tolist()
    ]


def _ex05_Q_properties(dt: float, q: float) -> Check:
    """The public test only checks what the visible asserts check: shape, symmetry, Q[0,0], Q[2,0]."""
    expected = _ex05_Q(dt, q)

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        got = as_float_array(outcome.value, (4, 4))
        if got is None:
            return 0.0, "expected an array of shape (4, 4)"
        if not np.allclose(got, got.T, rtol=1e-9, atol=1e-12):
            return 0.0, "Q is not symmetric"
        for i, j in ((0, 0), (2, 0)):
            if not np.isclose(got[i, j], expected[i, j], rtol=1e-9, atol=1e-12):
                return 0.0, f"Q[{i}, {j}] is wrong"
        return 1.0, "ok"

    return check


@_test("Q: shape, symmetry, var(px) and cov(vx, px) for dt = 0.5, q = 2", "test_Q", 2.0, hidden=False)
def _ex05_Q_public(rng):
    return [("cv_process_noise", (0.5, 2.0), {}, _ex05_Q_properties(0.5, 2.0))]


@_test("Q: the full matrix for random dt and q", "test_Q", 5.0, hidden=True)
def _ex05_Q_hidden(rng):
    # Q1d kron I2 and the syllabus' blkdiag(Q1d, Q1d) differ for every dt, q > 0
    out = []
    for dt, q in zip(rng.uniform(0.01, 2.0, 3).tolist(), rng.uniform(0.1, 10.0, 3).tolist()):
        out.append(("cv_process_noise", (dt, q), {}, _array_check(_ex05_Q(dt, q))))
    return out


# ==================================================================================================
# ex06: Kalman predict and update
# ==================================================================================================
def _ex06_model(rng, n: int, m: int):
    A = rng.normal(size=(n, n))
    P = A @ A.T + 0.1 * np.eye(n)
    B = rng.normal(size=(n, n))
    Q = 0.1 * (B @ B.T)
    F = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    H = rng.normal(size=(m, n))
    C = rng.normal(size=(m, m))
    R = C @ C.T + 0.2 * np.eye(m)
    x = rng.normal(size=n)
    z = rng.normal(size=m)
    return x, P, F, Q, z, H, R


def _ex06_predict(x, P, F, Q):
    from flowtrack.kalman import KalmanFilter

    m = 1
    kf = KalmanFilter(F, np.zeros((m, len(x))), Q, np.eye(m), x, P)
    kf.predict()
    return kf.x, kf.P


def _ex06_update(x, P, z, H, R):
    from flowtrack.kalman import KalmanFilter

    n = len(x)
    kf = KalmanFilter(np.eye(n), H, np.zeros((n, n)), R, x, P)
    kf.update(z)
    return kf.x, kf.P


def _state_check(expected: tuple[np.ndarray, np.ndarray]) -> Check:
    return _tuple_check([_array_check(e, rtol=1e-6, atol=1e-9) for e in expected], ("x", "P"))


_EX06_F = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
_EX06_Q = 0.01 * np.eye(4)
_EX06_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_EX06_R = 0.5 * np.eye(2)
_EX06_x = np.array([0.0, 0.0, 1.0, 2.0])
_EX06_P = np.eye(4)
_EX06_z = np.array([1.5, 1.0])


@_test("predict: constant-velocity model", "test_predict", 1.0, hidden=False)
def _ex06_predict_public(rng):
    args = (_EX06_x, _EX06_P, _EX06_F, _EX06_Q)
    return [("kf_predict", args, {}, _state_check(_ex06_predict(*args)))]


@_test("predict: random models", "test_predict", 3.0, hidden=True)
def _ex06_predict_hidden(rng):
    out = []
    for n in (1, 3, 4, 6):
        x, P, F, Q, *_ = _ex06_model(rng, n, 1)
        out.append(("kf_predict", (x, P, F, Q), {}, _state_check(_ex06_predict(x, P, F, Q))))
    return out


@_test("update: position measurement", "test_update", 2.0, hidden=False)
def _ex06_update_public(rng):
    args = (_EX06_x, 2.0 * _EX06_P, _EX06_z, _EX06_H, _EX06_R)
    return [("kf_update", args, {}, _state_check(_ex06_update(*args)))]


@_test("update: random models", "test_update", 4.0, hidden=True)
def _ex06_update_hidden(rng):
    out = []
    for n, m in ((1, 1), (4, 2), (6, 3), (3, 3)):
        x, P, _, _, z, H, R = _ex06_model(rng, n, m)
        out.append(("kf_update", (x, P, z, H, R), {}, _state_check(_ex06_update(x, P, z, H, R))))
    return out


# ==================================================================================================
# ex07: Mahalanobis cost with chi-square gating
# ==================================================================================================
def _ex07_cost(z_pred, S, Z):
    from flowtrack.association import mahalanobis_cost

    return mahalanobis_cost(z_pred, S, Z)


def _ex07_gated(z_pred, S, Z, prob):
    from flowtrack.association import chi2_gate

    C = _ex07_cost(z_pred, S, Z)
    return np.where(C <= chi2_gate(z_pred.shape[1], prob), C, np.inf)


_EX07_ZP = np.array([[0.0, 0.0], [10.0, 0.0]])
_EX07_S = np.stack([np.eye(2), 4.0 * np.eye(2)])
_EX07_Z = np.array([[1.0, 0.0], [10.0, 2.0], [3.0, 0.0]])


def _ex07_random(rng, M, N, m):
    z_pred = rng.normal(scale=3.0, size=(M, m))
    A = rng.normal(size=(M, m, m))
    S = A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(m)
    Z = rng.normal(scale=3.0, size=(N, m))
    return z_pred, S, Z


@_test("cost: two tracks, three detections", "test_cost", 2.0, hidden=False)
def _ex07_cost_public(rng):
    args = (_EX07_ZP, _EX07_S, _EX07_Z)
    return [("mahalanobis_cost", args, {}, _array_check(_ex07_cost(*args)))]


@_test("cost: random tracks and detections", "test_cost", 3.0, hidden=True)
def _ex07_cost_hidden(rng):
    out = []
    for M, N, m in ((1, 1, 1), (3, 5, 2), (6, 4, 3), (5, 8, 2)):
        args = _ex07_random(rng, M, N, m)
        out.append(("mahalanobis_cost", args, {}, _array_check(_ex07_cost(*args))))
    return out


@_test("gating: two tracks, three detections, p = 0.99", "test_gating", 2.0, hidden=False)
def _ex07_gate_public(rng):
    args = (_EX07_ZP, _EX07_S, _EX07_Z, 0.99)
    return [("gated_cost", args, {}, _array_check(_ex07_gated(*args)))]


@_test("gating: random tracks, detections and gate probabilities", "test_gating", 3.0, hidden=True)
def _ex07_gate_hidden(rng):
    out = []
    for (M, N, m), prob in (((3, 5, 2), 0.9), ((6, 4, 3), 0.99), ((5, 8, 1), 0.95), ((4, 4, 2), 0.5)):
        z_pred, S, Z = _ex07_random(rng, M, N, m)
        args = (z_pred, S, Z, prob)
        out.append(("gated_cost", args, {}, _array_check(_ex07_gated(*args))))
    return out


# ==================================================================================================
# ex08: the Hungarian algorithm
# ==================================================================================================
def _assignment_check(cost: np.ndarray, rtol: float = 1e-9) -> Check:
    """Valid min(M, N) pairs whose total cost is scipy's optimum (trusted ``linear_sum_assignment``)."""
    from scipy.optimize import linear_sum_assignment

    r, c = linear_sum_assignment(cost)
    best = float(cost[r, c].sum())
    M, N = cost.shape
    K = min(M, N)

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        pairs = as_float_array(outcome.value)
        if pairs is None or (pairs.size == 0 and K == 0):
            return (1.0, "ok") if pairs is not None else (0.0, "the result is not an array of index pairs")
        if pairs.ndim != 2 or pairs.shape != (K, 2):
            return 0.0, f"expected {K} (row, col) pairs, shape ({K}, 2), got shape {pairs.shape}"
        if not np.all(pairs == np.round(pairs)):
            return 0.0, "indices must be integers"
        rows = pairs[:, 0].astype(np.int64)
        cols = pairs[:, 1].astype(np.int64)
        if rows.min() < 0 or rows.max() >= M or cols.min() < 0 or cols.max() >= N:
            return 0.0, "an index is out of range"
        if len(set(rows.tolist())) != K or len(set(cols.tolist())) != K:
            return 0.0, "a row or a column is used twice"
        total = float(cost[rows, cols].sum())
        if abs(total - best) <= rtol * max(1.0, abs(best)):
            return 1.0, "ok"
        return 0.0, f"a valid assignment but not a minimal one (total {total:.6g}, the minimum is {best:.6g})"

    return check


_EX08_C = np.array([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])
_EX08_RECT = np.array([[10.0, 1.0, 7.0, 3.0], [2.0, 8.0, 9.0, 4.0]])


@_test("small matrices: 3x3, 2x4, 4x2, 1x1", "test_small", 3.0, hidden=False)
def _ex08_public(rng):
    mats = [_EX08_C, _EX08_RECT, _EX08_RECT.T.copy(), np.array([[7.0]])]
    return [("hungarian", (C,), {}, _assignment_check(C)) for C in mats]


@_test(
    "random matrices 12x12 to 30x30, with ties, rectangular", "test_random", 7.0, hidden=True, timeout=10.0
)
def _ex08_hidden(rng):
    mats = []
    # diagonally dominant (greedy finds it too), then hard ones
    # (12! = 4.8e8 permutations: every matrix is out of reach of brute force within the time limit)
    n = 12
    D = rng.uniform(5.0, 10.0, size=(n, n))
    D[np.arange(n), rng.permutation(n)] = rng.uniform(0.0, 1.0, size=n)
    mats.append(D)
    mats.append(rng.uniform(0.0, 1.0, size=(13, 13)))
    mats.append(rng.integers(0, 4, size=(12, 12)).astype(np.float64))  # many ties
    mats.append(rng.normal(size=(11, 17)))  # negative costs, wide
    mats.append(rng.integers(0, 3, size=(18, 13)).astype(np.float64))  # tall with ties
    mats.append(np.outer(rng.uniform(1, 2, 14), rng.uniform(1, 2, 14)))  # rank one
    mats.append(rng.uniform(0.0, 100.0, size=(30, 30)))
    return [("hungarian", (C,), {}, _assignment_check(C)) for C in mats]


# ==================================================================================================
# ex09: track management
# ==================================================================================================
def _ex09_expected(frames: Sequence[Sequence[int]], min_hits: int, max_misses: int) -> list[list[list[Any]]]:
    """Run the trusted :class:`flowtrack.tracking.MultiObjectTracker` on the scripted sequence.

    Object ``l`` sits still at ``(50 l, 0)`` and is detected exactly, so the tracker's gated
    nearest-neighbour association assigns a detection of ``l`` to the live track of ``l`` (if any):
    the association rule the exercise states.
    """
    from flowtrack.tracking import MultiObjectTracker

    trk = MultiObjectTracker(dt=1.0, q=1e-4, r=1e-2, dim=2, min_hits=min_hits, max_misses=max_misses)
    out = []
    for labels in frames:
        Z = np.array([[50.0 * lab, 0.0] for lab in labels]).reshape(-1, 2)
        trk.step(Z)
        out.append([[int(t.id), str(t.status)] for t in trk.tracks])
    return out


def _frames_check(expected: list[list[list[Any]]]) -> Check:
    """Credit per frame: the frame's list of ``[id, status]`` must match exactly."""

    def norm(frame: Any) -> list[tuple[Any, Any]] | None:
        if type(frame) not in (list, tuple):
            return None
        out = []
        for item in frame:
            if type(item) not in (list, tuple) or len(item) != 2:
                return None
            tid, status = item
            if type(tid) is float and tid == int(tid):
                tid = int(tid)
            if type(tid) is not int or type(status) is not str:
                return None
            out.append((tid, status))
        return out

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        got = outcome.value
        if type(got) not in (list, tuple) or len(got) != len(expected):
            return 0.0, f"expected a list with one entry per frame ({len(expected)} frames)"
        good = 0
        first_bad = None
        for t, (g, e) in enumerate(zip(got, expected)):
            if norm(g) == [tuple(x) for x in e]:
                good += 1
            elif first_bad is None:
                first_bad = t
        if first_bad is None:
            return 1.0, "ok"
        return good / len(expected), f"{good}/{len(expected)} frames right, first wrong frame: {first_bad}"

    return check


_EX09_FRAMES = [[0], [0, 1], [0], [0, 1], [], [], [2], [0], [], [], [], [], [0]]


@_test("scripted sequence: min_hits = 2, max_misses = 2", "test_public_sequence", 4.0, hidden=False)
def _ex09_public(rng):
    return [
        ("manage_tracks", (_EX09_FRAMES, 2, 2), {}, _frames_check(_ex09_expected(_EX09_FRAMES, 2, 2))),
        ("manage_tracks", (_EX09_FRAMES, 1, 0), {}, _frames_check(_ex09_expected(_EX09_FRAMES, 1, 0))),
    ]


def _ex09_random_frames(rng, n_frames: int, n_objects: int, p_detect: float) -> list[list[int]]:
    frames = []
    for _ in range(n_frames):
        labels = [lab for lab in range(n_objects) if rng.random() < p_detect]
        rng.shuffle(labels)  # the order of detections inside a frame decides the order of births
        frames.append([int(v) for v in labels])
    return frames


@_test("random scripted sequences", "test_random_sequences", 6.0, hidden=True)
def _ex09_hidden(rng):
    out = []
    for n_frames, n_obj, p, min_hits, max_misses in (
        (15, 3, 0.7, 2, 1),
        (25, 5, 0.6, 3, 2),
        (20, 4, 0.5, 1, 3),
        (30, 6, 0.8, 2, 0),
    ):
        frames = _ex09_random_frames(rng, n_frames, n_obj, p)
        out.append(
            (
                "manage_tracks",
                (frames, min_hits, max_misses),
                {},
                _frames_check(_ex09_expected(frames, min_hits, max_misses)),
            )
        )
    return out


# ==================================================================================================
# ex10: motion clustering into track initialisations
# ==================================================================================================
def _ex10_expected(P, V, radius, sigma_v, min_speed):
    from flowtrack.clustering import cluster_motion, tracks_from_clusters

    n = P.shape[0]
    # every moving point within `radius` is a candidate neighbour (k = N) and every component is a
    # cluster (min_size = 1): the plain connected components the exercise asks for
    labels = cluster_motion(
        P, V, radius, sigma_v, min_speed=min_speed, method="connected", k=max(n, 1), min_size=1
    )
    tracks = tracks_from_clusters(P, V, labels)
    D = P.shape[1]
    cents = np.array([c for c, _ in tracks]).reshape(-1, D)
    vels = np.array([v for _, v in tracks]).reshape(-1, D)
    sizes = np.array([np.sum(labels == k) for k in range(len(tracks))])
    return cents, vels, sizes


def _clusters_check(cents: np.ndarray, vels: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9) -> Check:
    """Same set of (centroid, velocity) pairs as the reference, in any order."""
    from scipy.optimize import linear_sum_assignment

    K, D = cents.shape

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        value = outcome.value
        if type(value) not in (list, tuple) or len(value) != 2:
            return 0.0, "expected a tuple (centroids, velocities)"
        gc = as_float_array(value[0])
        gv = as_float_array(value[1])
        if gc is None or gv is None:
            return 0.0, "centroids and velocities must be arrays of numbers"
        if K == 0:
            return (1.0, "ok") if gc.size == 0 and gv.size == 0 else (0.0, "expected no clusters")
        if gc.shape != (K, D) or gv.shape != (K, D):
            return 0.0, f"expected {K} clusters: arrays of shape ({K}, {D}), got {gc.shape} and {gv.shape}"
        if not (np.isfinite(gc).all() and np.isfinite(gv).all()):
            return 0.0, "NaN or inf in the result"
        cost = np.linalg.norm(gc[:, None, :] - cents[None], axis=2) + np.linalg.norm(
            gv[:, None, :] - vels[None], axis=2
        )
        r, c = linear_sum_assignment(cost)
        ok_c = np.allclose(gc[r], cents[c], rtol=rtol, atol=atol)
        ok_v = np.allclose(gv[r], vels[c], rtol=rtol, atol=atol)
        if ok_c and ok_v:
            return 1.0, "ok"
        return 0.0, "the right number of clusters, but " + (
            "centroids" if not ok_c else "velocities"
        ) + " differ"

    return check


def _ex10_public_data():
    g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2) * 0.1
    a = np.column_stack([g, np.zeros(len(g))])
    P = np.vstack([a, a + np.array([0.35, 0.0, 0.0]), a + np.array([2.0, 2.0, 0.0])])
    V = np.vstack([np.tile([1.0, 0.0, 0.0], (12, 1)), np.tile([0.0, -1.0, 0.0], (12, 1)), np.zeros((12, 3))])
    return P, V


@_test("two touching boxes moving apart and a static one", "test_public_clusters", 4.0, hidden=False)
def _ex10_public(rng):
    P, V = _ex10_public_data()
    out = []
    for radius, sigma_v, min_speed in ((0.15, 0.5, 0.1), (0.15, 2.0, 0.1), (0.15, 0.5, 0.0)):
        c, v, _ = _ex10_expected(P, V, radius, sigma_v, min_speed)
        out.append(("cluster_tracks", (P, V, radius, sigma_v, min_speed), {}, _clusters_check(c, v)))
    return out


def _ex10_random_scene(rng, n_objects: int, with_static: bool, radius: float):
    """Boxes of jittered grid points in a row, each with its velocity (+ small noise), and static
    clutter. Neighbouring boxes either touch (gap < radius: only their motion separates them) or
    stand apart (gap > 2 radius)."""
    P, V = [], []
    x = 0.0
    for _ in range(n_objects):
        nx, ny = (int(v) for v in rng.integers(2, 6, size=2))
        g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny)), -1).reshape(-1, 2) * 0.1
        pts = np.column_stack([g, np.zeros(len(g))]) + rng.uniform(-0.01, 0.01, size=(len(g), 3))
        P.append(pts + np.array([x, 0.0, 0.0]))
        x += 0.1 * (nx - 1) + (0.4 * radius if rng.random() < 0.5 else 3.0 * radius)
        vel = rng.normal(size=3)
        vel *= rng.uniform(1.0, 2.0) / np.linalg.norm(vel)
        V.append(vel + rng.normal(scale=0.01, size=(len(g), 3)))
    if with_static:
        m = int(rng.integers(5, 15))
        P.append(rng.uniform(-1.0, 4.0, size=(m, 3)))
        V.append(rng.normal(scale=0.01, size=(m, 3)))
    return np.vstack(P), np.vstack(V)


@_test("random scenes of moving boxes and static clutter", "test_random_clusters", 6.0, hidden=True)
def _ex10_hidden(rng):
    out = []
    for n_obj, static, radius, sigma_v, min_speed in (
        (2, False, 0.15, 0.5, 0.1),
        (3, True, 0.15, 0.5, 0.2),
        (4, True, 0.25, 0.3, 0.2),
        (5, True, 0.15, 1.5, 0.2),
    ):
        P, V = _ex10_random_scene(rng, n_obj, static, radius)
        c, v, _ = _ex10_expected(P, V, radius, sigma_v, min_speed)
        out.append(("cluster_tracks", (P, V, radius, sigma_v, min_speed), {}, _clusters_check(c, v)))
    return out


# ==================================================================================================
# the registry
# ==================================================================================================
EXERCISES: tuple[Exercise, ...] = (
    Exercise(
        id="ex01_projection_jacobian",
        title="The pinhole projection and its Jacobian",
        notebook="ex01_projection_jacobian.ipynb",
        answer_cells=("project", "projection_jacobian"),
        blocked=("flowtrack.camera", "flowtrack.symbolic"),
        tests=(_ex01_project_public, _ex01_project_hidden, _ex01_jac_public, _ex01_jac_hidden),
    ),
    Exercise(
        id="ex02_optical_flow",
        title="Optical flow from scene flow",
        notebook="ex02_optical_flow.ipynb",
        answer_cells=("optical_flow",),
        blocked=("flowtrack.camera", "flowtrack.symbolic"),
        tests=(_ex02_public, _ex02_hidden),
    ),
    Exercise(
        id="ex03_gauss_seidel",
        title="Red-black Gauss-Seidel for variational scene flow",
        notebook="ex03_gauss_seidel.ipynb",
        answer_cells=("red_black_sweep", "solve_gauss_seidel"),
        blocked=("flowtrack.variational", "flowtrack.sceneflow"),
        tests=(_ex03_sweep_public, _ex03_sweep_hidden, _ex03_solve_public, _ex03_solve_hidden),
    ),
    Exercise(
        id="ex04_graph_scene_flow",
        title="The kNN graph Laplacian and graph scene flow",
        notebook="ex04_graph_scene_flow.ipynb",
        answer_cells=("knn_laplacian", "graph_scene_flow"),
        blocked=("flowtrack.sceneflow", "flowtrack._graph", "flowtrack.variational", "flowtrack.clustering"),
        tests=(_ex04_L_public, _ex04_L_hidden, _ex04_flow_public, _ex04_flow_hidden),
    ),
    Exercise(
        id="ex05_cv_model",
        title="The constant-velocity model: F and the white-noise-acceleration Q",
        notebook="ex05_cv_model.ipynb",
        answer_cells=("cv_transition", "cv_process_noise"),
        blocked=("flowtrack.kalman", "flowtrack.symbolic", "flowtrack.tracking"),
        tests=(_ex05_F_public, _ex05_F_hidden, _ex05_Q_public, _ex05_Q_hidden),
    ),
    Exercise(
        id="ex06_kalman_predict_update",
        title="Kalman predict and update",
        notebook="ex06_kalman_predict_update.ipynb",
        answer_cells=("kf_predict", "kf_update"),
        blocked=("flowtrack.kalman", "flowtrack.tracking", "flowtrack.particle", "flowtrack.bayes"),
        tests=(_ex06_predict_public, _ex06_predict_hidden, _ex06_update_public, _ex06_update_hidden),
    ),
    Exercise(
        id="ex07_mahalanobis_gating",
        title="The Mahalanobis cost matrix with chi-square gating",
        notebook="ex07_mahalanobis_gating.ipynb",
        answer_cells=("mahalanobis_cost", "gated_cost"),
        blocked=("flowtrack.association", "flowtrack.tracking"),
        tests=(_ex07_cost_public, _ex07_cost_hidden, _ex07_gate_public, _ex07_gate_hidden),
    ),
    Exercise(
        id="ex08_hungarian",
        title="The Hungarian algorithm",
        notebook="ex08_hungarian.ipynb",
        answer_cells=("hungarian",),
        blocked=(
            "flowtrack.association",
            "flowtrack.tracking",
            "flowtrack.metrics",
            "scipy.optimize",
            "scipy.sparse.csgraph",
        ),
        tests=(_ex08_public, _ex08_hidden),
    ),
    Exercise(
        id="ex09_track_management",
        title="Track management: births, coasting and deletion",
        notebook="ex09_track_management.ipynb",
        answer_cells=("manage_tracks",),
        blocked=("flowtrack.tracking",),
        tests=(_ex09_public, _ex09_hidden),
    ),
    Exercise(
        id="ex10_motion_clustering",
        title="Motion clustering into track initialisations",
        notebook="ex10_motion_clustering.ipynb",
        answer_cells=("cluster_tracks",),
        blocked=("flowtrack.clustering",),
        tests=(_ex10_public, _ex10_hidden),
    ),
)


def get_exercise(id_or_notebook_path: str | Path | Exercise) -> Exercise:
    """Look up an exercise by id (``"ex01_projection_jacobian"``) or by a notebook path/file name.

    Raises
    ------
    KeyError
        No exercise has that id or notebook file name.
    """
    if isinstance(id_or_notebook_path, Exercise):
        return id_or_notebook_path
    if not isinstance(id_or_notebook_path, (str, Path)):
        raise TypeError(
            f"id_or_notebook_path must be a str or Path, got {type(id_or_notebook_path).__name__}"
        )
    key = str(id_or_notebook_path)
    name = Path(key).name
    stem = name[: -len(".ipynb")] if name.endswith(".ipynb") else name
    for ex in EXERCISES:
        if key == ex.id or stem == ex.id or name == ex.notebook:
            return ex
    raise KeyError(f"no exercise {key!r}; known: {', '.join(e.id for e in EXERCISES)}")


# ==================================================================================================
# in-process runner (nbgrader compatibility; NOT a sandbox)
# ==================================================================================================
class _NotPlain(TypeError):
    pass


def plain_data(value: Any, _depth: int = 0) -> Any:
    """Convert a returned value to plain JSON data as the sandboxed child does.

    numpy arrays -> nested lists (of the base-class data, so an ndarray subclass cannot lie about its
    values), numpy scalars -> Python scalars, tuples/lists -> lists (recursively), dicts with str
    keys -> dicts; ``int``/``float``/``bool``/``str``/``None`` stay; anything else raises ``TypeError``.
    """
    if _depth > 16:
        raise _NotPlain("the result is nested too deeply")
    if value is None or type(value) in (bool, int, float, str):
        return value
    if isinstance(value, np.ndarray):
        arr = np.array(value, copy=True).view(np.ndarray)
        if arr.dtype == object:
            return [plain_data(v, _depth + 1) for v in arr.tolist()]
        if arr.dtype.kind not in "biuf":
            raise _NotPlain(f"an array of dtype {arr.dtype} is not numeric")
        return arr.tolist()
    if isinstance(value, np.generic) and value.dtype.kind in "biuf":
        return value.item()
    if type(value) in (list, tuple):
        return [plain_data(v, _depth + 1) for v in value]
    if type(value) is dict:
        if not all(type(k) is str for k in value):
            raise _NotPlain("dict keys must be strings")
        return {k: plain_data(v, _depth + 1) for k, v in value.items()}
    raise _NotPlain(f"returned a {type(value).__name__}, expected numbers, lists or numpy arrays")


def _to_child(value: Any) -> Any:
    """Inputs as the child receives them: fresh float64/int64 arrays, plain lists/scalars copied."""
    if isinstance(value, np.ndarray):
        dtype = np.int64 if value.dtype.kind in "biu" else np.float64
        return np.array(value.tolist(), dtype=dtype).reshape(value.shape)
    return json.loads(json.dumps(value))


class _Timeout(BaseException):  # BaseException: a student's `except Exception` cannot swallow it
    pass


@contextlib.contextmanager
def _alarm(seconds: float):
    usable = hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if not usable or not seconds or seconds <= 0:
        yield
        return

    def handler(signum, frame):
        raise _Timeout()

    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)


def _call_all(namespace: Mapping[str, Any], calls: Sequence[Call], timeout: float) -> list[Outcome]:
    outcomes: list[Outcome] = []
    try:
        with _alarm(timeout), warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            for call in calls:
                fn = namespace.get(call.function)
                if not callable(fn):
                    outcomes.append(Outcome(False, error=f"no function named {call.function!r} was defined"))
                    continue
                args = [_to_child(a) for a in call.args]
                kwargs = {k: _to_child(v) for k, v in call.kwargs.items()}
                try:
                    value = plain_data(fn(*args, **kwargs))
                    value = json.loads(json.dumps(value, allow_nan=True))
                except _NotPlain as exc:
                    outcomes.append(Outcome(False, error=str(exc)))
                except NotImplementedError:
                    outcomes.append(Outcome(False, error=f"{call.function} is not implemented yet"))
                except (_Timeout, KeyboardInterrupt):
                    raise
                except BaseException as exc:  # SystemExit included: an answer that exits fails
                    outcomes.append(
                        Outcome(False, error=f"{call.function} raised {type(exc).__name__}: {exc}")
                    )
                else:
                    outcomes.append(Outcome(True, value=value))
    except _Timeout:
        pass
    while len(outcomes) < len(calls):
        outcomes.append(Outcome(False, error=f"timed out after {timeout:g} s"))
    return outcomes


def _clip_fraction(fraction: Any) -> float:
    """A scorer's fraction as ``flowtrack grade`` counts it: clipped to [0, 1], NaN and inf give 0.

    (``min(max(nan, 0.0), 1.0)`` is NaN: Python's ``max``/``min`` keep their first argument when a
    comparison with NaN is false.)
    """
    fraction = float(fraction)
    if not math.isfinite(fraction):
        return 0.0
    return min(1.0, max(0.0, fraction))


def run_in_process(
    exercise: Exercise | str,
    namespace: Mapping[str, Any],
    student: str = "public",
    *,
    cell: str | None = None,
    hidden: bool | None = None,
    verbose: bool = False,
) -> list[tuple[str, float, float, str]]:
    """Run an exercise's tests on the functions in ``namespace`` in this process (insecure).

    Parameters
    ----------
    exercise : Exercise or str
        The exercise or its id / notebook name.
    namespace : mapping
        Where the student's functions live (a notebook's ``globals()``).
    student : str
        Seeds the hidden tests' inputs (:func:`~flowtrack_course.grading.spec.student_seed`, without a
        secret). Public tests always use :func:`~flowtrack_course.grading.grade.public_seed`, the seed
        ``flowtrack grade`` and ``flowtrack check`` give them.
    cell : str, optional
        Only the tests of this notebook test cell (``grade_id``).
    hidden : bool, optional
        Only hidden (True) or only public (False) tests.
    verbose : bool
        Print one line per test (name and score; messages of public tests only).

    Returns
    -------
    list of (test name, points earned, max points, message)
        ``points x clip(fraction, 0, 1)`` as in ``flowtrack grade`` (a NaN or infinite fraction
        earns 0). Hidden tests' messages are replaced by their score only.
    """
    # Imported here, not at the top: grade imports this module (lazily today); a module-level import
    # in both directions would be a cycle as soon as either side imports the other eagerly.
    from .grade import public_seed

    ex = get_exercise(exercise)
    results = []
    for test in ex.tests:
        if cell is not None and test.grade_id != cell:
            continue
        if hidden is not None and test.hidden != hidden:
            continue
        if test.hidden:
            seed = student_seed(student, ex.id, test.name)
        else:
            seed = public_seed(ex.id, test.name)
        calls, scorer = test.build(np.random.default_rng(seed))
        outcomes = _call_all(namespace, calls, test.timeout)
        fraction, message = scorer(outcomes)
        earned = round(test.points * _clip_fraction(fraction), 6)
        if test.hidden:
            message = f"hidden test: {earned:g}/{test.points:g}"
        results.append((test.name, earned, float(test.points), message))
        if verbose:
            print(f"{test.name}: {earned:g}/{test.points:g}" + ("" if test.hidden else f" - {message}"))
    return results
