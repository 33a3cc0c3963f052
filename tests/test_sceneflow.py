"""Tests of flowtrack.sceneflow: graph scene flow, kNN graphs, Laplacians, ICP flow and metrics.

Oracles are built here, independently of the code under test: brute-force kNN from the full distance
matrix, the syllabus' dense 3N system ``kron(L, I3) + dt^2 I`` solved by ``np.linalg.solve``, known
rigid transforms, and metric values counted by hand.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtrack import _graph_solver, sceneflow
from flowtrack.sceneflow import (
    check_affinity,
    graph_laplacian,
    graph_scene_flow,
    knn_graph,
    nearest_neighbor_targets,
    rigid_flow_per_cluster,
    rigid_scene_flow,
    scene_flow_metrics,
)

SOLVERS = ["auto", "cg", "splu"] + (["cholmod"] if sceneflow.HAVE_CHOLMOD else [])
SOLVERS += ["amg"] if sceneflow.HAVE_PYAMG else []


# ----------------------------------------------------------------------------------------------
# independent oracles
# ----------------------------------------------------------------------------------------------
def brute_knn_affinity(X, k, sigma=None):
    """Dense W from the full distance matrix: kNN edges, union, Gaussian weights, median sigma."""
    n = len(X)
    D = np.sqrt(((X[:, None, :] - X[None, :, :]) ** 2).sum(-1))
    np.fill_diagonal(D, np.inf)
    nbr = np.argsort(D, axis=1)[:, :k]
    if sigma is None:
        sigma = np.median(np.take_along_axis(D, nbr, axis=1))
    E = np.zeros((n, n), dtype=bool)
    E[np.repeat(np.arange(n), k), nbr.ravel()] = True
    E |= E.T
    W = np.where(E, np.exp(-(np.where(E, D, 0.0) ** 2) / sigma**2), 0.0)
    return W


def dense_syllabus_solve(X, Y, dt, lam, W):
    """The syllabus' normal equations (A^T A + lam L kron I3) v = A^T b with A = dt I, b = Y - X."""
    n = len(X)
    L = np.diag(W.sum(1)) - W
    A = dt**2 * np.eye(3 * n) + lam * np.kron(L, np.eye(3))
    v = np.linalg.solve(A, dt * (Y - X).ravel())
    return v.reshape(n, 3)


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def box_surface(rng, n, size=(0.3, 0.2, 0.1), center=(0.0, 0.0, 0.0)):
    """n points uniformly on the surface of an axis-aligned box (area-weighted faces)."""
    a, b, c = size
    areas = np.array([b * c, b * c, a * c, a * c, a * b, a * b])
    face = rng.choice(6, size=n, p=areas / areas.sum())
    P = (rng.uniform(-0.5, 0.5, size=(n, 3))) * size
    axis = face // 2
    sign = np.where(face % 2 == 0, -0.5, 0.5)
    P[np.arange(n), axis] = sign * np.asarray(size)[axis]
    return P + center


def multi_body_scene(rng, noise=0.002, dt=0.1):
    """A table (static) and three boxes moving rigidly; the t+1 cloud is an independent resampling."""
    bodies = [  # (size, center, rotation axis, angle per frame, translation per frame)
        ((0.12, 0.08, 0.06), (-0.25, 0.0, 0.03), (0, 0, 1), 0.05, (0.012, 0.004, 0.0)),
        ((0.10, 0.10, 0.10), (0.05, 0.2, 0.05), (0, 0, 1), -0.04, (-0.006, -0.012, 0.0)),
        ((0.16, 0.06, 0.08), (0.25, -0.15, 0.04), (0, 0, 1), 0.0, (0.0, 0.015, 0.0)),
    ]

    def sample(t1):
        pts, gt, lab = [], [], []
        m = 6000  # the static table dominates a depth camera's view, as in flowtrack.synth
        table = np.column_stack([rng.uniform(-0.4, 0.4, m), rng.uniform(-0.3, 0.3, m), np.zeros(m)])
        pts.append(table)
        gt.append(np.zeros_like(table))
        lab.append(np.zeros(len(table), int))
        for j, (size, center, ax, ang, tr) in enumerate(bodies, start=1):
            P = box_surface(rng, 500, size, center)
            R, c = rot(ax, ang), np.asarray(center)
            moved = (P - c) @ R.T + c + tr
            pts.append(moved if t1 else P)
            gt.append((moved - P) / dt)
            lab.append(np.full(len(P), j))
        X = np.vstack(pts)
        return X + noise * rng.standard_normal(X.shape), np.vstack(gt), np.concatenate(lab)

    X, gt, lab = sample(False)
    Y, _, _ = sample(True)
    return X, Y, gt, lab


# ----------------------------------------------------------------------------------------------
# knn_graph and graph_laplacian
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("k", [1, 4, 8])
def test_knn_graph_matches_brute_force(rng, k):
    X = rng.uniform(size=(60, 3))
    W = knn_graph(X, k=k)
    assert sp.issparse(W) and W.shape == (60, 60)
    Wd = W.toarray()
    np.testing.assert_allclose(Wd, brute_knn_affinity(X, k), rtol=1e-12, atol=0)
    np.testing.assert_array_equal(Wd, Wd.T)
    assert (Wd >= 0).all() and (np.diag(Wd) == 0).all()
    # every point keeps at least its k own neighbours
    assert ((Wd > 0).sum(1) >= k).all()


def test_knn_graph_explicit_sigma_and_2d(rng):
    X = rng.normal(size=(40, 2))
    W = knn_graph(X, k=5, sigma=0.3).toarray()
    np.testing.assert_allclose(W, brute_knn_affinity(X, 5, 0.3), rtol=1e-12)


def test_knn_graph_duplicates_have_no_self_loops():
    X = np.array([[0.0, 0, 0], [0.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0]])
    W = knn_graph(X, k=2).toarray()
    assert (np.diag(W) == 0).all() and np.isfinite(W).all()
    np.testing.assert_array_equal(W, W.T)


def test_graph_laplacian_properties(rng):
    X = rng.uniform(size=(50, 3))
    W = knn_graph(X, k=6)
    L = graph_laplacian(W)
    Ld = L.toarray()
    Wd = W.toarray()
    np.testing.assert_allclose(Ld.sum(1), 0, atol=1e-12)
    np.testing.assert_allclose(Ld, Ld.T)
    assert np.linalg.eigvalsh(Ld).min() >= -1e-12
    x = rng.normal(size=50)
    iu = np.triu_indices(50, 1)
    quad = (Wd[iu] * (x[iu[0]] - x[iu[1]]) ** 2).sum()
    np.testing.assert_allclose(x @ Ld @ x, quad, rtol=1e-12)
    # dense input gives the same
    np.testing.assert_allclose(graph_laplacian(Wd).toarray(), Ld)


@pytest.mark.parametrize(
    "W, match",
    [
        (np.array([[0.0, 1.0], [2.0, 0.0]]), "symmetric"),
        (np.array([[0.0, -1.0], [-1.0, 0.0]]), "non-negative"),
        (np.ones((2, 3)), "W"),
        (np.array([[0.0, np.nan], [np.nan, 0.0]]), "NaN"),
        (sp.csr_matrix(np.array([[0.0, np.inf], [np.inf, 0.0]])), "NaN or inf"),
    ],
)
def test_graph_laplacian_rejects(W, match):
    with pytest.raises(ValueError, match=match):
        graph_laplacian(W)


# ----------------------------------------------------------------------------------------------
# graph scene flow
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("lam", [0.003, 0.05, 2.0])
def test_graph_flow_matches_dense_kron_system(rng, solver, lam):
    n, dt, k = 30, 0.1, 5
    X = rng.uniform(size=(n, 3))
    Y = X + 0.02 * rng.normal(size=(n, 3))
    V = graph_scene_flow(X, Y, dt, lam, k=k, solver=solver)
    expected = dense_syllabus_solve(X, Y, dt, lam, brute_knn_affinity(X, k))
    np.testing.assert_allclose(V, expected, rtol=1e-8, atol=1e-8 * np.abs(expected).max())


def _sparse_oracle(X, Y, dt, lam, W):
    """scipy's sparse direct solve of (dt² I + lam (D - W)) V = dt (Y - X), assembled here."""
    W = sp.csr_matrix(W)
    A = sp.diags(dt * dt + lam * np.asarray(W.sum(axis=1)).ravel()) - lam * W
    return np.column_stack([spla.spsolve(A.tocsc(), dt * (Y[:, c] - X[:, c])) for c in range(3)])


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("lam", [1e-3, 0.1, 1.0])
def test_graph_flow_on_a_volumetric_cloud_matches_spsolve(solver, lam):
    """Points filling a cube (not a camera surface): every solver, CG ones at their stated tol."""
    rng = np.random.default_rng(12)
    n, dt = 1500, 0.1
    X = rng.uniform(size=(n, 3))
    Y = X + 0.01 * np.sin(3 * X[:, ::-1]) + 0.002 * rng.normal(size=(n, 3))
    W = knn_graph(X, k=8)
    expected = _sparse_oracle(X, Y, dt, lam, W)
    V = graph_scene_flow(X, Y, dt, lam, W=W, solver=solver, tol=1e-8)
    rel = np.linalg.norm(V - expected, axis=0) / np.linalg.norm(expected, axis=0)
    assert rel.max() <= 2e-8, rel  # tol = 1e-8 per column for CG; direct solvers ~1e-14


@pytest.mark.skipif(not sceneflow.HAVE_PYAMG, reason="pyamg not installed")
def test_amg_preconditioner_is_symmetric_positive_definite_and_cuts_iterations():
    """CG needs an SPD M^-1; one V-cycle is, and it beats Jacobi's iteration count on a stiff system."""
    from flowtrack._graph import block_pcg

    rng = np.random.default_rng(3)
    n = 800
    X = rng.uniform(size=(n, 3))
    A, _ = sceneflow._graph_system(n, knn_graph(X, k=8), 0.1, 1.0)
    M = _graph_solver.amg_preconditioner(A)
    Minv = M(np.eye(n))
    np.testing.assert_allclose(Minv, Minv.T, atol=1e-10 * np.abs(Minv).max())
    assert np.linalg.eigvalsh((Minv + Minv.T) / 2).min() > 0
    B = rng.normal(size=(n, 3))
    _, it_jacobi, ok_j = block_pcg(A, B, 1e-10, 10_000)
    X_amg, it_amg, ok_a = block_pcg(A, B, 1e-10, 10_000, precond=M)
    assert ok_j and ok_a and it_amg * 3 < it_jacobi
    np.testing.assert_allclose(A @ X_amg, B, atol=1e-9 * np.abs(B).max())


@pytest.mark.skipif(not sceneflow.HAVE_CHOLMOD, reason="scikit-sparse not installed")
def test_cholmod_column_counts_are_the_factor_nonzeros():
    """Symbolic counts (no numeric work) against the non-zeros of dense and CHOLMOD numeric factors."""
    from sksparse.cholmod import analyze

    counts = _graph_solver.cholmod_counts()
    assert counts is not None
    rng = np.random.default_rng(5)
    X = rng.uniform(size=(200, 3))
    A, _ = sceneflow._graph_system(200, knn_graph(X, k=6), 0.1, 0.5)
    A = A + sp.diags(rng.uniform(0, 0.01, 200))  # generic values: no accidental cancellation
    perm = analyze(sp.csc_matrix(A), mode="simplicial", ordering_method="amd").P()
    c = counts.colcounts(A, perm)
    C = A.toarray()[np.ix_(perm, perm)]
    Ld = np.linalg.cholesky(C)
    np.testing.assert_array_equal(c, (np.abs(Ld) > 0).sum(axis=0))  # integers: exact
    assert c.sum() > 2 * (sp.triu(A).nnz)  # there is fill to see


@pytest.mark.skipif(not sceneflow.HAVE_CHOLMOD, reason="scikit-sparse not installed")
def test_auto_sees_the_fill_a_condition_bound_cannot():
    """Same N, similar kappa: a 2-D grid (a surface) factorises cheaply, a 3-D grid (a volume) not."""

    def grid_graph(shape):
        idx = np.arange(np.prod(shape)).reshape(shape)
        rows, cols = [], []
        for axis in range(len(shape)):
            a = np.take(idx, range(shape[axis] - 1), axis=axis).ravel()
            b = np.take(idx, range(1, shape[axis]), axis=axis).ravel()
            rows += [a, b]
            cols += [b, a]
        r, c = np.concatenate(rows), np.concatenate(cols)
        return sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(idx.size,) * 2)

    surface, volume = grid_graph((181, 181)), grid_graph((32, 32, 32))
    picks = {}
    for name, W in (("surface", surface), ("volume", volume)):
        A, kappa = sceneflow._graph_system(W.shape[0], W, 0.1, 1.0)
        assert 800 <= kappa <= 1300
        picks[name] = _graph_solver.auto_choice(A, kappa)[0]
    assert picks["surface"] == "cholmod"
    assert picks["volume"] in ("cg", "amg")


def test_graph_flow_auto_without_column_counts_or_pyamg(rng, monkeypatch):
    """The fallbacks: no ctypes column counts -> condition-bound rule; no pyamg -> "amg" fails clearly."""
    X = rng.uniform(size=(300, 3))
    Y = X + 0.02 * rng.normal(size=(300, 3))
    W = knn_graph(X, k=6)
    monkeypatch.setattr(_graph_solver, "_COUNTS", [None])
    monkeypatch.setattr(_graph_solver, "HAVE_PYAMG", False)
    for lam in (1e-3, 1.0):
        expected = _sparse_oracle(X, Y, 0.1, lam, W)
        V = graph_scene_flow(X, Y, 0.1, lam, W=W)
        np.testing.assert_allclose(V, expected, rtol=1e-7, atol=1e-8 * np.abs(expected).max())
    with pytest.raises(ValueError, match="solver='amg' needs pyamg"):
        graph_scene_flow(X, Y, 0.1, 0.1, W=W, solver="amg")


def test_graph_flow_cg_meets_stated_tolerance(rng):
    """CG with tol=1e-8 is within 1e-8 (relative, per column) of the exact solution even when stiff."""
    n, dt, lam = 400, 0.05, 5.0
    X = rng.uniform(size=(n, 3))
    Y = X + 0.01 * rng.normal(size=(n, 3))
    W = knn_graph(X, k=8)
    exact = dense_syllabus_solve(X, Y, dt, lam, W.toarray())
    V = graph_scene_flow(X, Y, dt, lam, W=W, solver="cg", tol=1e-8)
    rel = np.linalg.norm(V - exact, axis=0) / np.linalg.norm(exact, axis=0)
    assert rel.max() <= 1e-8


def test_graph_flow_with_W_skips_graph_build(rng, monkeypatch):
    n, dt, lam = 25, 0.2, 0.3
    X = rng.uniform(size=(n, 3))
    Y = X + 0.05 * rng.normal(size=(n, 3))
    A = rng.uniform(size=(n, n)) * (rng.uniform(size=(n, n)) < 0.2)
    Wd = np.triu(A, 1) + np.triu(A, 1).T

    def boom(*args, **kwargs):
        raise AssertionError("knn_graph must not be called when W is given")

    monkeypatch.setattr(sceneflow, "knn_graph", boom)
    for W in (Wd, sp.csr_matrix(Wd)):
        V = graph_scene_flow(X, Y, dt, lam, k=1000, W=W)  # k is ignored with W
        np.testing.assert_allclose(V, dense_syllabus_solve(X, Y, dt, lam, Wd), rtol=1e-8, atol=1e-10)


def test_graph_flow_lam_zero_is_raw_displacement(rng):
    X = rng.uniform(size=(5, 3))
    Y = rng.uniform(size=(5, 3))
    np.testing.assert_allclose(graph_scene_flow(X, Y, 0.1, 0.0), (Y - X) / 0.1, rtol=1e-15)
    np.testing.assert_allclose(graph_scene_flow(X, Y, 0.1, 0.0, k=50), (Y - X) / 0.1, rtol=1e-15)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    lam=st.floats(0.0, 10.0),
    dt=st.floats(0.01, 1.0),
    shift=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    seed=st.integers(0, 2**16),
)
def test_graph_flow_rigid_translation_is_exact(lam, dt, shift, seed):
    """L 1 = 0, so a common displacement c is reproduced exactly for every lam: v = c / dt."""
    X = np.random.default_rng(seed).uniform(size=(40, 3))
    V = graph_scene_flow(X, X + shift, dt, lam, k=4)
    np.testing.assert_allclose(V, np.broadcast_to(np.asarray(shift) / dt, V.shape), rtol=1e-7, atol=1e-7)


def test_graph_flow_beats_nearest_neighbour_on_noisy_multibody_scene(rng):
    dt = 0.1
    X, Y, gt, _ = multi_body_scene(rng, noise=0.002, dt=dt)
    T = nearest_neighbor_targets(X, Y)
    nn = scene_flow_metrics((T - X) / dt, gt)["epe3d"]
    graph = scene_flow_metrics(graph_scene_flow(X, T, dt, lam=0.3, k=8), gt)["epe3d"]
    assert graph <= 0.5 * nn, (graph, nn)


def test_graph_flow_beats_nearest_neighbour_on_synth_scene():
    synth = pytest.importorskip("flowtrack.synth")
    scene = synth.make_scene(n_objects=3, n_frames=2, image_size=(120, 160), noise=0.002, seed=3)
    f0, f1 = scene.frames[0], scene.frames[1]
    T = nearest_neighbor_targets(f0.points, f1.points)
    nn = scene_flow_metrics((T - f0.points) / scene.dt, f0.gt_flow)["epe3d"]
    V = graph_scene_flow(f0.points, T, scene.dt, lam=0.1, k=8)
    assert scene_flow_metrics(V, f0.gt_flow)["epe3d"] <= 0.5 * nn


def test_nearest_neighbor_targets_brute_force(rng):
    X = rng.uniform(size=(50, 3))
    Z = rng.uniform(size=(70, 3))
    D = ((X[:, None] - Z[None]) ** 2).sum(-1)
    np.testing.assert_array_equal(nearest_neighbor_targets(X, Z), Z[D.argmin(1)])


# ----------------------------------------------------------------------------------------------
# rigid (ICP) scene flow
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["point_to_point", "point_to_plane"])
def test_rigid_scene_flow_recovers_transform(rng, method):
    X = box_surface(rng, 3000)
    for _ in range(3):
        R = rot(rng.normal(size=3), np.deg2rad(rng.uniform(2, 10)))
        t = rng.uniform(-0.03, 0.03, size=3)
        Y = X @ R.T + t
        dt = 0.1
        flow, T = rigid_scene_flow(X, Y, dt, threshold=0.1, method=method, max_iter=100)
        np.testing.assert_allclose(T[:3, :3], R, atol=1e-6)
        np.testing.assert_allclose(T[:3, 3], t, atol=1e-6)
        np.testing.assert_allclose(T[3], [0, 0, 0, 1])
        np.testing.assert_allclose(flow, (Y - X) / dt, atol=1e-5)


def test_rigid_scene_flow_uses_init(rng):
    X = box_surface(rng, 2000)
    R, t = rot([0, 0, 1], np.deg2rad(30)), np.array([0.3, 0.0, 0.0])
    Y = X @ R.T + t
    init = np.eye(4)
    init[:3, :3], init[:3, 3] = rot([0, 0, 1], np.deg2rad(28)), [0.29, 0.005, 0.0]
    _, T = rigid_scene_flow(X, Y, 1.0, threshold=0.05, init=init, max_iter=100)
    np.testing.assert_allclose(T[:3, :3], R, atol=1e-6)
    np.testing.assert_allclose(T[:3, 3], t, atol=1e-6)


def test_rigid_flow_per_cluster(rng):
    A = box_surface(rng, 1500, center=(-0.4, 0, 0))
    B = box_surface(rng, 1500, size=(0.1, 0.25, 0.15), center=(0.4, 0, 0))
    S = rng.uniform(-1, 1, size=(200, 3)) * [1, 1, 0] + [0, 0, -0.5]  # "static" points
    X = np.vstack([A, B, S])
    labels = np.repeat([0, 1, -1], [len(A), len(B), len(S)])
    Ra, ta = rot([0, 0, 1], 0.1), np.array([0.01, 0.0, 0.0])
    Rb, tb = rot([1, 0, 0], -0.08), np.array([0.0, -0.02, 0.01])
    ca, cb = A.mean(0), B.mean(0)
    Y = np.vstack([(A - ca) @ Ra.T + ca + ta, (B - cb) @ Rb.T + cb + tb, S])
    dt = 0.1
    flow, Ts = rigid_flow_per_cluster(X, Y, labels, dt, threshold=0.05, max_iter=100, return_transforms=True)
    np.testing.assert_allclose(flow[labels >= 0], (Y - X)[labels >= 0] / dt, atol=1e-5)
    assert (flow[labels == -1] == 0).all()
    assert sorted(Ts) == [0, 1]
    np.testing.assert_allclose(Ts[1][:3, :3], Rb, atol=1e-6)
    # labels_t1 restricts the targets of each cluster to its own points
    flow2 = rigid_flow_per_cluster(X, Y, labels, dt, 0.05, labels_t1=labels, max_iter=100)
    np.testing.assert_allclose(flow2, flow, atol=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"threshold": 0.0}, "threshold"),
        ({"threshold": -1.0}, "threshold"),
        ({"dt": 0.0}, "dt"),
        ({"init": np.eye(3)}, "init"),
        ({"init": np.diag([1.0, 1.0, -1.0, 1.0])}, "init"),
        ({"init": 2 * np.eye(4)}, "init"),
        ({"method": "generalized"}, "method"),
        ({"points_t": np.zeros((2, 3))}, "points_t"),
        ({"points_t1": np.full((10, 3), np.nan)}, "points_t1"),
    ],
)
def test_rigid_scene_flow_rejects(rng, kwargs, match):
    args = {"points_t": rng.uniform(size=(10, 3)), "points_t1": rng.uniform(size=(10, 3)), "dt": 0.1}
    args["threshold"] = 0.1
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        rigid_scene_flow(**args)


# ----------------------------------------------------------------------------------------------
# metrics
# ----------------------------------------------------------------------------------------------
def test_metrics_hand_counted():
    gt = np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, 0.1], [0, 0, 0], [3.0, 0, 0]])
    err = np.array([[0.04, 0, 0], [0, 0.15, 0], [0, 0, 0.02], [0, 0, 0], [0, 0.35, 0]])
    # errors 0.04, 0.15, 0.02, 0, 0.35; relative 4 %, 7.5 %, 20 %, 0 (gt = 0, err = 0), 11.7 %
    # strict (e < 0.05 or r < 5 %): points 0, 2, 3          -> 3/5
    # relax  (e < 0.1  or r < 10 %): points 0, 1, 2, 3      -> 4/5
    # outliers (e > 0.3 or r > 10 %): points 2, 4           -> 2/5
    m = scene_flow_metrics(gt + err, gt)
    assert m["n"] == 5
    assert m["epe3d"] == pytest.approx((0.04 + 0.15 + 0.02 + 0 + 0.35) / 5, rel=1e-12)
    assert m["acc3d_strict"] == pytest.approx(3 / 5)
    assert m["acc3d_relax"] == pytest.approx(4 / 5)
    assert m["outliers"] == pytest.approx(2 / 5)
    mask = np.array([True, True, False, False, False])
    mm = scene_flow_metrics(gt + err, gt, mask=mask)
    assert mm["n"] == 2 and mm["epe3d"] == pytest.approx(0.095)
    assert (mm["acc3d_strict"], mm["acc3d_relax"], mm["outliers"]) == (0.5, 1.0, 0.0)


def test_metrics_zero_gt_guard_eps_and_dt():
    gt = np.zeros((2, 3))
    pred = np.array([[0.0, 0, 0], [0.01, 0, 0]])
    m = scene_flow_metrics(pred, gt)  # point 1: e = 0.01 < 0.05 (accurate) but r = inf (outlier)
    assert (m["acc3d_strict"], m["outliers"]) == (1.0, 0.5)
    m = scene_flow_metrics(pred, gt, eps=1.0)  # r = 0.01 / 1 = 1 %: no outlier
    assert m["outliers"] == 0.0
    # velocities: pred/gt in m/s with dt = 0.1 -> displacement error 0.02 m (< 0.05), 2 % relative
    g = np.array([[1.0, 0, 0]])
    m = scene_flow_metrics(g + np.array([0.2, 0, 0]), g, dt=0.1)
    assert m["epe3d"] == pytest.approx(0.02) and m["acc3d_strict"] == 1.0
    m0 = scene_flow_metrics(g, g, mask=np.array([False]))
    assert m0["n"] == 0 and np.isnan(m0["epe3d"])


@pytest.mark.parametrize(
    "pred, gt, kw, match",
    [
        (np.zeros((3, 2)), np.zeros((3, 2)), {}, "pred"),
        (np.zeros((3, 3)), np.zeros((4, 3)), {}, "gt"),
        (np.full((3, 3), np.inf), np.zeros((3, 3)), {}, "pred"),
        (np.zeros((3, 3)), np.zeros((3, 3)), {"mask": np.ones(3)}, "mask"),
        (np.zeros((3, 3)), np.zeros((3, 3)), {"mask": np.ones(2, bool)}, "mask"),
    ],
)
def test_metrics_rejects(pred, gt, kw, match):
    with pytest.raises(ValueError, match=match):
        scene_flow_metrics(pred, gt, **kw)


# ----------------------------------------------------------------------------------------------
# bad inputs of the graph functions
# ----------------------------------------------------------------------------------------------
def _good(n=10, seed=0):
    r = np.random.default_rng(seed)
    X = r.uniform(size=(n, 3))
    return X, X + 0.01


@pytest.mark.parametrize(
    "change, match",
    [
        ({"points_t": np.zeros((10, 2))}, "points_t"),
        ({"points_t": np.zeros((0, 3)), "targets": np.zeros((0, 3))}, "points_t"),
        ({"targets": np.zeros((9, 3))}, "targets"),
        ({"targets": np.full((10, 3), np.nan)}, "targets"),
        ({"dt": 0.0}, "dt"),
        ({"dt": -0.1}, "dt"),
        ({"dt": np.inf}, "dt"),
        ({"lam": -1e-3}, "lam"),
        ({"lam": np.nan}, "lam"),
        ({"k": 10}, "k"),
        ({"k": 0}, "k"),
        ({"sigma": 0.0}, "sigma"),
        ({"W": np.ones((9, 9))}, "W"),
        ({"W": np.array([[0.0, 1.0], [0.0, 0.0]])}, "W"),
        ({"solver": "qr"}, "solver"),
        ({"tol": 0.0}, "tol"),
    ],
)
def test_graph_scene_flow_rejects(change, match):
    X, Y = _good()
    args = {"points_t": X, "targets": Y, "dt": 0.1, "lam": 0.1}
    args.update(change)
    with pytest.raises(ValueError, match=match):
        graph_scene_flow(**args)


@pytest.mark.parametrize(
    "points, k, match",
    [(np.zeros((5, 3)), 5, "k"), (np.zeros((0, 3)), 1, "points"), (np.zeros(5), 1, "points")],
)
def test_knn_graph_rejects(points, k, match):
    with pytest.raises(ValueError, match=match):
        knn_graph(points, k=k)


def test_nearest_neighbor_targets_rejects():
    with pytest.raises(ValueError, match="points_t1"):
        nearest_neighbor_targets(np.zeros((3, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="points_t"):
        nearest_neighbor_targets(np.zeros((3, 4)), np.zeros((3, 3)))


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 12), k=st.integers(0, 20))
def test_knn_graph_k_range_property(n, k):
    X = np.random.default_rng(n).uniform(size=(n, 3))
    if 1 <= k < n:
        W = knn_graph(X, k=k)
        assert W.shape == (n, n) and ((W.toarray() > 0).sum(1) >= k).all()
    else:
        with pytest.raises(ValueError, match="k"):
            knn_graph(X, k=k)


@settings(max_examples=30, deadline=None)
@given(
    row=st.integers(0, 9),
    col=st.integers(0, 2),
    bad=st.sampled_from([np.nan, np.inf, -np.inf]),
    which=st.sampled_from(["points_t", "targets"]),
)
def test_graph_scene_flow_rejects_nonfinite_property(row, col, bad, which):
    X, Y = _good()
    args = {"points_t": X, "targets": Y}
    args[which] = args[which].copy()
    args[which][row, col] = bad
    with pytest.raises(ValueError, match=which):
        graph_scene_flow(args["points_t"], args["targets"], 0.1, 0.1, k=3)


@settings(max_examples=30, deadline=None)
@given(dt=st.floats(max_value=0.0, allow_nan=False), lam=st.floats(max_value=-1e-300, allow_nan=False))
def test_graph_scene_flow_rejects_bad_scalars_property(dt, lam):
    X, Y = _good()
    with pytest.raises(ValueError, match="dt"):
        graph_scene_flow(X, Y, dt, 0.1)
    with pytest.raises(ValueError, match="lam"):
        graph_scene_flow(X, Y, 0.1, lam)


def test_graph_flow_without_cholmod(rng, monkeypatch):
    """scikit-sparse is optional: "auto" falls back to CG/SuperLU, "cholmod" then fails clearly."""
    monkeypatch.setattr(_graph_solver, "HAVE_CHOLMOD", False)
    monkeypatch.setattr(_graph_solver, "_cholmod_cholesky", None)
    X = rng.uniform(size=(30, 3))
    Y = X + 0.02 * rng.normal(size=(30, 3))
    for lam in (0.003, 50.0):  # kappa below and above the CG limit
        expected = dense_syllabus_solve(X, Y, 0.1, lam, brute_knn_affinity(X, 5))
        V = graph_scene_flow(X, Y, 0.1, lam, k=5)
        np.testing.assert_allclose(V, expected, rtol=1e-8, atol=1e-8 * np.abs(expected).max())
    with pytest.raises(ValueError, match="solver"):
        graph_scene_flow(X, Y, 0.1, 0.1, k=5, solver="cholmod")


def test_check_affinity_accepts_dense_and_sparse_and_names_the_problem():
    W = np.array([[0.0, 2.0], [2.0, 0.0]])
    for given_W in (W, sp.coo_matrix(W)):
        out = check_affinity(given_W)
        assert sp.issparse(out)
        np.testing.assert_array_equal(out.toarray(), W)
    with pytest.raises(ValueError, match="Wx must be symmetric"):
        check_affinity([[0.0, 1.0], [2.0, 0.0]], "Wx")
    with pytest.raises(ValueError, match="non-negative"):
        check_affinity(-W)
    with pytest.raises(ValueError, match=r"shape \(3, 3\)"):
        check_affinity(W, n=3)
