"""Sparse-graph and linear-algebra helpers shared by the scene-flow and clustering modules.

Private: :mod:`flowtrack.sceneflow`, :mod:`flowtrack.variational`, :mod:`flowtrack.clustering`,
:mod:`flowtrack.synth` and :mod:`flowtrack.datasets` build on these; none of them validates its
input beyond what its docstring says (the public callers do that).

- :func:`knn_edges` — directed k-nearest-neighbour edges of a point cloud, self-pairs removed.
- :func:`laplacian` — combinatorial :math:`D - W` or normalised :math:`I - D^{-1/2} W D^{-1/2}`.
- :func:`block_pcg` — preconditioned CG (Jacobi, or any SPD preconditioner such as an AMG V-cycle)
  on several right-hand sides at once, restarted on the true residual.
- :func:`apply_transform` — a 4×4 rigid transform applied to points.
- :func:`as_labels` — validation of an integer label vector.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

__all__ = ["apply_transform", "as_labels", "block_pcg", "knn_edges", "laplacian"]


def knn_edges(
    P: np.ndarray, k: int, radius: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges from every point to its ``k`` nearest *other* points (``cKDTree``, all cores).

    With duplicated points the point itself need not come first among the ``k + 1`` results (ties
    at distance 0); where it is absent the farthest result is dropped instead, so a point never has
    more than ``k`` edges and never an edge to itself. With ``radius`` only neighbours within that
    distance are kept (a point may then have fewer than ``k``); ``k >= N`` keeps every other point.

    Parameters
    ----------
    P : ndarray, shape (N, D)
        Finite points.
    k : int >= 1
    radius : float > 0, optional

    Returns
    -------
    rows, cols : ndarray of int, shape (E,)
        Edge ``rows[e] -> cols[e]``, grouped by row in increasing order, by increasing distance
        within a row (``E = N k`` without ``radius`` when ``k < N``).
    dist : ndarray, shape (E,)
        Euclidean edge lengths.

    Examples
    --------
    >>> rows, cols, dist = knn_edges(np.array([[0.0], [0.0], [0.0], [5.0]]), k=1)
    >>> bool((rows != cols).all()), rows.tolist()
    (True, [0, 1, 2, 3])
    """
    n = P.shape[0]
    kk = min(k + 1, n)
    if radius is None:
        dist, idx = cKDTree(P).query(P, k=kk, workers=-1)
    else:
        dist, idx = cKDTree(P).query(P, k=kk, distance_upper_bound=radius, workers=-1)
    dist = np.atleast_2d(dist).reshape(n, kk)
    idx = np.atleast_2d(idx).reshape(n, kk)
    not_self = idx != np.arange(n)[:, None]
    not_self[not_self.all(axis=1), -1] = False
    if radius is not None:
        not_self &= idx < n  # missing neighbours (beyond radius) come back as index n
    rows = np.broadcast_to(np.arange(n)[:, None], idx.shape)[not_self]
    return rows, idx[not_self], dist[not_self]


def laplacian(W: sp.spmatrix, normed: bool = False, return_diag: bool = False):
    r"""Graph Laplacian of symmetric non-negative affinities ``W`` (not validated), as CSR.

    ``normed=False``: :math:`L = D - W`, :math:`D = \operatorname{diag}(W \mathbf{1})`, sorted
    indices. ``normed=True``: :math:`L_\mathrm{sym} = I - D^{-1/2} W D^{-1/2}` (degrees clamped
    at 1e-300, so an isolated vertex gets a diagonal of 1). ``return_diag`` also returns the
    degrees (``normed=False``) or their clamped square roots (``normed=True``), as
    :func:`scipy.sparse.csgraph.laplacian` does.

    Examples
    --------
    >>> laplacian(sp.csr_matrix([[0.0, 2.0], [2.0, 0.0]])).toarray()
    array([[ 2., -2.],
           [-2.,  2.]])
    >>> laplacian(sp.csr_matrix([[0.0, 2.0], [2.0, 0.0]]), normed=True).toarray()
    array([[ 1., -1.],
           [-1.,  1.]])
    """
    d = np.asarray(W.sum(axis=1)).ravel()
    if normed:
        n = W.shape[0]
        d = np.sqrt(np.maximum(d, 1e-300))
        dinv = 1.0 / d
        L = (sp.eye(n) - sp.diags(dinv) @ W @ sp.diags(dinv)).tocsr()
    else:
        L = (sp.diags(d) - W).tocsr()
        L.sort_indices()
    return (L, d) if return_diag else L


def block_pcg(
    A: sp.spmatrix,
    B: np.ndarray,
    rtol: float,
    maxiter: int,
    *,
    X0: np.ndarray | None = None,
    per_column: bool = True,
    callback: Callable[[np.ndarray], None] | None = None,
    precond: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, int, bool]:
    r"""Preconditioned CG for :math:`A X = B` with ``B`` of shape (n, C), SPD ``A`` (n, n).

    The preconditioner is Jacobi (:math:`M^{-1} = \operatorname{diag}(A)^{-1}`) unless ``precond``
    is given: ``precond(R)`` applies a symmetric positive definite :math:`M^{-1}` to the (n, C)
    block of residuals (e.g. one algebraic-multigrid V-cycle per column).

    Two ways of running the C systems at once:

    - ``per_column=True``: C independent CG runs in lock-step (one step length per column); done
      when every column satisfies :math:`\|b_c - A x_c\| \le \text{rtol}\,\|b_c\|`.
    - ``per_column=False``: one CG run on the block-diagonal system :math:`\operatorname{diag}(A,
      \dots, A)\, \operatorname{vec} X = \operatorname{vec} B` (shared step lengths); done when
      :math:`\|B - A X\|_F < \text{rtol}\,\|B\|_F`. This is, operation for operation,
      :func:`scipy.sparse.linalg.cg` with ``atol=0`` on that system (including its return of 0 for
      :math:`B = 0`).

    The recursively updated residual drifts from the true one near machine precision, so when it
    passes the test the true residual is checked and CG restarted from the current iterate if that
    fails (at most 4 runs in all, sharing ``maxiter`` iterations).

    Parameters
    ----------
    A : sparse matrix (n, n)
    B : ndarray (n, C)
    rtol : float > 0
    maxiter : int
        Total CG iterations over all restarts.
    X0 : ndarray (n, C), optional
        Start (zeros by default).
    per_column : bool
    callback : callable, optional
        ``callback(X)`` after every iteration (``X`` is the live iterate: copy it to keep it).
    precond : callable, optional
        ``precond(R) -> Z`` for (n, C) arrays; Jacobi when None.

    Returns
    -------
    X : ndarray (n, C)
    iterations : int
    converged : bool
        Whether the true residual passes the test.

    Examples
    --------
    >>> A = sp.csr_matrix([[4.0, 1.0], [1.0, 3.0]])
    >>> X, its, ok = block_pcg(A, np.array([[1.0, 0.0], [2.0, 1.0]]), 1e-12, 10)
    >>> np.allclose(A @ X, [[1.0, 0.0], [2.0, 1.0]]), its <= 2, ok
    (True, True, True)
    """
    if precond is None:
        dinv = 1.0 / A.diagonal()

        def precond(R):
            return R * dinv[:, None]

    if per_column:

        def dot(U, V):
            return np.einsum("ij,ij->j", U, V)

        def norm(R):
            return np.linalg.norm(R, axis=0)

        def done(r, target):
            return bool((r <= target).all())

    else:

        def dot(U, V):
            return np.dot(U.ravel(), V.ravel())

        norm = np.linalg.norm

        def done(r, target):
            return bool(r < target)

    target = rtol * norm(B)
    if not per_column and not target > 0.0:  # B == 0 (scipy's cg returns b itself)
        return np.zeros_like(B), 0, True
    X = np.zeros_like(B) if X0 is None else np.array(X0, dtype=np.float64, copy=True)
    it = 0
    for _restart in range(4):
        R = B - A @ X
        if done(norm(R), target):
            return X, it, True
        Z = precond(R)
        P = Z.copy()
        rz = dot(R, Z)
        while it < maxiter:
            Q = A @ P
            pq = dot(P, Q)
            alpha = np.divide(rz, pq, out=np.zeros_like(rz), where=pq > 0)
            X += alpha * P
            R -= alpha * Q
            it += 1
            if callback is not None:
                callback(X)
            if done(norm(R), target):
                break
            Z = precond(R)
            rz_new = dot(R, Z)
            beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
            P = Z + beta * P
            rz = rz_new
    return X, it, done(norm(B - A @ X), target)


def apply_transform(T: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Apply the 4×4 rigid transform ``T`` to the rows of ``X`` (N, 3): :math:`R x + t`.

    Examples
    --------
    >>> T = np.eye(4); T[:3, 3] = [1.0, 2.0, 3.0]
    >>> apply_transform(T, np.zeros((1, 3)))
    array([[1., 2., 3.]])
    """
    return X @ T[:3, :3].T + T[:3, 3]


def as_labels(
    labels,
    name: str = "labels",
    n: int | None = None,
    *,
    integral_floats: bool = False,
    type_error: bool = False,
    min_label: int | None = None,
) -> np.ndarray:
    """Validate a label vector and return it as int64.

    Parameters
    ----------
    labels : array_like, shape (N,)
    name : str
        Argument name for the messages.
    n : int, optional
        Required length (any length when None).
    integral_floats : bool
        Also accept floating-point labels holding finite whole numbers (and an empty array of any
        dtype); otherwise the dtype must be an integer type.
    type_error : bool
        Raise ``TypeError`` instead of ``ValueError`` for a non-integer dtype.
    min_label : int, optional
        Smallest allowed label (e.g. -1 for "background").

    Raises
    ------
    ValueError
        Wrong shape, non-integer labels (unless ``type_error``), a label below ``min_label``.
    TypeError
        Non-integer dtype with ``type_error=True``.

    Examples
    --------
    >>> as_labels([0.0, 2.0, -1.0], n=3, integral_floats=True)
    array([ 0,  2, -1])
    """
    lab = np.asarray(labels)
    if lab.ndim != 1 or (n is not None and lab.shape[0] != n):
        want = "1-D" if n is None else f"shape ({n},)"
        raise ValueError(f"{name} must have {want}, got shape {lab.shape}")
    if not np.issubdtype(lab.dtype, np.integer):
        ok = integral_floats and (
            lab.size == 0
            or (
                np.issubdtype(lab.dtype, np.floating)
                and bool(np.isfinite(lab).all())
                and bool((lab == np.round(lab)).all())
            )
        )
        if not ok:
            raise (TypeError if type_error else ValueError)(
                f"{name} must hold integer labels, got dtype {lab.dtype}"
            )
    if min_label is not None and (lab < min_label).any():
        raise ValueError(f"{name} must be >= {min_label}, got {lab.min()}")
    return lab.astype(np.int64)
