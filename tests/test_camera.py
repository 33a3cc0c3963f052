"""Camera geometry against independent oracles: sympy, finite differences, round trips."""

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtrack.camera import (
    PinholeCamera,
    backproject,
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
