"""Camera geometry against independent oracles: sympy, finite differences, round trips."""

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtrack.camera import (
    PinholeCamera,
    backproject,
    backproject_pixels,
    check_camera,
    depth_from_disparity,
    optical_flow_from_scene_flow,
    project,
    projection_jacobian,
    scene_flow_from_optical_flow,
)
from oracles import central_difference_jacobian

CAM = PinholeCamera(525.0, 520.0, 319.5, 239.5, 640, 480)


def random_points(rng, n=50):
    return np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0.5, 4, n)])


def test_K_and_project_match_homogeneous_formula(rng):
    X = random_points(rng)
    x_h = (CAM.K @ X.T).T
    np.testing.assert_allclose(project(X, CAM), x_h[:, :2] / x_h[:, 2:], rtol=1e-13)


def test_jacobian_against_sympy(rng):
    X, Y, Z, fx, fy, cx, cy = sp.symbols("X Y Z f_x f_y c_x c_y", real=True)
    pi = sp.Matrix([fx * X / Z + cx, fy * Y / Z + cy])
    J = sp.lambdify((X, Y, Z, fx, fy, cx, cy), pi.jacobian([X, Y, Z]), "numpy")
    pts = random_points(rng, 20)
    ours = projection_jacobian(pts, CAM)
    for p, Jp in zip(pts, ours):
        np.testing.assert_allclose(Jp, np.array(J(*p, CAM.fx, CAM.fy, CAM.cx, CAM.cy), float), rtol=1e-12)


def test_jacobian_against_central_differences(rng):
    pts = random_points(rng, 30)
    fd = central_difference_jacobian(lambda P: project(P, CAM), pts)
    np.testing.assert_allclose(projection_jacobian(pts, CAM), fd, rtol=1e-6, atol=1e-6)


def test_optical_flow_is_first_order_displacement(rng):
    X = random_points(rng, 40)
    v = rng.normal(size=(40, 3))
    for dt in (1e-2, 1e-3):
        u = optical_flow_from_scene_flow(X, v, dt, CAM)
        exact = project(X + v * dt, CAM) - project(X, CAM)
        # first-order: the error shrinks like dt^2
        assert np.abs(u - exact).max() < 50 * (dt**2) * CAM.fx


def test_backproject_then_project_returns_pixel_grid(rng):
    depth = rng.uniform(0.5, 3.0, size=(12, 17))
    depth[3, 4] = 0.0
    depth[5, 6] = np.nan
    pts = backproject(depth, CAM)
    assert np.isnan(pts[3, 4]).all() and np.isnan(pts[5, 6]).all()
    valid = np.isfinite(pts[..., 2])
    v, u = np.nonzero(valid)
    np.testing.assert_allclose(project(pts[valid], CAM), np.column_stack([u, v]), atol=1e-10)
    np.testing.assert_allclose(pts[valid][:, 2], depth[valid])


def test_backproject_depth_scale():
    depth = np.full((2, 3), 5000, dtype=np.uint16)
    pts = backproject(depth, CAM, depth_scale=5000.0)
    np.testing.assert_allclose(pts[..., 2], 1.0)


def test_scene_flow_round_trip_translation():
    """A fronto-parallel plane translating in 3-D: optical flow + depths give back the velocity."""
    cam = PinholeCamera(100.0, 100.0, 31.5, 23.5, 64, 48)
    H, W = 48, 64
    Z0, v = 2.0, np.array([0.05, -0.03, 0.1])
    dt = 0.1
    d0 = np.full((H, W), Z0)
    d1 = np.full((H, W), Z0 + v[2] * dt)
    X0 = backproject(d0, cam).reshape(-1, 3)
    exact_uv = (project(X0 + v * dt, cam) - project(X0, cam)).reshape(H, W, 2)
    sf = scene_flow_from_optical_flow(d0, d1, exact_uv, dt, cam)
    inside = np.isfinite(sf[..., 0])
    assert inside.mean() > 0.8
    np.testing.assert_allclose(sf[inside], np.broadcast_to(v, sf[inside].shape), atol=1e-9)


@pytest.mark.parametrize(
    "args, match",
    [
        (([[1.0, 2.0]],), "X must have shape"),
        (([[1.0, 2.0, 0.0]],), "Z > 0"),
        (([[1.0, np.nan, 1.0]],), "NaN"),
        (([[1.0, np.inf, 1.0]],), "inf"),
    ],
)
def test_bad_points(args, match):
    with pytest.raises(ValueError, match=match):
        project(*args, CAM)
    with pytest.raises(ValueError, match=match):
        projection_jacobian(*args, CAM)


def test_bad_camera_and_dt():
    with pytest.raises(ValueError, match="fx"):
        PinholeCamera(0.0, 1.0, 0.0, 0.0)
    with pytest.raises(TypeError, match="cam"):
        project([[0.0, 0.0, 1.0]], "camera")
    with pytest.raises(ValueError, match="dt"):
        optical_flow_from_scene_flow([[0, 0, 1.0]], [[0, 0, 0.0]], 0.0, CAM)
    with pytest.raises(ValueError, match="v must have shape"):
        optical_flow_from_scene_flow([[0, 0, 1.0]], [[0, 0.0]], 0.1, CAM)
    with pytest.raises(ValueError, match="depth"):
        backproject(np.ones(5), CAM)
    with pytest.raises(ValueError, match="depth"):
        backproject(-np.ones((2, 2)), CAM)
    with pytest.raises(ValueError, match="flow_uv"):
        scene_flow_from_optical_flow(np.ones((4, 4)), np.ones((4, 4)), np.zeros((4, 4, 3)), 0.1, CAM)


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.floats(max_value=0.0), st.sampled_from([np.nan, np.inf, -np.inf])))
def test_dt_property(dt):
    """Any non-positive or non-finite time step is rejected with a message naming dt."""
    with pytest.raises(ValueError, match="dt"):
        optical_flow_from_scene_flow([[0.1, 0.2, 1.0]], [[0.0, 0.0, 0.0]], dt, CAM)


# -- stereo depth from disparity ------------------------------------------------------------------------
def test_depth_from_disparity_hand_computed():
    # KITTI-like rig: f = 700 px, B = 0.54 m, so f B = 378 px m
    np.testing.assert_allclose(depth_from_disparity([378.0, 70.0, 10.0], 700.0, 0.54), [1.0, 5.4, 37.8],
                               rtol=1e-15)
    # with doffs: Z = 4 * 2 / (3 + 5) = 1; disparity 0 is a valid pixel when doffs > 0: Z = 8 / 5
    np.testing.assert_allclose(depth_from_disparity([3.0, 0.0, -4.0], 4.0, 2.0, doffs=5.0), [1.0, 1.6, 8.0],
                               rtol=1e-15)
    # negative doffs: d must exceed -doffs
    np.testing.assert_allclose(depth_from_disparity([10.0, 2.0], 4.0, 2.0, doffs=-2.0), [1.0, 0.0],
                               rtol=1e-15)


@pytest.mark.parametrize(
    ("value", "doffs"),
    [(np.nan, 0.0), (np.inf, 0.0), (-np.inf, 0.0), (0.0, 0.0), (-3.0, 0.0), (-5.0, 5.0), (-6.0, 5.0),
     (np.nan, 5.0), (np.inf, 5.0), (1.0, -1.0)],
)
def test_depth_from_disparity_invalid_values_give_zero(value, doffs):
    """NaN, +-inf and d + doffs <= 0 are invalid: depth 0, next to a valid pixel that keeps its depth."""
    Z = depth_from_disparity(np.array([[value, 10.0 - doffs]]), 2.0, 3.0, doffs)
    assert Z.dtype == np.float64 and Z.shape == (1, 2)
    assert Z[0, 0] == 0.0 and Z[0, 1] == pytest.approx(0.6, rel=1e-15)


def test_depth_from_disparity_overflow_is_invalid_and_shapes_are_kept():
    assert depth_from_disparity([5e-324], 1e10, 1.0)[0] == 0.0  # f B / d = inf: no depth, not inf
    assert depth_from_disparity(4.0, 2.0, 1.0).shape == ()
    d = np.array([[[2.0, np.nan]]])
    Z = depth_from_disparity(d, 2.0, 1.0)
    assert Z.shape == (1, 1, 2) and np.isnan(d[0, 0, 1]) and Z[0, 0, 0] == 1.0  # the input is untouched
    raw = np.array([0, 4], dtype=np.uint16)
    np.testing.assert_array_equal(depth_from_disparity(raw, 2.0, 1.0), [0.0, 0.5])


def test_depth_from_disparity_matches_backproject_convention():
    """0 is "no depth" for backproject: invalid disparities become NaN points, valid ones Z = f B / d."""
    cam = PinholeCamera(50.0, 50.0, 1.0, 0.5)
    disp = np.array([[25.0, np.inf, 0.0], [-1.0, 10.0, np.nan]])
    pts = backproject(depth_from_disparity(disp, cam.fx, 0.2), cam)
    valid = np.isfinite(disp) & (disp > 0)
    assert np.isnan(pts[~valid]).all() and np.isfinite(pts[valid]).all()
    np.testing.assert_allclose(pts[valid][:, 2], 50.0 * 0.2 / disp[valid], rtol=1e-15)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.05, 200.0), st.floats(1.0, 5000.0), st.floats(0.01, 2.0), st.floats(-50.0, 50.0))
def test_depth_from_disparity_inverts_the_disparity_of_a_depth(Z, f, B, doffs):
    """A point at depth Z has disparity d = f B / Z - doffs; converting back gives Z."""
    d = f * B / Z - doffs
    assert depth_from_disparity([d], f, B, doffs)[0] == pytest.approx(Z, rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"focal_px": 0.0}, ValueError, "focal_px must be > 0"),
        ({"focal_px": np.nan}, ValueError, "focal_px must be finite"),
        ({"baseline": -0.1}, ValueError, "baseline must be > 0"),
        ({"baseline": np.inf}, ValueError, "baseline must be finite"),
        ({"doffs": np.nan}, ValueError, "doffs must be finite"),
        ({"doffs": -np.inf}, ValueError, "doffs must be finite"),
        ({"doffs": "31"}, TypeError, "doffs must be a real number"),
        ({"disparity": "abc"}, TypeError, "disparity must be a numeric array"),
        ({"disparity": None}, TypeError, "disparity must be an array"),
    ],
)
def test_depth_from_disparity_bad_arguments(kwargs, exc, match):
    args = {"disparity": [1.0, 2.0], "focal_px": 500.0, "baseline": 0.1, "doffs": 0.0, **kwargs}
    with pytest.raises(exc, match=match):
        depth_from_disparity(**args)


def test_backproject_pixels_inverts_the_intrinsics(rng):
    u, v = rng.uniform(0, 640, size=20), rng.uniform(0, 480, size=20)
    Z = rng.uniform(0.5, 3.0, size=20)
    expected = (np.linalg.inv(CAM.K) @ np.stack([u, v, np.ones_like(u)])).T * Z[:, None]
    np.testing.assert_allclose(backproject_pixels(u, v, Z, CAM), expected, rtol=1e-12)
    grid = backproject_pixels(np.arange(3.0), np.arange(2.0)[:, None], 1.0, CAM)
    assert grid.shape == (2, 3, 3)
    assert np.isnan(backproject_pixels(1.0, 1.0, np.nan, CAM)).all()


def test_backproject_pixels_and_check_camera_bad_inputs():
    with pytest.raises(TypeError, match="cam must be a PinholeCamera"):
        backproject_pixels(0.0, 0.0, 1.0, "cam")
    with pytest.raises(ValueError, match="broadcast"):
        backproject_pixels(np.zeros(2), np.zeros(3), 1.0, CAM)
    with pytest.raises(ValueError, match="Z"):
        backproject_pixels(0.0, 0.0, np.inf, CAM)
    with pytest.raises(ValueError, match="camera must have width and height"):
        check_camera(PinholeCamera(1.0, 1.0, 0.0, 0.0), "camera", require_size=True)
    assert check_camera(CAM, require_size=True) is CAM
