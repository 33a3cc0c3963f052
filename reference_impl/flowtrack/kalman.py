r"""Linear-Gaussian tracking: the Kalman filter of syllabus section 6.

The model is

.. math::  x_t = F x_{t-1} + w_t,\quad w_t \sim \mathcal N(0, Q), \qquad
           z_t = H x_t + v_t,\quad v_t \sim \mathcal N(0, R),

with state :math:`x \in \mathbb R^n` and measurement :math:`z \in \mathbb R^m`. If the belief
:math:`p(x_{t-1}\mid z_{1:t-1}) = \mathcal N(\hat x, P)` is Gaussian, so are the prediction and the
posterior (Problem 3): a linear map of a Gaussian plus independent Gaussian noise is Gaussian, and a
Gaussian prior times a Gaussian likelihood linear in :math:`x` is, after completing the square, a
Gaussian posterior. The recursion on the mean and covariance is

.. math::
    \text{predict:}\quad & \hat x^- = F \hat x, \qquad P^- = F P F^\top + Q, \\
    \text{update:}\quad  & y = z - H\hat x^-, \quad S = H P^- H^\top + R, \quad K = P^- H^\top S^{-1}, \\
                         & \hat x = \hat x^- + K y, \quad
                           P = (I - K H) P^- (I - K H)^\top + K R K^\top .

The last line is the *Joseph form*: algebraically equal to the textbook :math:`(I - KH)P^-` for the
optimal gain, but a sum of two PSD terms, so rounding cannot make :math:`P` indefinite. ``S`` is
never inverted explicitly: ``K`` comes from a Cholesky solve with ``S``.

Contents
--------
- :func:`white_noise_acceleration_Q`, :func:`constant_velocity_model` – the CV model.
- :class:`KalmanFilter` – one filter, any ``(F, H, Q, R)``.
- :class:`KalmanFilterCV2D` – the syllabus' class (section 8), with the correct ``Q``.
- :class:`BatchKalmanFilter` – ``M`` independent tracks as stacked arrays (no Python loop);
  defined in :mod:`flowtrack.batch_kalman` with its kernels, re-exported here.
- :func:`steady_state_covariance` – the predicted steady-state ``P`` (discrete Riccati equation).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ._linear_gaussian import LOG_2PI, check_model, cholesky_innovation
from ._validation import (
    as_array,
    check_psd,
    nonnegative,
    positive,
    spatial_dim,
)
from .batch_kalman import BatchKalmanFilter

__all__ = [
    "BatchKalmanFilter",
    "KalmanFilter",
    "KalmanFilterCV2D",
    "constant_velocity_model",
    "steady_state_covariance",
    "white_noise_acceleration_Q",
]


# ----------------------------------------------------------------------------------------------------
# constant-velocity model
# ----------------------------------------------------------------------------------------------------
def white_noise_acceleration_Q(dt: float, q: float, dim: int = 2) -> np.ndarray:
    r"""Process noise of the discretised white-noise-acceleration (constant-velocity) model.

    For one axis with state :math:`[p, v]` and a piecewise-constant acceleration of variance
    :math:`q` over each step, :math:`w = [\tfrac12 \Delta t^2, \Delta t]^\top a` and

    .. math::  Q_{1D} = q \begin{bmatrix} \Delta t^4/4 & \Delta t^3/2 \\
                                           \Delta t^3/2 & \Delta t^2 \end{bmatrix}.

    The state here is ordered by derivative, :math:`x = [p_1, \dots, p_d, v_1, \dots, v_d]`
    (for ``dim=2``: ``[px, py, vx, vy]``), and the axes are independent, so

    .. math::  Q = Q_{1D} \otimes I_d, \qquad Q[i, j] = Q_{1D}[i // d, j // d]\,\delta_{i \% d,\, j \% d}.

    The block-diagonal :math:`\operatorname{blkdiag}(Q_{1D}, Q_{1D})` of the syllabus' code is the
    right matrix only for the *axis-major* order ``[px, vx, py, vy]``. Applied to ``[px, py, vx, vy]``
    its first block lands on the pair ``(px, py)``: it gives ``py`` the velocity-sized variance
    :math:`q\Delta t^2`, correlates ``px`` with ``py`` (covariance :math:`q\Delta t^3/2`) and ``vx``
    with ``vy``, and drops the position–velocity covariance of each axis. ``Q ⊗ I`` is the matrix
    for this ordering.

    Parameters
    ----------
    dt : float
        Time step (> 0).
    q : float
        Acceleration variance (>= 0), units of (length/time²)².
    dim : int
        Number of spatial axes, 1, 2 or 3.

    Returns
    -------
    Q : ndarray, shape (2*dim, 2*dim)

    Examples
    --------
    >>> white_noise_acceleration_Q(1.0, 4.0, dim=2)
    array([[1., 0., 2., 0.],
           [0., 1., 0., 2.],
           [2., 0., 4., 0.],
           [0., 2., 0., 4.]])
    """
    dt = positive(dt, "dt")
    q = nonnegative(q, "q")
    d = spatial_dim(dim, "dim")
    q1d = q * np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])
    return np.kron(q1d, np.eye(d))


def constant_velocity_model(dt: float, q: float, r, dim: int = 2):
    r"""Matrices ``(F, H, Q, R)`` of the constant-velocity model with position measurements.

    With state :math:`[p, v]` (``p, v`` each of length ``dim``)

    .. math::  F = \begin{bmatrix} I & \Delta t\, I \\ 0 & I \end{bmatrix}, \quad
               H = \begin{bmatrix} I & 0 \end{bmatrix}, \quad
               Q = Q_{1D} \otimes I, \quad R = r I .

    Parameters
    ----------
    dt : float
        Time step (> 0).
    q : float
        Acceleration variance (>= 0), see :func:`white_noise_acceleration_Q`.
    r : float or array_like, shape (dim, dim)
        Measurement noise variance (> 0), or a full positive definite covariance.
    dim : int
        Number of spatial axes, 1, 2 or 3.

    Returns
    -------
    F : ndarray, shape (2*dim, 2*dim)
    H : ndarray, shape (dim, 2*dim)
    Q : ndarray, shape (2*dim, 2*dim)
    R : ndarray, shape (dim, dim)

    Examples
    --------
    >>> F, H, Q, R = constant_velocity_model(0.5, 1.0, 2.0, dim=1)
    >>> F
    array([[1. , 0.5],
           [0. , 1. ]])
    >>> H, R
    (array([[1., 0.]]), array([[2.]]))
    """
    dt = positive(dt, "dt")
    d = spatial_dim(dim, "dim")
    Q = white_noise_acceleration_Q(dt, q, d)
    if np.ndim(r) == 0:
        R = positive(r, "r") * np.eye(d)
    else:
        R = as_array(r, "r", (d, d))
        check_psd(R, "r", strict=True)
    eye = np.eye(d)
    zero = np.zeros((d, d))
    F = np.block([[eye, dt * eye], [zero, eye]])
    H = np.hstack([eye, zero])
    return F, H, Q, R



class KalmanFilter:
    r"""Linear Kalman filter (syllabus section 6) with a Joseph-form update.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State transition.
    H : array_like, shape (m, n)
        Measurement matrix.
    Q : array_like, shape (n, n)
        Process noise covariance (symmetric PSD).
    R : array_like, shape (m, m)
        Measurement noise covariance (symmetric PSD; ``H P H^T + R`` must be PD).
    x0 : array_like, shape (n,)
        Initial state mean.
    P0 : array_like, shape (n, n)
        Initial state covariance (symmetric PSD).

    Attributes
    ----------
    x : ndarray, shape (n,)
        State mean (after the last ``predict``/``update``).
    P : ndarray, shape (n, n)
        State covariance.
    innovation : ndarray, shape (m,) or None
        :math:`y = z - H \hat x^-` of the last update (``None`` after a missed measurement).
    S : ndarray, shape (m, m) or None
        Innovation covariance :math:`H P^- H^\top + R` of the last update.
    K : ndarray, shape (n, m) or None
        Kalman gain of the last update (``None`` after a missed measurement).
    log_likelihood : float or None
        :math:`\log \mathcal N(z; H\hat x^-, S) = -\tfrac12 (y^\top S^{-1} y + \log\det S + m\log 2\pi)`
        of the last update; ``0.0`` after a missed measurement (``log p(∅) = 0``), so the sum over a
        sequence is the log marginal likelihood of the measurements that were made.

    Examples
    --------
    A 1-D random walk observed directly:

    >>> kf = KalmanFilter(F=[[1.0]], H=[[1.0]], Q=[[1.0]], R=[[1.0]], x0=[0.0], P0=[[1.0]])
    >>> kf.predict()
    >>> kf.P
    array([[2.]])
    >>> kf.update([3.0])
    >>> kf.x, kf.P          # gain 2/3
    (array([2.]), array([[0.66666667]]))
    >>> kf.update(None)      # missed measurement: nothing changes
    >>> kf.x
    array([2.])
    """

    def __init__(self, F, H, Q, R, x0, P0):
        self.F, self.H, self.Q, self.R = check_model(F, H, Q, R)
        self.dim_x = self.F.shape[0]
        self.dim_z = self.H.shape[0]
        self.x = as_array(x0, "x0", (self.dim_x,))
        P = as_array(P0, "P0", (self.dim_x, self.dim_x))
        check_psd(P, "P0")
        self.P = 0.5 * (P + P.T)
        self.innovation: np.ndarray | None = None
        self.S: np.ndarray | None = None
        self.K: np.ndarray | None = None
        self.log_likelihood: float | None = None

    # -- steps ---------------------------------------------------------------------------------------
    def predict(self) -> None:
        r"""Time update :math:`\hat x \leftarrow F\hat x`, :math:`P \leftarrow F P F^\top + Q`."""
        self.x = self.F @ self.x
        P = self.F @ self.P @ self.F.T + self.Q
        self.P = 0.5 * (P + P.T)

    def _measurement(self, z, name: str = "z") -> np.ndarray:
        z = as_array(z, name)
        if z.shape == (self.dim_z, 1):
            z = z[:, 0]
        if z.shape != (self.dim_z,):
            raise ValueError(f"{name} must have shape ({self.dim_z},), got {z.shape}")
        return z

    def _innovation_cov(self):
        PHt = self.P @ self.H.T
        S = self.H @ PHt + self.R
        S = 0.5 * (S + S.T)
        return PHt, S, (cholesky_innovation(S), True)

    def update(self, z) -> None:
        r"""Measurement update with ``z`` of shape ``(m,)``; ``None`` means a missed measurement.

        Joseph form :math:`P = (I-KH)P^-(I-KH)^\top + KRK^\top`; :math:`K` from a Cholesky solve.
        With ``z=None`` the state is left as predicted, ``innovation`` and ``K`` become ``None`` and
        ``log_likelihood`` is ``0.0``.
        """
        if z is None:
            self.innovation = None
            self.K = None
            self.S = self._innovation_cov()[1]
            self.log_likelihood = 0.0
            return
        z = self._measurement(z)
        PHt, S, cho = self._innovation_cov()
        y = z - self.H @ self.x
        K = scipy.linalg.cho_solve(cho, PHt.T, check_finite=False).T
        self.x = self.x + K @ y
        IKH = np.eye(self.dim_x) - K @ self.H
        P = IKH @ self.P @ IKH.T + K @ self.R @ K.T
        self.P = 0.5 * (P + P.T)
        w = scipy.linalg.cho_solve(cho, y, check_finite=False)
        logdet = 2.0 * float(np.log(np.diag(cho[0])).sum())
        self.innovation, self.S, self.K = y, S, K
        self.log_likelihood = -0.5 * (float(y @ w) + logdet + self.dim_z * LOG_2PI)

    def predicted_measurement(self):
        """Return ``(H x, S)`` for the current (predicted) state: shapes ``(m,)`` and ``(m, m)``."""
        return self.H @ self.x, self._innovation_cov()[1]

    def mahalanobis(self, z, squared: bool = False) -> float:
        r"""Mahalanobis distance of ``z`` from the current predicted measurement.

        :math:`d = \sqrt{(z - H\hat x)^\top S^{-1} (z - H\hat x)}` with :math:`S = HPH^\top + R`
        from the *current* ``x, P`` (call it after :meth:`predict`, before :meth:`update`);
        ``squared=True`` returns :math:`d^2` (the gating statistic, χ² with ``m`` degrees of freedom).
        """
        z = self._measurement(z)
        _, _, cho = self._innovation_cov()
        y = z - self.H @ self.x
        d2 = float(y @ scipy.linalg.cho_solve(cho, y, check_finite=False))
        return d2 if squared else float(np.sqrt(d2))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(dim_x={self.dim_x}, dim_z={self.dim_z}, x={self.x!r})"


class KalmanFilterCV2D(KalmanFilter):
    r"""The syllabus' constant-velocity filter in 2-D (section 8), with the correct ``Q``.

    State :math:`x = [p_x, p_y, v_x, v_y]^\top`, measurement :math:`z = [p_x, p_y]^\top`,
    ``Q = Q1d ⊗ I2`` (see :func:`white_noise_acceleration_Q`; the syllabus' ``blkdiag(Q1d, Q1d)``
    is wrong for this state order), ``R = meas_var·I``, ``x0 = 0``, ``P0 = 1e3·I``.

    Parameters
    ----------
    dt : float
        Time step (> 0).
    process_var : float
        Acceleration variance ``q`` (>= 0).
    meas_var : float
        Position measurement variance (> 0).

    Examples
    --------
    >>> kf = KalmanFilterCV2D(dt=0.1)
    >>> for z in [(0.0, 0.0), (0.9, 0.1), (2.1, 0.2), (3.0, 0.1)]:
    ...     kf.predict()
    ...     kf.update(z)
    >>> px, py = kf.position()
    >>> bool(2.5 < px < 3.1 and 0.0 < py < 0.3)
    True
    """

    def __init__(self, dt: float = 0.1, process_var: float = 1.0, meas_var: float = 4.0):
        self.dt = positive(dt, "dt")
        F, H, Q, R = constant_velocity_model(self.dt, process_var, positive(meas_var, "meas_var"), dim=2)
        super().__init__(F, H, Q, R, np.zeros(4), 1e3 * np.eye(4))

    def position(self) -> tuple[float, float]:
        """Return the estimated position ``(px, py)`` as two floats."""
        return float(self.x[0]), float(self.x[1])


# ----------------------------------------------------------------------------------------------------
# steady state
# ----------------------------------------------------------------------------------------------------
def _uncontrollable_on(F, B, eigs, which: str) -> complex | None:
    n = F.shape[0]
    tol = 1e-9 * max(1.0, float(np.abs(F).max()), float(np.abs(B).max(initial=0.0)))
    for lam in eigs:
        if which == "unstable" and abs(lam) < 1.0 - 1e-10:
            continue
        if which == "unit" and abs(abs(lam) - 1.0) > 1e-8:
            continue
        M = np.hstack([lam * np.eye(n) - F, B.astype(complex)])
        if np.linalg.matrix_rank(M, tol=tol * n) < n:
            return complex(lam)
    return None


def steady_state_covariance(F, H, Q, R) -> np.ndarray:
    r"""Predicted (a-priori) steady-state covariance :math:`P_\infty` of the Kalman filter.

    :math:`P_\infty` is the stabilising solution of the discrete algebraic Riccati equation

    .. math::  P = F P F^\top - F P H^\top (H P H^\top + R)^{-1} H P F^\top + Q,

    computed with ``scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)`` (the control DARE of the dual
    system). It exists when ``(F, H)`` is detectable and ``(F, Q^{1/2})`` has no uncontrollable mode
    on the unit circle; both are checked (PBH rank test) before calling scipy.

    Parameters
    ----------
    F : array_like, shape (n, n)
    H : array_like, shape (m, n)
    Q : array_like, shape (n, n)
        Symmetric PSD.
    R : array_like, shape (m, m)
        Symmetric positive definite.

    Returns
    -------
    P : ndarray, shape (n, n)
        The limit of the predicted covariance ``P⁻`` (after ``predict``); the posterior limit is
        ``P - P Hᵀ (H P Hᵀ + R)⁻¹ H P``.

    Examples
    --------
    Random walk ``x_t = x_{t-1} + w``, ``z = x + v`` with ``Q = R = 1``: ``P² - P - 1 = 0``.

    >>> P = steady_state_covariance([[1.0]], [[1.0]], [[1.0]], [[1.0]])
    >>> bool(np.isclose(P[0, 0], (1 + 5 ** 0.5) / 2))
    True
    """
    F, H, Q, R = check_model(F, H, Q, R)
    check_psd(R, "R", strict=True)
    eigs = np.linalg.eigvals(F)
    bad = _uncontrollable_on(F.T, H.T, eigs, "unstable")
    if bad is not None:
        raise ValueError(
            f"F, H: the pair (F, H) is not detectable (mode λ={bad:.4g} with |λ| >= 1 is unobservable); "
            "no steady-state covariance exists"
        )
    bad = _uncontrollable_on(F, Q, eigs, "unit")
    if bad is not None:
        raise ValueError(
            f"F, Q: the pair (F, Q^1/2) has an unexcited mode λ={bad:.4g} on the unit circle; "
            "the Riccati equation has no stabilising solution"
        )
    try:
        P = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ValueError(f"F, H, Q, R: scipy.linalg.solve_discrete_are failed: {exc}") from exc
    return 0.5 * (P + P.T)
