"""Re-matched graph flow, small-cluster removal and the demo's building blocks."""

import numpy as np
import pytest

from flowtrack.clustering import drop_small_clusters
from flowtrack.pipeline import PipelineConfig, scene_flow_and_clusters
from flowtrack.sceneflow import (
    graph_scene_flow,
    iterative_graph_scene_flow,
    nearest_neighbor_targets,
    scene_flow_metrics,
)
from flowtrack.synth import make_scene
from flowtrack_course.demo.run import cluster_purity


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
    flows, clusters, seconds = scene_flow_and_clusters(X, Y, dt, PipelineConfig())
    assert all(t >= 0 for t in seconds.values())
    moving = np.linalg.norm(gt, axis=1) > 0
    nn = scene_flow_metrics(flows["nearest-neighbour"], gt, moving, dt=dt)["epe3d"]
    rigid = scene_flow_metrics(flows["rigid per cluster"], gt, moving, dt=dt)["epe3d"]
    assert rigid < 0.5 * nn, (rigid, nn)
    assert clusters.shape == labels.shape
    assert set(flows) == {"nearest-neighbour", "graph", "graph + re-matching", "rigid per cluster"}


# --------------------------------------------------------------------------------------------------
# flowtrack.pipeline: clouds from frames, and the tracker's N-ahead prediction
def test_cloud_from_depth_is_the_pinhole_back_projection_of_the_valid_pixels():
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import cloud_from_depth

    rng = np.random.default_rng(3)
    cam = PinholeCamera(210.0, 190.0, 15.3, 9.7, width=32, height=20)
    Z = rng.uniform(0.3, 3.0, (20, 32))
    Z[rng.random(Z.shape) < 0.2] = 0.0
    Z[0, 1], Z[2, 3], Z[4, 5] = np.nan, np.inf, -1.0
    Kinv = np.linalg.inv(cam.K)
    # oracle: K^-1 (u, v, 1)^T Z pixel by pixel, row-major, for 0 < Z <= max_depth
    for max_depth in (None, 2.0):
        want = [Z[v, u] * (Kinv @ [u, v, 1.0]) for v in range(20) for u in range(32)
                if np.isfinite(Z[v, u]) and Z[v, u] > 0 and (max_depth is None or Z[v, u] <= max_depth)]
        got = cloud_from_depth(Z, cam, max_depth=max_depth)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


def test_cloud_from_depth_voxel_grid_thins_to_one_point_per_voxel():
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import cloud_from_depth

    cam = PinholeCamera(100.0, 100.0, 20.0, 20.0, width=40, height=40)
    P = cloud_from_depth(np.full((40, 40), 1.0), cam, voxel=0.05)
    full = cloud_from_depth(np.full((40, 40), 1.0), cam)
    # a plane of 0.4 m x 0.4 m at 1 m: 1 cm between pixels, 5 cm voxels -> at most 9 x 9 (+ edges)
    assert 64 <= len(P) <= 100 < len(full)
    assert np.allclose(P[:, 2], 1.0)
    with pytest.raises(ValueError, match="depth"):
        cloud_from_depth(np.ones(5), cam)


@pytest.mark.parametrize("n_fast", [0, 7, 40, 100])
def test_moving_first_subsample_keeps_every_fast_point_then_a_random_share_of_the_rest(n_fast):
    from flowtrack.pipeline import moving_first_subsample

    rng = np.random.default_rng(n_fast)
    speeds = rng.uniform(0.0, 0.019, 200)
    fast = np.sort(rng.choice(200, n_fast, replace=False))
    speeds[fast] = rng.uniform(0.02, 1.0, n_fast)
    speeds[rng.choice(np.setdiff1d(np.arange(200), fast), 5, replace=False)] = np.nan  # NaN is slow
    idx = moving_first_subsample(speeds, 50, 0.02, np.random.default_rng(0))
    assert len(idx) == 50 and len(np.unique(idx)) == 50 and np.all(np.diff(idx) > 0)
    kept_fast = np.intersect1d(idx, fast)
    # brute force: every fast point while they fit, otherwise only fast points
    assert len(kept_fast) == min(n_fast, 50)
    # the slow share is drawn at random: about uniform over the slow points (never the first ones only)
    slow_kept = np.setdiff1d(idx, fast)
    if len(slow_kept) > 10:
        assert slow_kept.max() > 150 and slow_kept.min() < 50
    assert moving_first_subsample(speeds, 500, 0.02, np.random.default_rng(0)).tolist() == list(range(200))


def test_moving_first_subsample_bad_input():
    from flowtrack.pipeline import moving_first_subsample

    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="speeds"):
        moving_first_subsample(np.zeros((3, 2)), 2, 0.1, rng)
    with pytest.raises(ValueError, match="max_points"):
        moving_first_subsample(np.zeros(3), 0, 0.1, rng)
    with pytest.raises(ValueError, match="min_speed"):
        moving_first_subsample(np.zeros(3), 2, -0.1, rng)


def test_predict_ahead_is_F_to_the_n_on_every_live_track_and_leaves_the_tracker_alone():
    from flowtrack.kalman import constant_velocity_model
    from flowtrack.tracking import MultiObjectTracker

    dt, q = 0.1, 0.3
    trk = MultiObjectTracker(dt=dt, q=q, r=1e-4, dim=3, min_hits=2)
    for t in range(4):
        trk.step(np.array([[0.01 * t, 0.0, 1.0], [0.5, -0.02 * t, 1.2]]), velocities=np.full((2, 3), 0.1))
    trk.step(np.array([[0.9, 0.9, 0.9]]))  # a new, tentative track and one miss
    F, _, Q, _ = constant_velocity_model(dt, q, 1e-4, 3)
    before = [(t.id, t.x.copy(), t.P.copy()) for t in trk.tracks]
    ahead = trk.predict_ahead(3)
    assert sorted(ahead) == sorted(t.id for t in trk.tracks) and len(ahead) == 3
    for tid, x, P in before:
        xp, Pp = x, P
        for _ in range(3):  # brute force: three predictions by hand
            xp, Pp = F @ xp, F @ Pp @ F.T + Q
        np.testing.assert_allclose(ahead[tid][0], xp, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ahead[tid][1], Pp, rtol=1e-10, atol=1e-14)
    for (tid, x, P), t in zip(before, trk.tracks):  # the tracker did not move
        assert t.id == tid and np.array_equal(t.x, x) and np.array_equal(t.P, P)
    with pytest.raises(ValueError, match="n"):
        trk.predict_ahead(0)


# --------------------------------------------------------------------------------------------------
# flowtrack.pipeline: the RGB-D flow at a cloud's points, and clustering a given flow
@pytest.fixture(scope="module")
def rgbd_pair():
    scene = make_scene(n_objects=2, n_frames=2, image_size=(96, 128), seed=1)
    return scene.frames, scene.camera, scene.dt


def test_rgbd_cloud_flow_lines_up_with_the_pixels_and_beats_nearest_neighbour(rgbd_pair):
    from flowtrack.camera import backproject
    from flowtrack.pipeline import rgbd_cloud_flow
    from flowtrack.rgbd_flow import rgbd_scene_flow

    (f0, f1), cam, dt = rgbd_pair
    dense = rgbd_scene_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, cam, dt)  # (H, W, 3)
    valid = f0.depth > 0
    P = backproject(f0.depth, cam)[valid]
    idx = np.random.default_rng(0).permutation(len(P))[: len(P) // 3]  # any subset, any order
    v = rgbd_cloud_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, cam, dt, P[idx])
    np.testing.assert_array_equal(v, dense[valid][idx])  # each point gets its own pixel's velocity
    # the issue-14 bar on moving points: at most half the nearest-neighbour error
    gt, moving = f0.gt_flow[idx], np.linalg.norm(f0.gt_flow[idx], axis=1) > 0
    nn = (nearest_neighbor_targets(P[idx], f1.points) - P[idx]) / dt
    e_rgbd = scene_flow_metrics(v, gt, moving, dt=dt)["epe3d"]
    e_nn = scene_flow_metrics(nn, gt, moving, dt=dt)["epe3d"]
    assert e_rgbd <= 0.5 * e_nn, (e_rgbd, e_nn)
    # a voxel-thinned cloud: the velocity of the nearest pixel point (brute force)
    from flowtrack.pipeline import cloud_from_depth

    V = cloud_from_depth(f0.depth, cam, voxel=0.02)
    got = rgbd_cloud_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, cam, dt, V)
    d = np.sqrt(((V[:, None, :] - P[None, :, :]) ** 2).sum(-1))
    nearest = d <= d.min(axis=1, keepdims=True) + 1e-12  # ties: a voxel mean halfway between pixels
    same = (dense[valid][None, :, :] == got[:, None, :]).all(-1)
    assert np.all((nearest & same).any(axis=1))
    assert rgbd_cloud_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, cam, dt, np.empty((0, 3))).shape == (0, 3)
    with pytest.raises(ValueError, match="points"):
        rgbd_cloud_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, cam, dt, np.zeros((4, 2)))


def test_scene_flow_and_clusters_clusters_a_given_flow(pair):
    from sklearn.metrics import adjusted_rand_score

    from flowtrack.pipeline import METHODS, RGBD_METHOD

    X, Y, gt, labels, dt = pair
    flows, clusters, _ = scene_flow_and_clusters(X, Y, dt, PipelineConfig(), flow=gt)
    assert list(flows) == [*METHODS, RGBD_METHOD]
    assert flows[RGBD_METHOD] is not None and np.array_equal(flows[RGBD_METHOD], gt)
    # the true flow gives the true objects (static points -1, each moving object its cluster)
    assert adjusted_rand_score(np.maximum(labels, 0), clusters + 1) > 0.95
    moving = np.linalg.norm(gt, axis=1) > 0
    assert np.all(clusters[~moving] == -1)
    # rigid ICP per cluster on the true objects: near-exact on the moving points
    rigid = scene_flow_metrics(flows["rigid per cluster"], gt, moving, dt=dt)["epe3d"]
    assert rigid < 0.002, rigid
    with pytest.raises(ValueError, match="flow"):
        scene_flow_and_clusters(X, Y, dt, PipelineConfig(), flow=gt[:-1])


# ------------------------------------------------------------------------------------------------
# the velocity of a visible centroid
# ------------------------------------------------------------------------------------------------
def _ray_cast_plate(cam, plate, occluder_x):
    """Depth image and the plate's visible pixel hits, by casting every pixel's ray (brute force).

    Scene: a background wall at Z = 2 m, a fronto-parallel plate ``(x0, x1, y0, y1, Z)`` and a static
    occluding wall at Z = 0.5 m covering ``x > occluder_x`` (x measured at that depth).
    """
    x0, x1, y0, y1, Zp = plate
    depth = np.full((cam.height, cam.width), 2.0)
    hits = []
    for v in range(cam.height):
        for u in range(cam.width):
            ray = np.array([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0])
            if 0.5 * ray[0] > occluder_x:
                depth[v, u] = 0.5
                continue
            p = Zp * ray
            if x0 <= p[0] <= x1 and y0 <= p[1] <= y1:
                depth[v, u] = Zp
                hits.append(p)
    return depth, np.array(hits)


@pytest.mark.parametrize("occluder_x", [np.inf, 0.0])
def test_visible_centroid_velocity_is_the_brute_force_centroid_difference(occluder_x):
    """A plate moving in x, y and z, fully visible or sliding behind a nearer wall: the velocity is the
    difference of the ray-cast visible centroids over dt; the covariance is widened by exactly the gap
    to the material flow, and only when it is hidden."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import cloud_from_depth, visible_centroid_velocities

    cam = PinholeCamera(fx=200.0, fy=200.0, cx=39.5, cy=29.5, width=80, height=60)
    dt, vel = 0.1, np.array([0.2, -0.05, 0.1])
    plate = np.array([-0.12, 0.04, -0.06, 0.05, 1.0])
    plate1 = plate + dt * np.array([vel[0], vel[0], vel[1], vel[1], vel[2]])
    d0, hits0 = _ray_cast_plate(cam, plate, occluder_x)
    d1, hits1 = _ray_cast_plate(cam, plate1, occluder_x)
    oracle = (hits1.mean(axis=0) - hits0.mean(axis=0)) / dt
    # a random half of the pixels as the cloud, with the exact flow (static elsewhere)
    rng = np.random.default_rng(1)
    P = cloud_from_depth(d0, cam)
    P = P[np.sort(rng.choice(len(P), len(P) // 2, replace=False))]
    piece = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    flow = np.zeros_like(P)
    flow[piece] = vel
    C_in = np.diag([1e-4, 2e-4, 3e-4])[None]
    # pixels are 5 mm apart on the plate and the cloud has every second one: radius 2 cm
    U, C = visible_centroid_velocities(P, [piece], flow, d0, d1, cam, dt, radius=0.02, velocity_covs=C_in,
                                       inflation=4.0)
    np.testing.assert_allclose(U[0], oracle, atol=1e-9)
    gap = oracle - vel
    np.testing.assert_allclose(C[0], C_in[0] + 4.0 * np.outer(gap, gap), atol=1e-12)
    if np.isfinite(occluder_x):  # hidden from the right: the visible centroid lags the material
        assert U[0, 0] < vel[0] - 0.05
    else:  # nothing hidden: only the pixel sampling separates the two
        np.testing.assert_allclose(U[0], vel, atol=0.02)


def test_visible_centroid_velocities_fall_back_to_the_mean_flow():
    """A piece with no labelled pixel (here: no pixel within radius) keeps its mean flow and covariance;
    a NaN covariance row stays NaN; no pieces give empty arrays."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import visible_centroid_velocities

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=4.5, cy=4.5, width=10, height=10)
    depth = np.full((10, 10), 1.0)
    P = np.array([[5.0, 5.0, 5.0], [5.1, 5.0, 5.0], [5.0, 5.1, 5.0], [9.0, 9.0, 9.0]])  # far from every pixel
    flow = np.array([[0.1, 0.0, 0.0], [0.3, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, 0.0, 0.0]])
    covs = np.stack([np.eye(3) * 1e-4, np.full((3, 3), np.nan)])
    U, C = visible_centroid_velocities(P, [np.arange(3), np.array([3])], flow, depth, depth, cam, 0.1,
                                       velocity_covs=covs)
    np.testing.assert_allclose(U, [[0.2, 0.0, 0.0], [0.0, 0.0, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(C[0], covs[0])
    assert np.isnan(C[1]).all()
    U, C = visible_centroid_velocities(P, [], flow, depth, depth, cam, 0.1)
    assert U.shape == (0, 3) and C is None


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"pieces": [np.array([0, 7])]}, "pieces"),
        ({"pieces": [np.array([0.5])]}, "pieces"),
        ({"depth_t1": np.ones((4, 5))}, "depth_t"),
        ({"radius": 0.0}, "radius"),
        ({"inflation": -1.0}, "inflation"),
        ({"dt": 0.0}, "dt"),
        ({"flow": np.zeros((3, 3))}, "flow"),
        ({"velocity_covs": np.zeros((2, 3, 3))}, "velocity_covs"),
    ],
)
def test_visible_centroid_velocities_bad_input(kwargs, match):
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import visible_centroid_velocities

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=2.0, cy=2.0, width=5, height=5)
    args = {"points": np.zeros((4, 3)), "pieces": [np.array([0, 1])], "flow": np.zeros((4, 3)),
            "depth_t": np.ones((5, 5)), "depth_t1": np.ones((5, 5)), "camera": cam, "dt": 0.1} | kwargs
    with pytest.raises(ValueError, match=match):
        visible_centroid_velocities(**args)


# ------------------------------------------------------------------------------------------------
# frame pairing at any frame rate, and the coherence and colour tests of detection_pieces
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, dt", [(2, 0.1), (5, 0.1), (9, 1 / 30), (4, 1 / 30), (30, 1 / 60), (7, 0.5)])
def test_flow_partners_against_the_rule_written_out(n, dt):
    from flowtrack.pipeline import flow_partners

    part = flow_partners(n, dt, interval=0.1)
    k = max(1, round(0.1 / dt))
    assert len(part) == n
    for t, s in enumerate(part):
        assert s != t and 0 <= s < n
        if t + k <= n - 1 or t - k >= 0:  # a pair spans exactly k frames, forward while it can
            assert abs(s - t) == k
            assert (s > t) == (t + k <= n - 1)
        else:  # the sequence is too short for k: the farthest frame
            assert abs(s - t) == max(t, n - 1 - t)


@pytest.mark.parametrize("kwargs, match",
                         [({"n": 1}, "n"), ({"dt": 0.0}, "dt"), ({"interval": -1.0}, "interval")])
def test_flow_partners_bad_input(kwargs, match):
    from flowtrack.pipeline import flow_partners

    with pytest.raises(ValueError, match=match):
        flow_partners(**({"n": 4, "dt": 0.1} | kwargs))


def _textured_wall(shift_px: float, seed: int = 0):
    """A fronto-parallel wall at Z = 1 m filling a 60x80 image, its texture shifted by ``shift_px``."""
    from flowtrack.camera import PinholeCamera

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=39.5, cy=29.5, width=80, height=60)
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0, 255, (8, 12))
    yy, xx = np.mgrid[0:60, 0:80].astype(float)

    def tex(x, y):  # bilinear upsampling of the coarse noise: a smooth texture, 8 px blobs
        gx, gy = np.clip(x / 8.0, 0, 10.999), np.clip(y / 8.0, 0, 6.999)
        i, j = gy.astype(int), gx.astype(int)
        a, b = gy - i, gx - j
        return ((1 - a) * (1 - b) * coarse[i, j] + (1 - a) * b * coarse[i, j + 1]
                + a * (1 - b) * coarse[i + 1, j] + a * b * coarse[i + 1, j + 1])

    img0 = np.repeat(tex(xx + 8, yy)[..., None], 3, axis=2).astype(np.uint8)
    img1 = np.repeat(tex(xx + 8 - shift_px, yy)[..., None], 3, axis=2).astype(np.uint8)
    X = np.column_stack([(xx.ravel() - cam.cx) / cam.fx, (yy.ravel() - cam.cy) / cam.fy, np.ones(xx.size)])
    return cam, img0, img1, X


def test_detection_pieces_colour_sees_a_wall_slide_along_itself():
    # A wall that slides 2 cm sideways in 0.1 s stays on its plane: geometry alone calls it static.
    # Its texture moves 2 px, which the colour test sees; a wall that stands still with the same
    # (wrong) flow is static by colour too.
    cam, img0, img1_moving, X = _textured_wall(shift_px=2.0)
    _, _, img1_static, _ = _textured_wall(shift_px=0.0)
    dt, v = 0.1, np.array([0.2, 0.0, 0.0])
    flow = np.tile(v, (len(X), 1))
    labels = np.zeros(len(X), dtype=int)
    cfg = PipelineConfig(max_planes=0, min_detection_points=10)
    from flowtrack.pipeline import detection_pieces

    geometry_only = detection_pieces(X, labels, flow, cfg, next_points=X, dt=dt)
    assert geometry_only == []  # the same plane at t+1: static is as good a fit as moving
    kept = detection_pieces(X, labels, flow, cfg, next_points=X, dt=dt, images=(img0, img1_moving, cam))
    assert len(kept) == 1 and len(kept[0]) == len(X)
    assert detection_pieces(X, labels, flow, cfg, next_points=X, dt=dt, images=(img0, img1_static, cam)) == []


def test_detection_pieces_min_speed_drops_incoherent_flow():
    # two blobs of 200 points: one moving together at 0.1 m/s, one whose points move 0.1 m/s each
    # in random directions (the flow noise of a depth-edge artefact): only the first is an object
    from flowtrack.pipeline import detection_pieces

    rng = np.random.default_rng(3)
    a = rng.normal([0.0, 0.0, 1.0], 0.01, (200, 3))
    b = rng.normal([0.5, 0.0, 1.0], 0.01, (200, 3))
    d = rng.normal(size=(200, 3))
    noise_flow = 0.1 * d / np.linalg.norm(d, axis=1, keepdims=True)
    P = np.vstack([a, b])
    flow = np.vstack([np.tile([0.1, 0.0, 0.0], (200, 1)), noise_flow])
    labels = np.r_[np.zeros(200, int), np.ones(200, int)]
    cfg = PipelineConfig(max_planes=0)
    assert len(detection_pieces(P, labels, flow, cfg)) == 2
    assert np.linalg.norm(noise_flow.mean(axis=0)) < 0.02  # what the test relies on: the mean is small
    kept = detection_pieces(P, labels, flow, cfg, min_speed=0.04)
    assert [sorted(p) for p in kept] == [list(range(200))]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"min_speed": -0.1}, "min_speed"),
        ({"images": (np.zeros((4, 4)), np.zeros((4, 4)), None)}, "next_points"),
        ({"images": (np.zeros((4, 4)), np.zeros((4, 4))), "next_points": np.zeros((3, 3)), "dt": 0.1},
         "images"),
        ({"images": (np.zeros((4, 4)), np.zeros((5, 4)), None), "next_points": np.zeros((3, 3)), "dt": 0.1},
         "same size"),
        ({"images": (np.zeros((4, 4, 2)), np.zeros((4, 4)), None), "next_points": np.zeros((3, 3)),
          "dt": 0.1},
         r"images\[0\]"),
    ],
)
def test_detection_pieces_bad_options(kwargs, match):
    from flowtrack.pipeline import detection_pieces

    args = {"points": np.zeros((5, 3)), "clusters": np.zeros(5, dtype=int), "flow": np.zeros((5, 3))} | kwargs
    with pytest.raises(ValueError, match=match):
        detection_pieces(config=PipelineConfig(max_planes=0), **args)


def _plate_behind_a_bar(bar_depth: float):
    """A plate at Z = 1.5 m (columns 10-69, rows 20-39 of an 80x60 image) in front of a wall at 2 m,
    with a vertical bar over columns 35-44 at ``bar_depth`` (farther than the plate: a gap between two
    plates that shows what is behind): the plate's visible pixels, back-projected by hand, and the
    depth image."""
    from flowtrack.camera import PinholeCamera

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=39.5, cy=29.5, width=80, height=60)
    depth = np.full((60, 80), 2.0)
    depth[20:40, 10:70] = 1.5
    if bar_depth < 1.5:
        depth[:, 35:45] = bar_depth
    else:
        depth[20:40, 35:45] = bar_depth
    rows, cols = np.nonzero(depth == 1.5)
    X = np.column_stack([(cols - cam.cx) / cam.fx * 1.5, (rows - cam.cy) / cam.fy * 1.5,
                         np.full(len(rows), 1.5)])
    return cam, depth, X, cols


@pytest.mark.parametrize("bar_depth, v_right, merged", [
    (1.0, 0.1, True),    # the bar hides the plate's middle: one object in two pieces
    (2.0, 0.1, False),   # nothing in front of the gap (the wall behind): two objects
    (1.0, 0.2, False),   # hidden middle, but the pieces move differently: two objects
    (1.49, 0.1, False),  # the bar is nearer by less than occlusion_margin (2 cm)
])
def test_detection_pieces_merge_pieces_split_by_a_nearer_occluder(bar_depth, v_right, merged):
    from flowtrack.pipeline import detection_pieces

    cam, depth, X, cols = _plate_behind_a_bar(bar_depth)
    right = cols >= 45
    flow = np.zeros((len(X), 3))
    flow[:, 0] = np.where(right, v_right, 0.1)
    labels = right.astype(int)  # two motion clusters, as the clustering finds them
    cfg = PipelineConfig(max_planes=0)
    plain = detection_pieces(X, labels, flow, cfg)
    assert sorted(len(p) for p in plain) == [500, 500]  # each visible end alone
    got = detection_pieces(X, labels, flow, cfg, occluders=(depth, cam))
    if merged:
        assert len(got) == 1 and np.array_equal(got[0], np.arange(len(X)))
    else:
        assert sorted(map(tuple, got)) == sorted(map(tuple, plain))


def test_detection_pieces_occluders_bad_input():
    from flowtrack.pipeline import detection_pieces

    cam, depth, X, cols = _plate_behind_a_bar(1.0)
    labels = (cols >= 45).astype(int)
    flow = np.tile([0.1, 0.0, 0.0], (len(X), 1))
    with pytest.raises(ValueError, match="occluders"):
        detection_pieces(X, labels, flow, PipelineConfig(max_planes=0), occluders=(depth,))
    with pytest.raises(ValueError, match=r"occluders\[0\]"):
        detection_pieces(X, labels, flow, PipelineConfig(max_planes=0), occluders=(depth[0], cam))


@pytest.mark.parametrize("spin, merged", [(1.5, True), (None, False)])
def test_detection_pieces_rigid_merge_joins_a_turning_box_split_by_velocity(spin, merged):
    # Two faces of a box (a 10 cm front face and a 6 cm side face meeting at an edge), sampled at 5 mm.
    # Turning at 1.5 rad/s about the vertical axis, the faces move about 0.1 m/s apart, and a motion
    # clustering by velocity similarity gives them two labels; one rigid motion explains both. Without
    # the turn (spin None) the side face slides at another velocity: two objects that touch.
    from flowtrack.pipeline import detection_pieces

    s = np.arange(0.0, 0.1001, 0.005)
    h = np.arange(0.0, 0.0601, 0.005)
    front = np.array([[x, y, 1.0] for x in s for y in h])
    side = np.array([[0.1, y, 1.0 + z] for z in s[1:13] for y in h])
    P = np.vstack([front, side])
    labels = np.r_[np.zeros(len(front), int), np.ones(len(side), int)]
    centre = np.array([0.05, 0.03, 1.03])
    if spin is not None:
        flow = np.cross([0.0, spin, 0.0], P - centre) + np.array([0.1, 0.0, 0.0])
    else:
        flow = np.where(labels[:, None] == 0, [0.1, 0.0, 0.0], [0.1, 0.0, 0.1])
    cfg = PipelineConfig(max_planes=0)
    plain = detection_pieces(P, labels, flow, cfg)
    assert len(plain) == 2
    gap = np.linalg.norm(flow[labels == 0].mean(0) - flow[labels == 1].mean(0))
    assert gap > 0.05  # the faces' mean velocities really differ by more than clustering's sigma_v
    got = detection_pieces(P, labels, flow, cfg, dt=0.1, rigid_merge=True)
    if merged:
        assert len(got) == 1 and np.array_equal(got[0], np.arange(len(P)))
    else:
        assert sorted(map(tuple, got)) == sorted(map(tuple, plain))


def test_detection_pieces_colour_test_ignores_static_surface_covered_at_t1():
    # A static wall whose points carry a leaked flow of 0.2 m/s; at t+1 a nearer object (0.8 m) has
    # moved over 60 % of it, and what it shows there happens to fit the leaked flow (the wall's
    # texture 2 px on). Without the next depth image the colour test is fooled (the wall is kept as
    # moving); with it the covered points do not count, and the rest says static.
    from flowtrack.pipeline import detection_pieces

    cam, img0, img1, X = _textured_wall(shift_px=0.0)
    _, _, looks_moved, _ = _textured_wall(shift_px=2.0)
    img1 = img1.copy()
    img1[:, :48] = looks_moved[:, :48]
    depth1 = np.ones((60, 80))
    depth1[:, :48] = 0.8
    flow = np.tile([0.2, 0.0, 0.0], (len(X), 1))
    labels = np.zeros(len(X), dtype=int)
    cfg = PipelineConfig(max_planes=0, min_detection_points=10)
    fooled = detection_pieces(X, labels, flow, cfg, next_points=X, dt=0.1, images=(img0, img1, cam))
    assert len(fooled) == 1
    covered = (img0, img1, cam, depth1)
    assert detection_pieces(X, labels, flow, cfg, next_points=X, dt=0.1, images=covered) == []


@pytest.mark.parametrize("hidden_depth", [0.0, 0.5])  # the sensor's shadow, a nearer object
def test_detection_pieces_geometry_ignores_background_hidden_where_it_stood(hidden_depth):
    # A static wall 1 m away whose points carry the flow of the object passing in front (1 m/s, 10 px
    # in 0.1 s): at t+1 the wall is unseen where these points stood (no depth there, or the object in
    # front), and the points moved along the leaked flow land on visible wall. Geometry then says
    # "moving" (median distance to the next cloud 9.5 cm static, 0.5 cm moved) although nothing
    # supports it; the points whose static pixel the next depth image does not see are left out.
    from flowtrack.pipeline import detection_pieces

    cam, img0, img1, X = _textured_wall(shift_px=0.0)
    col = np.rint(X[:, 0] * cam.fx + cam.cx).astype(int)
    piece = (col >= 30) & (col < 48)
    labels = np.where(piece, 0, -1)
    depth1 = np.ones((60, 80))
    depth1[:, :48] = hidden_depth
    nxt = X[col >= 48]  # what the sensor sees of the wall at t+1
    flow = np.tile([1.0, 0.0, 0.0], (len(X), 1))
    cfg = PipelineConfig(max_planes=0, min_detection_points=10)
    fooled = detection_pieces(X, labels, flow, cfg, next_points=nxt, dt=0.1, images=(img0, img1, cam))
    assert len(fooled) == 1 and np.array_equal(fooled[0], np.flatnonzero(piece))
    seen = (img0, img1, cam, depth1)
    assert detection_pieces(X, labels, flow, cfg, next_points=nxt, dt=0.1, images=seen) == []


def test_detection_pieces_an_object_coming_nearer_is_not_hidden_by_itself():
    # A plate 1 m away moving toward the camera at 0.3 m/s: at t+1 its old pixels show the plate
    # itself 3 cm nearer (more than occlusion_margin). That surface is where the moved points are, so
    # it does not hide them: the plate is kept as moving.
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import cloud_from_depth, detection_pieces

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=39.5, cy=29.5, width=80, height=60)
    yy, xx = np.mgrid[0:60, 0:80]
    on = (xx >= 30) & (xx < 50) & (yy >= 20) & (yy < 40)
    P = cloud_from_depth(np.where(on, 1.0, 2.0), cam)
    depth1 = np.where(on, 0.97, 2.0)
    nxt = cloud_from_depth(depth1, cam)
    plate = np.isclose(P[:, 2], 1.0)
    flow = np.where(plate[:, None], [0.0, 0.0, -0.3], 0.0)
    labels = np.where(plate, 0, -1)
    img = np.full((60, 80, 3), 128, dtype=np.uint8)
    cfg = PipelineConfig(max_planes=0, min_detection_points=10)
    got = detection_pieces(P, labels, flow, cfg, next_points=nxt, dt=0.1, images=(img, img, cam, depth1))
    assert len(got) == 1 and np.array_equal(got[0], np.flatnonzero(plate))


# -- occlusion_position_covariances -----------------------------------------------------------------


def _plate_scene():
    """A plate 1 m away (columns x in (-0.1, 0.1) m, rows y in (-0.08, 0.08) m) before a wall 2 m away."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import cloud_from_depth

    cam = PinholeCamera(fx=100.0, fy=100.0, cx=39.5, cy=29.5, width=80, height=60)
    x = (np.arange(80) - 39.5) / cam.fx
    y = (np.arange(60) - 29.5) / cam.fy
    on = (np.abs(x)[None, :] < 0.1) & (np.abs(y)[:, None] < 0.08)
    depth = np.where(on, 1.0, 2.0)
    P = cloud_from_depth(depth, cam)
    plate = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    return cam, depth, P, plate, x, y


def test_occlusion_covariance_grows_toward_the_occluder_by_half_the_visible_extent():
    from flowtrack.pipeline import occlusion_position_covariances as occ

    cam, depth, P, plate, x, y = _plate_scene()
    r = 1e-4
    ex = np.ptp(P[plate, 0])  # the plate's extents along x and y (hand-checked: 0.19 and 0.15 m)
    ey = np.ptp(P[plate, 1])
    assert ex == pytest.approx(0.19) and ey == pytest.approx(0.15)
    np.testing.assert_allclose(occ(P, [plate], depth, cam, r)[0], r * np.eye(3), atol=1e-15)  # free
    for where, axis, extent in [((slice(None), x > 0.1), 0, ex), ((slice(None), x < -0.1), 0, ex),
                                ((y > 0.08, slice(None)), 1, ey), ((y < -0.08, slice(None)), 1, ey)]:
        d = depth.copy()
        d[where] = 0.5  # a nearer surface right, left, below or above the plate
        R = occ(P, [plate], d, cam, r, scale=0.5)[0]
        want = r * np.eye(3)
        want[axis, axis] += (0.5 * extent) ** 2
        np.testing.assert_allclose(R, want, atol=1e-12)
        np.testing.assert_allclose(occ(P, [plate], d, cam, r, scale=0.0)[0], r * np.eye(3), atol=1e-15)


def test_occlusion_covariance_needs_a_surface_nearer_by_the_margin_and_next_to_the_piece():
    from flowtrack.pipeline import occlusion_position_covariances as occ

    cam, depth, P, plate, x, _ = _plate_scene()
    d = depth.copy()
    d[:, x > 0.1] = 0.99  # 1 cm nearer: the plate's own surface, bent (margin 2 cm)
    np.testing.assert_allclose(occ(P, [plate], d, cam, 1e-4)[0], 1e-4 * np.eye(3), atol=1e-15)
    assert occ(P, [plate], d, cam, 1e-4, margin=0.005)[0][0, 0] > 1e-3
    d = depth.copy()
    d[:, x > 0.16] = 0.5  # nearer, but 6 px from the plate's edge: the ring (4 px) does not reach it
    np.testing.assert_allclose(occ(P, [plate], d, cam, 1e-4)[0], 1e-4 * np.eye(3), atol=1e-15)
    assert occ(P, [plate], d, cam, 1e-4, offset=8)[0][0, 0] > 1e-3
    d = depth.copy()
    d[:2, :2] = 0.5  # a far-off nearer corner; NaN and 0 pixels are no surface
    d[:, x > 0.1] = np.nan
    np.testing.assert_allclose(occ(P, [plate], d, cam, 1e-4)[0], 1e-4 * np.eye(3), atol=1e-15)


def test_occlusion_covariance_of_a_diagonal_occluder_is_rank_one_at_constant_depth():
    from flowtrack.pipeline import occlusion_position_covariances as occ

    cam, depth, P, plate, x, y = _plate_scene()
    d = depth.copy()
    d[(x[None, :] > 0.08) & (y[:, None] > 0.06)] = 0.5  # the plate's lower right corner hidden
    R = occ(P, [plate], d, cam, 1e-4)[0] - 1e-4 * np.eye(3)
    w, V = np.linalg.eigh(R)
    u = V[:, -1] * np.sign(V[0, -1])
    assert w[-1] > 1e-3 and w[:2] == pytest.approx([0, 0], abs=1e-12)  # rank one
    assert u[2] == pytest.approx(0.0, abs=1e-12)  # at constant depth
    assert 0.2 < u[1] / u[0] < 5  # between the two edges it touches (right and bottom)


def test_occlusion_covariance_validates_its_arguments():
    from flowtrack.pipeline import occlusion_position_covariances as occ

    cam, depth, P, plate, _, _ = _plate_scene()
    assert occ(P, [], depth, cam, 1e-4).shape == (0, 3, 3)
    assert occ(P, [np.array([], dtype=int)], depth, cam, 1e-4).shape == (1, 3, 3)
    with pytest.raises(ValueError, match="depth_t"):
        occ(P, [plate], depth[0], cam, 1e-4)
    with pytest.raises(ValueError, match=r"pieces\[1\]"):
        occ(P, [plate, np.array([len(P)])], depth, cam, 1e-4)
    with pytest.raises(ValueError, match="min_fraction"):
        occ(P, [plate], depth, cam, 1e-4, min_fraction=2.0)
    with pytest.raises(ValueError, match=r"^r must be > 0"):
        occ(P, [plate], depth, cam, -1.0)
    with pytest.raises(ValueError, match="points"):
        occ(P[:, :2], [plate], depth, cam, 1e-4)


@pytest.mark.parametrize("q", [0.2, 0.5])
def test_free_space_matches_a_brute_force_cell_quantile(q):
    """FreeSpace against the rule written out pixel by pixel: project, take the cell's pixels, drop the
    missing readings, take the quantile, compare with the depth plus the margin."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import FreeSpace

    rng = np.random.default_rng(4)
    H, W, cell, margin = 37, 51, 6, 0.1
    depth = rng.uniform(0.5, 3.0, (H, W))
    depth[rng.random((H, W)) < 0.3] = 0.0  # holes
    depth[:12, :12] = 0.0                   # a cell with no reading at all
    depth[rng.random((H, W)) < 0.05] = np.nan
    cam = PinholeCamera(60.0, 55.0, 25.3, 18.1)
    fs = FreeSpace(depth, cam, margin=margin, cell=cell, min_valid=0.25, quantile=q)
    X = np.column_stack([rng.uniform(-1.5, 1.5, 400), rng.uniform(-1.2, 1.2, 400),
                         rng.uniform(-0.2, 3.0, 400)])
    got = fs(X)
    for x, g in zip(X, got):
        want = False
        if x[2] > 1e-6:
            u = int(np.floor(cam.fx * x[0] / x[2] + cam.cx + 0.5))
            v = int(np.floor(cam.fy * x[1] / x[2] + cam.cy + 0.5))
            if 0 <= u < W and 0 <= v < H:
                blk = depth[v // cell * cell:(v // cell + 1) * cell, u // cell * cell:(u // cell + 1) * cell]
                vals = blk[np.isfinite(blk) & (blk > 0)]
                if vals.size >= 0.25 * cell * cell:
                    want = bool(np.quantile(vals, q) > x[2] + margin)
        assert g == want, x
    assert 0 < got.sum() < len(X)


def test_free_space_tells_a_hidden_object_from_a_gone_one():
    """A box's coasting track: behind a nearer box it is hidden (not seen through); with the wall
    visible where it should be, it is gone."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import FreeSpace

    cam = PinholeCamera(300.0, 300.0, 159.5, 119.5)
    depth = np.full((240, 320), 2.5)            # wall
    depth[100:140, 60:120] = 0.9                # an occluder on the left
    fs = FreeSpace(depth, cam)
    left = np.array([[(90 - cam.cx) * 1.2 / cam.fx, 0.0, 1.2]])   # behind the occluder
    right = np.array([[(250 - cam.cx) * 1.2 / cam.fx, 0.0, 1.2]])  # in front of the bare wall
    on_wall = right * 2.45 / 1.2                                    # at the wall: within the margin
    assert fs(np.vstack([left, right, on_wall])).tolist() == [False, True, False]
    # outside the image or behind the camera: nothing known
    assert fs(np.array([[5.0, 0.0, 1.0], [0.0, 0.0, -1.0]])).tolist() == [False, False]
    # a small object covering a third of its centroid's cell still says "not seen through"
    small = np.full((240, 320), 2.5)
    small[56:64, 64:67] = 2.3
    pos = np.array([[(65 - cam.cx) * 2.28 / cam.fx, (60 - cam.cy) * 2.28 / cam.fy, 2.28]])
    assert FreeSpace(small, cam)(pos).tolist() == [False]
    assert FreeSpace(small, cam, quantile=0.5)(pos).tolist() == [True]  # the median looks past it


def test_free_space_bad_input():
    from flowtrack.camera import PinholeCamera
    from flowtrack.pipeline import FreeSpace

    cam = PinholeCamera(300.0, 300.0, 159.5, 119.5)
    with pytest.raises(ValueError, match="depth"):
        FreeSpace(np.zeros(5), cam)
    with pytest.raises(ValueError, match="inf"):
        FreeSpace(np.full((4, 4), np.inf), cam)
    with pytest.raises(ValueError, match="margin"):
        FreeSpace(np.ones((4, 4)), cam, margin=0.0)
    with pytest.raises(ValueError, match="min_valid"):
        FreeSpace(np.ones((4, 4)), cam, min_valid=0.0)
    with pytest.raises(ValueError, match="quantile"):
        FreeSpace(np.ones((4, 4)), cam, quantile=1.5)
    with pytest.raises(ValueError, match="positions"):
        FreeSpace(np.ones((4, 4)), cam)(np.zeros((2, 2)))
