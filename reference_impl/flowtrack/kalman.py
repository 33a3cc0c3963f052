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
- :class:`BatchKalmanFilter` – ``M`` independent tracks as stacked arrays (no Python loop).
- :func:`steady_state_covariance` – the predicted steady-state ``P`` (discrete Riccati equation).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ._validation import (
    as_array,
    check_psd,
    check_square,
    cholesky,
    nonnegative,
    not_positive_definite,
    positive,
    spatial_dim,
)

__all__ = [
    "BatchKalmanFilter",
    "KalmanFilter",
    "KalmanFilterCV2D",
    "constant_velocity_model",
    "steady_state_covariance",
    "white_noise_acceleration_Q",
]

_LOG_2PI = float(np.log(2.0 * np.pi))


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


# ----------------------------------------------------------------------------------------------------
# shared validation
# ----------------------------------------------------------------------------------------------------
def _model(F, H, Q, R):
    F = as_array(F, "F")
    check_square(F, "F")
    if F.ndim != 2:
        raise ValueError(f"F must have shape (n, n), got {F.shape}")
    n = F.shape[0]
    H = as_array(H, "H", ("m", n))
    m = H.shape[0]
    if m == 0:
        raise ValueError(f"H must have shape (m, {n}) with m >= 1, got {H.shape}")
    Q = as_array(Q, "Q", (n, n))
    check_psd(Q, "Q")
    R = as_array(R, "R", (m, m))
    check_psd(R, "R")
    return F, H, 0.5 * (Q + Q.T), 0.5 * (R + R.T)


# the error for an innovation covariance that is not positive definite: "<_S_NAME> must be positive
# definite; <_S_HINT>"
_S_NAME = "S (innovation covariance H P H^T + R)"
_S_HINT = "use a positive definite R or P"


def _not_pd() -> ValueError:
    return not_positive_definite(_S_NAME, _S_HINT)


def _cholesky_S(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor(s) of innovation covariance(s) ``S (..., m, m)``; ``ValueError`` if not PD."""
    return cholesky(S, _S_NAME, hint=_S_HINT)


_SMALL = 4  # up to this size, Cholesky and solves are unrolled over the matrix axes (vectorised over tracks)


def _batched_cholesky(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack ``S (k, m, m)``; ``ValueError`` if one is not PD."""
    m = S.shape[1]
    if m > _SMALL:
        return _cholesky_S(S)
    L = np.zeros_like(S)
    for j in range(m):
        d = S[:, j, j] - (L[:, j, :j] ** 2).sum(axis=1)
        if not (d > 0).all():
            raise _not_pd()
        L[:, j, j] = np.sqrt(d)
        for i in range(j + 1, m):
            L[:, i, j] = (S[:, i, j] - (L[:, i, :j] * L[:, j, :j]).sum(axis=1)) / L[:, j, j]
    return L


def _batched_cho_solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``(L Lᵀ) X = B`` for stacks ``L (k, m, m)``, ``B (k, m, r)`` by substitution.

    Forward ``L Y = B``, then backward ``Lᵀ X = Y``, vectorised over the stack (and, for
    ``m > _SMALL``, over the already solved rows: one batched product per row).
    """
    m = L.shape[1]
    if m > _SMALL:
        Y = np.empty_like(B)
        for i in range(m):  # forward: L Y = B
            acc = B[:, i, :] - np.matmul(L[:, i, None, :i], Y[:, :i, :])[:, 0, :]
            Y[:, i, :] = acc / L[:, i, i, None]
        X = np.empty_like(B)
        for i in reversed(range(m)):  # backward: Lᵀ X = Y
            acc = Y[:, i, :] - np.matmul(L[:, None, i + 1:, i], X[:, i + 1:, :])[:, 0, :]
            X[:, i, :] = acc / L[:, i, i, None]
        return X
    Y = np.empty_like(B)
    for i in range(m):  # forward: L Y = B
        acc = B[:, i, :].copy()
        for j in range(i):
            acc -= L[:, i, j, None] * Y[:, j, :]
        Y[:, i, :] = acc / L[:, i, i, None]
    X = np.empty_like(B)
    for i in reversed(range(m)):  # backward: Lᵀ X = Y
        acc = Y[:, i, :].copy()
        for j in range(i + 1, m):
            acc -= L[:, j, i, None] * X[:, j, :]
        X[:, i, :] = acc / L[:, i, i, None]
    return X


# OpenBLAS runs a GEMM on several threads once m·n·k exceeds 4·65536; for the thin products here the
# threads buy nothing, and on a loaded machine their busy-waiting slowed the numpy work after each
# call by 2-5x. So the batched filter splits its GEMMs over the track axis into pieces below that.
_GEMM_SINGLE_THREAD_WORK = 200_000


def _gemm_over_columns(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A (r, k) @ B (k, M)`` as GEMMs over blocks of columns small enough to stay single-threaded."""
    r, k = A.shape
    M = B.shape[1]
    step = max(1, _GEMM_SINGLE_THREAD_WORK // max(1, r * k))
    if M <= step:
        return A @ B
    out = np.empty((r, M))
    for s in range(0, M, step):
        np.matmul(A, B[:, s:s + step], out=out[:, s:s + step])
    return out


def _gemm_over_rows(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A (M, k) @ B (k, r)`` as GEMMs over blocks of rows small enough to stay single-threaded."""
    return _gemm_over_columns(B.T, A.T).T


_SIGN2 = np.array([[1.0, -1.0], [-1.0, 1.0]])[:, :, None]


def _spd_inverse_cm(S: np.ndarray, sel) -> tuple[np.ndarray, np.ndarray]:
    """Inverses and log-determinants of a component-major stack ``S (m, m, M)`` of symmetric matrices.

    Only the columns with ``sel`` True (all if ``sel`` is None) must be positive definite
    (``ValueError`` otherwise); the others get a zero inverse and log-determinant 0. For
    ``m <= 3`` closed form: adjugate over determinant, positive definiteness through the leading
    principal minors (Sylvester); larger ``m`` via the batched Cholesky factorisation.
    """
    m, M = S.shape[0], S.shape[2]
    if m > 3:
        idx = slice(None) if sel is None else np.flatnonzero(sel)
        St = np.ascontiguousarray(S.transpose(2, 0, 1)[idx])
        L = _batched_cholesky(St)
        inv = _batched_cho_solve(L, np.broadcast_to(np.eye(m), St.shape).copy())
        Si = np.zeros((m, m, M))
        Si[:, :, idx] = inv.transpose(1, 2, 0)
        logdet = np.zeros(M)
        logdet[idx] = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)
        return Si, logdet
    if m == 1:
        det = S[0, 0]
        minors_ok = det > 0
        adj = np.ones((1, 1, M))
    elif m == 2:
        a, b, d = S[0, 0], S[0, 1], S[1, 1]
        det = a * d
        det -= b * b
        minors_ok = a > 0
        minors_ok &= det > 0
        adj = S[::-1, ::-1] * _SIGN2                                       # [[d, -b], [-b, a]]
    else:
        s00, s01, s02, s11, s12, s22 = S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]
        adj = np.empty((3, 3, M))
        adj[0, 0] = s11 * s22 - s12 * s12
        adj[0, 1] = s02 * s12 - s01 * s22
        adj[0, 2] = s01 * s12 - s02 * s11
        adj[1, 1] = s00 * s22 - s02 * s02
        adj[1, 2] = s01 * s02 - s00 * s12
        adj[2, 2] = s00 * s11 - s01 * s01
        adj[1, 0], adj[2, 0], adj[2, 1] = adj[0, 1], adj[0, 2], adj[1, 2]
        det = s00 * adj[0, 0] + s01 * adj[0, 1] + s02 * adj[0, 2]
        minors_ok = (s00 > 0) & (adj[2, 2] > 0) & (det > 0)
    if sel is not None:
        minors_ok |= ~sel
    if not minors_ok.all():
        raise _not_pd()
    if sel is None:
        inv_det = 1.0 / det
    else:
        det = np.where(sel, det, 1.0)
        inv_det = np.where(sel, 1.0 / det, 0.0)
    adj *= inv_det
    return adj, np.log(det)


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
        self.F, self.H, self.Q, self.R = _model(F, H, Q, R)
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
        return PHt, S, (_cholesky_S(S), True)

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
        self.log_likelihood = -0.5 * (float(y @ w) + logdet + self.dim_z * _LOG_2PI)

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
# batch of independent tracks
# ----------------------------------------------------------------------------------------------------
def _model_property(name: str, doc: str) -> property:
    """Property ``F``/``H``/``Q``/``R`` of :class:`BatchKalmanFilter`.

    Reads give the stored read-only array; an assignment is validated like the constructor's
    argument (same dimensions) and recomputes the model's operators.
    """

    def fget(self):
        return getattr(self, "_" + name)

    def fset(self, value):
        mats = {k: getattr(self, "_" + k) for k in "FHQR"}
        mats[name] = as_array(value, name, mats[name].shape)  # the filter's dimensions are fixed
        self._set_model(*_model(*mats.values()))

    return property(fget, fset, doc=doc + " Read-only array; assign a new one to change the model.")


class BatchKalmanFilter:
    r"""``M`` independent Kalman filters sharing ``(F, H, Q, R)``, stored as stacked arrays.

    Every step is a handful of batched ``matmul``/``solve`` calls over the track axis (no Python
    loop over tracks); the maths is that of :class:`KalmanFilter` track by track. Tracks can be
    added with :meth:`append` and removed with :meth:`keep`, as a multi-object tracker needs.

    Parameters
    ----------
    F, H, Q, R : array_like
        Shapes ``(n, n)``, ``(m, n)``, ``(n, n)``, ``(m, m)`` as for :class:`KalmanFilter`.
    x0 : array_like, shape (M, n)
        Initial means (``M = 0`` is allowed: start empty, :meth:`append` later).
    P0 : array_like, shape (M, n, n) or (n, n)
        Initial covariances; one ``(n, n)`` matrix is shared by all tracks (copied).

    Attributes
    ----------
    F, H, Q, R : ndarray
        The model, as validated (``Q``, ``R`` symmetrised); read-only arrays, since the filter
        precomputes operators from them: assign a new matrix (same shape) to change one.
    x : ndarray, shape (M, n)
    P : ndarray, shape (M, n, n)
    innovation : ndarray, shape (M, m) or None
        Innovations of the last :meth:`update`; NaN rows for tracks that were not updated.
    S : ndarray, shape (M, m, m) or None
        Innovation covariances ``H P⁻ Hᵀ + R`` at the last :meth:`update` (all tracks).
    log_likelihood : ndarray, shape (M,) or None
        Per-track log-likelihood of the last update (0 for tracks not updated). ``innovation``,
        ``S`` and ``log_likelihood`` are reset to ``None`` by :meth:`append`/:meth:`keep`.

    Examples
    --------
    >>> F, H, Q, R = constant_velocity_model(1.0, 0.0, 1.0, dim=1)
    >>> bkf = BatchKalmanFilter(F, H, Q, R, x0=[[0.0, 1.0], [5.0, 0.0]], P0=np.eye(2))
    >>> bkf.predict()
    >>> bkf.x
    array([[1., 1.],
           [5., 0.]])
    >>> bkf.update([[1.0], [9.0]], mask=[True, False])   # second track missed
    >>> bkf.x[1]
    array([5., 0.])
    >>> idx = bkf.append([2.0, 0.0])                      # a third track, P0 = the first P0
    >>> len(bkf), idx
    (3, array([2]))
    >>> bkf.keep([0, 2]); len(bkf)
    2
    """

    def __init__(self, F, H, Q, R, x0, P0):
        F, H, Q, R = _model(F, H, Q, R)
        self.dim_x = n = F.shape[0]
        self.dim_z = H.shape[0]
        iu, ju = np.triu_indices(n)
        self._iu_ju = iu * n + ju                                  # flat index of upper entry (i, j), i <= j
        self._ju_iu = ju * n + iu                                  # ... and of its mirror (j, i)
        pos = np.empty((n, n), dtype=np.intp)
        pos[iu, ju] = np.arange(iu.size)
        pos[ju, iu] = pos[iu, ju]
        self._mirror = pos.ravel()                                 # full entry -> its packed slot
        self._x_cache: np.ndarray | None = None                    # x, P, _hph(): see _state_changed
        self._P_cache: np.ndarray | None = None
        self._hph_cache: tuple[np.ndarray, np.ndarray] | None = None
        self._set_model(F, H, Q, R)
        x0 = as_array(x0, "x0", ("M", n))
        self._P0_default: np.ndarray | None = None
        self._xc = np.ascontiguousarray(x0.T)
        self._Pu = self._pack(self._covariances(P0, "P0", x0.shape[0]))
        self._Pu_spare: np.ndarray | None = None                   # the other buffer of predict
        self._buf: np.ndarray | None = None                        # scratch of update
        self._reset_last()

    def _covariances(self, P0, name: str, M: int) -> np.ndarray:
        n = self.dim_x
        P0 = as_array(P0, name)
        if P0.shape == (n, n):
            check_psd(P0, name)
            P0 = 0.5 * (P0 + P0.T)
            if self._P0_default is None:
                self._P0_default = P0.copy()
            return np.broadcast_to(P0, (M, n, n)).copy()
        if P0.shape != (M, n, n):
            raise ValueError(f"{name} must have shape ({M}, {n}, {n}) or ({n}, {n}), got {P0.shape}")
        if M:
            check_psd(P0, name)
        return 0.5 * (P0 + np.swapaxes(P0, -1, -2))

    def _pack(self, P: np.ndarray) -> np.ndarray:
        """Symmetric ``(k, n, n)`` stack -> packed component-major ``(n(n+1)/2, k)`` (upper triangles)."""
        k, n = P.shape[0], self.dim_x
        return np.ascontiguousarray(P.reshape(k, n * n)[:, self._iu_ju].T)

    def _reset_last(self) -> None:
        self._yc: np.ndarray | None = None
        self._sel = None
        self._Sc: np.ndarray | None = None
        self._y_cache: np.ndarray | None = None
        self._S_cache: np.ndarray | None = None
        self.log_likelihood: np.ndarray | None = None

    def _state_changed(self) -> None:
        """Drop everything derived from the state (``x``, ``P``, ``H P Hᵀ + R``): call after every change."""
        self._x_cache = None
        self._P_cache = None
        self._hph_cache = None

    @property
    def M(self) -> int:
        """Number of tracks."""
        return self._xc.shape[1]

    def __len__(self) -> int:
        return self.M

    # -- public arrays -------------------------------------------------------------------------------
    #
    # Internally the state is component-major (see "Layout" below): ``_xc (n, M)`` and the upper
    # triangles of the covariances packed as ``_Pu (n(n+1)/2, M)``. The usual ``x (M, n)`` and
    # ``P (M, n, n)`` are built on access and cached until the next step or track change; they are
    # copies, so write them back by assignment (``bkf.P = ...``), not by item assignment.
    @property
    def x(self) -> np.ndarray:
        """Means, shape ``(M, n)``."""
        if self._x_cache is None:
            self._x_cache = np.ascontiguousarray(self._xc.T)
            self._x_cache.flags.writeable = False  # an in-place edit would not reach the filter
        return self._x_cache

    @x.setter
    def x(self, value) -> None:
        value = as_array(value, "x", (self.M, self.dim_x))
        self._xc = np.ascontiguousarray(value.T)
        self._state_changed()

    @property
    def P(self) -> np.ndarray:
        """Covariances, shape ``(M, n, n)`` (exactly symmetric)."""
        if self._P_cache is None:
            n = self.dim_x
            self._P_cache = np.ascontiguousarray(self._Pu[self._mirror].T).reshape(self.M, n, n)
            self._P_cache.flags.writeable = False  # assign the whole array instead
        return self._P_cache

    @P.setter
    def P(self, value) -> None:
        n = self.dim_x
        value = as_array(value, "P", (self.M, n, n))
        self._Pu = self._pack(0.5 * (value + np.swapaxes(value, -1, -2)))
        self._state_changed()

    @property
    def innovation(self) -> np.ndarray | None:
        """Innovations of the last :meth:`update`, shape ``(M, m)``; NaN rows for tracks not updated."""
        if self._y_cache is None and self._yc is not None:
            y = np.ascontiguousarray(self._yc.T)
            if self._sel is not None:
                y[~self._sel] = np.nan
            self._y_cache = y
        return self._y_cache

    @property
    def S(self) -> np.ndarray | None:
        """Innovation covariances ``H P⁻ Hᵀ + R`` of the last :meth:`update`, shape ``(M, m, m)``."""
        if self._S_cache is None and self._Sc is not None:
            m = self.dim_z
            self._S_cache = np.ascontiguousarray(self._Sc.reshape(m * m, -1).T).reshape(-1, m, m)
        return self._S_cache

    # -- track management ----------------------------------------------------------------------------
    def append(self, x0, P0=None) -> np.ndarray:
        """Add tracks; return their indices.

        Parameters
        ----------
        x0 : array_like, shape (k, n) or (n,)
            Means of the new tracks.
        P0 : array_like, shape (k, n, n) or (n, n), optional
            Their covariances; default: the ``(n, n)`` ``P0`` given to the constructor (an error
            if there was none).

        Returns
        -------
        indices : ndarray of int, shape (k,)
        """
        n = self.dim_x
        x0 = as_array(x0, "x0")
        if x0.shape == (n,):
            x0 = x0[None, :]
        if x0.ndim != 2 or x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (k, {n}) or ({n},), got {x0.shape}")
        k = x0.shape[0]
        if P0 is None:
            if self._P0_default is None:
                raise ValueError("P0 is required: the constructor was not given a shared (n, n) P0")
            P0 = self._P0_default
        P0 = self._covariances(P0, "P0", k)
        start = self.M
        self._xc = np.concatenate([self._xc, x0.T], axis=1)
        self._Pu = np.concatenate([self._Pu, self._pack(P0)], axis=1)
        self._state_changed()
        self._reset_last()
        return np.arange(start, start + k)

    def keep(self, indices) -> None:
        """Keep only the tracks selected by ``indices`` (int array, in that order, or bool mask (M,))."""
        idx = np.asarray(indices)
        if idx.dtype == bool:
            if idx.shape != (self.M,):
                raise ValueError(f"indices as a mask must have shape ({self.M},), got {idx.shape}")
        elif idx.size == 0:
            idx = np.zeros(0, dtype=int)
        elif not np.issubdtype(idx.dtype, np.integer) or idx.ndim != 1:
            raise ValueError(f"indices must be a 1-D int array or a bool mask of shape ({self.M},)")
        elif idx.min() < -self.M or idx.max() >= self.M:
            raise ValueError(f"indices out of range for {self.M} tracks")
        self._xc = np.ascontiguousarray(self._xc[:, idx])
        self._Pu = np.ascontiguousarray(self._Pu[:, idx])
        self._state_changed()
        self._reset_last()

    # -- steps ---------------------------------------------------------------------------------------
    #
    # Layout. A stack of M tiny matrices (M, 4, 4) is the worst case for numpy: a stacked ``matmul``
    # costs ~100 ns per 4x4 product and elementwise ops with an inner axis of length 4 run far below
    # memory speed. So the state is kept in the *component-major* ("structure of arrays") layout: a
    # ``(k, M)`` array whose row ``r`` is one matrix entry for all tracks; of each symmetric ``P``
    # only the upper triangle is stored (``n(n+1)/2`` rows), so ``P`` is exactly symmetric by
    # construction.
    #   * every product with a shared matrix (F, H) is one GEMM with a Kronecker matrix folded onto
    #     the packed triangle, e.g. vec(F P Fᵀ) = (F ⊗ F) vec(P) (row-major vec), for all tracks;
    #     when H selects entries (each row one 1), P Hᵀ and H P Hᵀ are a row gather instead;
    #   * every per-track product (K y, K S, D Kᵀ) is one broadcast multiply and a sum over the tiny
    #     m axis on contiguous length-M rows;
    #   * S⁻¹ for m <= 3 is closed form (adjugate / determinant, PD checked by leading minors).
    def _set_model(self, F, H, Q, R) -> None:
        """Store the validated model read-only and precompute its operators on the packed layout.

        ``F, H, Q, R`` are read-only (an in-place edit would bypass the operators); assigning one
        (``bkf.Q = ...``) validates it and comes back here.
        """
        for A in (F, H, Q, R):
            A.flags.writeable = False
        self._F, self._H, self._Q, self._R = F, H, Q, R
        n, m = self.dim_x, self.dim_z
        up, lo = self._iu_ju, self._ju_iu
        off = (up != lo)[None, :]

        def fold(A):  # A (r, n²) acting on vec(P) -> (r, n(n+1)/2) acting on the packed P
            return np.ascontiguousarray(A[:, up] + np.where(off, A[:, lo], 0.0))

        FF = np.einsum("ik,jl->ijkl", F, F).reshape(n * n, n * n)          # vec(F P Fᵀ) = FF vec(P)
        IH = np.einsum("ik,jl->ijkl", np.eye(n), H).reshape(n * m, n * n)  # vec(P Hᵀ)
        HH = np.einsum("ik,jl->ijkl", H, H).reshape(m * m, n * n)          # vec(H P Hᵀ)
        G = np.vstack([IH, HH])                  # vec(P) -> [vec(P Hᵀ); vec(H P Hᵀ)], component-major
        # H a selection matrix: every row of G picks one entry of P, a gather of packed rows
        take = None
        if np.array_equal(np.count_nonzero(G, axis=1), np.ones(len(G))) and (G.max(axis=1) == 1).all():
            take = self._mirror[np.argmax(G, axis=1)]
        cols = np.argmax(H, axis=1)
        if not np.array_equal(H, np.eye(n)[cols]):
            cols = None
        self._FFp = fold(FF[up])                           # (n(n+1)/2)² : packed F P Fᵀ
        self._Qu = Q.ravel()[up][:, None].copy()           # packed Q, a column
        self._take = take                                  # packed rows of [P Hᵀ; H P Hᵀ], or None
        self._G = fold(G)                                  # ... else this operator on the packed P
        self._Rcol = R.reshape(m * m, 1).copy()
        self._cols = cols                                  # H x = x[cols] if H selects, else None
        self._state_changed()

    F = _model_property("F", "State transition, shape ``(n, n)``.")
    H = _model_property("H", "Measurement matrix, shape ``(m, n)``.")
    Q = _model_property("Q", "Process noise covariance, shape ``(n, n)``.")
    R = _model_property("R", "Measurement noise covariance, shape ``(m, m)``.")

    def _hph(self):
        """Component-major ``P Hᵀ (n, m, M)`` and ``S = H P Hᵀ + R (m, m, M)`` (exactly symmetric).

        Cached until the state changes (:meth:`_state_changed`): the tracker's gating
        (:meth:`predicted_measurements`) and the :meth:`update` that follows share one build. The
        arrays are shared, so callers must not write into them.
        """
        c = self._hph_cache
        if c is None:
            M, n, m = self.M, self.dim_x, self.dim_z
            take = self._take
            if take is not None:
                Y = self._Pu.take(take, axis=0)
            else:
                Y = _gemm_over_columns(self._G, self._Pu)
            S = Y[n * m:]
            S += self._Rcol
            S = S.reshape(m, m, M)
            if take is None:
                for i in range(m):
                    for j in range(i + 1, m):
                        S[j, i] = S[i, j]
            c = self._hph_cache = (Y[:n * m].reshape(n, m, M), S)
        return c

    def predict(self) -> None:
        r"""Time update of every track: :math:`x_i \leftarrow F x_i`, :math:`P_i \leftarrow F P_i F^\top + Q`.

        One GEMM gives the (packed) upper triangle of every :math:`F P_i F^\top`, so ``P`` stays
        exactly symmetric.
        """
        FFp = self._FFp
        self._xc = _gemm_over_columns(self._F, self._xc)
        Pu, spare = self._Pu, self._Pu_spare
        if spare is None or spare.shape != Pu.shape or Pu.shape[1] * FFp.size > _GEMM_SINGLE_THREAD_WORK:
            spare = _gemm_over_columns(FFp, Pu)
        else:
            np.matmul(FFp, Pu, out=spare)
        spare += self._Qu
        self._Pu, self._Pu_spare = spare, Pu
        self._state_changed()

    def predicted_measurements(self):
        """Predicted measurements and innovation covariances of all tracks, for gating.

        Returns
        -------
        z_pred : ndarray, shape (M, m)
            :math:`H x_i`.
        S : ndarray, shape (M, m, m)
            :math:`H P_i H^\\top + R`.
        """
        M, m = self.M, self.dim_z
        cols = self._cols
        _, S = self._hph()
        z = self._xc[cols] if cols is not None else self._H @ self._xc
        # a copy, always (for M = 1 the transpose is already contiguous): S stays cached for update
        return np.ascontiguousarray(z.T), S.reshape(m * m, M).T.copy().reshape(M, m, m)

    def update(self, Z, mask=None) -> None:
        r"""Joseph-form measurement update of the tracks with ``mask[i]`` True.

        Per track, with :math:`S = HPH^\top + R`: :math:`K = P H^\top S^{-1}`,
        :math:`x \leftarrow x + K y`, and the Joseph form
        :math:`P \leftarrow (I - KH) P (I - KH)^\top + K R K^\top`, evaluated as
        :math:`P + D K^\top + K D^\top` with :math:`D = \tfrac12 K S - P H^\top` (the same
        polynomial in ``K`` expanded, so it keeps the Joseph form's property that an error
        :math:`\delta K` in the gain changes ``P`` only by :math:`\delta K\, S\, \delta K^\top`);
        only the upper triangle is computed and stored, so ``P`` is exactly symmetric.
        :math:`S^{-1}` is closed form for ``m <= 3`` (adjugate over determinant; positive
        definiteness checked through the leading principal minors) and from a Cholesky
        factorisation otherwise. Tracks with ``mask`` False get
        a zero gain, so their ``x`` and (symmetric) ``P`` are left bit-for-bit unchanged.

        Parameters
        ----------
        Z : array_like, shape (M, m)
            One measurement per track; rows with ``mask`` False are ignored and may be NaN.
        mask : array_like of bool, shape (M,), optional
            Which tracks have a measurement (default: all).
        """
        M, n, m = self.M, self.dim_x, self.dim_z
        Z = as_array(Z, "Z", (M, m), allow_nan=True)
        if mask is None:
            sel = None
        else:
            sel = np.asarray(mask)
            if sel.dtype != bool or sel.shape != (M,):
                raise ValueError(f"mask must be a bool array of shape ({M},), got {sel.dtype} {sel.shape}")
            if sel.all():
                sel = None
        cols = self._cols
        PHt, S = self._hph()                                               # (n, m, M), (m, m, M)
        xc = self._xc
        y = Z.T - (xc[cols] if cols is not None else self._H @ xc)         # (m, M), NaN if unmeasured
        if sel is not None:
            y = np.where(sel, y, 0.0)
        if np.isnan(y).any():  # Z is finite or NaN (as_array), x finite: a NaN in a measured row
            raise ValueError("Z contains NaN in a row that is to be updated (mask True)")
        Si, logdet = _spd_inverse_cm(S, sel)                               # (m, m, M), zero if unmeasured
        # K = P Hᵀ S⁻¹, the Joseph factor D = K S / 2 - P Hᵀ, K y, S⁻¹ y: sums over the tiny m axis,
        # unrolled (K, D, D Kᵀ) or one broadcast product and a sum; D Kᵀ in reused scratch buffers
        K = PHt[:, 0, None] * Si[0]                                        # (n, m, M)
        D = np.empty_like(K)
        for k in range(1, m):
            np.multiply(PHt[:, k, None], Si[k], out=D)
            K += D
        np.multiply(K[:, 0, None], S[0], out=D)
        for k in range(1, m):
            D += K[:, k, None] * S[k]
        D *= 0.5
        D -= PHt
        self._xc = xc + (K * y).sum(axis=1)
        # Joseph form (I - KH) P (I - KH)ᵀ + K R Kᵀ = P + D Kᵀ + K Dᵀ  (for any gain K), upper triangle
        buf = self._buf
        if buf is None or buf.shape[1] != n * n * M:
            buf = self._buf = np.empty((2, n * n * M))
        T = buf[0].reshape(n, n, M)                                        # (D Kᵀ)[i, j]
        tmp = buf[1].reshape(n, n, M)
        np.multiply(D[:, None, 0], K[None, :, 0], out=T)
        for k in range(1, m):
            np.multiply(D[:, None, k], K[None, :, k], out=tmp)
            T += tmp
        T = T.reshape(n * n, M)
        Pu = self._Pu
        Pu += T.take(self._iu_ju, axis=0)
        Pu += T.take(self._ju_iu, axis=0)
        quad = (y * (y[:, None] * Si).sum(axis=0)).sum(axis=0)
        ll = quad
        ll += logdet
        ll += m * _LOG_2PI
        ll *= -0.5
        if sel is not None:
            ll[~sel] = 0.0
        self._state_changed()
        self._reset_last()
        self._yc, self._sel, self._Sc, self.log_likelihood = y, sel, S, ll

    def __repr__(self) -> str:
        return f"BatchKalmanFilter(M={self.M}, dim_x={self.dim_x}, dim_z={self.dim_z})"


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
    F, H, Q, R = _model(F, H, Q, R)
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
