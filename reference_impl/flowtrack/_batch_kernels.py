"""Kernels of :class:`flowtrack.batch_kalman.BatchKalmanFilter`, vectorised over the track axis.

Stacks of small symmetric positive definite matrices are factorised, solved and inverted with the
matrix axes unrolled (loops over at most ``UNROLL_MAX_DIM`` rows) and the track axis vectorised;
the thin GEMMs are cut into single-threaded pieces.
"""

from __future__ import annotations

import numpy as np

from ._linear_gaussian import cholesky_innovation, innovation_not_pd

#: Up to this matrix size, Cholesky factorisations and solves are unrolled over the matrix axes
#: (vectorised over tracks); larger ones loop over rows with batched products.
UNROLL_MAX_DIM = 4


def batched_cholesky(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack ``S (k, m, m)``; ``ValueError`` if one is not PD."""
    m = S.shape[1]
    if m > UNROLL_MAX_DIM:
        return cholesky_innovation(S)
    L = np.zeros_like(S)
    for j in range(m):
        d = S[:, j, j] - (L[:, j, :j] ** 2).sum(axis=1)
        if not (d > 0).all():
            raise innovation_not_pd()
        L[:, j, j] = np.sqrt(d)
        for i in range(j + 1, m):
            L[:, i, j] = (S[:, i, j] - (L[:, i, :j] * L[:, j, :j]).sum(axis=1)) / L[:, j, j]
    return L


def batched_cho_solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``(L Lᵀ) X = B`` for stacks ``L (k, m, m)``, ``B (k, m, r)`` by substitution.

    Forward ``L Y = B``, then backward ``Lᵀ X = Y``, vectorised over the stack (and, for
    ``m > UNROLL_MAX_DIM``, over the already solved rows: one batched product per row).
    """
    m = L.shape[1]
    if m > UNROLL_MAX_DIM:
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
GEMM_SINGLE_THREAD_WORK = 200_000


def gemm_over_columns(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A (r, k) @ B (k, M)`` as GEMMs over blocks of columns small enough to stay single-threaded."""
    r, k = A.shape
    M = B.shape[1]
    step = max(1, GEMM_SINGLE_THREAD_WORK // max(1, r * k))
    if M <= step:
        return A @ B
    out = np.empty((r, M))
    for s in range(0, M, step):
        np.matmul(A, B[:, s:s + step], out=out[:, s:s + step])
    return out


SIGN2 = np.array([[1.0, -1.0], [-1.0, 1.0]])[:, :, None]


def spd_inverse_cm(S: np.ndarray, sel) -> tuple[np.ndarray, np.ndarray]:
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
        L = batched_cholesky(St)
        inv = batched_cho_solve(L, np.broadcast_to(np.eye(m), St.shape).copy())
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
        adj = S[::-1, ::-1] * SIGN2                                       # [[d, -b], [-b, a]]
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
        raise innovation_not_pd()
    if sel is None:
        inv_det = 1.0 / det
    else:
        det = np.where(sel, det, 1.0)
        inv_det = np.where(sel, 1.0 / det, 0.0)
    adj *= inv_det
    return adj, np.log(det)

