"""Tests of flowtrack.clustering (Problem 5: motion clustering and track initialisation)."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist
from sklearn.metrics import adjusted_rand_score

from flowtrack.clustering import cluster_motion, motion_affinity_graph, tracks_from_clusters
from flowtrack.synth import make_scene


@pytest.fixture(scope="module")
def frame():
    sc = make_scene(n_objects=3, n_frames=1, noise=0.0, seed=3)
    return sc.frames[0]


def _gt(f):
    return np.where(f.labels == 0, -1, f.labels)


@pytest.mark.parametrize("method", ["spectral", "connected"])
@pytest.mark.parametrize("flow_noise", [0.0, 0.005])
def test_ari_on_synthetic_scene(frame, method, flow_noise):
    rng = np.random.default_rng(0)
    V = frame.gt_flow + rng.normal(0.0, flow_noise, frame.gt_flow.shape)
    lab = cluster_motion(frame.points, V, radius=0.02, sigma_v=0.05, min_speed=0.03, method=method)
    assert adjusted_rand_score(_gt(frame), lab) >= 0.95
    assert lab.max() == 2  # three moving clusters


@pytest.mark.parametrize("method", ["spectral", "connected"])
def test_n_clusters_given(frame, method):
    lab = cluster_motion(
        frame.points, frame.gt_flow, radius=0.02, sigma_v=0.05, n_clusters=3, min_speed=0.03, method=method
    )
    assert adjusted_rand_score(_gt(frame), lab) >= 0.95
    assert set(lab.tolist()) == {-1, 0, 1, 2}
    counts = np.bincount(lab[lab >= 0])
    assert (np.diff(counts) <= 0).all()  # sorted by size
    # asking for fewer clusters keeps the largest ones and merges the rest
    lab2 = cluster_motion(
        frame.points, frame.gt_flow, radius=0.02, sigma_v=0.05, n_clusters=2, min_speed=0.03
    )
    assert set(lab2.tolist()) == {-1, 0, 1}


def test_min_speed_marks_static(rng):
    P = rng.uniform(0, 1, (400, 3))
    V = np.zeros((400, 3))
    V[:150] = [0.2, 0.0, 0.0]
    V[150:160] = [0.0, 0.04, 0.0]  # slower than min_speed
    lab = cluster_motion(P, V, radius=0.3, sigma_v=0.05, min_speed=0.05)
    speed = np.linalg.norm(V, axis=1)
    np.testing.assert_array_equal(lab == -1, speed < 0.05)
    assert (lab[:150] == 0).all()


def _two_patches(dv):
    g = np.stack(np.meshgrid(np.arange(20), np.arange(20)), -1).reshape(-1, 2) * 0.01
    P = np.vstack([g, g + np.array([0.2, 0.0])])  # touching 20x20 grids
    P = np.hstack([P, np.zeros((800, 1))])
    V = np.zeros((800, 3))
    V[:400, 0] = 1.0
    V[400:, 0] = 1.0 + dv
    return P, V, np.repeat([0, 1], 400)


def test_spectral_splits_a_weakly_linked_component():
    # velocity jump of 2.2 sigma: the boundary edges (w = e^-4.84) stay in the graph, so both patches
    # are one connected component; spectral clustering must cut it
    P, V, gt = _two_patches(0.11)
    W = motion_affinity_graph(P, V, radius=0.0101, sigma_v=0.05)
    from scipy.sparse.csgraph import connected_components

    assert connected_components(W, directed=False)[0] == 1
    for n_clusters in (None, 2):
        lab = cluster_motion(P, V, radius=0.0101, sigma_v=0.05, n_clusters=n_clusters)
        assert adjusted_rand_score(gt, lab) == 1.0
    # a rigid patch with uniform motion is never split by the eigengap rule
    lab = cluster_motion(P, np.tile([1.0, 0, 0], (800, 1)), radius=0.0101, sigma_v=0.05)
    assert (lab == 0).all()


def test_connected_components_are_clusters():
    P, V, gt = _two_patches(0.5)
    lab = cluster_motion(P, V, radius=0.0101, sigma_v=0.05, method="connected")
    assert adjusted_rand_score(gt, lab) == 1.0


def brute_motion_affinity(P, V, radius, sigma_v, k):
    """Dense W from all pairwise distances: each point's <= k nearest neighbours within ``radius``,
    union with the transpose, motion weights exp(-|v_i - v_j|^2 / sigma_v^2)."""
    n = len(P)
    D = cdist(P, P)
    np.fill_diagonal(D, np.inf)
    E = np.zeros((n, n), dtype=bool)
    for i in range(n):
        near = [j for j in np.argsort(D[i], kind="stable")[:k] if D[i, j] <= radius]
        E[i, near] = True
    E |= E.T
    dv2 = cdist(V, V, "sqeuclidean")
    return np.where(E, np.exp(-dv2 / sigma_v**2), 0.0)


@pytest.mark.parametrize(
    ("dim", "radius", "k"),
    [(3, 0.4, 5), (3, 0.25, 3), (2, 0.2, 4), (3, 0.3, 100), (3, 0.01, 5)],
)
def test_affinity_graph_matches_brute_force(rng, dim, radius, k):
    n = 60
    P = rng.uniform(0, 1, (n, dim))
    V = rng.normal(size=(n, dim))
    sigma_v = 0.7
    W = motion_affinity_graph(P, V, radius=radius, sigma_v=sigma_v, k=k)
    Wd = W.toarray()
    np.testing.assert_allclose(Wd, brute_motion_affinity(P, V, radius, sigma_v, k), rtol=1e-12, atol=0)
    np.testing.assert_array_equal(Wd, Wd.T)
    assert (np.diag(Wd) == 0).all()
    in_radius = (cdist(P, P) <= radius).sum(1) - 1
    if radius >= 0.2 and k < n:
        # both limits bite: the k cap trims some points, the radius limits others
        assert (in_radius > k).any() and (in_radius < k).any()


def test_affinity_graph_brute_force_is_sensitive():
    """The oracle tells the cap, the radius and the symmetrisation apart on a hand-made example."""
    P = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.25, 0, 0], [0.45, 0, 0], [2.0, 0, 0]])
    V = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 2.0, 0], [0.0, 0, 0], [0.0, 0, 0]])
    W = brute_motion_affinity(P, V, radius=0.3, sigma_v=1.0, k=1)
    # nearest (radius 0.3): 0->1, 1->0, 2->1, 3->2, 4 -> none (2.0 away); union with the transpose
    e = np.exp
    expected = np.array(
        [
            [0, e(-1), 0, 0, 0],
            [e(-1), 0, e(-5), 0, 0],
            [0, e(-5), 0, e(-4), 0],
            [0, 0, e(-4), 0, 0],
            [0, 0, 0, 0, 0],
        ]
    )
    np.testing.assert_allclose(W, expected, rtol=1e-15)
    np.testing.assert_allclose(motion_affinity_graph(P, V, radius=0.3, sigma_v=1.0, k=1).toarray(), expected)


def test_tracks_from_clusters(rng):
    P = rng.normal(size=(60, 3))
    V = rng.normal(size=(60, 3))
    lab = rng.integers(-1, 3, 60)
    tracks = tracks_from_clusters(P, V, lab)
    assert len(tracks) == 3
    for c, (cen, vel) in enumerate(tracks):
        m = lab == c
        np.testing.assert_allclose(cen, P[m].sum(0) / m.sum(), rtol=1e-12)
        np.testing.assert_allclose(vel, V[m].sum(0) / m.sum(), rtol=1e-12)
    assert tracks_from_clusters(P, V, np.full(60, -1)) == []


def test_tracks_on_scene_match_object_motion(frame):
    lab = cluster_motion(frame.points, frame.gt_flow, radius=0.02, sigma_v=0.05, min_speed=0.03)
    tracks = tracks_from_clusters(frame.points, frame.gt_flow, lab)
    gt_means = {k: frame.points[frame.labels == k].mean(0) for k in (1, 2, 3)}
    for cen, _ in tracks:
        assert min(np.linalg.norm(cen - g) for g in gt_means.values()) < 1e-9


def _noisy(frame):
    rng = np.random.default_rng(1)
    return frame.gt_flow + rng.normal(0.0, 0.005, frame.gt_flow.shape)


@pytest.mark.parametrize(
    ("case", "n_clusters"),
    [("scene", None), ("scene", 3), ("scene", 2), ("weak_link", None), ("weak_link", 2)],
)
@pytest.mark.parametrize("method", ["spectral", "connected"])
def test_partition_invariant_to_point_order(frame, case, method, n_clusters):
    if case == "scene":
        P, V, kw = frame.points, _noisy(frame), {"radius": 0.02, "sigma_v": 0.05, "min_speed": 0.03}
    else:  # one connected component that the spectral step must cut (k-means on eigenvectors)
        P, V, _ = _two_patches(0.11)
        kw = {"radius": 0.0101, "sigma_v": 0.05}
    kw.update(method=method, n_clusters=n_clusters)
    a = cluster_motion(P, V, **kw)
    perm = np.random.default_rng(7).permutation(len(P))
    b = np.empty_like(a)
    b[perm] = cluster_motion(P[perm], V[perm], **kw)  # un-permute: b[i] is the label of point i
    assert adjusted_rand_score(a, b) == 1.0
    np.testing.assert_array_equal(a == -1, b == -1)  # same static set
    assert len(set(a[a >= 0].tolist())) >= 2  # a non-trivial partition
    # and the call is deterministic
    np.testing.assert_array_equal(cluster_motion(P, V, **kw), a)


@pytest.mark.parametrize(
    ("args", "kwargs", "exc", "word"),
    [
        ((np.zeros((5, 3)), np.zeros((4, 3))), {}, ValueError, "flow"),
        ((np.zeros((5, 4)), np.zeros((5, 4))), {}, ValueError, "points"),
        ((np.full((5, 3), np.nan), np.zeros((5, 3))), {}, ValueError, "points"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"radius": 0.0}, ValueError, "radius"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"sigma_v": -1.0}, ValueError, "sigma_v"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"method": "kmeans"}, ValueError, "method"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"n_clusters": 0}, ValueError, "n_clusters"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"min_speed": -0.1}, ValueError, "min_speed"),
        ((np.zeros((5, 3)), np.zeros((5, 3))), {"k": 1.5}, TypeError, "k"),
        (("abc", np.zeros((5, 3))), {}, TypeError, "points"),
    ],
)
def test_bad_inputs(args, kwargs, exc, word):
    kw = {"radius": 0.1, "sigma_v": 0.1, **kwargs}
    with pytest.raises(exc, match=word):
        cluster_motion(*args, **kw)


def test_tracks_bad_inputs():
    with pytest.raises(ValueError, match="labels"):
        tracks_from_clusters(np.zeros((3, 3)), np.zeros((3, 3)), [0, 1])
    with pytest.raises(TypeError, match="labels"):
        tracks_from_clusters(np.zeros((3, 3)), np.zeros((3, 3)), [0.0, 1.0, 0.5])
    with pytest.raises(ValueError, match="labels"):
        tracks_from_clusters(np.zeros((3, 3)), np.zeros((3, 3)), [0, -2, 1])
