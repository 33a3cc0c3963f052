"""The held-out evaluation scenes (``benchmarks/_evalscenes.py``): ground truth, depth model, splits.

The generator is checked against facts it does not compute itself: its displacements are rigid per
object (a Kabsch fit, numpy SVD, leaves no residual) and zero on the background; a point moved by its
true displacement lands on its own object's surface in the next rendered frame (interpolated in
inverse depth, exact on planes) unless something nearer hides it; the sensor model leaves holes and
flying pixels and the ground truth marks them; the TUM files round-trip through
``flowtrack.rgbd_io``; the splits are disjoint and as large as the protocol says.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from flowtrack.rgbd_io import load_tum_sequence

COURSE = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("_evalscenes", COURSE / "benchmarks" / "_evalscenes.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("_evalscenes", mod)  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return sys.modules["_evalscenes"]


E = _module()


@pytest.fixture(scope="module")
def pair():
    # a 320x240 medium-motion training pair with a brightness change (several objects, occlusions)
    spec = next(s for s in E.TRAIN_PAIRS if s.size == (240, 320) and s.motion == "medium" and s.brightness)
    return E.make_pair(spec)


def _backproject(depth, K):
    fx, fy, cx, cy = K
    H, W = depth.shape
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    return np.stack([(u - cx) / fx * depth, (v - cy) / fy * depth, depth], -1)


def test_generator_shares_no_code_with_flowtrack():
    text = (COURSE / "benchmarks" / "_evalscenes.py").read_text()
    imports = [line for line in text.splitlines() if line.startswith(("import ", "from "))]
    assert not any("flowtrack" in line or "_boxes" in line for line in imports), imports


def test_displacements_are_rigid_per_object_and_zero_on_the_background(pair):
    X = _backproject(pair["depth_true0"], pair["K"])
    s = pair["flow3d"]
    ok = np.isfinite(s).all(-1)
    assert np.all(s[ok & (pair["labels0"] == 0)] == 0.0)
    n_fitted = 0
    for k in np.unique(pair["labels0"][ok & pair["moving"]]):
        m = ok & (pair["labels0"] == k)
        if m.sum() < 20:
            continue
        A, B = X[m], X[m] + s[m]
        ca, cb = A.mean(0), B.mean(0)
        U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
        R = Vt.T @ D @ U.T
        resid = np.linalg.norm((A - ca) @ R.T + cb - B, axis=1)
        assert resid.max() < 1e-6, (k, resid.max())
        assert np.linalg.norm(s[m], axis=1).max() > 1e-4  # it does move
        n_fitted += 1
    assert n_fitted >= 1


def test_moved_points_land_on_their_own_surface_in_the_next_frame(pair):
    K = pair["K"]
    fx, fy, cx, cy = K
    X1 = _backproject(pair["depth_true0"], K) + pair["flow3d"]
    lab0, lab1, z1 = pair["labels0"], pair["labels1"], pair["depth_true1"]
    H, W = lab0.shape
    m = np.isfinite(X1).all(-1) & (lab0 > 0)
    u = fx * X1[m, 0] / X1[m, 2] + cx
    v = fy * X1[m, 1] / X1[m, 2] + cy
    inside = (u >= 0) & (u < W - 1) & (v >= 0) & (v < H - 1)
    u, v, zp, lab = u[inside], v[inside], X1[m][inside, 2], lab0[m][inside]
    i0, j0 = np.floor(v).astype(int), np.floor(u).astype(int)
    corners = [(i0, j0), (i0 + 1, j0), (i0, j0 + 1), (i0 + 1, j0 + 1)]
    same = np.all([lab1[a, b] == lab1[i0, j0] for a, b in corners], axis=0)  # no silhouette in between
    a, b = v - i0, u - j0
    inv = ((1 - a) * (1 - b) / z1[i0, j0] + a * (1 - b) / z1[i0 + 1, j0] + (1 - a) * b / z1[i0, j0 + 1]
           + a * b / z1[i0 + 1, j0 + 1])
    zs = 1.0 / inv  # the surface seen at the projection, exact where it is planar
    own = same & (lab1[i0, j0] == lab)
    assert own.sum() > 500
    # seen again: on its own object, at its own depth (spheres and cylinders bend within a pixel)
    assert np.percentile(np.abs(zs[own] - zp[own]), 99) < 2e-3
    assert np.abs(zs[own] - zp[own]).max() < 1e-2
    # never floating in front of what the next frame shows there: it is seen, or hidden by a nearer surface
    other = same & (lab1[i0, j0] != lab)
    assert np.all(zs[other] < zp[other] + 1e-3)


def test_depth_model_has_holes_and_flying_pixels_and_the_truth_marks_them(pair):
    d, zt = pair["depth0"], pair["depth_true0"]
    holes = d == 0
    assert 0.01 < holes.mean() < 0.25
    off = (d > 0) & (np.abs(d - zt) > 0.2)  # flying pixels: measured far from the true surface
    assert off.sum() > 10
    assert not pair["valid"][off].any()
    assert np.isnan(pair["flow3d"][~pair["valid"]]).all()
    assert np.isfinite(pair["flow3d"][pair["valid"]]).all()
    # away from edges the measured depth follows the true one (noise + quantisation)
    good = pair["valid"]
    assert np.median(np.abs(d[good] - zt[good])) < 0.01


def test_brightness_change_is_global_and_as_drawn(pair):
    g = pair["gain_ratio"]
    assert 0.03 - 1e-9 <= abs(g - 1.0) <= 0.10 + 1e-9
    static = (pair["labels0"] == 0) & (pair["labels1"] == 0)
    a = pair["rgb0"].astype(float)[static].mean(-1)
    b = pair["rgb1"].astype(float)[static].mean(-1)
    ok = (a > 30) & (a < 200) & (b < 240)
    assert abs(np.median(b[ok] / a[ok]) - g) < 0.015


def test_pairs_are_deterministic_and_the_large_class_moves_up_to_25_px():
    spec = next(s for s in E.TEST_PAIRS if s.size == (240, 320) and s.motion == "large")
    p, q = E.make_pair(spec), E.make_pair(spec)
    assert np.array_equal(p["rgb1"], q["rgb1"]) and np.array_equal(p["depth0"], q["depth0"])
    assert 12.0 <= p["max_px"] <= 25.5


def test_splits_are_disjoint_and_as_large_as_the_protocol_says():
    tr_pairs, tr_seqs = E.split("train")
    te_pairs, te_seqs = E.split("test")
    seeds = [s.seed for s in (*tr_pairs, *tr_seqs, *te_pairs, *te_seqs)]
    assert len(seeds) == len(set(seeds))
    for pairs, seqs in ((tr_pairs, tr_seqs), (te_pairs, te_seqs)):
        assert len(pairs) >= 60 and len(seqs) >= 12
        assert {s.size for s in pairs} == {(240, 320), (480, 640)} == {s.size for s in seqs}
        assert {s.motion for s in pairs} == {"small", "medium", "large"}
        assert sum(s.brightness > 0 for s in pairs) >= len(pairs) // 3
        assert all(s.n_frames >= 60 for s in seqs)
    with pytest.raises(ValueError, match="split"):
        E.split("validation")


def test_a_sequence_round_trips_through_the_tum_reader(tmp_path):
    spec = E.SequenceSpec(seed=99, size=(240, 320), n_frames=4, speed="mixed", brightness=0.1)
    made = E.write_sequence(tmp_path / "seq", spec)
    seq = load_tum_sequence(tmp_path / "seq")  # intrinsics.txt is read
    assert len(seq) == 4
    assert np.allclose([seq.camera.fx, seq.camera.cx], [float(v) for v in made["intrinsics"].split(",")][::2])
    assert np.allclose(np.diff(seq.timestamps), 1 / 30, atol=0.0025)
    frames = list(E.render_sequence_frames(spec))
    assert np.array_equal(seq.rgb[2], frames[2][1])  # the frames written are the frames rendered
    assert np.abs(seq.depth[2] - frames[2][2]).max() <= 0.5 / 5000 + 1e-9
    truth = E.read_objects_csv(tmp_path / "seq" / "objects.csv")
    assert sorted(truth) == [0, 1, 2, 3]
    assert 2 <= len(truth[0]) <= 6
    for k, (c, npx, area, speed) in truth[3].items():
        assert np.allclose(c, made["truth"][3][k][0], atol=1e-6)
        assert npx == made["truth"][3][k][1] and (npx > 0) == (area > 0)
        # the speed bound is at least the centre's speed (finite difference of the centres)
        assert speed >= np.linalg.norm(truth[3][k][0] - truth[2][k][0]) * 30 * 0.95 - 1e-6


def test_sequence_objects_never_move_faster_than_their_class_allows():
    for spec in E.TEST_SEQUENCES[::2]:
        scene = E._sequence_scene(spec)
        times = np.arange(spec.n_frames, dtype=float)
        hi = E.SEQUENCE_SPEEDS[spec.speed][1]
        assert 2 <= len(scene.objects) <= 6
        for ob in scene.objects:
            assert E.fastest_pixel(ob, scene.K, spec.size, times) <= hi + 1e-6


def _ob(shape, amp):
    from types import SimpleNamespace

    return SimpleNamespace(shape=shape, texture=SimpleNamespace(amp=amp))


def _axis_angle(R):
    from scipy.spatial.transform import Rotation

    rv = Rotation.from_matrix(R).as_rotvec()
    a = float(np.linalg.norm(rv))
    return (rv / a if a > 0 else rv), a


def test_observable_rotation_removes_only_the_twist_of_uniform_bodies_of_revolution():
    # rotations from scipy (independent of the generator's Rodrigues formula)
    from scipy.spatial.transform import Rotation

    R0, R1 = Rotation.random(2, random_state=4).as_matrix()
    R = R1 @ R0.T
    # textured bodies and bodies without symmetry keep the whole rotation
    for ob in (_ob("cylinder", 0.5), _ob("box", 0.01), _ob("plate", 0.01)):
        R_obs, rec = E.observable_rotation(ob, R0, R1)
        assert np.allclose(R_obs, R, atol=1e-12) and rec["twist"] == 0.0
    # a uniform sphere: no rotation is observable, the whole angle is removed
    R_obs, rec = E.observable_rotation(_ob("sphere", 0.01), R0, R1)
    assert np.allclose(R_obs, np.eye(3)) and np.isclose(rec["twist"], _axis_angle(R)[1])
    # a uniform cylinder: the swing carries the axis R0 e_z onto R1 e_z, turning about an axis normal to
    # both by the angle between them; what is left (R_obs^T R) turns about the old axis only
    a0, a1 = R0[:, 2], R1[:, 2]
    for shape in ("cylinder", "rod"):
        R_obs, rec = E.observable_rotation(_ob(shape, 0.02), R0, R1)
        assert np.allclose(R_obs @ a0, a1, atol=1e-9)
        axis, angle = _axis_angle(R_obs)
        assert abs(axis @ a0) < 1e-9 and abs(axis @ a1) < 1e-9
        assert np.isclose(angle, np.arccos(np.clip(a0 @ a1, -1, 1)), atol=1e-9)
        rest_axis, rest_angle = _axis_angle(R_obs.T @ R)
        assert np.isclose(abs(rest_axis @ a0), 1.0, atol=1e-9) and np.isclose(rec["twist"], rest_angle)
    # a pure twist about the axis is removed entirely
    twist = Rotation.from_rotvec(0.3 * a0).as_matrix()
    R_obs, rec = E.observable_rotation(_ob("cylinder", 0.01), R0, twist @ R0)
    assert np.allclose(R_obs, np.eye(3), atol=1e-12) and np.isclose(rec["twist"], 0.3)


def test_observable_ground_truth_differs_only_on_uniform_bodies_of_revolution(pair):
    # on any pair: equal to the raw truth outside the objects whose twist was removed, and on those the
    # moved points still lie on the body (distance to the centre unchanged for a sphere)
    raw, obs, lab = pair["flow3d"], pair["flow3d_observable"], pair["labels0"]
    ok = np.isfinite(raw).all(-1)
    assert np.array_equal(np.isfinite(obs).all(-1), ok)
    changed = {k for k, rec in pair["observability"].items() if rec["twist"] > 0}
    same = ok & ~np.isin(lab, list(changed))
    assert np.allclose(obs[same], raw[same], atol=1e-12)
    for rec in pair["observability"].values():
        assert rec["twist"] == 0.0 or (rec["uniform"] and rec["symmetry"] in ("point", "axis"))
    assert not (pair["moving_observable"] & ~pair["moving"]).any()
