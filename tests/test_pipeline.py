"""Re-matched graph flow, small-cluster removal and the demo's building blocks."""

import numpy as np
import pytest

from flowtrack.clustering import drop_small_clusters
from flowtrack.sceneflow import (
    graph_scene_flow,
    iterative_graph_scene_flow,
    nearest_neighbor_targets,
    scene_flow_metrics,
)
from flowtrack.synth import make_scene
from flowtrack_course.demo import DemoConfig, cluster_purity, estimate_clouds


@pytest.fixture(scope="module")
def pair():
    scene = make_scene(n_objects=3, n_frames=2, image_size=(240, 320), seed=0)
    f0, f1 = scene.frames
    return f0.points, f1.points, f0.gt_flow, f0.labels, scene.dt


def test_iterative_equals_one_graph_pass_with_one_iteration(pair):
    X, Y, _, _, dt = pair
    one = iterative_graph_scene_flow(X, Y, dt, 0.5, iterations=1)
    ref = graph_scene_flow(X, nearest_neighbor_targets(X, Y), dt, 0.5)
    np.testing.assert_allclose(one, ref, rtol=1e-7, atol=1e-9)


def test_iterative_with_lam_zero_is_nearest_neighbour(pair):
    X, Y, _, _, dt = pair
    np.testing.assert_allclose(
        iterative_graph_scene_flow(X, Y, dt, 0.0, iterations=3), (nearest_neighbor_targets(X, Y) - X) / dt
    )


def test_rematching_reduces_error_on_moving_objects(pair):
    X, Y, gt, _, dt = pair
    moving = np.linalg.norm(gt, axis=1) > 0
    single = graph_scene_flow(X, nearest_neighbor_targets(X, Y), dt, 1.0)
    rematched = iterative_graph_scene_flow(X, Y, dt, 1.0, iterations=5)
    e1 = scene_flow_metrics(single, gt, moving, dt=dt)["epe3d"]
    e5 = scene_flow_metrics(rematched, gt, moving, dt=dt)["epe3d"]
    assert e5 < 0.85 * e1, (e5, e1)


def test_rigid_translation_is_recovered_exactly():
    rng = np.random.default_rng(0)
    # two perpendicular planes moving together: every direction of motion is seen by some normal
    g = rng.uniform(0, 0.1, size=(400, 2))
    X = np.vstack([np.column_stack([g, np.zeros(400)]), np.column_stack([np.zeros(400), g])])
    shift = np.array([0.006, 0.004, 0.005])
    V = iterative_graph_scene_flow(X, X + shift, 0.1, 10.0, iterations=30, tol=1e-9)
    np.testing.assert_allclose(V.mean(axis=0), shift / 0.1, atol=2e-3)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"dt": 0.0}, "dt"),
        ({"lam": -1.0}, "lam"),
        ({"iterations": 0}, "iterations"),
        ({"tol": 0.0}, "tol"),
    ],
)
def test_iterative_bad_input(pair, kwargs, match):
    X, Y, _, _, dt = pair
    args = {"dt": dt, "lam": 1.0} | kwargs
    with pytest.raises(ValueError, match=match):
        iterative_graph_scene_flow(X, Y, **args)


def test_drop_small_clusters_against_counting():
    rng = np.random.default_rng(1)
    labels = rng.integers(-1, 8, size=500)
    out = drop_small_clusters(labels, 60)
    sizes = {c: int((labels == c).sum()) for c in range(8)}
    kept = sorted((c for c in sizes if sizes[c] >= 60), key=lambda c: -sizes[c])
    for new, old in enumerate(kept):
        assert np.array_equal(out == new, labels == old)
    dropped = [c for c in sizes if sizes[c] < 60] + [-1]
    assert (out[np.isin(labels, dropped)] == -1).all()
    with pytest.raises(ValueError, match="min_size"):
        drop_small_clusters(labels, 0)
    with pytest.raises(ValueError, match="labels"):
        drop_small_clusters(labels.astype(float), 2)


def test_cluster_purity_by_hand():
    truth = np.array([0, 0, 0, 1, 1, 1])
    assert cluster_purity(truth, np.array([0, 0, 1, 2, 2, 2])) == 1.0  # over-segmentation is free
    assert cluster_purity(truth, np.array([0, 0, 0, 0, 1, 1])) == pytest.approx(5 / 6)


def test_estimate_clouds_beats_nearest_neighbour_on_moving_points(pair):
    X, Y, gt, labels, dt = pair
    flows, clusters, seconds = estimate_clouds(X, Y, dt, DemoConfig())
    assert all(t >= 0 for t in seconds.values())
    moving = np.linalg.norm(gt, axis=1) > 0
    nn = scene_flow_metrics(flows["nearest-neighbour"], gt, moving, dt=dt)["epe3d"]
    rigid = scene_flow_metrics(flows["rigid per cluster"], gt, moving, dt=dt)["epe3d"]
    assert rigid < 0.5 * nn, (rigid, nn)
    assert clusters.shape == labels.shape
    assert set(flows) == {"nearest-neighbour", "graph", "graph + re-matching", "rigid per cluster"}
