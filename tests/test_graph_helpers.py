"""The private shared helpers of flowtrack._graph (used by sceneflow, variational, clustering ...)."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import laplacian as csgraph_laplacian
from scipy.sparse.linalg import LinearOperator, cg

from flowtrack._graph import apply_transform, as_labels, block_pcg, knn_edges, laplacian
from flowtrack.variational import grid_laplacian


def _spd(n, rng):
    W = sp.random(n, n, density=0.1, random_state=rng)
    W = W + W.T
    return (laplacian(W.tocsr()) + sp.eye(n)).tocsr()


def test_block_pcg_joint_mode_is_scipy_cg_on_the_stacked_system():
    rng = np.random.default_rng(0)
    A = _spd(80, rng)
    B = rng.normal(size=(80, 3))
    n, C = B.shape
    dinv = 1.0 / A.diagonal()
    op = LinearOperator((n * C, n * C), matvec=lambda x: (A @ x.reshape(n, C)).ravel(), dtype=float)
    pre = LinearOperator(
        (n * C, n * C), matvec=lambda x: (dinv[:, None] * x.reshape(n, C)).ravel(), dtype=float
    )
    x_ref, _ = cg(op, B.ravel(), rtol=1e-10, atol=0.0, maxiter=1000, M=pre)
    X, its, ok = block_pcg(A, B, 1e-10, 1000, per_column=False)
    assert ok and its > 0
    np.testing.assert_array_equal(X.ravel(), x_ref)
    assert np.linalg.norm(B - A @ X) < 1e-10 * np.linalg.norm(B)


def test_block_pcg_per_column_tolerance_and_callback():
    rng = np.random.default_rng(1)
    A = _spd(60, rng)
    B = rng.normal(size=(60, 3)) * [1.0, 1e-6, 1e3]
    seen = []
    X, its, ok = block_pcg(A, B, 1e-9, 1000, callback=lambda x: seen.append(x.copy()))
    assert ok and len(seen) == its
    res = np.linalg.norm(B - A @ X, axis=0) / np.linalg.norm(B, axis=0)
    assert (res <= 1e-9).all()
    # zero right-hand side: zero solution, no iteration, in both modes
    for per_column in (True, False):
        X0, its0, ok0 = block_pcg(A, np.zeros((60, 2)), 1e-9, 100, per_column=per_column)
        assert ok0 and its0 == 0 and not X0.any()


def test_knn_edges_duplicates_and_radius():
    P = np.array([[0.0, 0, 0], [0.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0]])
    rows, cols, dist = knn_edges(P, 2)
    assert (rows != cols).all()
    np.testing.assert_array_equal(np.bincount(rows), [2, 2, 2, 2])
    rows, cols, dist = knn_edges(P, 5, radius=0.5)  # k >= N: every other point within the radius
    assert (rows != cols).all() and (dist <= 0.5).all()
    np.testing.assert_array_equal(np.bincount(rows, minlength=4), [2, 2, 2, 0])


def test_laplacians():
    rng = np.random.default_rng(2)
    W = sp.random(30, 30, density=0.2, random_state=rng)
    W = (W + W.T).tocsr()
    W.setdiag(0)
    W.eliminate_zeros()
    L, d = laplacian(W, return_diag=True)
    np.testing.assert_allclose(L.toarray(), csgraph_laplacian(W.toarray()), atol=1e-14)
    np.testing.assert_allclose(d, W.toarray().sum(1))
    Ln = laplacian(W, normed=True)
    np.testing.assert_allclose(Ln.toarray(), csgraph_laplacian(W.toarray(), normed=True), atol=1e-14)
    np.testing.assert_array_equal(grid_laplacian(3, 4).toarray() @ np.ones(12), np.zeros(12))


def test_apply_transform():
    T = np.eye(4)
    T[:3, :3] = [[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T[:3, 3] = [1.0, 2, 3]
    np.testing.assert_array_equal(apply_transform(T, np.array([[1.0, 0, 0]])), [[1.0, 3, 3]])


def test_as_labels_rules():
    assert as_labels([0.0, 2.0], n=2, integral_floats=True).dtype == np.int64
    with pytest.raises(ValueError, match="lab"):
        as_labels([0.5, 2.0], "lab", integral_floats=True)
    with pytest.raises(ValueError, match="labels"):
        as_labels([0.0, 2.0])
    with pytest.raises(TypeError, match="labels"):
        as_labels([0.0, 2.0], type_error=True)
    with pytest.raises(ValueError, match="shape"):
        as_labels([0, 1], n=3)
    with pytest.raises(ValueError, match=">= -1"):
        as_labels([0, -2], min_label=-1)
