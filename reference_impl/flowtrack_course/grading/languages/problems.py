r"""The four problems every language answers, each computed by the Python reference.

A problem turns inputs (a dict in the shared vectors format's ``"input"`` form: numbers and nested
lists, row-major) into named outputs (``"expected"``). Its public inputs are fixed; its hidden inputs
are drawn from the student's keyed seed (:func:`flowtrack_course.grading.spec.student_seed`) by
``hidden(rng)``. Expected values come from the reference (``reference(inp)``) and never enter a
sandbox. ``mistakes`` are catalogued wrong answers (``id``, message, a function computing the wrong
answer): when a student's output matches one, the feedback names it with a ``mistake <id>:`` line.

``cv_model``
    ``{"dt", "q"}`` -> ``{"F" (4, 4), "Q" (4, 4)}``: state :math:`[p_x, p_y, v_x, v_y]`,
    :math:`F = [[I, \Delta t I], [0, I]]`, :math:`Q = q\,Q_{1D}(\Delta t) \otimes I_2` with
    :math:`Q_{1D} = [[\Delta t^4/4, \Delta t^3/2], [\Delta t^3/2, \Delta t^2]]` (piecewise-constant
    white acceleration, :func:`flowtrack.kalman.white_noise_acceleration_Q`).
``kalman_step``
    ``{"x" (n,), "P" (n, n), "F" (n, n), "Q" (n, n), "H" (m, n), "R" (m, m), "z" (m,)}`` ->
    ``{"x" (n,), "P" (n, n)}``: one predict, then one update with ``z``.
``projection_jacobian``
    ``{"X" (3,), "fx", "fy", "cx", "cy"}`` -> ``{"J" (2, 3)}``, :math:`\partial\pi/\partial X`.
``mahalanobis_gating``
    ``{"z_pred" (m,), "S" (m, m), "Z" (N, m), "gate"}`` -> ``{"d2" (N,), "inside" (N,)}``:
    :math:`d^2_j = (z_j - \hat z)^\top S^{-1} (z_j - \hat z)` and ``inside[j] = 1`` iff
    :math:`d^2_j \le` ``gate`` (else 0).
``assignment`` (C++, Octave and Java: the student writes the solver)
    ``{"C" (n, m)}``, :math:`n \le m` -> ``{"assignment" (n,)}``: the column given to each row, distinct,
    minimising :math:`\sum_i C_{i, a_i}` (the linear assignment problem; reference
    :func:`scipy.optimize.linear_sum_assignment`). Hidden costs are continuous random draws, so the
    optimum is unique; two of the three hidden cases (and one public case) are drawn so that the
    greedy answer (each row in turn takes its cheapest free column) is not optimal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["PROBLEMS", "Problem", "get_problem"]

Inputs = dict
Outputs = dict


@dataclass(frozen=True)
class Problem:
    """One language-neutral problem (see the module docstring)."""

    name: str
    title: str
    outputs: tuple[str, ...]
    public: Callable[[], list[Inputs]]
    hidden: Callable[[np.random.Generator], list[Inputs]]
    reference: Callable[[Inputs], Outputs]
    rtol: float = 1e-7
    atol: float = 1e-9
    mistakes: tuple[tuple[str, str, Callable[[Inputs], Outputs]], ...] = ()
    languages: tuple[str, ...] | None = None  # the languages it is set in (None: every language)


def _plain(d: dict) -> dict:
    return {
        k: (np.asarray(v, dtype=float).tolist() if not np.isscalar(v) else float(v)) for k, v in d.items()
    }


# -- cv_model ------------------------------------------------------------------------------------------
def _cv_reference(inp: Inputs) -> Outputs:
    from flowtrack.kalman import constant_velocity_model

    F, _H, Q, _R = constant_velocity_model(float(inp["dt"]), float(inp["q"]), 1.0, dim=2)
    return {"F": F, "Q": Q}


def _cv_blockdiag(inp: Inputs) -> Outputs:
    dt, q = float(inp["dt"]), float(inp["q"])
    q1 = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    return {"Q": np.kron(np.eye(2), q1)}


def _cv_continuous(inp: Inputs) -> Outputs:
    dt, q = float(inp["dt"]), float(inp["q"])
    q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return {"Q": np.kron(q1, np.eye(2))}


def _cv_hidden(rng: np.random.Generator) -> list[Inputs]:
    return [{"dt": float(rng.uniform(0.02, 1.5)), "q": float(rng.uniform(0.05, 5.0))} for _ in range(3)]


CV_MODEL = Problem(
    "cv_model",
    "The constant-velocity model: F and Q",
    ("F", "Q"),
    lambda: [{"dt": 0.1, "q": 2.0}, {"dt": 1.0, "q": 1.0}],
    _cv_hidden,
    _cv_reference,
    rtol=1e-9,
    atol=1e-12,
    mistakes=(
        (
            "cv-q-blockdiag",
            "Q is blkdiag(Q1d, Q1d), the ordering of a [px, vx, py, vy] state; this "
            "state is [px, py, vx, vy], so Q = Q1d kron I2",
            _cv_blockdiag,
        ),
        (
            "cv-q-continuous",
            "Q is the continuous white-noise model (dt^3/3, dt^2/2, dt); the course's "
            "model holds the acceleration constant over a step: dt^4/4, dt^3/2, dt^2",
            _cv_continuous,
        ),
    ),
)


# -- kalman_step -----------------------------------------------------------------------------------
def _kalman_reference(inp: Inputs) -> Outputs:
    from flowtrack.kalman import KalmanFilter

    kf = KalmanFilter(
        inp["F"], inp["H"], inp["Q"], inp["R"], np.asarray(inp["x"], float), np.asarray(inp["P"], float)
    )
    kf.predict()
    kf.update(np.asarray(inp["z"], float))
    return {"x": kf.x.copy(), "P": kf.P.copy()}


def _kalman_no_q(inp: Inputs) -> Outputs:
    return _kalman_reference({**inp, "Q": np.zeros_like(np.asarray(inp["Q"], float)).tolist()})


def _kalman_no_predict(inp: Inputs) -> Outputs:
    n = len(inp["x"])
    eye = np.eye(n).tolist()
    return _kalman_reference({**inp, "F": eye, "Q": np.zeros((n, n)).tolist()})


def _kalman_prior_cov(inp: Inputs) -> Outputs:
    F, P, Q = (np.asarray(inp[k], float) for k in ("F", "P", "Q"))
    return {"P": F @ P @ F.T + Q}


def _spd(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T / n + 0.3 * np.eye(n))


def _kalman_case(rng: np.random.Generator, dt: float) -> Inputs:
    from flowtrack.kalman import constant_velocity_model

    q, r = float(rng.uniform(0.1, 3.0)), float(rng.uniform(0.01, 1.0))
    F, H, Q, R = constant_velocity_model(dt, q, r, dim=2)
    x = rng.normal(size=4)
    P = _spd(rng, 4, float(rng.uniform(0.2, 5.0)))
    z = H @ (F @ x) + rng.normal(scale=0.5, size=2)
    return _plain({"x": x, "P": P, "F": F, "Q": Q, "H": H, "R": R, "z": z})


def _kalman_public() -> list[Inputs]:
    rng = np.random.default_rng(19)
    return [_kalman_case(rng, 0.1), _kalman_case(rng, 0.5)]


KALMAN_STEP = Problem(
    "kalman_step",
    "One Kalman filter step: predict, then update",
    ("x", "P"),
    _kalman_public,
    lambda rng: [_kalman_case(rng, float(rng.uniform(0.05, 1.0))) for _ in range(3)],
    _kalman_reference,
    rtol=1e-7,
    atol=1e-9,
    mistakes=(
        (
            "kalman-no-q",
            "the prediction leaves out the process noise: P must become F P F' + Q",
            _kalman_no_q,
        ),
        (
            "kalman-no-predict",
            "the update starts from x and P without predicting them first",
            _kalman_no_predict,
        ),
        (
            "kalman-prior-cov",
            "P is the predicted covariance: the update must shrink it, P = (I - K H) P",
            _kalman_prior_cov,
        ),
    ),
)


# -- projection_jacobian ------------------------------------------------------------------------
def _jac_reference(inp: Inputs) -> Outputs:
    from flowtrack.camera import PinholeCamera, projection_jacobian

    cam = PinholeCamera(float(inp["fx"]), float(inp["fy"]), float(inp["cx"]), float(inp["cy"]))
    return {"J": projection_jacobian(np.asarray(inp["X"], float)[None, :], cam)[0]}


def _jac_no_focal(inp: Inputs) -> Outputs:
    return _jac_reference({**inp, "fx": 1.0, "fy": 1.0})


def _jac_hidden(rng: np.random.Generator) -> list[Inputs]:
    out = []
    for _ in range(3):
        X = rng.uniform(-1.0, 1.0, size=3)
        X[2] = rng.uniform(0.5, 4.0)
        out.append(
            _plain(
                {
                    "X": X,
                    "fx": rng.uniform(200, 900),
                    "fy": rng.uniform(200, 900),
                    "cx": rng.uniform(100, 400),
                    "cy": rng.uniform(100, 300),
                }
            )
        )
    return out


PROJECTION_JACOBIAN = Problem(
    "projection_jacobian",
    "The Jacobian of the pinhole projection",
    ("J",),
    lambda: [
        {"X": [1.0, 2.0, 4.0], "fx": 100.0, "fy": 100.0, "cx": 0.0, "cy": 0.0},
        {"X": [-0.3, 0.25, 1.5], "fx": 525.0, "fy": 520.0, "cx": 319.5, "cy": 239.5},
    ],
    _jac_hidden,
    _jac_reference,
    rtol=1e-9,
    atol=1e-9,
    mistakes=(
        ("jacobian-no-focal", "the focal lengths fx, fy are missing: u = fx X / Z + cx", _jac_no_focal),
    ),
)


# -- mahalanobis_gating -------------------------------------------------------------------------
def _maha_reference(inp: Inputs) -> Outputs:
    from flowtrack.association import mahalanobis_cost

    zp = np.atleast_1d(np.asarray(inp["z_pred"], float))
    S = np.atleast_2d(np.asarray(inp["S"], float))
    Z = np.asarray(inp["Z"], float).reshape(-1, zp.size)
    d2 = mahalanobis_cost(zp[None, :], S[None, :, :], Z)[0]
    return {"d2": d2, "inside": (d2 <= float(inp["gate"])).astype(float)}


def _maha_no_inverse(inp: Inputs) -> Outputs:
    zp = np.atleast_1d(np.asarray(inp["z_pred"], float))
    S = np.atleast_2d(np.asarray(inp["S"], float))
    r = np.asarray(inp["Z"], float).reshape(-1, zp.size) - zp
    return {"d2": np.einsum("ni,ij,nj->n", r, S, r)}


def _maha_sqrt(inp: Inputs) -> Outputs:
    return {"d2": np.sqrt(_maha_reference(inp)["d2"])}


def _maha_case(rng: np.random.Generator, m: int, n: int, prob: float) -> Inputs:
    from flowtrack.association import chi2_gate

    zp = rng.normal(scale=2.0, size=m)
    S = _spd(rng, m, float(rng.uniform(0.5, 3.0)))
    Z = zp + rng.normal(scale=2.5, size=(n, m))
    # one detection surely inside the gate and one surely outside (d2 = |u|^2 for r = L u), so an
    # answer that never (or always) gates cannot score on ``inside``
    L = np.linalg.cholesky(S)
    u = rng.normal(size=(2, m))
    Z[0] = zp + L @ (0.2 * u[0] / np.linalg.norm(u[0]))
    Z[-1] = zp + L @ (8.0 * u[1] / np.linalg.norm(u[1]))
    return _plain({"z_pred": zp, "S": S, "Z": Z, "gate": chi2_gate(m, prob)})


def _maha_public() -> list[Inputs]:
    return [
        {
            "z_pred": [0.0, 0.0],
            "S": [[4.0, 0.0], [0.0, 1.0]],
            "Z": [[2.0, 0.0], [0.0, 2.0], [6.0, 1.0]],
            "gate": 9.21,
        },
        _maha_case(np.random.default_rng(7), 3, 4, 0.95),
    ]


MAHALANOBIS_GATING = Problem(
    "mahalanobis_gating",
    "Mahalanobis distances and chi-square gating",
    ("d2", "inside"),
    _maha_public,
    lambda rng: [_maha_case(rng, 2, 5, 0.9), _maha_case(rng, 3, 4, 0.99), _maha_case(rng, 2, 6, 0.5)],
    _maha_reference,
    rtol=1e-8,
    atol=1e-10,
    mistakes=(
        (
            "mahalanobis-no-inverse",
            "d2 uses S itself; the distance weighs the residual by S^-1",
            _maha_no_inverse,
        ),
        (
            "mahalanobis-sqrt",
            "d2 is the distance, not its square; the chi-square gate is on the square",
            _maha_sqrt,
        ),
    ),
)

# -- assignment ---------------------------------------------------------------------------------
def _lsa_reference(inp: Inputs) -> Outputs:
    from scipy.optimize import linear_sum_assignment

    C = np.atleast_2d(np.asarray(inp["C"], float))
    rows, cols = linear_sum_assignment(C)
    out = np.full(C.shape[0], -1.0)
    out[rows] = cols
    return {"assignment": out}


def _lsa_greedy(inp: Inputs) -> Outputs:
    C = np.atleast_2d(np.asarray(inp["C"], float))
    free = list(range(C.shape[1]))
    out = []
    for row in C:
        j = min(free, key=lambda k: row[k])
        free.remove(j)
        out.append(float(j))
    return {"assignment": np.array(out)}


def _lsa_maximize(inp: Inputs) -> Outputs:
    from scipy.optimize import linear_sum_assignment

    C = np.atleast_2d(np.asarray(inp["C"], float))
    rows, cols = linear_sum_assignment(C, maximize=True)
    out = np.full(C.shape[0], -1.0)
    out[rows] = cols
    return {"assignment": out}


def _lsa_case(rng: np.random.Generator, greedy_fails: bool) -> Inputs:
    """A random cost matrix (n in 3..6, m in n..n+2) on which the greedy answer is (or is not) optimal."""
    for _ in range(10_000):
        n = int(rng.integers(3, 7))
        C = rng.uniform(0.0, 10.0, size=(n, n + int(rng.integers(0, 3))))
        inp = {"C": C.tolist()}
        same = np.array_equal(_lsa_greedy(inp)["assignment"], _lsa_reference(inp)["assignment"])
        if same != greedy_fails:
            return inp
    raise RuntimeError("no cost matrix of the requested kind was drawn")  # pragma: no cover


ASSIGNMENT = Problem(
    "assignment",
    "The linear assignment problem (write the solver)",
    ("assignment",),
    lambda: [
        {"C": [[1.0, 2.0, 9.0], [2.0, 9.0, 9.0], [9.0, 9.0, 3.0]]},  # greedy: 1 + 9 + 3; optimum 2 + 2 + 3
        {"C": [[4.0, 1.0, 3.0, 7.0], [2.0, 0.5, 5.0, 8.0], [3.0, 2.0, 2.0, 6.0]]},  # 3 x 4, greedy optimal
    ],
    lambda rng: [_lsa_case(rng, False), _lsa_case(rng, True), _lsa_case(rng, True)],
    _lsa_reference,
    rtol=0.0,
    atol=1e-9,
    mistakes=(
        (
            "assignment-greedy",
            "each row took its cheapest free column in turn (greedy); the optimum may give a row a "
            "dearer column so that the others get cheaper ones: search all assignments (small n) or "
            "use the Hungarian algorithm",
            _lsa_greedy,
        ),
        (
            "assignment-maximize",
            "the assignment maximises the total cost; it must minimise it",
            _lsa_maximize,
        ),
    ),
    languages=("cpp", "octave", "java"),
)

PROBLEMS: dict[str, Problem] = {
    p.name: p for p in (CV_MODEL, KALMAN_STEP, PROJECTION_JACOBIAN, MAHALANOBIS_GATING, ASSIGNMENT)
}


def get_problem(name: str) -> Problem:
    """The problem called ``name`` (a key of :data:`PROBLEMS`)."""
    try:
        return PROBLEMS[name]
    except KeyError:
        raise KeyError(f"no problem {name!r}; known: {', '.join(PROBLEMS)}") from None
