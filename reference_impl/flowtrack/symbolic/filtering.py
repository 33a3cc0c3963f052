r"""Symbolic derivations of lesson 4 (Bayes and Kalman filtering): the white-noise-acceleration process
noise (§6), the Kalman gain as the minimiser of the posterior trace (§6), the Gaussian posterior
(Problem 3) and the scalar steady-state variance (§11.2).

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from .._validation import as_array, check_psd, nonnegative, positive, positive_int

__all__ = [
    "kalman_gain",
    "kalman_gain_closed_form",
    "kalman_gain_numeric",
    "kalman_matrices",
    "kalman_posterior",
    "kalman_posterior_numeric",
    "steady_state_variance_scalar",
    "steady_state_variance_scalar_numeric",
    "white_noise_acceleration_Q",
    "white_noise_acceleration_Q_numeric",
]


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
