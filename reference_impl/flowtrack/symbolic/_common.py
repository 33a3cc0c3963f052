"""Helpers shared by the graph and clustering derivations of :mod:`flowtrack.symbolic`."""

from __future__ import annotations

import numpy as np
import sympy as sp

from .._validation import positive_int


def small_int(value, name: str, minimum: int, maximum: int) -> int:
    """``positive_int(value, name, minimum)`` that is also at most ``maximum`` (sizes sympy can handle)."""
    v = positive_int(value, name, minimum=minimum)
    if v > maximum:
        raise ValueError(f"{name} must be <= {maximum} for the symbolic derivation, got {v}")
    return v


def weight_matrix(W, name: str, n_max: int) -> np.ndarray:
    """A dense, symmetric, non-negative (N, N) weight matrix with 2 <= N <= n_max (a fresh copy)."""
    from ..sceneflow import check_affinity  # the affinity check of graph scene flow, dense or sparse

    A = check_affinity(W, name).toarray()
    if not 2 <= A.shape[0] <= n_max:
        raise ValueError(f"{name} must have shape (N, N) with 2 <= N <= {n_max}, got {A.shape}")
    return A


def pairs(n: int) -> list[tuple[int, int]]:
    """All index pairs ``(a, b)`` with ``a < b < n``."""
    return [(a, b) for a in range(n) for b in range(a + 1, n)]


def symbolic_weights(n: int, edges, **assumptions) -> tuple[dict, sp.Matrix]:
    """Weight symbols ``w_ab`` (1-based names) for the edges, and the symmetric matrix W."""
    w = {(a, b): sp.Symbol(f"w_{a + 1}_{b + 1}", **assumptions) for a, b in edges}
    W = sp.zeros(n, n)
    for (a, b), wab in w.items():
        W[a, b] = W[b, a] = wab
    return w, W


def laplacian(W: sp.Matrix) -> sp.Matrix:
    """The combinatorial Laplacian :math:`D - W` of a symbolic weight matrix."""
    n = W.shape[0]
    return sp.diag(*[sum(W.row(a)) for a in range(n)]) - W
