r"""Symbolic derivations of lesson 5 (multi-object tracking): the chi-square gate (§7) and the
assignment problem as a linear program with a totally unimodular constraint matrix (Problem 4).

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np
import sympy as sp

from .._validation import as_array, nonnegative, positive_int, probability
from ._common import small_int

__all__ = [
    "ChiSquare",
    "assignment_constraints",
    "assignment_count",
    "assignment_lp_numeric",
    "chi2_cdf_numeric",
    "chi2_distribution",
    "chi2_gate_closed_form",
    "chi2_gate_numeric",
    "is_totally_unimodular",
]


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
    m = small_int(m, "m", 1, _CHI2_MAX)
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
    m = small_int(m, "m", 1, 2)
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
    m = small_int(m, "m", 1, _CHI2_MAX)
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

    m = small_int(m, "m", 1, _CHI2_MAX)
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
