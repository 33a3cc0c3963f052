r"""The Kalman-filter problems: the constant-velocity model, its filter, one step, the scalar steady state.

State :math:`[p_x, p_y, v_x, v_y]`, :math:`F = [[I, \Delta t I], [0, I]]`, :math:`H = [I\ 0]`,
:math:`Q = q\,Q_{1D}(\Delta t) \otimes I_2` with :math:`Q_{1D} = [[\Delta t^4/4, \Delta t^3/2],
[\Delta t^3/2, \Delta t^2]]` (piecewise-constant white acceleration,
:func:`flowtrack.kalman.white_noise_acceleration_Q`; not the syllabus' ``blkdiag(Q1d, Q1d)``).

``kalman_cv2d`` (ports)
    ``{"dt", "process_var", "meas_var", "x0" (4,), "P0" (4, 4), "measurements" (T, 2)}`` ->
    ``{"positions" (T, 2), "P_final" (4, 4)}``, :math:`R = r I`; for every measurement predict then
    update; ``positions[t]`` is :math:`(x_0, x_1)` after update ``t``, ``P_final`` the covariance
    after the last update. The syllabus' own run (``x0 = 0``, ``P0 = 1e3 I``) is the case
    ``syllabus``; others are seeded random tracks (one of 1000 steps) and one informative prior.
``white_noise_q`` (ports)
    ``{"dt", "q", "dim"}`` -> ``{"Q" (2 dim, 2 dim)}``, :math:`Q = q\,Q_{1D}(\Delta t) \otimes I_{dim}`.
``steady_state_scalar`` (ports)
    ``{"f", "h", "q", "r"}`` -> ``{"P", "P_post"}``: the predicted steady-state variance of the scalar
    model :math:`x_t = f x_{t-1} + w`, :math:`z_t = h x_t + v` (:func:`scalar_riccati_P`) and the
    posterior one :math:`P - P^2 h^2 / (h^2 P + r)`.
``cv_model`` (graded)
    ``{"dt", "q"}`` -> ``{"F" (4, 4), "Q" (4, 4)}``.
``kalman_step`` (graded)
    ``{"x" (n,), "P" (n, n), "F" (n, n), "Q" (n, n), "H" (m, n), "R" (m, m), "z" (m,)}`` ->
    ``{"x" (n,), "P" (n, n)}``: one predict, then one update with ``z``.
"""

from __future__ import annotations

import math

import numpy as np

from .base import Case, Problem, as_inputs, spd

__all__ = [
    "CV_MODEL",
    "KALMAN_CV2D",
    "KALMAN_STEP",
    "STEADY_STATE_SCALAR",
    "WHITE_NOISE_Q",
    "scalar_riccati_P",
]


# -- kalman_cv2d ------------------------------------------------------------------------------------
def _filter_reference(inp: dict) -> dict:
    from flowtrack.kalman import KalmanFilter, constant_velocity_model

    F, H, Q, R = constant_velocity_model(inp["dt"], inp["process_var"], inp["meas_var"], dim=2)
    kf = KalmanFilter(F, H, Q, R, np.asarray(inp["x0"], float), np.asarray(inp["P0"], float))
    positions = []
    for z in np.asarray(inp["measurements"], float):
        kf.predict()
        kf.update(z)
        positions.append(kf.x[:2].copy())
    return {"positions": np.array(positions), "P_final": kf.P}


def _cv_track(rng: np.random.Generator, steps: int, dt: float, q: float, r: float) -> np.ndarray:
    """Noisy position measurements of a simulated constant-velocity target, shape (steps, 2)."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    G = np.vstack([0.5 * dt * dt * np.eye(2), dt * np.eye(2)])  # piecewise-constant acceleration
    x = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-2, 2), rng.uniform(-2, 2)])
    Z = np.empty((steps, 2))
    for t in range(steps):
        x = F @ x + G @ (np.sqrt(q) * rng.standard_normal(2))
        Z[t] = x[:2] + np.sqrt(r) * rng.standard_normal(2)
    return np.round(Z, 6)  # short decimal measurements keep the files small


def _filter_input(dt, q, r, x0, P0, Z) -> dict:
    return {"dt": dt, "process_var": q, "meas_var": r, "x0": x0, "P0": P0, "measurements": Z}


def _filter_cases() -> list[Case]:
    x0 = np.zeros(4)
    P0 = 1e3 * np.eye(4)
    syllabus = np.array([[0.0, 0.0], [0.9, 0.1], [2.1, 0.2], [3.0, 0.1]])
    cases = [Case("syllabus", _filter_input(0.1, 1.0, 4.0, x0, P0, syllabus))]
    for seed, steps, dt, q, r in [(1, 25, 0.1, 1.0, 4.0), (2, 40, 0.05, 3.0, 0.25), (3, 1000, 0.1, 0.5, 1.0)]:
        Z = _cv_track(np.random.default_rng(seed), steps, dt, q, r)
        cases.append(Case(f"random_seed{seed}_steps{steps}", _filter_input(dt, q, r, x0, P0, Z)))
    # a filter started at the first measurement with a tighter prior (x0/P0 are inputs, not fixed)
    Z = _cv_track(np.random.default_rng(4), 30, 0.2, 2.0, 0.5)
    x0 = np.array([Z[0, 0], Z[0, 1], 0.0, 0.0])
    P0 = np.diag([0.5, 0.5, 10.0, 10.0])
    P0[0, 2] = P0[2, 0] = 0.1
    cases.append(Case("informative_prior_seed4", _filter_input(0.2, 2.0, 0.5, x0, P0, Z[1:])))
    return cases


KALMAN_CV2D = Problem(
    "kalman_cv2d",
    "The constant-velocity Kalman filter over a track",
    ("positions", "P_final"),
    _filter_reference,
    rtol=1e-9,
    atol=1e-9,
    vector_cases=_filter_cases,
)


# -- white_noise_q ----------------------------------------------------------------------------------
def _wnq_reference(inp: dict) -> dict:
    from flowtrack.kalman import white_noise_acceleration_Q

    return {"Q": white_noise_acceleration_Q(inp["dt"], inp["q"], inp["dim"])}


WHITE_NOISE_Q = Problem(
    "white_noise_q",
    "The white-noise-acceleration process noise Q",
    ("Q",),
    _wnq_reference,
    rtol=1e-12,
    atol=1e-15,
    vector_cases=lambda: [
        Case(f"dim{dim}_dt{dt:g}_q{q:g}", {"dt": dt, "q": q, "dim": dim})
        for dt, q, dim in [(0.1, 1.0, 2), (1.0, 4.0, 2), (0.5, 2.0, 1), (0.033, 9.81, 3), (2.0, 0.1, 3)]
    ],
)


# -- steady_state_scalar ------------------------------------------------------------------------------
def scalar_riccati_P(f: float, h: float, q: float, r: float) -> float:
    r"""Predicted steady-state variance of the scalar Kalman filter, closed form.

    The fixed point of :math:`P \mapsto f^2 P - f^2 P^2 h^2 / (h^2 P + r) + q` satisfies
    :math:`h^2 P^2 + \beta P - q r = 0` with :math:`\beta = r (1 - f^2) - q h^2`; its positive root is

    .. math::  P = \frac{-\beta + \sqrt{\beta^2 + 4 h^2 q r}}{2 h^2}
                 = \frac{2 q r}{\beta + \sqrt{\beta^2 + 4 h^2 q r}},

    (the second form is used when :math:`\beta > 0`, avoiding cancellation).

    Parameters
    ----------
    f, h : float
        Transition and measurement coefficients, ``h != 0``.
    q, r : float
        Process and measurement noise variances, both > 0.

    Returns
    -------
    float

    Examples
    --------
    >>> print(f"{scalar_riccati_P(1.0, 1.0, 1.0, 1.0):.12f}")  # golden ratio
    1.618033988750
    """
    for name, val in (("f", f), ("h", h), ("q", q), ("r", r)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
            raise TypeError(f"{name}: expected a finite real number, got {val!r}")
    if h == 0:
        raise ValueError("h: must be non-zero (an unobserved state has no steady state unless |f| < 1)")
    if q <= 0 or r <= 0:
        raise ValueError(f"q, r: expected q > 0 and r > 0, got q={q!r}, r={r!r}")
    a = h * h
    beta = r * (1.0 - f * f) - q * a
    disc = math.sqrt(beta * beta + 4.0 * a * q * r)
    if beta > 0:
        return 2.0 * q * r / (beta + disc)
    return (-beta + disc) / (2.0 * a)


def _steady_reference(inp: dict) -> dict:
    f, h, q, r = inp["f"], inp["h"], inp["q"], inp["r"]
    P = scalar_riccati_P(f, h, q, r)
    return {"P": P, "P_post": P - P * P * h * h / (h * h * P + r)}


def _steady_cases() -> list[Case]:
    """The random walk with ``q = r = 1`` (``P`` = golden ratio), a stable and an unstable ``f``, a
    small and a large noise ratio, and seeded random models."""
    models = [
        ("random_walk_unit", 1.0, 1.0, 1.0, 1.0),
        ("random_walk_q0.01_r4", 1.0, 1.0, 0.01, 4.0),
        ("stable_f0.5", 0.5, 1.0, 0.2, 1.0),
        ("unstable_f1.2_h2", 1.2, 2.0, 0.5, 3.0),
        ("precise_sensor", 1.0, 1.0, 10.0, 1e-4),
    ]
    rng = np.random.default_rng(6)
    for i in range(5):
        f = float(np.round(rng.uniform(-1.5, 1.5), 6))
        h = float(np.round(rng.uniform(0.2, 3.0), 6))
        q = float(np.round(10 ** rng.uniform(-2, 1), 6))
        r = float(np.round(10 ** rng.uniform(-2, 1), 6))
        models.append((f"random_{i}", f, h, q, r))
    return [Case(cid, {"f": f, "h": h, "q": q, "r": r}) for cid, f, h, q, r in models]


STEADY_STATE_SCALAR = Problem(
    "steady_state_scalar",
    "The steady-state variance of the scalar Kalman filter",
    ("P", "P_post"),
    _steady_reference,
    rtol=1e-10,
    atol=1e-12,
    vector_cases=_steady_cases,
)


# -- cv_model -------------------------------------------------------------------------------------
def _cv_reference(inp: dict) -> dict:
    from flowtrack.kalman import constant_velocity_model

    F, _H, Q, _R = constant_velocity_model(float(inp["dt"]), float(inp["q"]), 1.0, dim=2)
    return {"F": F, "Q": Q}


def _cv_blockdiag(inp: dict) -> dict:
    dt, q = float(inp["dt"]), float(inp["q"])
    q1 = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    return {"Q": np.kron(np.eye(2), q1)}


def _cv_continuous(inp: dict) -> dict:
    dt, q = float(inp["dt"]), float(inp["q"])
    q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return {"Q": np.kron(q1, np.eye(2))}


CV_MODEL = Problem(
    "cv_model",
    "The constant-velocity model: F and Q",
    ("F", "Q"),
    _cv_reference,
    rtol=1e-9,
    atol=1e-12,
    public=lambda: [{"dt": 0.1, "q": 2.0}, {"dt": 1.0, "q": 1.0}],
    hidden=lambda rng: [
        {"dt": float(rng.uniform(0.02, 1.5)), "q": float(rng.uniform(0.05, 5.0))} for _ in range(3)
    ],
    mistakes=(("q-block-diagonal", _cv_blockdiag), ("q-continuous-white-noise", _cv_continuous)),
)


# -- kalman_step -----------------------------------------------------------------------------------
def _step_reference(inp: dict) -> dict:
    from flowtrack.kalman import KalmanFilter

    kf = KalmanFilter(
        inp["F"], inp["H"], inp["Q"], inp["R"], np.asarray(inp["x"], float), np.asarray(inp["P"], float)
    )
    kf.predict()
    kf.update(np.asarray(inp["z"], float))
    return {"x": kf.x.copy(), "P": kf.P.copy()}


def _step_no_q(inp: dict) -> dict:
    return _step_reference({**inp, "Q": np.zeros_like(np.asarray(inp["Q"], float)).tolist()})


def _step_no_predict(inp: dict) -> dict:
    n = len(inp["x"])
    return _step_reference({**inp, "F": np.eye(n).tolist(), "Q": np.zeros((n, n)).tolist()})


def _step_prior_cov(inp: dict) -> dict:
    F, P, Q = (np.asarray(inp[k], float) for k in ("F", "P", "Q"))
    return {"P": F @ P @ F.T + Q}


def _step_case(rng: np.random.Generator, dt: float) -> dict:
    from flowtrack.kalman import constant_velocity_model

    q, r = float(rng.uniform(0.1, 3.0)), float(rng.uniform(0.01, 1.0))
    F, H, Q, R = constant_velocity_model(dt, q, r, dim=2)
    x = rng.normal(size=4)
    P = spd(rng, 4, float(rng.uniform(0.2, 5.0)))
    z = H @ (F @ x) + rng.normal(scale=0.5, size=2)
    return as_inputs({"x": x, "P": P, "F": F, "Q": Q, "H": H, "R": R, "z": z})


def _step_public() -> list[dict]:
    rng = np.random.default_rng(19)
    return [_step_case(rng, 0.1), _step_case(rng, 0.5)]


KALMAN_STEP = Problem(
    "kalman_step",
    "One Kalman filter step: predict, then update",
    ("x", "P"),
    _step_reference,
    rtol=1e-7,
    atol=1e-9,
    public=_step_public,
    hidden=lambda rng: [_step_case(rng, float(rng.uniform(0.05, 1.0))) for _ in range(3)],
    mistakes=(
        ("predict-without-Q", _step_no_q),
        ("kalman-no-predict", _step_no_predict),
        ("kalman-prior-cov", _step_prior_cov),
    ),
)
