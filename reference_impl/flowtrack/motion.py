r"""Rigid motion from scene flow, and a track model that extrapolates it (syllabus sections 5 and 7).

Scene flow enters the tracker twice:

1. **Per cluster, a rigid motion.** A cluster's points :math:`X_i` and their flow :math:`v_i` give the
   displaced points :math:`Y_i = X_i + v_i\,\Delta t`; the rigid motion :math:`(R, t)` with
   :math:`Y_i \approx R X_i + t` is the Kabsch (orthogonal Procrustes) solution
   (:func:`kabsch`, :func:`rigid_motion_from_flow`). The velocity of the cluster's centroid
   :math:`\bar X` is :math:`u = ((R - I)\bar X + t)/\Delta t`, which for the least-squares fit is
   exactly the mean flow; its covariance comes from the flow residuals
   :math:`e_i = v_i - ((R - I)X_i + t)/\Delta t` (:class:`RigidMotion`). A detection then carries
   ``(position, velocity, velocity covariance)``.

2. **A track model that extrapolates rigid motion in the plane of motion**: constant speed plus a
   constant yaw rate :math:`\omega` about the plane's normal :math:`n` (the coordinated-turn model).
   State, in ``dim`` = 3:

   .. math::  x = [p_x, p_y, p_z, v_x, v_y, v_z, \omega]^\top

   (``dim`` = 2: :math:`[p_x, p_y, v_x, v_y, \omega]`, normal = the out-of-plane axis). With
   :math:`K = [n]_\times` (the cross-product matrix, so :math:`K^2 = nn^\top - I` projects on the plane
   with a minus sign) and :math:`\theta = \omega T` the velocity turns about :math:`n` by Rodrigues'
   formula and the position integrates it:

   .. math::
       v' &= \mathrm{Rot}(n, \theta)\, v = (I + \sin\theta\, K + (1 - \cos\theta) K^2)\, v, \\
       p' &= p + \int_0^T \mathrm{Rot}(n, \omega s)\, v\, ds = p + (T I + A K + B K^2)\, v, \qquad
       A = \frac{1 - \cos\theta}{\omega}, \; B = T - \frac{\sin\theta}{\omega}, \\
       \omega' &= \omega .

   The component of :math:`v` along :math:`n` is not turned (:math:`K n = 0`): it moves at constant
   velocity. As :math:`\omega \to 0`, :math:`A \to \omega T^2/2` and :math:`B \to \omega^2 T^3/6`, so the
   model becomes constant velocity. The closed forms lose digits there: :math:`T - \sin\theta/\omega`
   subtracts two nearly equal numbers, with a relative rounding error of about
   :math:`6\epsilon/\theta^2` (:math:`\epsilon = 2.2\cdot 10^{-16}`; 1e-10 at :math:`\theta = 10^{-3}`).
   For :math:`|\theta| <` 0.3 the code therefore evaluates :math:`1 - \cos\theta`, A, B and their
   :math:`\omega`-derivatives by eight terms of their Taylor series in :math:`\theta^2` (truncation
   below 1e-19 relative at :math:`|\theta| = 0.3`) and the closed forms above (rounding below 2e-14
   relative): every coefficient is within 1e-13 of its exact value, relative, for every
   :math:`\theta`, with no :math:`0/0` (tested against 50-digit arithmetic, mpmath). The model is
   nonlinear in :math:`\omega`; :class:`MotionBatchFilter` runs it as an
   extended Kalman filter with the Jacobian :func:`turn_rate_jacobian` (derived in sympy in
   :mod:`flowtrack.symbolic.motion`, checked by finite differences in the tests).

Process noise (:func:`turn_rate_Q`): white acceleration of variance ``q`` on ``(p, v)`` exactly as the
constant-velocity model (:func:`flowtrack.kalman.white_noise_acceleration_Q`), plus a random walk of
the yaw rate, variance ``q_omega * T`` per step.

Examples
--------
A point moving at 1 m/s along x and turning at 1 rad/s about z, a quarter turn ahead:

>>> import numpy as np
>>> x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
>>> np.round(turn_rate_predict(x, np.pi / 2), 6)
array([1., 1., 0., 0., 1., 0., 1.])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validation import as_array, check_psd, nonnegative, positive, spatial_dim
from .kalman import white_noise_acceleration_Q

__all__ = [
    "MotionBatchFilter",
    "RigidMotion",
    "detection_velocity_covariances",
    "kabsch",
    "rigid_motion_from_flow",
    "turn_rate_Q",
    "turn_rate_jacobian",
    "turn_rate_predict",
]

#: |omega T| below this: the Taylor series of 1 - cos, A, B and their derivatives (the closed forms
#: lose about log10(1 / theta^2) digits to cancellation; see the module docstring)
_SERIES = 0.3
_SERIES_TERMS = 8  # powers theta^0 .. theta^14 of the series in theta^2 below: truncation < 1e-19 at 0.3


def _series(theta2: np.ndarray, coefficients) -> np.ndarray:
    """Horner evaluation of sum_k c_k theta^(2k)."""
    out = np.zeros_like(theta2)
    for c in reversed(coefficients):
        out = out * theta2 + c
    return out


def _taylor(sign_offset: int, factorial_of):
    """Coefficients (-1)^k / factorial_of(k) of the series in theta^2, k = 0 .. _SERIES_TERMS - 1."""
    from math import factorial

    return [(-1) ** (k + sign_offset) / factorial(factorial_of(k)) for k in range(_SERIES_TERMS)]


# (1 - cos t) / t^2 = sum (-1)^k t^2k / (2k+2)!     d/dt[(1 - cos t)/t] = sum (-1)^k (2k+1) t^2k / (2k+2)!
# (t - sin t) / t^3 = sum (-1)^k t^2k / (2k+3)!     (sin t - t cos t)/t^3 = sum (-1)^k (2k+2) t^2k / (2k+3)!
_OMC = _taylor(0, lambda k: 2 * k + 2)
_B3 = _taylor(0, lambda k: 2 * k + 3)
_DA = [c * (2 * k + 1) for k, c in enumerate(_OMC)]
_DB = [c * (2 * k + 2) for k, c in enumerate(_B3)]


# ----------------------------------------------------------------------------------------------------
# rigid motion from flow
# ----------------------------------------------------------------------------------------------------
def kabsch(X, Y, weights=None) -> tuple[np.ndarray, np.ndarray]:
    r"""Least-squares rigid motion :math:`(R, t)` with :math:`Y_i \approx R X_i + t` (Kabsch).

    Minimises :math:`\sum_i w_i \|R X_i + t - Y_i\|^2` over rotations :math:`R` (det = +1) and
    translations :math:`t`: with the weighted centroids :math:`\bar X, \bar Y` and the cross-covariance
    :math:`H = \sum_i w_i (X_i - \bar X)(Y_i - \bar Y)^\top = U \Sigma V^\top`,
    :math:`R = V\,\mathrm{diag}(1, \dots, 1, \det(VU^\top))\,U^\top` and :math:`t = \bar Y - R\bar X`.

    Parameters
    ----------
    X, Y : array_like, shape (N, D)
        Corresponding points, D = 2 or 3, N >= 1 (N >= D for a unique rotation).
    weights : array_like, shape (N,), optional
        Non-negative weights with a positive sum (default: all 1).

    Returns
    -------
    R : numpy.ndarray, shape (D, D)
    t : numpy.ndarray, shape (D,)

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> R, t = kabsch(X, X @ Rz.T + [1.0, 2.0, 3.0])
    >>> np.allclose(R, Rz), np.round(t, 12).tolist()
    (True, [1.0, 2.0, 3.0])
    """
    X = as_array(X, "X", ("N", None), min_rows=1)
    D = X.shape[1]
    if D not in (2, 3):
        raise ValueError(f"X must have shape (N, 2) or (N, 3), got {X.shape}")
    Y = as_array(Y, "Y", X.shape)
    if weights is None:
        w = np.ones(len(X))
    else:
        w = as_array(weights, "weights", (len(X),))
        if (w < 0).any() or w.sum() <= 0:
            raise ValueError("weights must be non-negative with a positive sum")
    w = w / w.sum()
    mx, my = w @ X, w @ Y
    Hm = (X - mx).T @ ((Y - my) * w[:, None])
    U, _, Vt = np.linalg.svd(Hm)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    Dg = np.eye(D)
    Dg[-1, -1] = d
    R = Vt.T @ Dg @ U.T
    return R, my - R @ mx


def _rotation_vector(R: np.ndarray) -> np.ndarray:
    """Axis-angle vector of a 3x3 rotation (log map), stable near 0 and pi."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


@dataclass(frozen=True)
class RigidMotion:
    r"""The rigid motion of one cluster over one frame interval, fitted to its flow.

    Attributes
    ----------
    R : numpy.ndarray, shape (D, D)
        Rotation over ``dt`` (:math:`Y \approx R X + t`).
    t : numpy.ndarray, shape (D,)
    dt : float
    centroid : numpy.ndarray, shape (D,)
        :math:`\bar X`, the mean of the cluster's points.
    velocity : numpy.ndarray, shape (D,)
        Velocity of the centroid, :math:`((R - I)\bar X + t)/\Delta t` (= the mean flow).
    angular_velocity : numpy.ndarray, shape (3,) or (1,)
        Rotation vector of :math:`R` divided by ``dt`` (rad/s); in 2-D the signed rate about the
        out-of-plane axis.
    velocity_cov : numpy.ndarray, shape (D, D)
        Covariance of :attr:`velocity`: the residual covariance
        :math:`\Sigma_e = \frac{1}{n - p/D}\sum_i e_i e_i^\top` (``p`` = 6 in 3-D, 3 in 2-D parameters
        fitted, i.e. p/D degrees of freedom per axis) divided by the effective number of independent flow
        vectors
        :math:`n_\mathrm{eff} = \min(n, n_\mathrm{max})` (neighbouring flow vectors of a smoothed field
        are correlated, so the :math:`1/n` of independent residuals would be overconfident), plus
        ``min_std**2 I``, plus the error shared by the whole cluster
        :math:`\alpha^2\, u u^\top` (``speed_fraction`` :math:`\alpha`, see
        :func:`rigid_motion_from_flow`).
    residual_rms : float
        Root mean square of the flow residuals :math:`\|e_i\|` (m/s).
    n_points : int
    """

    R: np.ndarray
    t: np.ndarray
    dt: float
    centroid: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    velocity_cov: np.ndarray
    residual_rms: float
    n_points: int

    def velocity_at(self, point) -> np.ndarray:
        """Velocity of the rigid motion at ``point`` (D,): :math:`((R - I)p + t)/\\Delta t`."""
        p = as_array(point, "point", (self.R.shape[0],))
        return ((self.R - np.eye(len(p))) @ p + self.t) / self.dt

    def yaw_rate(self, axis) -> float:
        """Angular velocity about the unit vector ``axis`` (3-D; ignored in 2-D), rad/s."""
        if self.R.shape[0] == 2:
            return float(self.angular_velocity[0])
        n = _unit(axis, "axis")
        return float(self.angular_velocity @ n)


def rigid_motion_from_flow(points, flow, dt, *, max_effective_points=25, min_std=0.002,
                           rotation_spread=False, speed_fraction=0.0) -> RigidMotion:
    r"""Fit the rigid motion of one cluster to its flow: Kabsch on :math:`X` and :math:`X + v\,\Delta t`.

    Parameters
    ----------
    points : array_like, shape (n, D)
        The cluster's points at time t (D = 2 or 3), n >= D + 1.
    flow : array_like, shape (n, D)
        Their velocities (m/s).
    dt : float, > 0
    max_effective_points : int, >= 1
        :math:`n_\mathrm{max}` of :attr:`RigidMotion.velocity_cov`.
    min_std : float, >= 0
        Floor of the velocity standard deviation per axis (m/s), so that an exactly rigid flow
        (e.g. already projected on a rigid motion) still gets a positive-definite covariance.
    rotation_spread : bool
        Add the spread of the rigid velocity over the cluster,
        :math:`\mathrm{Cov}_i[\Omega (X_i - \bar X)] = \Omega\,\mathrm{Cov}(X)\,\Omega^\top`
        (:math:`\Omega = [\omega]_\times`, in 2-D the 90° rotation times :math:`\omega`): for a
        track that follows the centroid of the *visible* surface, which is not a fixed body point,
        so a spinning object's flow at the centroid is not its velocity.
    speed_fraction : float, >= 0
        :math:`\alpha`: add :math:`\alpha^2\, u u^\top` (:math:`u` the fitted velocity), an error of
        standard deviation :math:`\alpha\lVert u\rVert` along the motion *shared by every point of the
        cluster*. The residuals measure how the flow scatters about one rigid motion; they cannot
        see an error common to all points, and the flow of geometric correspondences (nearest
        neighbours, ICP, graph flow) has one: a surface sliding along itself looks still, so such a
        flow sees the motion along the surfaces' normals and loses part of the motion along the
        surfaces, for the whole cluster alike. The loss grows with the motion, hence a fraction of
        the speed. 0 (the default) leaves it out: the covariance then describes the flow's noise
        only, and is overconfident for such flows (lesson 6 §5b measures it).

    Returns
    -------
    RigidMotion

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(50, 3))
    >>> v = np.cross([0.0, 0.0, 0.5], X) + [0.1, 0.0, 0.0]     # 0.5 rad/s about z, 0.1 m/s along x
    >>> m = rigid_motion_from_flow(X, v, 1e-4)
    >>> np.round(m.angular_velocity, 4).tolist(), bool(np.allclose(m.velocity, v.mean(0)))
    ([0.0, 0.0, 0.5], True)
    """
    X = as_array(points, "points", ("n", None))
    D = X.shape[1]
    if D not in (2, 3):
        raise ValueError(f"points must have shape (n, 2) or (n, 3), got {X.shape}")
    if len(X) < D + 1:
        raise ValueError(f"points must have at least {D + 1} rows for a rigid fit, got {len(X)}")
    V = as_array(flow, "flow", X.shape)
    dt = positive(dt, "dt")
    n_max = int(max_effective_points)
    if n_max < 1:
        raise ValueError(f"max_effective_points must be >= 1, got {max_effective_points}")
    min_std = nonnegative(min_std, "min_std")
    speed_fraction = nonnegative(speed_fraction, "speed_fraction")
    R, t = kabsch(X, X + V * dt)
    c = X.mean(axis=0)
    u = ((R - np.eye(D)) @ c + t) / dt
    E = V - ((X @ (R - np.eye(D)).T) + t) / dt
    n = len(X)
    n_par = 6 if D == 3 else 3
    Se = E.T @ E / max(n - n_par / D, 1)  # the fit's n_par parameters take n_par / D dof per axis
    cov = Se / min(n, n_max) + min_std**2 * np.eye(D) + speed_fraction**2 * np.outer(u, u)
    if D == 3:
        w = _rotation_vector(R) / dt
    else:
        w = np.array([np.arctan2(R[1, 0], R[0, 0]) / dt])
    if rotation_spread:
        Om = _cross_matrix(w) if D == 3 else w[0] * _cross_matrix(np.zeros(2))
        cov = cov + Om @ np.cov(X.T, bias=True) @ Om.T
    return RigidMotion(R, t, dt, c, u, w, 0.5 * (cov + cov.T), float(np.sqrt((E**2).sum(1).mean())), n)


def detection_velocity_covariances(points, clusters, flow, detections, dt, **options) -> np.ndarray:
    r"""Velocity covariance of each detection, from the flow residuals of its motion cluster.

    Each detection (e.g. a centroid from :func:`flowtrack_course.demo.detect_objects`) belongs to the
    cluster of its nearest clustered point (label >= 0); that cluster's rigid motion is fitted to
    ``flow`` (:func:`rigid_motion_from_flow`) and its :attr:`RigidMotion.velocity_cov` is the
    detection's. Pass the *raw* estimated flow (e.g. graph flow with re-matching), not a flow already
    projected on one rigid motion per cluster, whose residuals are zero by construction.

    Parameters
    ----------
    points : array_like, shape (N, D)
    clusters : array_like of int, shape (N,)
        Motion-cluster labels, -1 = static.
    flow : array_like, shape (N, D)
    detections : array_like, shape (K, D)
    dt : float, > 0
    **options
        Passed to :func:`rigid_motion_from_flow` (``max_effective_points``, ``min_std``,
        ``speed_fraction``: without it the covariance describes the flow's scatter about the rigid
        motion only, not the error the whole cluster shares).

    Returns
    -------
    numpy.ndarray, shape (K, D, D)
        A detection whose cluster is too small for a fit (or with no clustered point at all) gets NaN.
    """
    from scipy.spatial import cKDTree

    X = as_array(points, "points", ("N", None))
    D = X.shape[1]
    lab = np.asarray(clusters)
    if lab.shape != (len(X),) or not np.issubdtype(lab.dtype, np.integer):
        raise ValueError(f"clusters must be an int array of shape ({len(X)},), got {lab.dtype} {lab.shape}")
    V = as_array(flow, "flow", X.shape)
    Z = as_array(detections, "detections", ("K", D))
    dt = positive(dt, "dt")
    out = np.full((len(Z), D, D), np.nan)
    on = np.flatnonzero(lab >= 0)
    if len(Z) == 0 or len(on) == 0:
        return out
    _, nn = cKDTree(X[on]).query(Z)
    fits: dict[int, np.ndarray] = {}
    for k, idx in enumerate(nn.tolist()):
        c = int(lab[on[idx]])
        if c not in fits:
            m = lab == c
            fits[c] = (rigid_motion_from_flow(X[m], V[m], dt, **options).velocity_cov if m.sum() > D
                       else np.full((D, D), np.nan))
        out[k] = fits[c]
    return out


# ----------------------------------------------------------------------------------------------------
# the turn-rate (coordinated turn) model
# ----------------------------------------------------------------------------------------------------
def _unit(axis, name: str) -> np.ndarray:
    n = as_array(axis, name, (3,))
    nn = np.linalg.norm(n)
    if nn == 0:
        raise ValueError(f"{name} must be a non-zero vector, got {n.tolist()}")
    return n / nn


def _cross_matrix(n: np.ndarray) -> np.ndarray:
    if n.shape == (2,):  # 2-D: the out-of-plane axis, K = [[0, -1], [1, 0]]
        return np.array([[0.0, -1.0], [1.0, 0.0]])
    return np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])


def _coefficients(w: np.ndarray, T: float):
    """sin θ, 1 - cos θ, A, B and dA/dω, dB/dω for θ = ω T (arrays over tracks), series near 0."""
    th = w * T
    small = np.abs(th) < _SERIES
    ws = np.where(small, 1.0, w)  # avoids 0/0 in the branch not taken
    s, omc = np.sin(th), 1.0 - np.cos(th)
    t2 = np.where(small, th * th, 0.0)
    omc_t2 = _series(t2, _OMC)  # (1 - cos θ) / θ²
    omc = np.where(small, th * th * omc_t2, omc)
    A = np.where(small, T * th * omc_t2, omc / ws)  # T (1 - cos θ) / θ
    B = np.where(small, T * th * th * _series(t2, _B3), T - s / ws)  # T (θ - sin θ) / θ
    dA = np.where(small, T * T * _series(t2, _DA), (T * s * ws - omc) / ws**2)
    dB = np.where(small, T * T * th * _series(t2, _DB), (s - T * ws * np.cos(th)) / ws**2)
    return s, omc, A, B, dA, dB


def _split(x: np.ndarray):
    d = (x.shape[-1] - 1) // 2
    return d, x[..., :d], x[..., d : 2 * d], x[..., 2 * d]


def _axis_for(d: int, axis) -> np.ndarray:
    if d == 2:
        return np.zeros(2)  # placeholder: _cross_matrix gives the planar generator
    return _unit((0.0, 0.0, 1.0) if axis is None else axis, "axis")


def turn_rate_predict(x, T, axis=None) -> np.ndarray:
    r"""Predict turn-rate states ``T`` seconds ahead (see the module docstring for the model).

    Parameters
    ----------
    x : array_like, shape (n,) or (M, n)
        States ``[p (d), v (d), omega]``, n = 2d + 1, d = 2 or 3.
    T : float, >= 0
        Horizon in seconds.
    axis : array_like, shape (3,), optional
        Normal :math:`n` of the plane of motion (3-D; default z). Ignored in 2-D.

    Returns
    -------
    numpy.ndarray, shape like ``x``
    """
    x = as_array(x, "x")
    if x.ndim not in (1, 2) or x.shape[-1] not in (5, 7):
        raise ValueError(f"x must have shape (5,), (7,), (M, 5) or (M, 7), got {x.shape}")
    T = nonnegative(T, "T")
    X = np.atleast_2d(x)
    d, p, v, w = _split(X)
    K = _cross_matrix(_axis_for(d, axis))
    K2 = K @ K
    s, omc, A, B, _, _ = _coefficients(w, T)
    Kv, K2v = v @ K.T, v @ K2.T
    out = np.empty_like(X)
    out[:, :d] = p + T * v + A[:, None] * Kv + B[:, None] * K2v
    out[:, d : 2 * d] = v + s[:, None] * Kv + omc[:, None] * K2v
    out[:, 2 * d] = w
    return out if x.ndim == 2 else out[0]


def turn_rate_jacobian(x, T, axis=None) -> np.ndarray:
    r"""Jacobian :math:`\partial f/\partial x` of :func:`turn_rate_predict`, shape (n, n) or (M, n, n).

    .. math::
        \frac{\partial p'}{\partial (p, v, \omega)} = [I,\; TI + AK + BK^2,\; (A'K + B'K^2) v], \quad
        \frac{\partial v'}{\partial (p, v, \omega)} = [0,\; \mathrm{Rot}(n,\theta),\;
        T(\cos\theta\, K + \sin\theta\, K^2) v], \quad
        \frac{\partial \omega'}{\partial x} = e_\omega^\top,

    with :math:`A' = (\omega T \sin\theta - (1 - \cos\theta))/\omega^2`,
    :math:`B' = (\sin\theta - \omega T\cos\theta)/\omega^2` (series near :math:`\omega = 0`:
    :math:`A' \to T^2/2`, :math:`B' \to \omega T^3/3`). Derived in
    :func:`flowtrack.symbolic.motion.turn_rate_model`.
    """
    x = as_array(x, "x")
    if x.ndim not in (1, 2) or x.shape[-1] not in (5, 7):
        raise ValueError(f"x must have shape (5,), (7,), (M, 5) or (M, 7), got {x.shape}")
    T = nonnegative(T, "T")
    X = np.atleast_2d(x)
    d, _, v, w = _split(X)
    n = 2 * d + 1
    K = _cross_matrix(_axis_for(d, axis))
    K2 = K @ K
    s, omc, A, B, dA, dB = _coefficients(w, T)
    c = np.cos(w * T)
    Kv, K2v = v @ K.T, v @ K2.T
    I = np.eye(d)
    J = np.zeros((len(X), n, n))
    J[:, :d, :d] = I
    J[:, :d, d : 2 * d] = T * I + A[:, None, None] * K + B[:, None, None] * K2
    J[:, :d, 2 * d] = dA[:, None] * Kv + dB[:, None] * K2v
    J[:, d : 2 * d, d : 2 * d] = I + s[:, None, None] * K + omc[:, None, None] * K2
    J[:, d : 2 * d, 2 * d] = T * (c[:, None] * Kv + s[:, None] * K2v)
    J[:, 2 * d, 2 * d] = 1.0
    return J if x.ndim == 2 else J[0]


def turn_rate_Q(T, q, q_omega, dim=3) -> np.ndarray:
    r"""Process noise of the turn-rate model: ``blockdiag(white_noise_acceleration_Q(T, q, dim), q_omega T)``.

    Parameters
    ----------
    T : float, > 0
    q : float, >= 0
        Acceleration variance ((m/s²)²), as in :func:`flowtrack.kalman.white_noise_acceleration_Q`.
    q_omega : float, >= 0
        Yaw-acceleration spectral density ((rad/s)²/s): the yaw rate's variance grows by
        ``q_omega * T`` per step.
    dim : int
        2 or 3.

    Returns
    -------
    numpy.ndarray, shape (2 dim + 1, 2 dim + 1)
    """
    dim = spatial_dim(dim, "dim")
    T = positive(T, "T")
    Q = np.zeros((2 * dim + 1, 2 * dim + 1))
    Q[: 2 * dim, : 2 * dim] = white_noise_acceleration_Q(T, q, dim)
    Q[2 * dim, 2 * dim] = nonnegative(q_omega, "q_omega") * T
    return Q


# ----------------------------------------------------------------------------------------------------
# a batched (extended) Kalman filter with optional velocity measurements
# ----------------------------------------------------------------------------------------------------
def _joseph(x, P, H, R, z):
    """Joseph-form update of a batch (G, n) / (G, n, n) with H (G, m, n) or (m, n), R (G, m, m), z (G, m)."""
    Ht = np.swapaxes(H, -1, -2)
    PHt = P @ Ht
    S = H @ PHt + R
    S = 0.5 * (S + np.swapaxes(S, -1, -2))
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)  # P H^T S^-1 (S symmetric)
    nu = z - np.einsum("...mn,...n->...m", H, x) if H.ndim == 3 else z - x @ H.T
    x = x + np.einsum("gnm,gm->gn", K, nu)
    IKH = np.eye(P.shape[-1]) - K @ H
    P = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    return x, 0.5 * (P + np.swapaxes(P, -1, -2))


class MotionBatchFilter:
    r"""Kalman filter for M tracks with position and (optionally) velocity measurements.

    Model ``"cv"``: the constant-velocity model of :func:`flowtrack.kalman.constant_velocity_model`
    (state ``[p, v]``, n = 2 dim). Model ``"turn_rate"``: the coordinated-turn model of this module
    (state ``[p, v, omega]``, n = 2 dim + 1) as an extended Kalman filter,
    :math:`\hat x \leftarrow f(\hat x)`, :math:`P \leftarrow J P J^\top + Q` with
    :math:`J = \partial f/\partial x` at the prior mean.

    Measurements are linear: a position :math:`z = H_p x + r`, :math:`H_p = [I_d\; 0]`, covariance
    ``R``; and, for detections that carry one, a velocity :math:`z_v = H_v x + r_v`,
    :math:`H_v = [0\; I_d\; 0]`, covariance ``Rv`` (per detection). A track with both is updated with
    the stacked :math:`H = [H_p; H_v]`, :math:`R = \mathrm{blockdiag}(R, R_v)` in Joseph form
    :math:`P^+ = (I - KH)P(I - KH)^\top + KRK^\top`; one without a velocity with :math:`H_p, R` alone.

    It has the interface of :class:`flowtrack.kalman.BatchKalmanFilter` that
    :class:`flowtrack.tracking.MultiObjectTracker` uses (``predict``, ``predicted_measurements``,
    ``update(Z, mask)``, ``append``, ``keep``, ``x``, ``P``, ``dim_z``, ``len``), plus
    :meth:`update_joint` and :meth:`predicted`.

    Parameters
    ----------
    dt : float, > 0
    q : float, >= 0
        Acceleration variance.
    R : array_like, shape (dim, dim)
        Position measurement covariance.
    dim : int
        2 or 3.
    model : {"cv", "turn_rate"}
    q_omega : float, >= 0
        Yaw-rate random walk of the turn-rate model (see :func:`turn_rate_Q`).
    axis : array_like, shape (3,), optional
        Normal of the plane of motion for ``"turn_rate"`` in 3-D (default z).
    """

    def __init__(self, dt, q, R, dim=3, model="cv", q_omega=1.0, axis=None):
        from .kalman import constant_velocity_model

        self.dt = positive(dt, "dt")
        self.dim = spatial_dim(dim, "dim")
        if model not in ("cv", "turn_rate"):
            raise ValueError(f"model must be 'cv' or 'turn_rate', got {model!r}")
        self.model = model
        d = self.dim
        F, _, Q, Rm = constant_velocity_model(self.dt, q, R, d)
        self.R = Rm
        self.axis = None
        if model == "turn_rate" and d == 3:
            self.axis = _unit((0.0, 0.0, 1.0) if axis is None else axis, "axis")
        if model == "cv":
            self.F, self.Q = F, Q
            self.n = 2 * d
        else:
            if d not in (2, 3):
                raise ValueError(f"the turn-rate model needs dim 2 or 3, got {d}")
            self.F = None
            self.Q = turn_rate_Q(self.dt, q, q_omega, d)
            self.n = 2 * d + 1
        self.H = np.zeros((d, self.n))
        self.H[:, :d] = np.eye(d)
        self.Hv = np.zeros((2 * d, self.n))
        self.Hv[:, : 2 * d] = np.eye(2 * d)
        self.dim_z = d
        self.x = np.zeros((0, self.n))
        self.P = np.zeros((0, self.n, self.n))

    def __len__(self) -> int:
        return self.x.shape[0]

    def transition(self, x: np.ndarray, T: float | None = None):
        """``(f(x), J)`` over ``T`` seconds (default ``dt``) for states (M, n)."""
        T = self.dt if T is None else T
        if self.model == "cv":
            from .kalman import constant_velocity_model

            F = self.F if T == self.dt else constant_velocity_model(T, 0.0, self.R, self.dim)[0]
            return x @ F.T, np.broadcast_to(F, (len(x), self.n, self.n))
        return turn_rate_predict(x, T, self.axis), turn_rate_jacobian(x, T, self.axis)

    def predict(self) -> None:
        """One time update of every track."""
        if len(self) == 0:
            return
        self.x, J = self.transition(self.x)
        P = J @ self.P @ np.swapaxes(J, -1, -2) + self.Q
        self.P = 0.5 * (P + np.swapaxes(P, -1, -2))

    def predicted(self, steps: int):
        """Prior ``(x (M, n), P (M, n, n))`` ``steps`` frames ahead, without changing the filter."""
        x, P = self.x.copy(), self.P.copy()
        for _ in range(int(steps)):
            if len(x) == 0:
                break
            x, J = self.transition(x)
            P = J @ P @ np.swapaxes(J, -1, -2) + self.Q
        return x, P

    def predicted_measurements(self):
        """``z_pred = H_p x`` (M, d) and ``S = H_p P H_p^T + R`` (M, d, d)."""
        d = self.dim
        return self.x[:, :d].copy(), self.P[:, :d, :d] + self.R

    def joint_innovation(self, Z, V=None, Rv=None, Rp=None):
        r"""Innovations and their covariances of every (track, detection) pair.

        Returns ``nu (M, N, m)``, ``S (M, N, m, m)`` and ``m (N,)``: for a detection with a velocity
        (finite row of ``V`` and ``Rv``) :math:`\nu = [z - \hat p;\; z_v - \hat v]`,
        :math:`S = H P H^\top + \mathrm{blockdiag}(R, R_v)` with m = 2d; otherwise the position part
        (m = d) padded with zeros and an identity block so that all pairs share one array shape.
        """
        d = self.dim
        Z = np.asarray(Z, dtype=float)
        M, N = len(self), len(Z)
        has_v = _has_velocity(V, Rv, N)
        nu = np.zeros((M, N, 2 * d))
        S = np.zeros((M, N, 2 * d, 2 * d))
        nu[:, :, :d] = Z[None] - self.x[:, None, :d]
        PHt = self.P[:, :, : 2 * d]  # P Hv^T (M, n, 2d)
        Sfull = PHt[:, : 2 * d, :]  # Hv P Hv^T (M, 2d, 2d)
        S[:] = Sfull[:, None]
        S[:, :, :d, :d] += self.R if Rp is None else Rp[None]
        if has_v.any():
            nu[:, has_v, d:] = V[None, has_v] - self.x[:, None, d : 2 * d]
            S[:, has_v, d:, d:] += Rv[has_v][None]
        no = ~has_v
        S[:, no, :d, d:] = 0.0
        S[:, no, d:, :d] = 0.0
        S[:, no, d:, d:] = np.eye(d)
        return nu, S, np.where(has_v, 2 * d, d)

    def update(self, Z, mask=None) -> None:
        """Position-only update of the tracks in ``mask`` with rows of ``Z`` (M, d)."""
        M = len(self)
        mask = np.ones(M, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        self.update_joint(Z, None, None, mask)

    def update_joint(self, Z, V=None, Rv=None, mask=None, Rp=None) -> None:
        """Update track i (``mask[i]``) with ``Z[i]`` and, where ``V[i]`` and ``Rv[i]`` are finite, ``V[i]``.

        ``Z`` (M, d); ``V`` (M, d) or None; ``Rv`` (M, d, d) or None (rows of NaN = no velocity).
        """
        M, d = len(self), self.dim
        if M == 0:
            return
        mask = np.ones(M, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        Z = np.asarray(Z, dtype=float)
        has_v = _has_velocity(V, Rv, M) & mask
        pos = mask & ~has_v
        if pos.any():
            g = np.flatnonzero(pos)
            Rg = np.broadcast_to(self.R, (len(g), d, d)) if Rp is None else Rp[g]
            self.x[g], self.P[g] = _joseph(self.x[g], self.P[g], self.H, Rg, Z[g])
        if has_v.any():
            g = np.flatnonzero(has_v)
            Rg = np.zeros((len(g), 2 * d, 2 * d))
            Rg[:, :d, :d] = self.R if Rp is None else Rp[g]
            Rg[:, d:, d:] = Rv[g]
            zg = np.concatenate([Z[g], V[g]], axis=1)
            self.x[g], self.P[g] = _joseph(self.x[g], self.P[g], self.Hv, Rg, zg)

    def append(self, x0, P0) -> None:
        """Add tracks with states ``x0 (k, n)`` and covariances ``P0 (k, n, n)``."""
        x0 = np.asarray(x0, dtype=float).reshape(-1, self.n)
        P0 = np.asarray(P0, dtype=float).reshape(-1, self.n, self.n)
        self.x = np.concatenate([self.x, x0])
        self.P = np.concatenate([self.P, P0])

    def keep(self, keep) -> None:
        """Keep the tracks of the bool mask or index array ``keep``."""
        self.x = self.x[keep]
        self.P = self.P[keep]

    def __repr__(self) -> str:
        return f"MotionBatchFilter(model={self.model!r}, dim={self.dim}, M={len(self)})"


def _has_velocity(V, Rv, N: int) -> np.ndarray:
    if V is None or Rv is None:
        return np.zeros(N, dtype=bool)
    V = np.asarray(V, dtype=float)
    Rv = np.asarray(Rv, dtype=float)
    return np.isfinite(V).all(axis=1) & np.isfinite(Rv).all(axis=(1, 2))


def check_velocity_covs(Rv, N: int, d: int, name: str = "velocity_covs") -> np.ndarray:
    """Validate per-detection velocity covariances (N, d, d): symmetric PSD rows, NaN rows = none."""
    Rv = as_array(Rv, name, (N, d, d), allow_nan=True)
    ok = np.isfinite(Rv).all(axis=(1, 2))
    if ok.any():
        check_psd(Rv[ok], name, strict=True)
    return Rv
