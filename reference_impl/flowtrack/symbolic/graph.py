r"""Symbolic derivations of lesson 3 (graph scene flow): the normal equations of the graph energy (§4)
and the commutation matrix that splits them into three N×N systems.

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np
import sympy as sp

from .._validation import as_array, nonnegative, positive, positive_int
from ._common import laplacian, pairs, small_int, symbolic_weights, weight_matrix

__all__ = [
    "GraphNormalEquations",
    "commutation_matrix",
    "graph_normal_equations",
    "graph_normal_equations_numeric",
]


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
    n = small_int(n_points, "n_points", 2, _GRAPH_MAX)
    if edges is None:
        edge_list = pairs(n)
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
    w, W = symbolic_weights(n, edge_list, nonnegative=True)
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
        laplacian=laplacian(W),
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
    Wn = weight_matrix(W, "W", _GRAPH_MAX)
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
