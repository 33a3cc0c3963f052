r"""Symbolic derivations of lesson 6 (flow to tracks) and Problem 5: the mean velocity of a rigid
cluster, the motion-affinity threshold and the normalised cut.

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np
import sympy as sp

from .._validation import as_array, positive
from ._common import pairs, small_int, symbolic_weights, weight_matrix

__all__ = [
    "NormalizedCut",
    "RigidMeanVelocity",
    "affinity_threshold",
    "affinity_threshold_numeric",
    "normalized_cut",
    "normalized_cut_numeric",
    "rigid_mean_velocity",
    "rigid_mean_velocity_numeric",
    "rigid_twist_mean_velocity_numeric",
]


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
    n = small_int(n_points, "n_points", 1, 12)
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
    n = small_int(n_nodes, "n_nodes", 2, _NCUT_MAX)
    s = sp.Matrix(sp.symbols(f"s_1:{n + 1}", nonnegative=True))
    w, W = symbolic_weights(n, pairs(n), positive=True)
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
    Wn = weight_matrix(W, "W", _NCUT_MAX)
    n = Wn.shape[0]
    side = _side(side_a, n)
    np.fill_diagonal(Wn, 0.0)
    deg = Wn.sum(axis=1)
    in_a = np.isin(np.arange(n), side)
    if deg[in_a].sum() <= 0 or deg[~in_a].sum() <= 0:
        raise ValueError("W must give both sides of the cut a positive volume (sum of degrees)")
    f, edges = _ncut_fn(n)
    return float(f([Wn[a, b] for a, b in edges], [float(x) for x in in_a]))
