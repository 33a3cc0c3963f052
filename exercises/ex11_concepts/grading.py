"""Ex11: conceptual and symbolic items: the trusted tests of the notebook next to this file.

Six items, each answered by a function in its own answer cell:

1. ``q_order()``: Q for the state order [px, vx, py, vy], a sympy matrix in ``dt`` and ``q`` given as
   text; graded by sympy equivalence: the sandboxed child parses the text (an :mod:`ast` whitelist,
   never ``eval``/``sympify``) and evaluates it at random points (:mod:`grading_sandbox.formula`);
   the grader compares those numbers with its own expressions' values
   (:mod:`~flowtrack_course.grading.engine.symbolic`) and never parses student text.
2. ``euler_lagrange()``: the left side of the Euler-Lagrange equation of the energy of Problem 2, in
   ``a, b, v, dt, lam`` and ``Lv`` (the Laplacian of v), up to a nonzero constant factor.
3. ``inverse_depth_jacobian()``: the Jacobian of the inverse-depth projection (f X/Z, f Y/Z, 1/Z).
4. ``unexcited_directions(dt)``: a basis of the state combinations the listings' Q cannot excite
   (its null space, state order [px, py, vx, vy]); graded as a subspace.
5. ``nees_value(q_true, q_filter, r)``: the steady-state expected NEES of a random-walk filter whose
   process noise is mis-specified; a number within 1 %.
6. ``chosen_lambda()``: the smoothness weight chosen from a sweep; a number in the range of good
   values.

Every item has its catalogue of wrong answers (recognised from the answer itself).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Outcome,
    Report,
    as_float_array,
    graded_test,
    safe_error,
)
from flowtrack_course.grading.engine.symbolic import (
    FormulaValues,
    expected_values,
    formula_request,
    sample_points,
    values_of,
)

# ----------------------------------------------------------------------------------------------
# symbols and the expected formulas (derived here with sympy)


def _syms(names: str) -> dict[str, Any]:
    import sympy as sp

    return {s.name: s for s in sp.symbols(names, positive=True)}


def _q1d(model: str = "discrete"):
    import sympy as sp

    s = _syms("dt q")
    dt, q = s["dt"], s["q"]
    if model == "discrete":
        G = sp.Matrix([dt**2 / 2, dt])
        return q * G * G.T
    return q * sp.Matrix([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])


def q_order_expected():
    """Q for [px, vx, py, vy]: the position-velocity pairs are adjacent, so blkdiag(Q1d, Q1d)."""
    import sympy as sp

    return sp.diag(_q1d(), _q1d())


def _q_order_variants() -> dict[str, Any]:
    import sympy as sp

    s = _syms("dt q")
    Q1 = _q1d()
    return {
        "q-kron-for-this-order": sp.kronecker_product(Q1, sp.eye(2)),
        "q-continuous-white-noise": sp.diag(_q1d("continuous"), _q1d("continuous")),
        "q-missing-q": sp.diag(Q1, Q1) / s["q"],
    }


def euler_lagrange_expected():
    s = _syms("a b v dt lam Lv")
    return s["dt"] * (s["a"] + s["v"] * s["dt"] - s["b"]) - s["lam"] * s["Lv"]


def _el_variants() -> dict[str, Any]:
    s = _syms("a b v dt lam Lv")
    a, b, v, dt, lam, Lv = (s[k] for k in ("a", "b", "v", "dt", "lam", "Lv"))
    return {
        "el-laplacian-sign": dt * (a + v * dt - b) + lam * Lv,
        "el-missing-inner-derivative": (a + v * dt - b) - lam * Lv,
        # the factor 2 of one square kept and the other's dropped: either one
        "el-half-factor": (2 * dt * (a + v * dt - b) - lam * Lv, dt * (a + v * dt - b) - 2 * lam * Lv),
    }


def inverse_depth_jacobian_expected():
    import sympy as sp

    s = _syms("X Y Z f")
    X, Y, Z, f = s["X"], s["Y"], s["Z"], s["f"]
    return sp.Matrix([f * X / Z, f * Y / Z, 1 / Z]).jacobian([X, Y, Z])


def _jac_variants() -> dict[str, Any]:
    J = inverse_depth_jacobian_expected()
    signs = []
    for rows in ((0, 1), (0,), (1,)):  # the d/dZ sign lost in both rows, or in either one
        sign = J.copy()
        for r in rows:
            sign[r, 2] = -sign[r, 2]
        signs.append(sign)
    inv = J.copy()
    inv[2, 2] = -inv[2, 2]
    return {"jacobian-sign": tuple(signs), "inverse-depth-sign": inv, "generic-transpose": J.T}


# ----------------------------------------------------------------------------------------------
# numeric items


def listing_Q(dt: float, q: float = 1.0) -> np.ndarray:
    """The syllabus listings' Q: blkdiag(Q1d, Q1d) used with the state [px, py, vx, vy]."""
    g = np.array([dt**2 / 2.0, dt])
    q1d = q * np.outer(g, g)
    Q = np.zeros((4, 4))
    Q[:2, :2] = q1d
    Q[2:, 2:] = q1d
    return Q


def _null_basis(Q: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    w, V = np.linalg.eigh(Q)
    return V[:, w <= tol * max(1.0, w.max())].T


def nees_expected(q_true: float, q_filter: float, r: float) -> dict[str, float]:
    """Steady-state expected NEES of the posterior of a scalar random-walk Kalman filter.

    Truth x_k = x_{k-1} + w_k, w ~ N(0, q_true); z_k = x_k + v_k, v ~ N(0, r). The filter assumes
    q_filter: its predicted variance solves P- = P-(r)/(P- + r) + q_filter, its gain is
    K = P-/(P- + r) and its posterior variance P+ = (1 - K) P-. The actual posterior error
    e_k = (1 - K)(e_{k-1} + w_k) - K v_k has the stationary variance
    S = ((1 - K)^2 q_true + K^2 r) / (1 - (1 - K)^2). The expected NEES is S / P+.
    Returned with the catalogued wrong answers.
    """
    Pm = 0.5 * (q_filter + math.sqrt(q_filter**2 + 4.0 * q_filter * r))
    K = Pm / (Pm + r)
    Pp = (1.0 - K) * Pm
    S = ((1.0 - K) ** 2 * q_true + K**2 * r) / (1.0 - (1.0 - K) ** 2)
    return {
        "ok": S / Pp,
        "nees-inverted": Pp / S,
        "nees-assumed-consistent": 1.0,
        "nees-prior-covariance": (S + q_true) / Pm,
    }


LAMBDAS = np.logspace(-6.0, 0.0, 13)


def lambda_problem():
    """The λ-sweep problem of item 6 (the notebook builds the same data with the same code)."""
    rng = np.random.default_rng(7)
    H, W, dt = 24, 24, 0.1
    yy, xx = np.mgrid[0:H, 0:W]
    X_t = np.stack([xx * 0.01, yy * 0.01, 1.0 + 0.1 * rng.random((H, W))], axis=-1)
    v_true = np.stack(
        [0.2 * np.sin(2 * np.pi * xx / W), 0.2 * np.cos(2 * np.pi * yy / H), np.full((H, W), 0.1)], axis=-1
    )
    X_t1 = X_t + v_true * dt + rng.normal(scale=0.005, size=(H, W, 3))
    return X_t, X_t1, dt, v_true


def lambda_sweep() -> tuple[np.ndarray, np.ndarray]:
    """(lambdas, mean end-point error of the velocity for each) with the trusted solver."""
    from flowtrack.sceneflow import variational_scene_flow

    X_t, X_t1, dt, v_true = lambda_problem()
    epe = []
    for lam in LAMBDAS:
        v = variational_scene_flow(X_t, X_t1, dt, float(lam), method="dct")
        epe.append(float(np.mean(np.linalg.norm(v - v_true, axis=-1))))
    return LAMBDAS.copy(), np.array(epe)


def lambda_range(slack: float = 1.10) -> tuple[float, float]:
    """The accepted λ: from half a sweep step below the smallest to half a step above the largest
    sweep value whose error is within ``slack`` of the best."""
    lams, epe = lambda_sweep()
    good = lams[epe <= slack * epe.min()]
    half = math.sqrt(lams[1] / lams[0])
    return float(good.min() / half), float(good.max() * half)


# ----------------------------------------------------------------------------------------------
# checks


def symbolic_check(
    expected, names: Sequence[str], variants: dict[str, Any], points: np.ndarray, *, up_to_scale: bool = False
) -> Check:
    """The answer (a formula the sandbox evaluated at ``points``) equals ``expected`` there (or is a
    nonzero constant multiple of it, ``up_to_scale``). The grader never parses the answer's text
    (:mod:`~flowtrack_course.grading.engine.symbolic`). ``variants`` maps a mistake's id to its
    formula, or to a tuple of its forms."""
    import sympy as sp

    want = expected_values(expected, names, points)
    # a mistake may have several forms (a tuple of formulas): each one names it
    known = {k: [expected_values(f, names, points) for f in (v if isinstance(v, tuple) else (v,))]
             for k, v in variants.items()}
    shape = expected.shape if isinstance(expected, sp.MatrixBase) else ()

    def same(a: FormulaValues, b: FormulaValues) -> bool:
        return a.proportional(b) is not None if up_to_scale else a.equivalent(b)

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            return 0.0, Report(err, safe_error(err))
        got = values_of(outcome.value)
        if got.values is None:
            return 0.0, Report(f"the answer could not be read: {got.error}", "the answer could not be read")
        if same(got, want):
            return 1.0, "ok"
        mistakes = [k for k, forms in known.items() if any(same(got, v) for v in forms)]
        # a formula equal to a variant (or a multiple of the answer) at every random point is as many
        # independent evaluations: a generic id it shows needs no other call
        relations = {"generic-transpose": "transpose"} if "generic-transpose" in mistakes else {}
        evidence = len(points)
        if got.shape != tuple(shape):
            want_text = f"a {'matrix of shape ' + str(tuple(shape)) if shape else 'scalar expression'}"
            msg = f"expected {want_text}, got " + (
                f"a matrix of shape {got.shape}" if got.shape else "a scalar expression")
            return 0.0, Report(msg, f"wrong shape (expected {want_text})", mistakes, relations=relations,
                               evidence=evidence)
        if not mistakes and not up_to_scale:
            c = got.proportional(want)
            if c is not None and abs(c + 1) < 1e-9:
                mistakes, relations = ["generic-sign"], {"generic-sign": -1.0}
            elif shape and c is not None and abs(c - 1) > 1e-9 and abs(c.imag) < 1e-9:
                mistakes, relations = ["generic-scale"], {"generic-scale": float(c.real)}
        if shape:
            wrong = [str(list(ix)) for ix in got.differing_entries(want)]
            msg = f"not equivalent to the expected matrix: entries {', '.join(wrong)} differ"
            safe = "not equivalent to the expected matrix"  # which entries is the answer's choice
        else:
            msg = safe = "not equivalent to the expected expression" + (
                " (up to a constant factor)" if up_to_scale else ""
            )
        return 0.0, Report(msg, safe, mistakes, relations=relations, evidence=evidence)

    return check


def _formula_entry(function: str, expected, names: str, variants: dict[str, Any], rng, **kw) -> tuple:
    """A call of ``function()`` whose formula the sandbox evaluates at random points, and its check."""
    names_ = names.split()
    points = sample_points(names_, rng)
    check = symbolic_check(expected, names_, variants, points, **kw)
    return (function, (), {}, check, formula_request(names_, points))


def subspace_check(basis: np.ndarray, variants: dict[str, np.ndarray], tol: float = 1e-6) -> Check:
    """The rows of the answer span the same subspace as the rows of ``basis``."""
    k, n = basis.shape

    def span_equal(A: np.ndarray, B: np.ndarray) -> bool:
        if A.ndim != 2 or A.shape[1] != n or np.linalg.matrix_rank(A, tol=tol) != B.shape[0]:
            return False
        Qb, _ = np.linalg.qr(B.T)
        resid = A.T - Qb @ (Qb.T @ A.T)
        return bool(np.linalg.norm(resid) <= tol * max(1.0, np.linalg.norm(A)))

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            return 0.0, Report(err, safe_error(err))
        A = as_float_array(outcome.value)
        if A is None:
            return 0.0, Report("the result is not an array of numbers")
        A = np.atleast_2d(A)
        if A.ndim != 2 or A.shape[1] != n or not np.all(np.isfinite(A)):
            msg = f"expected rows of {n} numbers (one combination of the state per row), got shape {A.shape}"
            safe = f"expected rows of {n} finite numbers (one combination of the state per row)"
            return 0.0, Report(msg, safe)
        if span_equal(A, basis):
            return 1.0, "ok"
        mistakes = [m for m, V in variants.items() if span_equal(A, V)]
        rank = int(np.linalg.matrix_rank(A, tol=tol))
        msg = (
            f"your {A.shape[0]} row(s) span a {rank}-dimensional space; the combinations Q cannot excite "
            f"form a {k}-dimensional one"
            if rank != k
            else "your rows span a space of the right dimension, but not the one Q cannot excite"
        )
        safe = "your rows do not span the space of the combinations Q cannot excite"
        return 0.0, Report(msg, safe, mistakes)

    return check


def number_check(lo: float, hi: float, variants: dict[str, tuple[float, float]], what: str) -> Check:
    """A number in ``[lo, hi]``; a number in a variant's range names that mistake."""

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            return 0.0, Report(err, safe_error(err))
        v = outcome.value
        if type(v) not in (int, float) or not math.isfinite(v):
            return 0.0, Report(f"{what} must be a finite number", f"{what} must be a finite number")
        if lo <= v <= hi:
            return 1.0, "ok"
        mistakes = [m for m, (a, b) in variants.items() if a <= v <= b and not (a <= lo and hi <= b)]
        direction = "too large" if v > hi else "too small"
        # "your answer" first: "the expected NEES = 0.2 is too small" read like the right value
        return 0.0, Report(f"your answer for {what}, {v:.6g}, is {direction}",
                           f"your answer for {what} is {direction}", mistakes)

    return check


def _within(x: float, rel: float = 0.01) -> tuple[float, float]:
    return (x * (1 - rel), x * (1 + rel)) if x >= 0 else (x * (1 + rel), x * (1 - rel))


def _nees_check(q_true: float, q_filter: float, r: float) -> Check:
    vals = nees_expected(q_true, q_filter, r)
    lo, hi = _within(vals["ok"])
    variants = {
        k: _within(v) for k, v in vals.items() if k != "ok" and abs(v - vals["ok"]) > 0.03 * vals["ok"]
    }
    return number_check(lo, hi, variants, "the expected NEES")


def _unexcited_check(dt: float) -> Check:
    Q = listing_Q(dt)
    right_Q = np.zeros((4, 4))  # the right Q for [px, py, vx, vy]: Q1d kron I2
    g = np.array([dt**2 / 2.0, dt])
    right_Q = np.kron(np.outer(g, g), np.eye(2))
    w, V = np.linalg.eigh(Q)
    variants = {
        "null-space-assumed-px-vx-order": _null_basis(right_Q),
        "most-excited-not-unexcited": V[:, w > 1e-10 * w.max()].T,
    }
    return subspace_check(_null_basis(Q), variants)


# ----------------------------------------------------------------------------------------------
# tests


@graded_test("Q for the state order [px, vx, py, vy] (sympy)", "test_q_order", 2.0, hidden=False)
def _ex11_q(rng):
    return [_formula_entry("q_order", q_order_expected(), "dt q", _q_order_variants(), rng)]


@graded_test(
    "Euler-Lagrange equation of the energy (sympy, up to a factor)", "test_euler_lagrange", 2.0, hidden=False
)
def _ex11_el(rng):
    names = "a b v dt lam Lv"
    return [
        _formula_entry(
            "euler_lagrange", euler_lagrange_expected(), names, _el_variants(), rng, up_to_scale=True
        )
    ]


@graded_test("Jacobian of the inverse-depth projection (sympy)", "test_jacobian", 2.0, hidden=False)
def _ex11_jac(rng):
    return [
        _formula_entry(
            "inverse_depth_jacobian", inverse_depth_jacobian_expected(), "X Y Z f", _jac_variants(), rng
        )
    ]


@graded_test("what the listings' Q cannot excite, dt = 0.1", "test_unexcited", 1.0, hidden=False)
def _ex11_unexcited_public(rng):
    return [("unexcited_directions", (0.1,), {}, _unexcited_check(0.1))]


@graded_test("what the listings' Q cannot excite, other time steps", "test_unexcited", 0.5, hidden=True)
def _ex11_unexcited_hidden(rng):
    return [
        ("unexcited_directions", (dt,), {}, _unexcited_check(dt)) for dt in rng.uniform(0.02, 1.0, 2).tolist()
    ]


@graded_test(
    "NEES of a mis-specified filter: q_true = 1, q_filter = 0.1, r = 1", "test_nees", 1.0, hidden=False
)
def _ex11_nees_public(rng):
    return [("nees_value", (1.0, 0.1, 1.0), {}, _nees_check(1.0, 0.1, 1.0))]


@graded_test("NEES of mis-specified filters: other noise levels", "test_nees", 0.5, hidden=True)
def _ex11_nees_hidden(rng):
    out = []
    for _ in range(2):
        q_true = float(rng.uniform(0.5, 2.0))
        q_filter = float(rng.uniform(0.05, 0.2)) * q_true  # an over-confident filter, NEES > 1
        r = float(rng.uniform(0.5, 2.0))
        out.append(("nees_value", (q_true, q_filter, r), {}, _nees_check(q_true, q_filter, r)))
    return out


@graded_test("λ chosen from the sweep", "test_lambda", 1.0, hidden=False)
def _ex11_lambda(rng):
    lo, hi = lambda_range()
    lams = LAMBDAS
    half = math.sqrt(lams[1] / lams[0])
    variants = {
        "lambda-largest": (lams[-1] / half, lams[-1] * half),
        "lambda-smallest": (0.0, lams[0] * half),
        "lambda-log10": (math.log10(lo), math.log10(hi)) if hi < 1 else (math.inf, math.inf),
    }
    return [("chosen_lambda", (), {}, number_check(lo, hi, variants, "λ"))]


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L1 = "lesson 01_camera_geometry"
_L2 = "lesson 02_variational_scene_flow"
_L4 = "lesson 04_bayes_and_kalman"

MISTAKES = (
    Mistake(
        "q-kron-for-this-order",
        "this is Q1d kron I2, the Q of the order [px, py, vx, vy]; with [px, vx, py, vy] each "
        "position sits next to its own velocity, so Q = blkdiag(Q1d, Q1d); "
        f"see {_L4} §3 (deriving Q, the ordering bug)",
    ),
    Mistake(
        "el-laplacian-sign",
        "the smoothness term has the wrong sign: integrating 2 lam grad v . grad(dv) by parts gives "
        "-2 lam Lap(v) dv, so the equation is dt (a + v dt - b) - lam Lap(v) = 0; "
        f"see {_L2} §3 (the Euler–Lagrange equation, Problem 2)",
    ),
    Mistake(
        "el-missing-inner-derivative",
        "the inner derivative dt is missing: d/dv (a + v dt - b)^2 = 2 dt (a + v dt - b) (chain "
        f"rule); see {_L2} §3 (the Euler–Lagrange equation, Problem 2)",
    ),
    Mistake(
        "el-half-factor",
        "the two terms are scaled differently: both squares give a factor 2 (2 dt (a + v dt - b) "
        "and -2 lam Lap(v)), which cancel together, not one of them alone; "
        f"see {_L2} §3 (the Euler–Lagrange equation, Problem 2)",
    ),
    Mistake(
        "inverse-depth-sign",
        f"d(1/Z)/dZ = -1/Z^2: the inverse depth decreases as Z grows; see {_L1} §2 (the projection Jacobian)",
    ),
    Mistake(
        "null-space-assumed-px-vx-order",
        "these are the combinations the right Q cannot excite (2 p - dt v for each axis); the "
        "listings use blkdiag(Q1d, Q1d) with the state [px, py, vx, vy], which couples px with py "
        "and vx with vy, so what it cannot excite is 2 px - dt py and 2 vx - dt vy; "
        f"see {_L4} §3 (deriving Q, the ordering bug)",
    ),
    Mistake(
        "most-excited-not-unexcited",
        "these are the directions Q excites (its range); the question asks for its null space, "
        f"the combinations x with Q x = 0; see {_L4} §3 (deriving Q)",
    ),
    Mistake(
        "nees-inverted",
        "the ratio is inverted: NEES = e^T P^-1 e, the actual squared error measured in the "
        "filter's claimed covariance, so its expectation is (actual variance) / P, above 1 for "
        f"an over-confident filter; see {_L4} §8 (NEES and innovations)",
    ),
    Mistake(
        "nees-assumed-consistent",
        "the expected NEES is the state dimension only when the filter's model is right; with "
        f"q_filter != q_true it is not; see {_L4} §8 (NEES and innovations)",
    ),
    Mistake(
        "nees-prior-covariance",
        "this uses the predicted (prior) error and covariance; the question asks for the NEES of "
        f"the posterior (after the update); see {_L4} §8 (NEES and innovations)",
    ),
    Mistake(
        "lambda-largest",
        "the largest λ of the sweep over-smooths: it flattens the motion the data show; choose "
        "the λ with the smallest error against the ground truth; "
        f"see {_L2} §A.4 (choosing λ for the special case)",
    ),
    Mistake(
        "lambda-smallest",
        "the smallest λ (or 0) fits the noise: it minimises the data term, not the error against "
        f"the ground truth; see {_L2} §A.4 (choosing λ for the special case)",
    ),
    Mistake(
        "lambda-log10",
        "this looks like log10(λ): give λ itself; "
        f"see {_L2} §A.4 (choosing λ for the special case)",
    ),
)


EXERCISE = Exercise(
    id="ex11_concepts",
    title="Concepts: Q for another state order, Euler-Lagrange, a Jacobian, NEES and λ",
    notebook="ex11_concepts.ipynb",
    answer_cells=(
        "q_order",
        "euler_lagrange",
        "inverse_depth_jacobian",
        "unexcited_directions",
        "nees_value",
        "chosen_lambda",
    ),
    blocked=("flowtrack.symbolic",),
    tests=(
        _ex11_q,
        _ex11_el,
        _ex11_jac,
        _ex11_unexcited_public,
        _ex11_unexcited_hidden,
        _ex11_nees_public,
        _ex11_nees_hidden,
        _ex11_lambda,
    ),
    allowed=("numpy", "sympy", "flowtrack.sceneflow", "flowtrack.kalman"),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
