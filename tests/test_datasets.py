"""Tests of flowtrack.datasets: Middlebury 2014 Motorcycle (shipped with scikit-image), MOTChallenge files."""

import importlib.util

import numpy as np
import pytest
from scipy.spatial import cKDTree

from flowtrack.camera import depth_from_disparity
from flowtrack.datasets import (
    MOTORCYCLE_CALIBRATION,
    load_mot_challenge,
    motorcycle_cloud,
    motorcycle_depth,
    motorcycle_flow_case,
    tud_campus_paths,
)

# numbers printed in the docstring of skimage.data.stereo_motorcycle (independent of the module)
F, CX, CY, DOFFS, B_MM = 994.978, 311.193, 254.877, 31.086, 193.001


@pytest.fixture(scope="module")
def cloud():
    return motorcycle_cloud(step=4, return_pixels=True)


def test_cloud_shape_and_depth_formula(cloud):
    from skimage import data

    P, C, pix = cloud
    assert P.ndim == 2 and P.shape[1] == 3 and P.shape[0] > 10000
    assert np.isfinite(P).all() and C.shape == P.shape and ((C >= 0) & (C <= 1)).all()
    assert (pix % 4 == 0).all()
    disp = data.stereo_motorcycle()[2].astype(float)
    d = disp[pix[:, 0], pix[:, 1]]
    Z = B_MM * F / (d + DOFFS) / 1000.0
    np.testing.assert_allclose(P[:, 2], Z, rtol=1e-12)
    np.testing.assert_allclose(P[:, 0], (pix[:, 1] - CX) / F * Z, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(P[:, 1], (pix[:, 0] - CY) / F * Z, rtol=1e-12, atol=1e-12)


def test_calibration_is_the_one_in_the_skimage_docstring():
    """The numbers above (and the module's) are those the installed scikit-image documents."""
    from skimage import data

    doc = " ".join(data.stereo_motorcycle.__doc__.split())
    for label, value, unit in [("Focal length", F, "px"), ("Principal point x", CX, "px"),
                               ("Principal point y", CY, "px"), ("Principal point dx", DOFFS, "px"),
                               ("Baseline", B_MM, "mm")]:
        assert f"{label}: {value}{unit}" in doc
    c = MOTORCYCLE_CALIBRATION
    assert (c["f"], c["cx"], c["cy"], c["doffs"], c["baseline_mm"]) == (F, CX, CY, DOFFS, B_MM)


def test_depth_by_hand_at_a_few_pixels():
    """Z = B f / (d + doffs) with the docstring's numbers, at the nearest and farthest pixel, at a pixel
    in the middle of the bike and at an unknown (inf) pixel; and the shared helper agrees."""
    from skimage import data

    disp = data.stereo_motorcycle()[2].astype(float)
    depth, _ = motorcycle_depth()
    finite = np.where(np.isfinite(disp), disp, np.nan)
    nearest = np.unravel_index(np.nanargmax(finite), disp.shape)
    farthest = np.unravel_index(np.nanargmin(finite), disp.shape)
    pixels = [nearest, farthest, (250, 370)]
    for r, c in pixels:
        d = disp[r, c]
        assert np.isfinite(d)
        assert depth[r, c] == pytest.approx(B_MM * F / (d + DOFFS) / 1000.0, rel=1e-15)
    unknown = ~np.isfinite(disp)
    assert unknown.sum() > 1000 and (depth[unknown] == 0).all() and (depth[~unknown] > 0).all()
    # the helper with the baseline in metres: the same depths up to rounding
    np.testing.assert_allclose(depth_from_disparity(disp, F, B_MM / 1000.0, DOFFS), depth, rtol=1e-15, atol=0)


def test_metric_scale_plausible(cloud):
    P, _, pix = cloud
    # the motorcycle occupies roughly columns 95..690, rows 100..460 and is the nearest object
    bike = (pix[:, 1] > 95) & (pix[:, 1] < 690) & (pix[:, 0] > 100) & (pix[:, 0] < 460) & (P[:, 2] < 2.7)
    x = P[bike, 0]
    width = np.percentile(x, 99) - np.percentile(x, 1)
    assert 1.0 < width < 2.5
    assert 1.5 < np.median(P[bike, 2]) < 3.0


def _rigid(T):
    R = T[:3, :3]
    return np.allclose(R.T @ R, np.eye(3), atol=1e-12) and abs(np.linalg.det(R) - 1) < 1e-12


def test_flow_case_consistent_with_transforms():
    c = motorcycle_flow_case(seed=2, noise=0.0)
    X, v, lab, dt = c["clean_t"], c["gt_flow"], c["labels_t"], c["dt"]
    Tg, Tp = c["T_global"], c["T_part"]
    assert _rigid(Tg) and _rigid(Tp)
    assert 100 < lab.sum() < 0.5 * lab.size
    np.testing.assert_array_equal(c["points_t"], X)
    moved = X + v * dt
    rest = lab == 0
    np.testing.assert_allclose(moved[rest], X[rest] @ Tg[:3, :3].T + Tg[:3, 3], atol=1e-12)
    Y = X[~rest] @ Tp[:3, :3].T + Tp[:3, 3]
    np.testing.assert_allclose(moved[~rest], Y @ Tg[:3, :3].T + Tg[:3, 3], atol=1e-12)
    # t+1 points are moved cloud points, but not index-aligned with points_t
    P0, _ = motorcycle_cloud(step=4)
    both = np.vstack([P0, P0 @ Tp[:3, :3].T + Tp[:3, 3]])  # each point moves by Tg or by Tg Tp
    tree = cKDTree(both @ Tg[:3, :3].T + Tg[:3, 3])
    dist, _ = tree.query(c["points_t1"])
    assert dist.max() < 1e-9
    assert not np.allclose(c["points_t1"][: len(moved)], moved[: len(c["points_t1"])])


def test_flow_case_noise_and_determinism():
    a = motorcycle_flow_case(seed=1, noise=0.002, step=8)
    b = motorcycle_flow_case(seed=1, noise=0.002, step=8)
    # same seed, same cloud; to 1e-12 m, as the motion is applied by matrix products (BLAS)
    np.testing.assert_allclose(a["points_t1"], b["points_t1"], rtol=0, atol=1e-12)
    e = a["points_t"] - a["clean_t"]
    assert abs(e.std() - 0.002) < 0.0002


@pytest.mark.parametrize(
    ("kwargs", "exc", "word"),
    [
        ({"noise": -1.0}, ValueError, "noise"),
        ({"dt": 0.0}, ValueError, "dt"),
        ({"keep": 1.5}, ValueError, "keep"),
        ({"seed": 1.5}, TypeError, "seed"),
        ({"step": 0}, ValueError, "step"),
    ],
)
def test_bad_inputs(kwargs, exc, word):
    with pytest.raises(exc, match=word):
        motorcycle_flow_case(**kwargs)


# --------------------------------------------------------------------------------------------------
# MOTChallenge files
# --------------------------------------------------------------------------------------------------
HAVE_MOTMETRICS_DATA = importlib.util.find_spec("motmetrics") is not None
needs_data = pytest.mark.skipif(not HAVE_MOTMETRICS_DATA, reason="motmetrics wheel (data files) missing")


@needs_data
def test_tud_campus_paths_point_at_the_wheel_files():
    gt_path, test_path = tud_campus_paths()
    assert gt_path.name == "gt.txt" and test_path.name == "test.txt"
    assert gt_path.parent.name == "TUD-Campus"
    frames = load_mot_challenge(gt_path)
    assert len(frames) == 71
    # first line of gt.txt: 1,1,399,182,121,229,1,-1,-1,-1
    np.testing.assert_array_equal(frames[0][1], [399, 182, 121, 229])



def test_load_mot_challenge(tmp_path):
    p = tmp_path / "res.txt"
    p.write_text("2 5 1.5 2 3 4 0.9\n2,6,0,0,1,1,0.2,-1,-1,-1\n\n4,5,2,2,3,4,1,-1,-1,-1\n")
    frames = load_mot_challenge(p)
    assert len(frames) == 4 and frames[0] == {} and frames[2] == {}
    np.testing.assert_array_equal(frames[1][5], [1.5, 2, 3, 4])
    assert set(frames[1]) == {5, 6}
    assert set(load_mot_challenge(p, min_confidence=0.5)[1]) == {5}
    assert len(load_mot_challenge(p, num_frames=6)) == 6
    with pytest.raises(ValueError, match="num_frames"):
        load_mot_challenge(p, num_frames=3)
    dup = tmp_path / "dup.txt"
    dup.write_text("1,1,0,0,1,1\n1,1,2,2,1,1\n")
    with pytest.raises(ValueError, match="duplicate"):
        load_mot_challenge(dup)
    bad = tmp_path / "bad.txt"
    bad.write_text("1,1,0,0\n")
    with pytest.raises(ValueError, match="path"):
        load_mot_challenge(bad)
    with pytest.raises(ValueError, match="path"):
        load_mot_challenge(tmp_path / "missing.txt")
