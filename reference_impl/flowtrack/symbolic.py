r"""Symbolic (sympy) derivations of the lesson's formulas.

Every derivation is a function returning sympy objects, built from first principles (differentiate,
integrate, minimise, complete the square), never by typing in the answer. Each has a numeric
counterpart (``*_numeric``) obtained with :func:`sympy.lambdify` from the *derived* expression, so
tests and lessons can compare the derivation with the numerical reference implementation.

- :func:`projection_jacobian` — :math:`\partial\pi/\partial X` of the pinhole projection (§2, Problem 1);
- :func:`euler_lagrange_scene_flow` — :math:`2\Delta t(a + v\Delta t - b) - 2\lambda\Delta v = 0`
  (§3, Problem 2);
- :func:`white_noise_acceleration_Q` — process noise of the constant-velocity model, discrete and
  continuous white-noise acceleration, :math:`Q_{1D} \otimes I_d` for the state ``[p, v]`` (§6);
- :func:`kalman_gain` — :math:`K = PH^\top(HPH^\top + R)^{-1}` as the minimiser of
  :math:`\operatorname{tr} P^+` (§6);
- :func:`kalman_posterior` — Gaussian prior × Gaussian likelihood is Gaussian, with the Kalman
  update's mean and variance (Problem 3);
- :func:`steady_state_variance_scalar` — the positive root of the scalar Riccati equation (§11.2);
- :func:`graph_normal_equations` — :math:`(\Delta t^2 I + \lambda L\otimes I_3)\mathbf v
  = \Delta t\operatorname{vec}(Y - X)` from the gradient of the graph energy (§4, lesson 3), and
  :func:`commutation_matrix` — :math:`\Pi(A\otimes B)\Pi^\top = B\otimes A`, which splits it into
  three :math:`N\times N` systems and relates :math:`Q_{1D}\otimes I_d` to
  :math:`\operatorname{blkdiag}(Q_{1D},\dots)` (:func:`process_noise_orderings`, lessons 4 and 7);
- :func:`rigid_mean_velocity` — the mean velocity of a rigid cluster is the velocity of the body
  point at its centroid (Problem 5, lesson 6);
- :func:`affinity_threshold` — :math:`e^{-\lVert\Delta v\rVert^2/\sigma_v^2} = e^{-m}` at
  :math:`\lVert\Delta v\rVert = \sqrt m\,\sigma_v` (lesson 6);
- :func:`normalized_cut` — :math:`\mathrm{Ncut}(A,B) = y^\top Ly/y^\top Dy` for the two-valued
  indicator (Problem 5);
- :func:`chi2_distribution` — the squared Mahalanobis distance of a Gaussian innovation is
  :math:`\chi^2_m`: CDF, mean m, variance 2m (§7, lesson 5), and the gate that inverts it;
- :func:`assignment_constraints` — the assignment problem's constraint matrix, totally unimodular
  (:func:`is_totally_unimodular`), so its LP relaxation (:func:`assignment_lp_numeric`) is integral
  (Problem 4).
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np
import sympy as sp
from sympy.calculus.euler import euler_equations

from ._validation import as_array, check_psd, nonnegative, positive, positive_int, probability

__all__ = [
    "ChiSquare",
    "GraphNormalEquations",
    "NormalizedCut",
    "RigidMeanVelocity",
    "affinity_threshold",
    "affinity_threshold_numeric",
    "assignment_constraints",
    "assignment_count",
    "assignment_lp_numeric",
    "chi2_cdf_numeric",
    "chi2_distribution",
    "chi2_gate_closed_form",
    "chi2_gate_numeric",
    "commutation_matrix",
    "euler_lagrange_scene_flow",
    "graph_normal_equations",
    "graph_normal_equations_numeric",
    "is_totally_unimodular",
    "kalman_gain",
    "kalman_gain_closed_form",
    "kalman_gain_numeric",
    "kalman_matrices",
    "kalman_posterior",
    "kalman_posterior_numeric",
    "normalized_cut",
    "normalized_cut_numeric",
    "process_noise_orderings",
    "projection_jacobian",
    "projection_jacobian_numeric",
    "projection_symbols",
    "rigid_mean_velocity",
    "rigid_mean_velocity_numeric",
    "rigid_twist_mean_velocity_numeric",
    "scene_flow_lagrangian",
    "steady_state_variance_scalar",
    "steady_state_variance_scalar_numeric",
    "white_noise_acceleration_Q",
    "white_noise_acceleration_Q_numeric",
]


# --------------------------------------------------------------------------------------------------
# §2 / Problem 1: projection Jacobian
# --------------------------------------------------------------------------------------------------
def projection_symbols() -> tuple[sp.Symbol, ...]:
    """The symbols ``(X, Y, Z, fx, fy, cx, cy)`` used by :func:`projection_jacobian` (real; Z, fx, fy > 0)."""
    X, Y, cx, cy = sp.symbols("X Y c_x c_y", real=True)
    Z, fx, fy = sp.symbols("Z f_x f_y", positive=True)
    return X, Y, Z, fx, fy, cx, cy


def projection_jacobian() -> sp.Matrix:
    r"""Jacobian of the pinhole projection, derived by differentiation.

    .. math::

       \pi(X) = \begin{bmatrix} f_x X/Z + c_x \\ f_y Y/Z + c_y \end{bmatrix}, \qquad
       \frac{\partial\pi}{\partial X} =
       \begin{bmatrix} f_x/Z & 0 & -f_x X/Z^2 \\ 0 & f_y/Z & -f_y Y/Z^2 \end{bmatrix}.

    Returns
    -------
    sympy.Matrix, shape (2, 3)
        ``pi.jacobian([X, Y, Z])`` in the symbols of :func:`projection_symbols`.

    Examples
    --------
    >>> J = projection_jacobian()
    >>> J
    Matrix([
    [f_x/Z,     0, -X*f_x/Z**2],
    [    0, f_y/Z, -Y*f_y/Z**2]])
    """
    X, Y, Z, fx, fy, cx, cy = projection_symbols()
    pi = sp.Matrix([fx * X / Z + cx, fy * Y / Z + cy])
    return pi.jacobian(sp.Matrix([X, Y, Z]))


@cache
def _projection_fn():
    return sp.lambdify(projection_symbols(), projection_jacobian(), "numpy")


def projection_jacobian_numeric(X, cam) -> np.ndarray:
    """Evaluate the *derived* :func:`projection_jacobian` at points ``X (N, 3)`` for a camera.

    Parameters
    ----------
    X : array_like, shape (N, 3)
        Camera-frame points, Z > 0.
    cam : flowtrack.camera.PinholeCamera

    Returns
    -------
    ndarray, shape (N, 2, 3)

    Examples
    --------
    >>> from flowtrack.camera import PinholeCamera
    >>> projection_jacobian_numeric([[1.0, 2.0, 4.0]], PinholeCamera(100.0, 100.0, 0.0, 0.0))[0]
    array([[ 25.  ,   0.  ,  -6.25],
           [  0.  ,  25.  , -12.5 ]])
    """
    pts = as_array(X, "X", ("N", 3))
    if (pts[:, 2] <= 0).any():
        raise ValueError("X must have Z > 0 for every point")
    for attr in ("fx", "fy", "cx", "cy"):
        if not hasattr(cam, attr):
            raise TypeError(f"cam must be a PinholeCamera, got {type(cam).__name__}")
    f = _projection_fn()
    out = np.empty((pts.shape[0], 2, 3))
    for k, (x, y, z) in enumerate(pts):
        out[k] = f(x, y, z, cam.fx, cam.fy, cam.cx, cam.cy)
    return out


# --------------------------------------------------------------------------------------------------
# §3 / Problem 2: Euler-Lagrange equation of the quadratic scene-flow energy
# --------------------------------------------------------------------------------------------------
def scene_flow_lagrangian():
    r"""The integrand of the scalar scene-flow energy and its ingredients.

    .. math::  \mathcal{L} = (a + v\,\Delta t - b)^2 + \lambda\,(v_x^2 + v_y^2)

    Returns
    -------
    (L, v, a, b, (x, y), (dt, lam))
        ``v, a, b`` are sympy functions of ``(x, y)``; ``dt`` and ``lam`` positive symbols.
    """
    x, y = sp.symbols("x y", real=True)
    dt, lam = sp.symbols("Delta_t lambda", positive=True)
    v, a, b = (sp.Function(n)(x, y) for n in ("v", "a", "b"))
    L = (a + v * dt - b) ** 2 + lam * (sp.diff(v, x) ** 2 + sp.diff(v, y) ** 2)
    return L, v, a, b, (x, y), (dt, lam)


def euler_lagrange_scene_flow() -> sp.Eq:
    r"""Euler–Lagrange equation of :math:`E(v) = \int_\Omega (a + v\Delta t - b)^2 + \lambda\|\nabla v\|^2`.

    Derived with :func:`sympy.calculus.euler.euler_equations`, i.e.
    :math:`\partial\mathcal{L}/\partial v - \partial_x \partial\mathcal{L}/\partial v_x
    - \partial_y \partial\mathcal{L}/\partial v_y = 0`, which gives

    .. math::  2\Delta t\,(a + v\,\Delta t - b) - 2\lambda\,\Delta v = 0
       \iff \Delta t^2 v - \lambda \Delta v = \Delta t\,(b - a).

    Returns
    -------
    sympy.Eq
        ``Eq(lhs, 0)`` in the functions/symbols of :func:`scene_flow_lagrangian`.

    Examples
    --------
    >>> eq = euler_lagrange_scene_flow()
    >>> L, v, a, b, (x, y), (dt, lam) = scene_flow_lagrangian()
    >>> laplacian = sp.diff(v, x, 2) + sp.diff(v, y, 2)
    >>> sp.simplify(eq.lhs - (2 * dt * (a + v * dt - b) - 2 * lam * laplacian))
    0
    """
    L, v, _a, _b, (x, y), _ = scene_flow_lagrangian()
    (eq,) = euler_equations(L, [v], [x, y])
    return eq


# --------------------------------------------------------------------------------------------------
# §6: process noise of the white-noise-acceleration model
# --------------------------------------------------------------------------------------------------
def white_noise_acceleration_Q(dim: int = 2, model: str = "discrete") -> sp.Matrix:
    r"""Process-noise covariance of the constant-velocity model, derived for the full state.

    The state is ordered by derivative, :math:`x = [p_1..p_d, v_1..v_d]` (``[px, py, vx, vy]`` for
    ``dim=2``); :math:`F = \begin{bmatrix} I & \Delta t I \\ 0 & I\end{bmatrix}`.

    ``model="discrete"`` (*discrete white-noise acceleration*, the syllabus' :math:`Q_{1D}`): the
    acceleration :math:`a \sim \mathcal N(0, q I_d)` is constant over a step, so the state noise is
    :math:`w = G a` with :math:`G = [\tfrac12\Delta t^2 I_d;\ \Delta t I_d]` and

    .. math::  Q = G\,(q I_d)\,G^\top
       = q\begin{bmatrix} \Delta t^4/4 & \Delta t^3/2 \\ \Delta t^3/2 & \Delta t^2 \end{bmatrix}
         \otimes I_d.

    ``model="continuous"`` (*continuous white-noise acceleration* with spectral density
    :math:`q`): with :math:`\Phi(\tau) = e^{A\tau}`, :math:`A = \begin{bmatrix} 0 & I \\ 0 & 0
    \end{bmatrix}`, :math:`L = [0; I_d]`,

    .. math::  Q = \int_0^{\Delta t} \Phi(\tau) L\, q\, L^\top \Phi(\tau)^\top d\tau
       = q\begin{bmatrix} \Delta t^3/3 & \Delta t^2/2 \\ \Delta t^2/2 & \Delta t \end{bmatrix}
         \otimes I_d.

    Either way the result is a Kronecker product :math:`Q_{1D} \otimes I_d` — *not*
    :math:`\operatorname{blkdiag}(Q_{1D}, \dots)`, which is the matrix for the axis-major order
    ``[px, vx, py, vy]``.

    Parameters
    ----------
    dim : int
        Number of spatial axes (>= 1).
    model : {"discrete", "continuous"}

    Returns
    -------
    sympy.Matrix, shape (2*dim, 2*dim)
        In the positive symbols ``Delta_t`` and ``q``.

    Examples
    --------
    >>> Q = white_noise_acceleration_Q(2)
    >>> dt, q = sp.symbols("Delta_t q", positive=True)
    >>> Q1d = q * sp.Matrix([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    >>> from sympy.physics.quantum import TensorProduct
    >>> Q == TensorProduct(Q1d, sp.eye(2)), Q == sp.diag(Q1d, Q1d)
    (True, False)
    >>> white_noise_acceleration_Q(1, model="continuous")
    Matrix([
    [Delta_t**3*q/3, Delta_t**2*q/2],
    [Delta_t**2*q/2,      Delta_t*q]])
    """
    d = positive_int(dim, "dim")
    if not isinstance(model, str):
        raise TypeError(f"model must be a string, got {type(model).__name__}")
    dt, q = sp.symbols("Delta_t q", positive=True)
    Id, Zd = sp.eye(d), sp.zeros(d, d)
    if model == "discrete":
        G = sp.Matrix(sp.BlockMatrix([[dt**2 / 2 * Id], [dt * Id]]))
        return sp.simplify(G * (q * Id) * G.T)
    if model == "continuous":
        tau = sp.symbols("tau", nonnegative=True)
        A = sp.Matrix(sp.BlockMatrix([[Zd, Id], [Zd, Zd]]))
        Phi = sp.simplify((A * tau).exp())
        L = sp.Matrix(sp.BlockMatrix([[Zd], [Id]]))
        integrand = Phi * L * (q * Id) * L.T * Phi.T
        return integrand.applyfunc(lambda e: sp.integrate(e, (tau, 0, dt)))
    raise ValueError(f"model must be 'discrete' or 'continuous', got {model!r}")


def white_noise_acceleration_Q_numeric(dt, q, dim: int = 2, model: str = "discrete") -> np.ndarray:
    """Evaluate the *derived* :func:`white_noise_acceleration_Q` at ``dt > 0``, ``q >= 0``.

    Examples
    --------
    >>> white_noise_acceleration_Q_numeric(1.0, 4.0, dim=1)
    array([[1., 2.],
           [2., 4.]])
    """
    dt = positive(dt, "dt")
    q = nonnegative(q, "q")
    if not isinstance(model, str):
        raise TypeError(f"model must be a string, got {type(model).__name__}")
    return np.asarray(_q_fn(positive_int(dim, "dim"), model)(dt, q), dtype=float)


@cache
def _q_fn(dim: int, model: str):
    Q = white_noise_acceleration_Q(dim, model)
    return sp.lambdify(sp.symbols("Delta_t q", positive=True), Q, "numpy")


# --------------------------------------------------------------------------------------------------
# §6: Kalman gain by minimising the posterior trace
# --------------------------------------------------------------------------------------------------
def kalman_matrices(n: int = 2, m: int = 1):
    """Generic symbolic ``P`` (n×n symmetric), ``H`` (m×n), ``R`` (m×m symmetric), ``K`` (n×m).

    Entries are named ``P_ij`` (``P_ij = P_ji``), ``H_ij``, ``R_ij``, ``K_ij`` (1-based).

    Returns
    -------
    (P, H, R, K) : tuple of sympy.Matrix
    """
    n = positive_int(n, "n")
    m = positive_int(m, "m")

    def sym(name, k):
        return sp.Matrix(k, k, lambda i, j: sp.Symbol(f"{name}_{min(i, j) + 1}{max(i, j) + 1}", real=True))

    P = sym("P", n)
    R = sym("R", m)
    H = sp.Matrix(m, n, lambda i, j: sp.Symbol(f"H_{i + 1}{j + 1}", real=True))
    K = sp.Matrix(n, m, lambda i, j: sp.Symbol(f"K_{i + 1}{j + 1}", real=True))
    return P, H, R, K


def kalman_gain(n: int = 2, m: int = 1) -> sp.Matrix:
    r"""Kalman gain derived by minimising the trace of the updated covariance.

    For any gain :math:`K` the update :math:`x^+ = x + K(z - Hx)` has covariance (Joseph form)

    .. math::  P^+(K) = (I - KH) P (I - KH)^\top + K R K^\top .

    :math:`\operatorname{tr} P^+` (the expected squared error) is a convex quadratic in the
    :math:`nm` entries of :math:`K`; setting all partial derivatives to zero and solving the linear
    system gives the optimum, which equals :math:`K^\star = P H^\top (H P H^\top + R)^{-1}`
    (see :func:`kalman_gain_closed_form`).

    Parameters
    ----------
    n, m : int
        State and measurement dimensions; ``n * m <= 4`` (the stationarity system is solved
        symbolically, which grows quickly). The gradient identity
        :math:`\partial \operatorname{tr} P^+ / \partial K = 2(K S - P H^\top)`,
        :math:`S = HPH^\top + R`, behind the closed form holds for every size.

    Returns
    -------
    sympy.Matrix, shape (n, m)
        The minimiser, in the symbols of :func:`kalman_matrices`.

    Examples
    --------
    >>> K = kalman_gain(2, 1)
    >>> sp.simplify(K - kalman_gain_closed_form(2, 1))
    Matrix([
    [0],
    [0]])
    """
    P, H, R, K = kalman_matrices(n, m)
    if P.shape[0] * R.shape[0] > 4:
        raise ValueError(f"n * m must be <= 4 for the symbolic solve (got n={n}, m={m})")
    I_KH = sp.eye(P.shape[0]) - K * H
    trace = (I_KH * P * I_KH.T + K * R * K.T).trace()
    unknowns = list(K)
    sol = sp.solve([sp.diff(trace, k) for k in unknowns], unknowns, dict=True)
    if len(sol) != 1:  # pragma: no cover - the stationarity system is linear and regular
        raise RuntimeError("the stationarity conditions did not have a unique solution")
    return K.subs(sol[0]).applyfunc(sp.simplify)


def kalman_gain_closed_form(n: int = 2, m: int = 1) -> sp.Matrix:
    r""":math:`P H^\top (H P H^\top + R)^{-1}` in the symbols of :func:`kalman_matrices`."""
    P, H, R, _ = kalman_matrices(n, m)
    return P * H.T * (H * P * H.T + R).inv()


@cache
def _gain_fn(n: int, m: int):
    Ps, Hs, Rs, _ = kalman_matrices(n, m)
    syms = sorted(Ps.free_symbols | Hs.free_symbols | Rs.free_symbols, key=lambda s: s.name)
    return sp.lambdify(syms, kalman_gain(n, m), "numpy"), syms, (Ps, Hs, Rs)


def kalman_gain_numeric(P, H, R) -> np.ndarray:
    """Evaluate the *derived* :func:`kalman_gain` at numeric ``P (n,n)``, ``H (m,n)``, ``R (m,m)``.

    Examples
    --------
    >>> kalman_gain_numeric([[2.0, 0.0], [0.0, 1.0]], [[1.0, 0.0]], [[2.0]])
    array([[0.5],
           [0. ]])
    """
    P = check_psd(as_array(P, "P", ("n", "n")), "P")
    n = P.shape[0]
    H = as_array(H, "H", (None, n))
    m = H.shape[0]
    R = check_psd(as_array(R, "R", (m, m)), "R", strict=True)
    if n * m > 4:
        raise ValueError(f"H: n * m must be <= 4 for the symbolic gain, got H of shape {H.shape}")
    f, syms, (Ps, Hs, Rs) = _gain_fn(n, m)
    values = {}
    for S, A in ((Ps, P), (Hs, H), (Rs, R)):
        for (i, j), s in np.ndenumerate(np.array(S, dtype=object)):
            values[s] = A[i, j]
    return np.asarray(f(*[values[s] for s in syms]), dtype=float)


# --------------------------------------------------------------------------------------------------
# Problem 3: Gaussian prior x Gaussian likelihood
# --------------------------------------------------------------------------------------------------
def kalman_posterior():
    r"""Posterior of a scalar Gaussian prior and linear-Gaussian likelihood, by completing the square.

    With prior :math:`\mathcal N(x; \mu, p)` and likelihood :math:`\mathcal N(z; h x, r)`,

    .. math::  -2\log p(x \mid z) = \frac{(x-\mu)^2}{p} + \frac{(z - h x)^2}{r} + \text{const}
       = \alpha x^2 - 2\beta x + \text{const},

    a quadratic in :math:`x` with :math:`\alpha = 1/p + h^2/r > 0`, so the posterior is Gaussian
    with variance :math:`1/\alpha` and mean :math:`\beta/\alpha`. Both are returned as derived and
    equal the Kalman update :math:`\mu + k(z - h\mu)`, :math:`(1 - kh)p` with
    :math:`k = ph/(h^2 p + r)`.

    Returns
    -------
    (mean, variance, symbols)
        Sympy expressions and the tuple of symbols ``(x, mu, p, z, h, r)``.

    Examples
    --------
    >>> mean, var, (x, mu, p, z, h, r) = kalman_posterior()
    >>> k = p * h / (h**2 * p + r)
    >>> sp.simplify(mean - (mu + k * (z - h * mu))), sp.simplify(var - (1 - k * h) * p)
    (0, 0)
    """
    x, mu, z, h = sp.symbols("x mu z h", real=True)
    p, r = sp.symbols("p r", positive=True)
    quad = sp.expand((x - mu) ** 2 / p + (z - h * x) ** 2 / r)
    poly = sp.Poly(quad, x)
    alpha, minus_two_beta, _ = poly.all_coeffs()
    beta = -minus_two_beta / 2
    mean = sp.simplify(beta / alpha)
    var = sp.simplify(1 / alpha)
    return mean, var, (x, mu, p, z, h, r)


@cache
def _posterior_fn():
    mean, var, (_x, *syms) = kalman_posterior()
    return sp.lambdify(syms, (mean, var), "math")


def kalman_posterior_numeric(mu, p, z, h, r) -> tuple[float, float]:
    """Evaluate the *derived* :func:`kalman_posterior` (mean, variance) at numbers.

    Examples
    --------
    >>> kalman_posterior_numeric(0.0, 1.0, 2.0, 1.0, 1.0)
    (1.0, 0.5)
    """
    vals = (
        float(as_array(mu, "mu", ())),
        positive(p, "p"),
        float(as_array(z, "z", ())),
        float(as_array(h, "h", ())),
        positive(r, "r"),
    )
    m, v = _posterior_fn()(*vals)
    return float(m), float(v)


# --------------------------------------------------------------------------------------------------
# §11.2: steady state of the scalar Riccati recursion
# --------------------------------------------------------------------------------------------------
def steady_state_variance_scalar():
    r"""Steady-state predicted variance of the scalar model :math:`x' = f x + w`, :math:`z = h x + v`.

    The predicted variance obeys the Riccati recursion
    :math:`p \leftarrow f^2 p - f^2 p^2 h^2 / (h^2 p + r) + q`. Its fixed point solves

    .. math::  h^2 p^2 + \big(r(1 - f^2) - q h^2\big)\,p - q r = 0,

    whose roots have product :math:`-qr/h^2 < 0`: exactly one is positive, the steady state

    .. math::  p_\infty = \frac{q h^2 - r(1-f^2) + \sqrt{(r(1-f^2) - q h^2)^2 + 4 q r h^2}}{2 h^2}.

    (The filtered steady-state variance is :math:`p_\infty r / (h^2 p_\infty + r)`.)

    Returns
    -------
    (p_inf, symbols)
        Sympy expression and the symbols ``(f, h, q, r)`` (``f`` real, the others positive).

    Examples
    --------
    >>> p_inf, (f, h, q, r) = steady_state_variance_scalar()
    >>> sp.simplify(p_inf.subs({f: 1, h: 1, q: 1, r: 1}))  # random walk: (1 + sqrt 5)/2
    1/2 + sqrt(5)/2
    """
    f = sp.Symbol("f", real=True)
    h, q, r = sp.symbols("h q r", positive=True)
    p = sp.Symbol("p")
    riccati = sp.Eq(p, f**2 * p - f**2 * p**2 * h**2 / (h**2 * p + r) + q)
    numerator = sp.numer(sp.together(riccati.lhs - riccati.rhs))
    roots = sp.solve(numerator, p)
    # one root is positive for every (f, h, q, r); identify it at a sample point
    sample = {f: sp.Rational(9, 10), h: 1, q: 1, r: 1}
    (positive_root,) = [s for s in roots if s.subs(sample).evalf() > 0]
    return sp.simplify(positive_root), (f, h, q, r)


def steady_state_variance_scalar_numeric(f, h, q, r) -> float:
    """Evaluate the *derived* :func:`steady_state_variance_scalar` (``h, q, r > 0``).

    Examples
    --------
    >>> round(steady_state_variance_scalar_numeric(1.0, 1.0, 1.0, 1.0), 6)
    1.618034
    """
    vals = (float(as_array(f, "f", ())), positive(h, "h"), positive(q, "q"), positive(r, "r"))
    return float(_steady_fn()(*vals))


@cache
def _steady_fn():
    expr, syms = steady_state_variance_scalar()
    return sp.lambdify(syms, expr, "math")


# --------------------------------------------------------------------------------------------------
# shared helpers of the sections below
# --------------------------------------------------------------------------------------------------
def _small_int(value, name: str, minimum: int, maximum: int) -> int:
    v = positive_int(value, name, minimum=minimum)
    if v > maximum:
        raise ValueError(f"{name} must be <= {maximum} for the symbolic derivation, got {v}")
    return v


def _weight_matrix(W, name: str, n_max: int) -> np.ndarray:
    """A dense, symmetric, non-negative (N, N) weight matrix with 2 <= N <= n_max (a fresh copy)."""
    from .sceneflow import _as_affinity  # the affinity check of graph scene flow, dense or sparse

    A = _as_affinity(W, name).toarray()
    if not 2 <= A.shape[0] <= n_max:
        raise ValueError(f"{name} must have shape (N, N) with 2 <= N <= {n_max}, got {A.shape}")
    return A


def _pairs(n: int) -> list[tuple[int, int]]:
    return [(a, b) for a in range(n) for b in range(a + 1, n)]


def _symbolic_weights(n: int, edges, **assumptions) -> tuple[dict, sp.Matrix]:
    """Weight symbols ``w_ab`` (1-based names) for the edges, and the symmetric matrix W."""
    w = {(a, b): sp.Symbol(f"w_{a + 1}_{b + 1}", **assumptions) for a, b in edges}
    W = sp.zeros(n, n)
    for (a, b), wab in w.items():
        W[a, b] = W[b, a] = wab
    return w, W


def _laplacian(W: sp.Matrix) -> sp.Matrix:
    n = W.shape[0]
    return sp.diag(*[sum(W.row(a)) for a in range(n)]) - W


# --------------------------------------------------------------------------------------------------
# §4 / lesson 3: normal equations of graph scene flow, and the Kronecker permutation
# --------------------------------------------------------------------------------------------------
class GraphNormalEquations(NamedTuple):
    """Result of :func:`graph_normal_equations` (all entries sympy objects)."""

    matrix: sp.Matrix  #: (3N, 3N), half the Hessian of the energy
    rhs: sp.Matrix  #: (3N, 1)
    velocities: sp.Matrix  #: (3N, 1) unknowns, point-major (v_1x, v_1y, v_1z, v_2x, ...)
    energy: sp.Expr
    laplacian: sp.Matrix  #: (N, N) L = D - W in the weight symbols
    weights: dict  #: {(a, b): w_ab} for the edges, 0-based a < b
    points: sp.Matrix  #: (N, 3) X
    targets: sp.Matrix  #: (N, 3) Y
    dt: sp.Symbol
    lam: sp.Symbol


_GRAPH_MAX = 8


def graph_normal_equations(n_points: int = 4, edges=None) -> GraphNormalEquations:
    r"""Normal equations of the graph scene-flow energy, derived from its gradient (§4, lesson 3).

    For points :math:`X_i`, correspondences :math:`Y_i` and velocities :math:`v_i\in\mathbb R^3` on a
    graph with symbolic weights :math:`w_{ij}\ge 0`,

    .. math::  E(\mathbf v) = \sum_{i=1}^N \lVert X_i + v_i\Delta t - Y_i\rVert^2
               + \lambda\sum_{(i,j)\in\mathcal E} w_{ij}\lVert v_i - v_j\rVert^2 .

    Setting :math:`\partial E/\partial\mathbf v = 0` (differentiated entry by entry, then written as
    a matrix with :func:`sympy.linear_eq_to_matrix`) and dividing by 2 gives, for the point-major
    stacking :math:`\mathbf v = (v_{1x}, v_{1y}, v_{1z}, v_{2x}, \dots)`,

    .. math::  \big(\Delta t^2 I_{3N} + \lambda\, L\otimes I_3\big)\,\mathbf v
               = \Delta t\,\operatorname{vec}(Y - X), \qquad L = D - W,

    which the tests check against :func:`flowtrack.sceneflow.graph_scene_flow` and a dense solve;
    :func:`commutation_matrix` turns :math:`L\otimes I_3` into :math:`I_3\otimes L` (three
    :math:`N\times N` systems with one matrix).

    Parameters
    ----------
    n_points : int
        Number of points N, ``2 <= N <= 8``.
    edges : sequence of (int, int), optional
        Edges ``(a, b)`` (0-based, ``a != b``); default every pair (a zero weight removes an edge, so
        the complete graph covers every graph on N points).

    Returns
    -------
    GraphNormalEquations
        ``matrix`` (3N, 3N) and ``rhs`` (3N, 1) with ``matrix @ velocities = rhs``; the energy, the
        Laplacian, the weight symbols ``w_a_b`` (1-based names), ``X``, ``Y``, ``Delta_t``, ``lambda``.

    Examples
    --------
    >>> ne = graph_normal_equations(2)
    >>> ne.laplacian
    Matrix([
    [ w_1_2, -w_1_2],
    [-w_1_2,  w_1_2]])
    >>> ne.matrix[:, 0].T
    Matrix([[Delta_t**2 + lambda*w_1_2, 0, 0, -lambda*w_1_2, 0, 0]])
    >>> ne.rhs[0]
    -Delta_t*X_1x + Delta_t*Y_1x
    """
    n = _small_int(n_points, "n_points", 2, _GRAPH_MAX)
    if edges is None:
        edge_list = _pairs(n)
    else:
        try:
            raw = [tuple(int(i) for i in e) for e in edges]
        except (TypeError, ValueError):
            raise TypeError("edges must be a sequence of (a, b) index pairs") from None
        if any(len(e) != 2 or e[0] == e[1] or not (0 <= min(e) and max(e) < n) for e in raw):
            raise ValueError(f"edges must be pairs (a, b) of distinct point indices in 0..{n - 1}")
        edge_list = sorted({(min(e), max(e)) for e in raw})
    dt, lam = sp.symbols("Delta_t lambda", positive=True)
    X = sp.Matrix(n, 3, lambda a, c: sp.Symbol(f"X_{a + 1}{'xyz'[c]}", real=True))
    Y = sp.Matrix(n, 3, lambda a, c: sp.Symbol(f"Y_{a + 1}{'xyz'[c]}", real=True))
    V = sp.Matrix(n, 3, lambda a, c: sp.Symbol(f"v_{a + 1}{'xyz'[c]}", real=True))
    v = sp.Matrix([V[a, c] for a in range(n) for c in range(3)])
    w, W = _symbolic_weights(n, edge_list, nonnegative=True)
    data = sum((X[a, c] + V[a, c] * dt - Y[a, c]) ** 2 for a in range(n) for c in range(3))
    smooth = sum(wab * sum((V[a, c] - V[b, c]) ** 2 for c in range(3)) for (a, b), wab in w.items())
    energy = data + lam * smooth
    grad = [sp.expand(sp.diff(energy, s)) for s in v]
    M2, r2 = sp.linear_eq_to_matrix(grad, list(v))
    return GraphNormalEquations(
        matrix=(M2 / 2).applyfunc(sp.expand),
        rhs=(r2 / 2).applyfunc(sp.expand),
        velocities=v,
        energy=energy,
        laplacian=_laplacian(W),
        weights=w,
        points=X,
        targets=Y,
        dt=dt,
        lam=lam,
    )


@cache
def _graph_fn(n: int):
    ne = graph_normal_equations(n)
    args = (ne.dt, ne.lam, list(ne.weights.values()), list(ne.points), list(ne.targets))
    return sp.lambdify(args, (ne.matrix, ne.rhs), "numpy"), list(ne.weights)


def graph_normal_equations_numeric(points_t, targets, dt, lam, W) -> tuple[np.ndarray, np.ndarray]:
    r"""Evaluate the *derived* :func:`graph_normal_equations` at numbers.

    Parameters
    ----------
    points_t, targets : array_like, shape (N, 3)
        :math:`X` and :math:`Y`, ``2 <= N <= 8``.
    dt : float > 0
    lam : float >= 0
    W : array_like or sparse, shape (N, N)
        Symmetric non-negative weights (the diagonal is ignored, as self-loops cancel in
        :math:`L = D - W`).

    Returns
    -------
    (matrix, rhs) : ndarray (3N, 3N), ndarray (3N,)
        The point-major system; ``np.linalg.solve(matrix, rhs).reshape(N, 3)`` is the flow ``V``.

    Examples
    --------
    >>> M, b = graph_normal_equations_numeric([[0, 0, 0], [1, 0, 0]], [[1, 0, 0], [1, 0, 0]], 1.0, 1.0,
    ...                                      [[0, 1], [1, 0]])
    >>> np.linalg.solve(M, b).reshape(2, 3)[:, 0]  # smoothing moves one third of the motion to point 2
    array([0.66666667, 0.33333333])
    """
    X = as_array(points_t, "points_t", ("N", 3))
    Wn = _weight_matrix(W, "W", _GRAPH_MAX)
    n = Wn.shape[0]
    if X.shape[0] != n:
        raise ValueError(f"points_t must have shape ({n}, 3) to match W, got {X.shape}")
    Y = as_array(targets, "targets", (n, 3))
    dt = positive(dt, "dt")
    lam = nonnegative(lam, "lam")
    f, edges = _graph_fn(n)
    M, b = f(dt, lam, [Wn[a, c] for a, c in edges], list(X.ravel()), list(Y.ravel()))
    return np.asarray(M, dtype=float), np.asarray(b, dtype=float).ravel()


def commutation_matrix(n: int, d: int = 3) -> sp.Matrix:
    r"""The permutation :math:`\Pi` from point-major to coordinate-major stacking of an (n, d) array.

    :math:`\Pi\operatorname{vec}_\text{row}(V) = \operatorname{vec}_\text{row}(V^\top)`, i.e.
    ``Pi @ V.ravel() == V.T.ravel()`` (:math:`\Pi_{cn + a,\ da + c} = 1`). For square
    :math:`A\in\mathbb R^{n\times n}`, :math:`B\in\mathbb R^{d\times d}`

    .. math::  \Pi\,(A\otimes B)\,\Pi^\top = B\otimes A ,

    so :math:`\Pi(L\otimes I_3)\Pi^\top = I_3\otimes L = \operatorname{blkdiag}(L, L, L)` (graph scene
    flow decouples into three systems) and, with ``n = 2`` derivative orders and ``d`` axes,
    :math:`\Pi(Q_{1D}\otimes I_d)\Pi^\top = I_d\otimes Q_{1D} = \operatorname{blkdiag}(Q_{1D},\dots)`:
    the syllabus' block-diagonal Q is the right matrix for the *axis-major* state order only (see
    :func:`process_noise_orderings`). The tests prove the identity for generic symbolic A, B.

    Parameters
    ----------
    n, d : int >= 1
        Rows ("points" or derivative orders) and columns (coordinates/axes) of the stacked array.

    Returns
    -------
    sympy.Matrix, shape (n*d, n*d)
        A 0/1 permutation matrix.

    Examples
    --------
    >>> commutation_matrix(2, 2)
    Matrix([
    [1, 0, 0, 0],
    [0, 0, 1, 0],
    [0, 1, 0, 0],
    [0, 0, 0, 1]])
    """
    n = positive_int(n, "n")
    d = positive_int(d, "d")
    Pi = sp.zeros(n * d, n * d)
    for a in range(n):
        for c in range(d):
            Pi[c * n + a, d * a + c] = 1
    return Pi


def process_noise_orderings(dim: int = 2, model: str = "discrete") -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    r"""The derived process noise in both state orders, and the permutation between them (§6, lesson 7).

    ``Q`` is :func:`white_noise_acceleration_Q` for the derivative-major order
    ``[p_1..p_d, v_1..v_d]`` (:math:`Q_{1D}\otimes I_d`); ``Q_axis`` is
    :math:`\operatorname{blkdiag}(Q_{1D},\dots,Q_{1D}) = I_d\otimes Q_{1D}` built from the derived
    one-axis :math:`Q_{1D}` = ``white_noise_acceleration_Q(1)``, the matrix for the axis-major order
    ``[p_1, v_1, p_2, v_2, ...]``; ``Pi`` = ``commutation_matrix(2, dim)`` maps the first order to the
    second, and :math:`\Pi Q \Pi^\top = Q_{axis}`.

    Returns
    -------
    (Q, Q_axis, Pi) : sympy.Matrix, each (2*dim, 2*dim)

    Examples
    --------
    >>> Q, Q_axis, Pi = process_noise_orderings(2)
    >>> Pi * Q * Pi.T == Q_axis, Q == Q_axis
    (True, False)
    """
    d = positive_int(dim, "dim")
    Q = white_noise_acceleration_Q(d, model)
    Q1d = white_noise_acceleration_Q(1, model)
    return Q, sp.diag(*([Q1d] * d)), commutation_matrix(2, d)


# --------------------------------------------------------------------------------------------------
# Problem 5 / lesson 6: the mean velocity of a rigid cluster
# --------------------------------------------------------------------------------------------------
class RigidMeanVelocity(NamedTuple):
    """Result of :func:`rigid_mean_velocity` (all entries sympy objects)."""

    velocity: sp.Matrix  #: (3, 1) the mean velocity, in the centroid and the motion parameters only
    mean: sp.Matrix  #: (3, 1) the mean of the point velocities, in the points
    field: sp.Matrix  #: (3, 1) the rigid velocity field at the generic point ``query``
    query: sp.Matrix  #: (3, 1) the symbols q_x, q_y, q_z
    centroid: sp.Matrix  #: (3, 1) the symbols c_x, c_y, c_z
    parameters: tuple  #: (R, t, Delta_t) or (v_o, omega, o)
    points: tuple  #: the n symbolic points, each (3, 1)


_RIGID_MODELS = ("finite", "instantaneous")


def rigid_mean_velocity(n_points: int = 4, model: str = "finite") -> RigidMeanVelocity:
    r"""Mean velocity of the points of a rigid body, expressed through their centroid (Problem 5).

    The velocity field of a rigid motion is affine in the position:

    * ``"finite"``: one step :math:`p \mapsto Rp + t` over :math:`\Delta t` gives
      :math:`v(p) = \big((R - I)p + t\big)/\Delta t` (any matrix :math:`R`, rotation or not);
    * ``"instantaneous"``: :math:`v(p) = v_o + \omega\times(p - o)` for a reference point :math:`o`
      with velocity :math:`v_o`.

    The mean :math:`\bar v = \frac1n\sum_i v(p_i)` of n symbolic points is formed, and the first point
    is eliminated with the definition of the centroid, :math:`p_1 = n c - \sum_{i>1} p_i`. Every
    other point cancels (checked: a ``RuntimeError`` otherwise), which proves

    .. math::  \bar v = v(c):\quad \bar v = \frac{(R - I)c + t}{\Delta t}
               \quad\text{or}\quad \bar v = v_o + \omega\times(c - o),

    the velocity of the body point at the centroid — :math:`v_c` itself when :math:`o = c`. So the
    initial velocity :func:`flowtrack.clustering.tracks_from_clusters` gives a track is exact for a
    rigid cluster.

    Parameters
    ----------
    n_points : int
        Number of symbolic points, ``1 <= n <= 12``.
    model : {"finite", "instantaneous"}

    Returns
    -------
    RigidMeanVelocity

    Examples
    --------
    >>> res = rigid_mean_velocity(3, "instantaneous")
    >>> v_o, omega, o = res.parameters
    >>> sp.simplify(res.velocity - res.field.subs(dict(zip(res.query, res.centroid))))
    Matrix([
    [0],
    [0],
    [0]])
    >>> res.velocity.subs(dict(zip(o, res.centroid))).T  # reference point at the centroid
    Matrix([[v_ox, v_oy, v_oz]])
    """
    n = _small_int(n_points, "n_points", 1, 12)
    if not isinstance(model, str):
        raise TypeError(f"model must be a string, got {type(model).__name__}")
    if model not in _RIGID_MODELS:
        raise ValueError(f"model must be one of {_RIGID_MODELS}, got {model!r}")

    def vec(names):
        return sp.Matrix(sp.symbols(names, real=True))

    P = tuple(vec(f"p{i + 1}_x p{i + 1}_y p{i + 1}_z") for i in range(n))
    c, q = vec("c_x c_y c_z"), vec("q_x q_y q_z")
    if model == "finite":
        R = sp.Matrix(3, 3, lambda a, b: sp.Symbol(f"R_{a + 1}{b + 1}", real=True))
        t, dt = vec("t_x t_y t_z"), sp.Symbol("Delta_t", positive=True)
        params = (R, t, dt)

        def field(p):
            return ((R - sp.eye(3)) * p + t) / dt

    else:
        v_o, omega, o = vec("v_ox v_oy v_oz"), vec("omega_x omega_y omega_z"), vec("o_x o_y o_z")
        params = (v_o, omega, o)

        def field(p):
            return v_o + omega.cross(p - o)

    mean = sum((field(p) for p in P), sp.zeros(3, 1)) / n
    first = n * c - sum(P[1:], sp.zeros(3, 1))
    velocity = mean.subs(dict(zip(P[0], first)), simultaneous=True).applyfunc(sp.expand)
    left = velocity.free_symbols & set().union(*(p.free_symbols for p in P))
    if left:  # pragma: no cover - would mean the mean velocity is not a function of the centroid
        raise RuntimeError(f"the mean velocity still depends on {sorted(map(str, left))}")
    return RigidMeanVelocity(velocity.applyfunc(sp.factor_terms), mean, field(q), q, c, params, P)


@cache
def _rigid_fn(model: str):
    res = rigid_mean_velocity(2, model)
    args = [list(res.centroid)] + [list(p) if isinstance(p, sp.MatrixBase) else [p] for p in res.parameters]
    return sp.lambdify(args, res.velocity, "numpy")


def rigid_mean_velocity_numeric(centroid, R, t, dt) -> np.ndarray:
    r"""Evaluate the *derived* finite-step :func:`rigid_mean_velocity` :math:`((R - I)c + t)/\Delta t`.

    Parameters
    ----------
    centroid : array_like, shape (3,)
    R : array_like, shape (3, 3)
    t : array_like, shape (3,)
    dt : float > 0

    Returns
    -------
    ndarray, shape (3,)

    Examples
    --------
    >>> rigid_mean_velocity_numeric([1.0, 0.0, 0.0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], [0, 0, 0.5], 0.5)
    array([-2.,  2.,  1.])
    """
    c = as_array(centroid, "centroid", (3,))
    R = as_array(R, "R", (3, 3))
    t = as_array(t, "t", (3,))
    dt = positive(dt, "dt")
    return np.asarray(_rigid_fn("finite")(list(c), list(R.ravel()), list(t), [dt]), dtype=float).ravel()


def rigid_twist_mean_velocity_numeric(centroid, v_ref, omega, ref) -> np.ndarray:
    r"""Evaluate the *derived* instantaneous :func:`rigid_mean_velocity` :math:`v_o + \omega\times(c - o)`.

    Parameters
    ----------
    centroid, v_ref, omega, ref : array_like, shape (3,)
        :math:`c`, the velocity :math:`v_o` of the reference point :math:`o`, the angular velocity
        :math:`\omega`, and :math:`o`.

    Returns
    -------
    ndarray, shape (3,)

    Examples
    --------
    >>> rigid_twist_mean_velocity_numeric([1.0, 0, 0], [0, 0, 0], [0, 0, 2.0], [0, 0, 0])
    array([0., 2., 0.])
    """
    vals = [
        list(as_array(x, name, (3,)))
        for x, name in ((centroid, "centroid"), (v_ref, "v_ref"), (omega, "omega"), (ref, "ref"))
    ]
    return np.asarray(_rigid_fn("instantaneous")(*vals), dtype=float).ravel()


# --------------------------------------------------------------------------------------------------
# Problem 5 / lesson 6: motion affinity threshold and the normalised cut
# --------------------------------------------------------------------------------------------------
def affinity_threshold():
    r"""Velocity difference at which the motion affinity equals :math:`e^{-m}` (lesson 6).

    Solving :math:`\exp(-d^2/\sigma_v^2) = e^{-m}` for :math:`d > 0` gives :math:`d = \sqrt m\,\sigma_v`:
    ``cluster_motion(method="connected")`` keeps edges with :math:`w \ge e^{-1}`
    (:math:`\lVert\Delta v\rVert \le \sigma_v`), ``method="spectral"`` those with :math:`w \ge e^{-9}`
    (:math:`\lVert\Delta v\rVert \le 3\sigma_v`).

    Returns
    -------
    (d, (m, sigma_v))
        The sympy expression and its (positive) symbols.

    Examples
    --------
    >>> d, (m, s) = affinity_threshold()
    >>> d, d.subs(m, 9)
    (sqrt(m)*sigma_v, 3*sigma_v)
    """
    d, s, m = sp.symbols("d sigma_v m", positive=True)
    (root,) = sp.solve(sp.Eq(sp.exp(-(d**2) / s**2), sp.exp(-m)), d)
    return root, (m, s)


@cache
def _affinity_fn():
    expr, syms = affinity_threshold()
    return sp.lambdify(syms, expr, "math")


def affinity_threshold_numeric(m, sigma_v) -> float:
    """Evaluate the *derived* :func:`affinity_threshold` (``m, sigma_v > 0``).

    Examples
    --------
    >>> affinity_threshold_numeric(9.0, 0.05)
    0.15000000000000002
    """
    return float(_affinity_fn()(positive(m, "m"), positive(sigma_v, "sigma_v")))


class NormalizedCut(NamedTuple):
    """Result of :func:`normalized_cut` (all entries sympy objects)."""

    ncut: sp.Expr  #: cut/vol(A) + cut/vol(B)
    rayleigh: sp.Expr  #: y^T L y / y^T D y
    indicator: sp.Matrix  #: (n, 1) y = 1 on A, -vol(A)/vol(B) on B
    constraint: sp.Expr  #: y^T D 1
    laplacian: sp.Matrix  #: (n, n) L = D - W
    degree: sp.Matrix  #: (n, n) D
    weights: dict  #: {(a, b): w_ab}, 0-based a < b
    membership: sp.Matrix  #: (n, 1) the symbols s_i (1 on A, 0 on B), substituted when side_a is given


_NCUT_MAX = 8


def _side(side_a, n: int) -> tuple[int, ...]:
    try:
        side = tuple(sorted({int(i) for i in side_a}))
    except (TypeError, ValueError):
        raise TypeError("side_a must be a sequence of node indices") from None
    if not side or len(side) >= n or side[0] < 0 or side[-1] >= n:
        raise ValueError(f"side_a must be a non-empty proper subset of the nodes 0..{n - 1}, got {side_a!r}")
    return side


def normalized_cut(n_nodes: int = 4, side_a=(0, 1)) -> NormalizedCut:
    r"""The normalised cut as a Rayleigh quotient of the graph Laplacian (Shi & Malik 2000; Problem 5).

    For a complete graph on n nodes with positive symbolic weights, :math:`D` the degree matrix,
    :math:`L = D - W`, and a cut :math:`A\mid B` given by memberships :math:`s_i = 1` on :math:`A`,
    :math:`0` on :math:`B`,

    .. math::  \mathrm{Ncut}(A, B) = \frac{\mathrm{cut}(A,B)}{\mathrm{vol}A}
               + \frac{\mathrm{cut}(A,B)}{\mathrm{vol}B}
               = \frac{y^\top L y}{y^\top D y},\qquad
               y = \mathbf 1_A - \frac{\mathrm{vol}A}{\mathrm{vol}B}\mathbf 1_B,\quad y^\top D\mathbf 1 = 0,

    with :math:`\mathrm{cut} = \sum_{i<j} w_{ij}(s_i + s_j - 2 s_i s_j)`,
    :math:`\mathrm{vol}A = \sum_i s_i d_i`. Both sides are returned as built (``ncut`` from cut and
    volumes, ``rayleigh`` from the matrices); for a given ``side_a`` their difference simplifies to 0,
    and so does the ``constraint``. Relaxing :math:`y` to all of :math:`\mathbb R^n` with
    :math:`y^\top D\mathbf 1 = 0` gives the generalised eigenproblem :math:`Ly = \lambda Dy`: its
    second eigenvector (Fiedler vector) is the spectral cut and :math:`\lambda_2 \le \min\mathrm{Ncut}`.

    Parameters
    ----------
    n_nodes : int
        ``2 <= n <= 8``.
    side_a : sequence of int or None
        The nodes of :math:`A`, a non-empty proper subset of ``0..n-1``; ``None`` keeps the
        membership symbols :math:`s_i` (the identity then holds for every 0/1 assignment with both
        sides non-empty, which is how :func:`normalized_cut_numeric` evaluates it).

    Returns
    -------
    NormalizedCut

    Examples
    --------
    >>> nc = normalized_cut(3, side_a=[0])
    >>> sp.simplify(nc.rayleigh - nc.ncut), sp.simplify(nc.constraint)
    (0, 0)
    """
    n = _small_int(n_nodes, "n_nodes", 2, _NCUT_MAX)
    s = sp.Matrix(sp.symbols(f"s_1:{n + 1}", nonnegative=True))
    w, W = _symbolic_weights(n, _pairs(n), positive=True)
    deg = [sum(W.row(a)) for a in range(n)]
    D = sp.diag(*deg)
    L = D - W
    cut = sum(wab * (s[a] + s[b] - 2 * s[a] * s[b]) for (a, b), wab in w.items())
    vol_a = sum(s[i] * deg[i] for i in range(n))
    vol_b = sum((1 - s[i]) * deg[i] for i in range(n))
    y = sp.Matrix([s[i] - (1 - s[i]) * vol_a / vol_b for i in range(n)])
    res = NormalizedCut(
        cut / vol_a + cut / vol_b,
        (y.T * L * y)[0] / (y.T * D * y)[0],
        y,
        (y.T * D * sp.ones(n, 1))[0],
        L,
        D,
        w,
        s,
    )
    if side_a is None:
        return res
    side = _side(side_a, n)
    values = {s[i]: int(i in side) for i in range(n)}
    return res._replace(
        ncut=res.ncut.subs(values),
        rayleigh=res.rayleigh.subs(values),
        indicator=res.indicator.subs(values),
        constraint=res.constraint.subs(values),
    )


@cache
def _ncut_fn(n: int):
    nc = normalized_cut(n, None)
    return sp.lambdify([list(nc.weights.values()), list(nc.membership)], nc.rayleigh, "math"), list(
        nc.weights
    )


def normalized_cut_numeric(W, side_a) -> float:
    r"""Evaluate the *derived* Rayleigh quotient :math:`y^\top Ly / y^\top Dy` of :func:`normalized_cut`.

    Parameters
    ----------
    W : array_like or sparse, shape (n, n)
        Symmetric non-negative weights, ``2 <= n <= 8`` (diagonal ignored); both sides need a
        positive volume.
    side_a : sequence of int
        Nodes of one side of the cut.

    Returns
    -------
    float
        :math:`\mathrm{Ncut}(A, B)`.

    Examples
    --------
    >>> W = [[0, 1, 0.1], [1, 0, 0.1], [0.1, 0.1, 0]]
    >>> round(normalized_cut_numeric(W, [2]), 4)  # cut 0.2, volumes 2.2 and 0.2
    1.0909
    """
    Wn = _weight_matrix(W, "W", _NCUT_MAX)
    n = Wn.shape[0]
    side = _side(side_a, n)
    np.fill_diagonal(Wn, 0.0)
    deg = Wn.sum(axis=1)
    in_a = np.isin(np.arange(n), side)
    if deg[in_a].sum() <= 0 or deg[~in_a].sum() <= 0:
        raise ValueError("W must give both sides of the cut a positive volume (sum of degrees)")
    f, edges = _ncut_fn(n)
    return float(f([Wn[a, b] for a, b in edges], [float(x) for x in in_a]))


# --------------------------------------------------------------------------------------------------
# §7 / lesson 5: the chi-square gate
# --------------------------------------------------------------------------------------------------
class ChiSquare(NamedTuple):
    """Result of :func:`chi2_distribution` (sympy expressions in ``gamma``)."""

    cdf: sp.Expr  #: P(C <= gamma)
    density: sp.Expr  #: d cdf / d gamma
    mean: sp.Expr  #: E[C]
    variance: sp.Expr  #: Var[C]
    sphere_area: sp.Expr  #: surface of the unit sphere in R^m, from normalisation
    gamma: sp.Symbol


_CHI2_MAX = 6


def chi2_distribution(m: int = 2) -> ChiSquare:
    r"""Distribution of the squared Mahalanobis distance of a Gaussian innovation (§7, lesson 5).

    If :math:`\nu\sim\mathcal N(0, S)` in :math:`\mathbb R^m` and :math:`S = LL^\top`, then
    :math:`u = L^{-1}\nu\sim\mathcal N(0, I_m)` and :math:`C = \nu^\top S^{-1}\nu = \lVert u\rVert^2`.
    In spherical coordinates the density of :math:`u` at radius :math:`r` is
    :math:`(2\pi)^{-m/2}e^{-r^2/2}` on a sphere of area :math:`A_m r^{m-1}`; :math:`A_m` is derived
    from the normalisation :math:`\int_0^\infty A_m r^{m-1}(2\pi)^{-m/2}e^{-r^2/2}\,dr = 1`, and

    .. math::  P(C\le\gamma) = \int_0^{\sqrt\gamma} A_m r^{m-1}(2\pi)^{-m/2}e^{-r^2/2}\,dr,\qquad
               \mathbb E[C] = m,\quad \operatorname{Var}[C] = 2m,

    the :math:`\chi^2_m` distribution (e.g. :math:`1 - e^{-\gamma/2}` for m = 2), which is what
    :func:`flowtrack.association.chi2_gate` inverts.

    Parameters
    ----------
    m : int
        Measurement dimension, ``1 <= m <= 6``.

    Returns
    -------
    ChiSquare

    Examples
    --------
    >>> chi = chi2_distribution(2)
    >>> chi.cdf, chi.mean, chi.variance, chi.sphere_area
    (1 - exp(-gamma/2), 2, 4, 2*pi)
    """
    m = _small_int(m, "m", 1, _CHI2_MAX)
    r = sp.Symbol("r", positive=True)
    gamma = sp.Symbol("gamma", positive=True)
    radial = r ** (m - 1) * sp.exp(-(r**2) / 2) / (2 * sp.pi) ** sp.Rational(m, 2)
    area = sp.simplify(1 / sp.integrate(radial, (r, 0, sp.oo)))
    dens_r = area * radial
    cdf = sp.simplify(sp.integrate(dens_r, (r, 0, sp.sqrt(gamma))))
    mean = sp.simplify(sp.integrate(r**2 * dens_r, (r, 0, sp.oo)))
    variance = sp.simplify(sp.integrate(r**4 * dens_r, (r, 0, sp.oo)) - mean**2)
    return ChiSquare(cdf, sp.simplify(sp.diff(cdf, gamma)), mean, variance, area, gamma)


def chi2_gate_closed_form(m: int = 2) -> sp.Expr:
    r"""The gate :math:`\gamma(p)` solving :math:`P(C\le\gamma) = p` with sympy (m = 1 or 2).

    Examples
    --------
    >>> chi2_gate_closed_form(2)  # = -2 log(1 - p)
    2*log(-1/(p - 1))
    >>> chi2_gate_closed_form(1)
    2*erfinv(p)**2
    """
    m = _small_int(m, "m", 1, 2)
    chi = chi2_distribution(m)
    p = sp.Symbol("p", positive=True)
    (root,) = sp.solve(sp.Eq(chi.cdf, p), chi.gamma)
    return root


@cache
def _chi2_cdf_fn(m: int):
    chi = chi2_distribution(m)
    return sp.lambdify(chi.gamma, chi.cdf, "scipy")


def chi2_cdf_numeric(gamma, m: int = 2) -> float:
    r"""Evaluate the *derived* :math:`P(C \le \gamma)` of :func:`chi2_distribution` (``gamma >= 0``).

    Examples
    --------
    >>> round(chi2_cdf_numeric(9.2103, 2), 4)
    0.99
    """
    g = nonnegative(gamma, "gamma")
    m = _small_int(m, "m", 1, _CHI2_MAX)
    return 0.0 if g == 0 else float(_chi2_cdf_fn(m)(g))


def chi2_gate_numeric(m: int, prob) -> float:
    r"""The gate :math:`\gamma` with :math:`P(C\le\gamma) = p`, by root-finding on the *derived* CDF.

    Independent of :func:`flowtrack.association.chi2_gate` (which inverts the regularised incomplete
    gamma function): bracketing and Brent's method on :func:`chi2_cdf_numeric`.

    Examples
    --------
    >>> round(chi2_gate_numeric(2, 0.99), 4)
    9.2103
    """
    from scipy.optimize import brentq

    m = _small_int(m, "m", 1, _CHI2_MAX)
    p = probability(prob, "prob")
    hi = float(m)
    while chi2_cdf_numeric(hi, m) < p:
        hi *= 2.0
    return float(brentq(lambda g: chi2_cdf_numeric(g, m) - p, 0.0, hi, xtol=1e-14, rtol=1e-15))


# --------------------------------------------------------------------------------------------------
# Problem 4 / lesson 5: the assignment problem as a linear program
# --------------------------------------------------------------------------------------------------
def assignment_constraints(n_tracks: int = 2, n_detections: int = 3) -> tuple[sp.Matrix, sp.Matrix]:
    r"""Constraint matrix of the assignment problem, :math:`A y \le \mathbf 1`, from its constraints.

    With :math:`y_{ij}\in\{0,1\}` ("track i takes detection j"), each track takes at most one detection,
    :math:`\sum_j y_{ij}\le 1`, and each detection goes to at most one track,
    :math:`\sum_i y_{ij}\le 1`. :func:`sympy.linear_eq_to_matrix` turns these M + N expressions into
    :math:`A` (rows: tracks, then detections; columns: :math:`y` row-major). :math:`A` is the incidence
    matrix of the complete bipartite graph, *totally unimodular* (:func:`is_totally_unimodular`), so
    the LP relaxation :math:`y\ge 0` has an integral optimum (:func:`assignment_lp_numeric`).

    Parameters
    ----------
    n_tracks, n_detections : int >= 1
        M and N, ``M * N <= 100``.

    Returns
    -------
    (A, Y) : sympy.Matrix (M + N, M N), sympy.Matrix (M, N) of the symbols ``y_ij``

    Examples
    --------
    >>> A, Y = assignment_constraints(2, 2)
    >>> A
    Matrix([
    [1, 1, 0, 0],
    [0, 0, 1, 1],
    [1, 0, 1, 0],
    [0, 1, 0, 1]])
    """
    M = positive_int(n_tracks, "n_tracks")
    N = positive_int(n_detections, "n_detections")
    if M * N > 100:
        raise ValueError(f"n_tracks * n_detections must be <= 100, got {M} * {N}")
    Y = sp.Matrix(M, N, lambda i, j: sp.Symbol(f"y_{i + 1}_{j + 1}", nonnegative=True))
    rows = [sum(Y[i, :]) - 1 for i in range(M)] + [sum(Y[:, j]) - 1 for j in range(N)]
    A, _ = sp.linear_eq_to_matrix(rows, list(Y))
    return A, Y


def assignment_count(n_tracks: int = 2, n_detections: int = 3) -> sp.Integer:
    r"""Number of feasible associations (matchings) :math:`\sum_k \binom Mk\binom Nk k!` (sympy sum).

    Examples
    --------
    >>> assignment_count(2, 3)
    13
    """
    M = positive_int(n_tracks, "n_tracks")
    N = positive_int(n_detections, "n_detections")
    k = sp.Symbol("k", integer=True, nonnegative=True)
    return sp.summation(sp.binomial(M, k) * sp.binomial(N, k) * sp.factorial(k), (k, 0, min(M, N)))


def is_totally_unimodular(A) -> bool:
    r"""Whether every square submatrix of ``A`` has determinant -1, 0 or 1 (exact, sympy; small A).

    Examples
    --------
    >>> is_totally_unimodular(assignment_constraints(2, 2)[0])
    True
    >>> is_totally_unimodular(sp.Matrix([[1, 1, 0], [0, 1, 1], [1, 0, 1]]))  # an odd cycle
    False
    """
    from itertools import combinations

    if not isinstance(A, sp.MatrixBase):
        A = sp.Matrix(as_array(A, "A", (None, None)).astype(np.int64).tolist())
    rows, cols = A.shape
    if sum(sp.binomial(rows, k) * sp.binomial(cols, k) for k in range(1, min(rows, cols) + 1)) > 20000:
        raise ValueError(f"A of shape {A.shape} has too many square submatrices for an exact check")
    for k in range(1, min(rows, cols) + 1):
        for r in combinations(range(rows), k):
            for c in combinations(range(cols), k):
                if A.extract(list(r), list(c)).det() not in (-1, 0, 1):
                    return False
    return True


@cache
def _assignment_A(M: int, N: int) -> np.ndarray:
    return np.array(assignment_constraints(M, N)[0].tolist(), dtype=float)


def assignment_lp_numeric(cost, reward=None) -> np.ndarray:
    r"""Solve the LP relaxation (:math:`y \ge 0`) of the assignment problem with the derived constraints.

    * ``reward=None``: every track is matched (requires M <= N): minimise :math:`\sum C_{ij}y_{ij}`
      subject to :math:`\sum_j y_{ij} = 1`, :math:`\sum_i y_{ij} \le 1` — the rectangular linear
      assignment problem of :func:`scipy.optimize.linear_sum_assignment`;
    * ``reward=gamma``: minimise :math:`\sum (C_{ij} - \gamma) y_{ij}` subject to :math:`Ay\le\mathbf 1`:
      a pair is taken when it is worth more than the reward it forgoes (a gate).

    Entries ``+inf`` of ``cost`` are forbidden pairs (bound :math:`y_{ij} = 0`). The dual simplex
    returns a vertex, integral by total unimodularity (checked; ``RuntimeError`` otherwise).

    Parameters
    ----------
    cost : array_like, shape (M, N)
        Finite or ``+inf`` entries, ``M * N <= 100``.
    reward : float, optional

    Returns
    -------
    ndarray of int, shape (M, N)
        The 0/1 assignment :math:`y`.

    Examples
    --------
    >>> assignment_lp_numeric([[1.0, 5.0, 9.0], [2.0, 3.0, 9.0]])
    array([[1, 0, 0],
           [0, 1, 0]])
    >>> assignment_lp_numeric([[1.0, 5.0, 9.0], [2.0, 3.0, 9.0]], reward=2.5)
    array([[1, 0, 0],
           [0, 0, 0]])
    """
    from scipy.optimize import linprog

    C = as_array(cost, "cost", ("M", "N"), finite=False)
    if np.isnan(C).any() or (C == -np.inf).any():
        raise ValueError("cost must contain finite values or +inf (forbidden pairs), not NaN or -inf")
    M, N = C.shape
    if M == 0 or N == 0 or M * N > 100:
        raise ValueError(f"cost must have shape (M, N) with 1 <= M * N <= 100, got {C.shape}")
    A = _assignment_A(M, N)
    allowed = np.isfinite(C).ravel()
    c = np.where(allowed, C.ravel(), 0.0)
    bounds = [(0.0, None if ok else 0.0) for ok in allowed]
    if reward is None:
        if M > N:
            raise ValueError(f"cost: every track can be matched only when M <= N, got shape {C.shape}")
        res = linprog(
            c, A_ub=A[M:], b_ub=np.ones(N), A_eq=A[:M], b_eq=np.ones(M), bounds=bounds, method="highs-ds"
        )
    else:
        gamma = float(as_array(reward, "reward", ()))
        res = linprog(c - gamma * allowed, A_ub=A, b_ub=np.ones(M + N), bounds=bounds, method="highs-ds")
    if res.status == 2:
        raise ValueError("cost: no assignment matches every track with the allowed (finite) pairs")
    if res.status != 0:  # pragma: no cover - bounded feasible LPs
        raise RuntimeError(f"linprog failed: {res.message}")
    y = res.x.reshape(M, N)
    if not np.allclose(y, np.round(y), atol=1e-7):  # pragma: no cover - total unimodularity
        raise RuntimeError("the LP vertex is not integral")
    return np.round(y).astype(np.int64)
