"""Tests of flowtrack.clustering (Problem 5: motion clustering and track initialisation)."""

import numpy as np
import pytest
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


def test_affinity_weights(rng):
    P = rng.uniform(0, 1, (50, 3))
    V = rng.normal(size=(50, 3))
    W = motion_affinity_graph(P, V, radius=0.4, sigma_v=0.7, k=5).tocoo()
    i, j, w = W.row, W.col, W.data
    np.testing.assert_allclose(w, np.exp(-np.sum((V[i] - V[j]) ** 2, 1) / 0.49), rtol=1e-12)
    assert (np.linalg.norm(P[i] - P[j], axis=1) <= 0.4).all() and (i != j).all()
    D = W.toarray()
    np.testing.assert_array_equal(D, D.T)


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


def test_deterministic(frame):
    rng = np.random.default_rng(1)
    V = frame.gt_flow + rng.normal(0.0, 0.005, frame.gt_flow.shape)
    a = cluster_motion(frame.points, V, radius=0.02, sigma_v=0.05, min_speed=0.03, n_clusters=3)
    b = cluster_motion(frame.points, V, radius=0.02, sigma_v=0.05, min_speed=0.03, n_clusters=3)
    np.testing.assert_array_equal(a, b)


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
