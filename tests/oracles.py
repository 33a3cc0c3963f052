"""Independent numerical oracles shared by the tests (never the code under test)."""

import numpy as np


def central_difference_jacobian(f, X, h=1e-6):
    """Per-point Jacobian of ``f: (N, d) -> (N, m)`` by central differences, shape (N, m, d)."""
    X = np.asarray(X, dtype=float)
    cols = []
    for j in range(X.shape[1]):
        e = np.zeros(X.shape[1])
        e[j] = h
        cols.append((f(X + e) - f(X - e)) / (2 * h))
    return np.stack(cols, axis=-1)
