"""RGB-D variational scene flow (flowtrack.rgbd_flow) against independent oracles.

Oracles: analytically rendered translating planes (exact flow), the camera module's projection
Jacobian, central finite differences of the energy, scipy's direct sparse solver on a system assembled
here from the definition (with flowtrack.variational.grid_laplacian), and the Euler–Lagrange equations
derived by sympy (flowtrack.symbolic.rgbd).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import sympy
from scipy.sparse.linalg import spsolve

from flowtrack import _rgbd_energy as E
from flowtrack import rgbd_flow as R
from flowtrack.camera import PinholeCamera, projection_jacobian
from flowtrack.sceneflow import rgbd_scene_flow
from flowtrack.symbolic.rgbd import pixel_data_term, rgbd_euler_lagrange
from flowtrack.variational import grid_laplacian

CAM = PinholeCamera(120.0, 120.0, 47.5, 35.5)
H, W = 72, 96


def _texture(u, v):
    """A smooth, non-periodic texture on the plane (plane coordinates u, v in metres).

    At most about 0.3 rad per pixel at 1 m, so that bilinear interpolation is accurate.
    """
    return (0.5 + 0.18 * np.sin(27.0 * u + 2.0 * np.cos(15.0 * v)) * np.cos(23.0 * v)
            + 0.12 * np.sin(19.0 * u - 13.0 * v + 40.0 * u * v))


def _plane_pair(d, Z=1.0):
    """Grey images and depths of a fronto-parallel textured plane at depth Z moving by ``d`` (metres)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    Z1 = Z + d[2]
    I0 = _texture((xx - CAM.cx) * Z / CAM.fx, (yy - CAM.cy) * Z / CAM.fy)
    # at t + dt pixel (x, y) sees the plane point (x - cx) Z1 / f, which was at that minus d
    I1 = _texture((xx - CAM.cx) * Z1 / CAM.fx - d[0], (yy - CAM.cy) * Z1 / CAM.fy - d[1])
    return I0, np.full((H, W), Z), I1, np.full((H, W), Z1)


# --------------------------------------------------------------------------------------------------
# exact flow of a translating plane
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "d", [(0.02, 0.0, 0.0), (0.0, -0.015, 0.0), (0.0, 0.0, 0.03), (0.01, 0.008, -0.02)],
    ids=["x", "y", "z", "xyz"],
)
def test_translating_plane_exact_flow(d):
    dt = 0.1
    I0, D0, I1, D1 = _plane_pair(np.array(d))
    v = rgbd_scene_flow(I0, D0, I1, D1, CAM, dt)
    assert v.shape == (H, W, 3) and np.isfinite(v).all()
    # pixels whose point stays in view (the border ones leave the image for x/y motions)
    inner = v[12:-12, 12:-12].reshape(-1, 3)
    err = np.linalg.norm(inner * dt - np.array(d), axis=1)
    # one pixel is 8.3 mm here: 0.4 mm is 0.05 px, about 2 % of these motions (15-30 mm per frame)
    assert np.median(err) < 4e-4
    assert np.mean(err < 1.5e-3) > 0.95


def test_both_backends_agree():
    I0, D0, I1, D1 = _plane_pair(np.array([0.01, 0.005, 0.01]))
    D0 = D0.copy()
    D0[30:36, 40:50] = 0.0
    v1 = rgbd_scene_flow(I0, D0, I1, D1, CAM, 0.1, backend="numba")
    v2 = rgbd_scene_flow(I0, D0, I1, D1, CAM, 0.1, backend="numpy")
    np.testing.assert_array_equal(np.isnan(v1), np.isnan(v2))
    ok = np.isfinite(v1)
    np.testing.assert_allclose(v1[ok], v2[ok], rtol=0, atol=1e-7)


def test_without_numba_auto_falls_back_to_numpy(monkeypatch):
    args = _plane_pair(np.array([0.01, 0.0, 0.0]))
    ref = rgbd_scene_flow(*args, CAM, 0.1, backend="numpy")
    monkeypatch.setattr(R, "_KERNELS", [None])  # as if numba could not be imported
    np.testing.assert_array_equal(rgbd_scene_flow(*args, CAM, 0.1), ref)
    with pytest.raises(ValueError, match="numba"):
        rgbd_scene_flow(*args, CAM, 0.1, backend="numba")


# --------------------------------------------------------------------------------------------------
# the per-pixel data term: rank 2, aperture null space
# --------------------------------------------------------------------------------------------------
def test_pixel_normal_matrix_rank_and_aperture_null_space():
    rng = np.random.default_rng(3)
    n = 200
    X = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.4, 0.4, n), rng.uniform(0.5, 3.0, n)])
    gi, gd = rng.normal(size=(n, 2)), 0.01 * rng.normal(size=(n, 2))
    ri, rd = rng.normal(size=n), 0.01 * rng.normal(size=n)
    wi, wd = rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 2.0, n)
    N, b = R.pixel_normal_equations(X, gi, ri, gd, rd, CAM, wi, wd)
    # oracle: a_I = J^T grad I, a_D = J^T grad D - e_z with J from flowtrack.camera
    J = projection_jacobian(X, CAM)
    a_i = np.einsum("nji,nj->ni", J, gi)
    a_d = np.einsum("nji,nj->ni", J, gd) - np.array([0.0, 0.0, 1.0])
    N_ref = wi[:, None, None] * np.einsum("ni,nj->nij", a_i, a_i) + wd[:, None, None] * np.einsum(
        "ni,nj->nij", a_d, a_d)
    np.testing.assert_allclose(N, N_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b, -(wi * ri)[:, None] * a_i - (wd * rd)[:, None] * a_d, rtol=1e-12)
    sv = np.linalg.svd(N, compute_uv=False)
    assert (sv[:, 1] > 1e-6 * sv[:, 0]).all()  # rank 2 exactly: two independent equations
    assert (sv[:, 2] < 1e-12 * sv[:, 0]).all()  # ... never three
    null = np.cross(a_i, a_d)
    null /= np.linalg.norm(null, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", N, null), 0.0, atol=1e-9 * sv[:, :1].max())
    # moving along the aperture direction changes neither linearised residual: the data cannot see it
    delta = np.linalg.lstsq(N[0], b[0], rcond=None)[0]
    for t in (0.0, 0.3, -2.0):
        moved = delta + t * null[0]
        e = wi[0] * (ri[0] + a_i[0] @ moved) ** 2 + wd[0] * (rd[0] + a_d[0] @ moved) ** 2
        e0 = wi[0] * (ri[0] + a_i[0] @ delta) ** 2 + wd[0] * (rd[0] + a_d[0] @ delta) ** 2
        assert abs(e - e0) <= 1e-9 * max(1.0, e0)


def test_symbolic_normal_matrix_is_singular():
    d = pixel_data_term()
    assert sympy.simplify(d["N"].det()) == 0
    assert sympy.simplify(d["N"] * d["null"]) == sympy.zeros(3, 1)


# --------------------------------------------------------------------------------------------------
# the discrete energy, its gradient and the linear systems
# --------------------------------------------------------------------------------------------------
def _random_problem(rng, h=6, w=7, penalty="charbonnier", holes=True):
    a_i = rng.normal(size=(h, w, 3)) * [30.0, 30.0, 10.0]
    a_d = rng.normal(size=(h, w, 3)) * [0.3, 0.3, 1.0]
    m_i = np.ones((h, w))
    m_d = np.ones((h, w))
    if holes:
        m_i[1, 2] = m_d[1, 2] = 0.0
        m_d[3, 4] = 0.0
    return E.Linearised(
        s0=0.01 * rng.normal(size=(h, w, 3)), a_i=a_i, r_i=0.05 * rng.normal(size=(h, w)), m_i=m_i,
        a_d=a_d, r_d=0.005 * rng.normal(size=(h, w)), m_d=m_d,
        wv=rng.uniform(0.05, 1.0, (h - 1, w)), wh=rng.uniform(0.05, 1.0, (h, w - 1)),
        lam=0.3, sigma_i=0.02, sigma_d=0.004, sigma_s=0.002, penalty=penalty,
    )


@pytest.mark.parametrize("penalty", ["charbonnier", "quadratic"])
def test_energy_gradient_matches_finite_differences(penalty):
    rng = np.random.default_rng(7)
    prob = _random_problem(rng, penalty=penalty)
    s = prob.s0 + 0.003 * rng.normal(size=prob.s0.shape)
    g = prob.gradient(s)
    eps = 1e-7
    for _ in range(25):
        i, j, k = rng.integers(prob.s0.shape[0]), rng.integers(prob.s0.shape[1]), rng.integers(3)
        sp_, sm = s.copy(), s.copy()
        sp_[i, j, k] += eps
        sm[i, j, k] -= eps
        fd = (prob.energy(sp_) - prob.energy(sm)) / (2 * eps)
        assert fd == pytest.approx(g[i, j, k], rel=1e-5, abs=1e-6 * np.abs(g).max())


def _sparse_system(prob):
    """The quadratic problem's normal equations assembled from the definition (an independent oracle)."""
    h, w, _ = prob.s0.shape
    c_i = prob.m_i / prob.sigma_i**2
    c_d = prob.m_d / prob.sigma_d**2
    blocks = [c_i[p // w, p % w] * np.outer(prob.a_i.reshape(-1, 3)[p], prob.a_i.reshape(-1, 3)[p])
              + c_d[p // w, p % w] * np.outer(prob.a_d.reshape(-1, 3)[p], prob.a_d.reshape(-1, 3)[p])
              for p in range(h * w)]
    L = grid_laplacian(h, w, weights=(prob.wv, prob.wh))
    A = sp.block_diag(blocks) + (prob.lam / prob.sigma_s**2) * sp.kron(L, sp.identity(3))
    # data residual r + a.(s - s0): the minimiser solves A s = sum_p N_p s0_p - c r a
    a_i, a_d = prob.a_i.reshape(-1, 3), prob.a_d.reshape(-1, 3)
    s0 = prob.s0.reshape(-1, 3)
    rhs = (np.einsum("pij,pj->pi", np.array(blocks), s0)
           - (c_i.ravel() * prob.r_i.ravel())[:, None] * a_i
           - (c_d.ravel() * prob.r_d.ravel())[:, None] * a_d)
    return A.tocsc(), rhs.ravel()


def test_quadratic_case_equals_direct_sparse_solve():
    rng = np.random.default_rng(11)
    prob = _random_problem(rng, h=9, w=11, penalty="quadratic")
    A, rhs = _sparse_system(prob)
    s_ref = spsolve(A, rhs).reshape(prob.s0.shape)
    N, b, Wv, Wh = prob.system(prob.s0)
    s_np = E.pcg(N, b, Wv, Wh, prob.s0.copy(), 2000)
    np.testing.assert_allclose(s_np, s_ref, rtol=0, atol=1e-9 * np.abs(s_ref).max())
    K = R._kernels()
    M = np.empty((*prob.s0.shape[:2], 6))
    rhs6 = np.empty(prob.s0.shape)
    c_i, c_d, Wv, Wh = prob.weights(prob.s0)
    K.assemble(prob.a_i, prob.a_d, c_i, c_d, prob.r_i, prob.r_d, prob.s0, Wv, Wh, M, rhs6)
    s_nb = K.pcg(M, rhs6, Wv, Wh, prob.s0.copy(), 2000)
    np.testing.assert_allclose(s_nb, s_ref, rtol=0, atol=1e-9 * np.abs(s_ref).max())
    # and it is the minimiser: the energy's gradient vanishes there
    assert np.abs(prob.gradient(s_ref)).max() < 1e-6 * np.abs(prob.gradient(prob.s0)).max()


def test_estimator_quadratic_single_step_is_the_sparse_solution():
    """End to end: one level, one warp, one reweighting, CG to convergence = spsolve of that problem."""
    I0, D0, I1, D1 = _plane_pair(np.array([0.004, 0.0, 0.002]))
    D0 = D0 + 0.05 * np.linspace(0, 1, W)[None, :]  # a slanted plane: a_D varies
    h, w = 18, 24
    v, info = rgbd_scene_flow(I0[:h, :w], D0[:h, :w], I1[:h, :w], D1[:h, :w],
                              CAM, 0.1, penalty="quadratic", levels=1, warps=1, irls=1,
                              cg_iterations=3000, return_info=True)
    prob = info["problem"]
    A, rhs = _sparse_system(prob)
    s_ref = spsolve(A, rhs).reshape(h, w, 3)
    np.testing.assert_allclose(v * 0.1, s_ref, rtol=0, atol=1e-8 * np.abs(s_ref).max())


def test_euler_lagrange_from_sympy_matches_the_discrete_operator():
    """grad E_h / h^2 of the implementation = the sympy Euler–Lagrange expression + O(h^2)."""
    eqs, S = rgbd_euler_lagrange()
    x, y = S["x"], S["y"]
    fields = {
        S["s"][0]: sympy.sin(2 * x) * sympy.cos(y), S["s"][1]: x * y + sympy.cos(3 * y),
        S["s"][2]: sympy.exp(-x) * sympy.sin(y + 1),
        S["a_I"][0]: 1 + x, S["a_I"][1]: sympy.cos(x + y), S["a_I"][2]: y - x * x,
        S["a_D"][0]: sympy.sin(x), S["a_D"][1]: x * y, S["a_D"][2]: -1 + 0.2 * y,
        S["r_I"]: sympy.cos(2 * y), S["r_D"]: x - y, S["c_I"]: 1 + x * x, S["c_D"]: 2 + sympy.sin(y),
        S["w"]: 1 + 0.5 * sympy.sin(x) * sympy.cos(y),
    }
    lam = 0.7
    el = [sympy.lambdify((x, y), e.subs(fields).doit().subs(S["lam"], lam), "numpy") for e in eqs]
    f = {k: sympy.lambdify((x, y), v, "numpy") for k, v in fields.items()}
    errs = []
    for h in (0.02, 0.01):
        n = round(0.6 / h) + 1
        yy, xx = np.mgrid[0:n, 0:n] * h + 0.1
        full = lambda e, X=xx, Y=yy: np.broadcast_to(np.asarray(f[e](X, Y), dtype=float), X.shape)  # noqa: E731
        s = np.stack([full(S["s"][k]) for k in range(3)], -1)
        a_i = np.stack([full(S["a_I"][k]) for k in range(3)], -1)
        a_d = np.stack([full(S["a_D"][k]) for k in range(3)], -1)
        # the implementation's energy with unit scales: data c * (r + a.s)^2 * h^2 (area element),
        # smoothness lam * w_edge * |s_p - s_q|^2 with w at the edge midpoints
        wv = full(S["w"], xx[:-1], yy[:-1] + h / 2)
        wh = full(S["w"], xx[:, :-1] + h / 2, yy[:, :-1])
        prob = E.Linearised(np.zeros_like(s), a_i, full(S["r_I"]), full(S["c_I"]) * h * h, a_d,
                             full(S["r_D"]), full(S["c_D"]) * h * h, wv, wh, lam, 1.0, 1.0, 1.0, "quadratic")
        g = prob.gradient(s) / (h * h)
        ref = np.stack([np.broadcast_to(e(xx, yy), xx.shape) for e in el], -1)
        errs.append(np.abs(g - ref)[2:-2, 2:-2].max() / np.abs(ref[2:-2, 2:-2]).max())
    assert errs[1] < 1e-3
    assert errs[0] / errs[1] > 3.0  # second order: halving h divides the error by about 4


# --------------------------------------------------------------------------------------------------
# invalid depth
# --------------------------------------------------------------------------------------------------
def test_invalid_depth_is_nan_and_never_spreads():
    d = np.array([0.01, 0.0, 0.005])
    I0, D0, I1, D1 = _plane_pair(d)
    D0h, D1h = D0.copy(), D1.copy()
    D0h[20:30, 30:45] = np.nan
    D0h[50:54, 10:14] = 0.0
    D0h[5, 80] = np.inf
    D1h[40:50, 60:70] = np.nan
    v = rgbd_scene_flow(I0, D0h, I1, D1h, CAM, 0.1)
    invalid = ~(np.isfinite(D0h) & (D0h > 0))
    assert np.isnan(v[invalid]).all()
    assert np.isfinite(v[~invalid]).all()
    # the valid pixels still get the plane's motion, around the holes too
    inner = np.zeros((H, W), bool)
    inner[12:-12, 12:-12] = True
    err = np.linalg.norm(v * 0.1 - d, axis=-1)[inner & ~invalid]
    assert np.median(err) < 4e-4 and np.mean(err < 1.5e-3) > 0.9


# --------------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------------
def _good():
    I0, D0, I1, D1 = _plane_pair(np.array([0.01, 0.0, 0.0]))
    return [I0, D0, I1, D1, CAM, 0.1]


@pytest.mark.parametrize(
    "index, value, match",
    [
        (0, np.zeros((H, W, 3)), "rgb_t"),  # float RGB
        (0, np.zeros((H, W, 4), np.uint8), "rgb_t"),  # four channels
        (0, np.zeros((H, W), np.int32), "rgb_t"),
        (2, np.zeros((H, W + 1)), "rgb_t1"),
        (2, np.zeros((H, W, 3), np.uint8), "rgb_t1"),  # a different kind than rgb_t
        (1, np.ones((H, W), np.uint16), "depth_t"),  # raw sensor units
        (1, np.ones((H - 1, W)), "depth_t"),
        (3, np.ones((H, W + 2)), "depth_t1"),
        (1, np.zeros((H, W)), "depth_t"),  # no valid depth
        (3, np.full((H, W), np.nan), "depth_t1"),
        (1, -np.ones((H, W)), "depth_t"),
        (5, 0.0, "dt"),
        (5, -0.1, "dt"),
    ],
)
def test_bad_input_names_the_argument(index, value, match):
    args = _good()
    args[index] = value
    with pytest.raises(ValueError, match=match):
        rgbd_scene_flow(*args)


def test_bad_camera_and_options():
    args = _good()
    with pytest.raises(TypeError, match="cam"):
        rgbd_scene_flow(*args[:4], "camera", 0.1)
    with pytest.raises(ValueError, match="cam"):
        rgbd_scene_flow(*args[:4], PinholeCamera(100.0, 100.0, 10.0, 10.0, width=W + 1, height=H), 0.1)
    with pytest.raises(TypeError, match="unknown option"):
        rgbd_scene_flow(*args, lambda_=1.0)
    with pytest.raises(ValueError, match="penalty"):
        rgbd_scene_flow(*args, penalty="huber")
    with pytest.raises(ValueError, match="lam"):
        rgbd_scene_flow(*args, lam=-1.0)
    with pytest.raises(ValueError, match="lam"):  # no smoothing: singular (rank-2 data terms)
        rgbd_scene_flow(*args, lam=0.0)
    with pytest.raises(ValueError, match="use_depth"):
        rgbd_scene_flow(*args, use_depth=False, use_color=False)


# --------------------------------------------------------------------------------------------------
# the cloud helper for the demo
# --------------------------------------------------------------------------------------------------
def test_point_flow_lines_up_with_the_synthetic_clouds():
    from flowtrack.synth import make_scene

    scene = make_scene(n_objects=2, n_frames=8, image_size=(60, 80), seed=4, scenario="crossing")
    f0, f1 = scene.frames[3], scene.frames[4]
    depth = f0.depth.copy()
    depth[10:14, 20:30] = 0.0  # a hole: those pixels are not points
    X, v = R.rgbd_point_flow(f0.rgb, depth, f1.rgb, f1.depth, scene.camera, scene.dt)
    keep = (depth > 0)[f0.valid]  # frame.points are the valid pixels in row-major order
    np.testing.assert_allclose(X, f0.points[keep], rtol=0, atol=1e-12)
    assert np.isfinite(v).all()
    # the velocities belong to those points: far closer to their ground truth than to zero motion
    moving = np.linalg.norm(f0.gt_flow[keep], axis=1) > 0
    err = np.linalg.norm(v - f0.gt_flow[keep], axis=1)
    assert np.median(err[moving]) < 0.3 * np.median(np.linalg.norm(f0.gt_flow[keep][moving], axis=1))
