"""Tests of flowtrack.variational against oracles built independently in this file.

Oracles: the grid Laplacian is assembled here from explicit Python loops over the edges; the
linear system is solved with scipy's sparse direct solver; the energy is evaluated here from its
definition (loops over pixels and edges); gradients are checked by central finite differences; the
Euler–Lagrange link by a manufactured smooth solution of the continuous PDE.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse.linalg import spsolve

from flowtrack.variational import (
    grid_laplacian,
    red_black_sweep,
    solve_component,
    variational_energy,
    variational_scene_flow,
)

METHODS = ["dct", "cg", "gauss_seidel"]


# --------------------------------------------------------------------------------------------------
# independent oracles
# --------------------------------------------------------------------------------------------------
def edges(H, W):
    """4-neighbour edges (p, q) of an H x W grid, each once, pixel (i, j) -> i * W + j."""
    out = []
    for i in range(H):
        for j in range(W):
            if i + 1 < H:
                out.append((i * W + j, (i + 1) * W + j))
            if j + 1 < W:
                out.append((i * W + j, i * W + j + 1))
    return out


def loop_laplacian(H, W, weight=None):
    """L = sum over edges of w (e_p - e_q)(e_p - e_q)^T, as a dense array."""
    L = np.zeros((H * W, H * W))
    for k, (p, q) in enumerate(edges(H, W)):
        w = 1.0 if weight is None else weight[k]
        L[p, p] += w
        L[q, q] += w
        L[p, q] -= w
        L[q, p] -= w
    return L


def oracle_solve(X_t, X_t1, dt, lam, m):
    """spsolve of (dt^2 M + lam L) v = dt M (X_t1 - X_t) per component, m (H, W) 0/1."""
    H, W = m.shape
    A = sp.csc_matrix(dt**2 * np.diag(m.ravel()) + lam * loop_laplacian(H, W))
    diff = np.where(m[..., None] > 0, X_t1 - X_t, 0.0).reshape(H * W, 3)
    rhs = dt * m.ravel()[:, None] * diff
    v = np.stack([spsolve(A, rhs[:, k]) for k in range(3)], axis=-1)
    return v.reshape(H, W, 3), A.toarray(), rhs


def energy(v, X_t, X_t1, dt, lam, m, psi=None):
    """The energy from its definition, with loops over pixels and edges."""
    H, W = m.shape
    vf = v.reshape(H * W, 3)
    a = np.nan_to_num(X_t).reshape(H * W, 3)
    b = np.nan_to_num(X_t1).reshape(H * W, 3)
    mf = m.ravel()
    e = 0.0
    for p in range(H * W):
        if mf[p]:
            e += float(np.sum((a[p] + vf[p] * dt - b[p]) ** 2))
    for p, q in edges(H, W):
        s2 = float(np.sum((vf[p] - vf[q]) ** 2))
        e += lam * (s2 if psi is None else psi(s2))
    return e


def charbonnier(eps):
    return lambda s2: 2.0 * eps**2 * (np.sqrt(1.0 + s2 / eps**2) - 1.0)


def random_problem(rng, H=7, W=9, nan_frac=0.0):
    X_t = rng.normal(size=(H, W, 3)) + np.array([0.0, 0.0, 1.5])
    X_t1 = X_t + 0.05 * rng.normal(size=(H, W, 3)) + 0.02
    if nan_frac:
        bad = rng.random((H, W)) < nan_frac
        X_t[bad, 2] = np.nan
    return X_t, X_t1


def assert_within_guarantee(v, v_star, A, rhs, dt, tol):
    """The documented bound ||v - v*||_F <= tol ||B||_F / lambda_min(A) (scaled system A / dt^2)."""
    lam_min = np.linalg.eigvalsh(A / dt**2)[0]
    bound = tol * np.linalg.norm(rhs / dt**2) / lam_min
    err = np.linalg.norm(v - v_star)
    assert err <= 1.01 * bound + 1e-13 * (1 + np.linalg.norm(v_star)), (err, bound)


# --------------------------------------------------------------------------------------------------
# the grid Laplacian
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("H,W", [(1, 1), (1, 5), (4, 1), (7, 9), (3, 3)])
def test_grid_laplacian_matches_edge_loops(H, W):
    L = grid_laplacian(H, W)
    assert sp.issparse(L) and L.format == "csr" and L.shape == (H * W, H * W)
    np.testing.assert_array_equal(L.toarray(), loop_laplacian(H, W))


def test_weighted_grid_laplacian_matches_edge_loops(rng):
    H, W = 5, 6
    wv, wh = rng.random((H - 1, W)), rng.random((H, W - 1))
    # edge order of `edges`: for each pixel, vertical edge then horizontal edge
    weight = []
    for i in range(H):
        for j in range(W):
            if i + 1 < H:
                weight.append(wv[i, j])
            if j + 1 < W:
                weight.append(wh[i, j])
    np.testing.assert_allclose(
        grid_laplacian(H, W, weights=(wv, wh)).toarray(), loop_laplacian(H, W, weight), atol=1e-15
    )
    with pytest.raises(ValueError, match="weights"):
        grid_laplacian(H, W, weights=(-wv, wh))
    with pytest.raises(ValueError, match="weights"):
        grid_laplacian(H, W, weights=(wh, wv))


def test_grid_laplacian_quadratic_form_is_sum_over_edges(rng):
    H, W = 6, 8
    v = rng.normal(size=H * W)
    direct = sum((v[p] - v[q]) ** 2 for p, q in edges(H, W))
    assert np.isclose(v @ (grid_laplacian(H, W) @ v), direct, rtol=1e-12)


# --------------------------------------------------------------------------------------------------
# every method against the direct sparse solve
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("method", METHODS)
def test_methods_match_spsolve_full_data(method, seed):
    rng = np.random.default_rng(100 + seed)
    H, W = [(7, 9), (5, 4), (1, 6), (8, 3)][seed]
    dt = float(rng.uniform(0.05, 0.5))
    lam = float(rng.uniform(0.001, 0.5)) * dt**2 * 10 ** rng.uniform(-1, 1.3)
    X_t, X_t1 = random_problem(rng, H, W)
    tol = 1e-10
    v, info = variational_scene_flow(X_t, X_t1, dt, lam, method=method, tol=tol, return_info=True)
    v_star, A, rhs = oracle_solve(X_t, X_t1, dt, lam, np.ones((H, W)))
    assert v.shape == (H, W, 3)
    assert_within_guarantee(v, v_star, A, rhs, dt, tol)
    np.testing.assert_allclose(v, v_star, rtol=0, atol=1e-7 * np.abs(v_star).max())
    assert info["residual"] < (1e-12 if method == "dct" else tol)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("method", ["cg", "gauss_seidel"])
def test_iterative_methods_match_spsolve_with_mask(method, seed):
    rng = np.random.default_rng(200 + seed)
    H, W = 7, 9
    dt = float(rng.uniform(0.05, 0.5))
    lam = float(rng.uniform(0.2, 5.0)) * dt**2
    X_t, X_t1 = random_problem(rng, H, W)
    mask = rng.random((H, W)) < 0.6
    mask[3:6, 2:6] = False  # a hole to be filled by the smoothness term
    mask[0, 0] = True
    tol = 1e-11
    v = variational_scene_flow(X_t, X_t1, dt, lam, method=method, mask=mask, tol=tol)
    v_star, A, rhs = oracle_solve(X_t, X_t1, dt, lam, mask.astype(float))
    assert_within_guarantee(v, v_star, A, rhs, dt, tol)
    assert np.isfinite(v).all()


@pytest.mark.parametrize("method", ["cg", "gauss_seidel"])
def test_nan_depth_is_treated_as_missing_data(method, rng):
    X_t, X_t1 = random_problem(rng, 7, 9, nan_frac=0.25)
    X_t1[0, 1, 0] = np.nan
    dt, lam = 0.1, 0.02
    finite = np.isfinite(X_t).all(-1) & np.isfinite(X_t1).all(-1)
    v = variational_scene_flow(X_t, X_t1, dt, lam, method=method, tol=1e-11)
    v_star, A, rhs = oracle_solve(X_t, X_t1, dt, lam, finite.astype(float))
    assert_within_guarantee(v, v_star, A, rhs, dt, 1e-11)
    # a user mask is combined with finiteness
    mask = np.ones((7, 9), bool)
    mask[:, :2] = False
    v2 = variational_scene_flow(X_t, X_t1, dt, lam, method=method, mask=mask, tol=1e-11)
    v2_star, A2, rhs2 = oracle_solve(X_t, X_t1, dt, lam, (finite & mask).astype(float))
    assert_within_guarantee(v2, v2_star, A2, rhs2, dt, 1e-11)


def test_dct_refuses_missing_data(rng):
    X_t, X_t1 = random_problem(rng, 5, 6, nan_frac=0.2)
    with pytest.raises(ValueError, match=r"X_t.*NaN.*cg"):
        variational_scene_flow(X_t, X_t1, 0.1, 0.1, method="dct")
    X_t, X_t1 = random_problem(rng, 5, 6)
    mask = np.ones((5, 6), bool)
    mask[2, 2] = False
    with pytest.raises(ValueError, match="mask"):
        variational_scene_flow(X_t, X_t1, 0.1, 0.1, method="dct", mask=mask)
    # a trivial mask is accepted and changes nothing
    v = variational_scene_flow(X_t, X_t1, 0.1, 0.1, method="dct", mask=np.ones((5, 6)))
    np.testing.assert_array_equal(v, variational_scene_flow(X_t, X_t1, 0.1, 0.1))


def test_no_data_at_all_is_a_clear_error(rng):
    X_t, X_t1 = random_problem(rng, 4, 5)
    with pytest.raises(ValueError, match=r"mask.*singular"):
        variational_scene_flow(X_t, X_t1, 0.1, 0.1, method="cg", mask=np.zeros((4, 5), bool))
    X_t[..., 0] = np.nan
    with pytest.raises(ValueError, match="singular"):
        variational_scene_flow(X_t, X_t1, 0.1, 0.1, method="gauss_seidel")


@pytest.mark.parametrize("method", METHODS)
def test_lam_zero_gives_pointwise_velocity(method, rng):
    X_t, X_t1 = random_problem(rng, 6, 5)
    dt = 0.07
    v = variational_scene_flow(X_t, X_t1, dt, 0.0, method=method)
    np.testing.assert_allclose(v, (X_t1 - X_t) / dt, rtol=1e-13, atol=1e-13)
    if method != "dct":
        mask = rng.random((6, 5)) < 0.5
        v = variational_scene_flow(X_t, X_t1, dt, 0, method=method, mask=mask)
        np.testing.assert_allclose(v[mask], ((X_t1 - X_t) / dt)[mask], rtol=1e-13)
        assert np.isnan(v[~mask]).all()  # undetermined without data and without smoothness


def test_solve_component_is_the_scalar_energy(rng):
    X_t, X_t1 = random_problem(rng, 7, 9)
    dt, lam = 0.2, 0.01
    mask = rng.random((7, 9)) < 0.7
    v3 = variational_scene_flow(X_t, X_t1, dt, lam, method="cg", mask=mask, tol=1e-12)
    v_star, _, _ = oracle_solve(X_t, X_t1, dt, lam, mask.astype(float))
    for method in ("cg", "gauss_seidel"):
        for k in range(3):
            vk = solve_component(X_t[..., k], X_t1[..., k], dt, lam, mask=mask, method=method, tol=1e-12)
            assert vk.shape == (7, 9)
            np.testing.assert_allclose(vk, v_star[..., k], atol=1e-8)
            np.testing.assert_allclose(vk, v3[..., k], atol=1e-8)
    vk, info = solve_component(X_t[..., 0], X_t1[..., 0], dt, lam, return_info=True)
    v_full, _, _ = oracle_solve(X_t, X_t1, dt, lam, np.ones((7, 9)))
    np.testing.assert_allclose(vk, v_full[..., 0], atol=1e-10)
    assert info["method"] == "dct"


def test_all_methods_agree_on_a_larger_grid(rng):
    H, W = 24, 30
    X_t, X_t1 = random_problem(rng, H, W)
    dt, lam = 0.1, 0.05
    tol = 1e-10
    vs = {m: variational_scene_flow(X_t, X_t1, dt, lam, method=m, tol=tol) for m in METHODS}
    d_norm = np.linalg.norm((X_t1 - X_t) / dt)  # documented: error <= tol * ||d||_F with full data
    for m in ("cg", "gauss_seidel"):
        assert np.linalg.norm(vs[m] - vs["dct"]) <= 1.01 * tol * d_norm


# --------------------------------------------------------------------------------------------------
# red-black Gauss–Seidel sweep (the students' exercise)
# --------------------------------------------------------------------------------------------------
def loop_sweep(v, rhs, c, lam):
    """Red pixels then black pixels, one at a time, with explicit neighbour loops."""
    v = v.copy()
    H, W = v.shape
    for colour in (0, 1):
        for i in range(H):
            for j in range(W):
                if (i + j) % 2 != colour:
                    continue
                s, deg = 0.0, 0
                for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                    if 0 <= i + di < H and 0 <= j + dj < W:
                        s += v[i + di, j + dj]
                        deg += 1
                v[i, j] = (rhs[i, j] + lam * s) / (c[i, j] + lam * deg)
    return v


def test_red_black_sweep_matches_pixel_loops(rng):
    H, W = 6, 7
    v = rng.normal(size=(H, W))
    rhs = rng.normal(size=(H, W))
    c = rng.random((H, W)) * (rng.random((H, W)) < 0.7)
    lam = 0.8
    expected = loop_sweep(v, rhs, c, lam)
    out = red_black_sweep(v, rhs, c, lam)
    assert out is v  # in place
    np.testing.assert_allclose(v, expected, rtol=1e-13, atol=1e-15)
    # several components at once: each behaves like its own (H, W) system
    V = rng.normal(size=(H, W, 3))
    R = rng.normal(size=(H, W, 3))
    expected = np.stack([loop_sweep(V[..., k], R[..., k], c, lam) for k in range(3)], -1)
    np.testing.assert_allclose(red_black_sweep(V, R, c, lam), expected, rtol=1e-13, atol=1e-15)


def test_red_black_sweeps_converge_to_the_direct_solution(rng):
    H, W = 5, 6
    c = np.ones((H, W))
    lam = 2.0
    rhs = rng.normal(size=(H, W))
    A = sp.csc_matrix(np.diag(c.ravel()) + lam * loop_laplacian(H, W))
    v_star = spsolve(A, rhs.ravel()).reshape(H, W)
    v = np.zeros((H, W))
    for _ in range(300):
        red_black_sweep(v, rhs, c, lam)
    np.testing.assert_allclose(v, v_star, atol=1e-10)


def test_red_black_sweep_validates():
    v = np.zeros((3, 3))
    with pytest.raises(ValueError, match="singular"):
        red_black_sweep(v, np.zeros((3, 3)), np.zeros((3, 3)), 0.0)
    with pytest.raises(ValueError, match="rhs"):
        red_black_sweep(v, np.zeros((3, 4)), np.ones((3, 3)), 1.0)
    with pytest.raises(ValueError, match="diag_data"):
        red_black_sweep(v, np.zeros((3, 3)), -np.ones((3, 3)), 1.0)
    with pytest.raises(ValueError, match="lam"):
        red_black_sweep(v, np.zeros((3, 3)), np.ones((3, 3)), -1.0)
    with pytest.raises(TypeError, match="v"):
        red_black_sweep([[0.0]], [[0.0]], [[1.0]], 1.0)


# --------------------------------------------------------------------------------------------------
# info, convergence, warnings
# --------------------------------------------------------------------------------------------------
def test_return_info_residual_histories(rng):
    X_t, X_t1 = random_problem(rng, 12, 14)
    dt, lam, tol = 0.1, 0.1, 1e-9
    _, i_cg = variational_scene_flow(X_t, X_t1, dt, lam, method="cg", tol=tol, return_info=True)
    _, i_gs = variational_scene_flow(X_t, X_t1, dt, lam, method="gauss_seidel", tol=tol, return_info=True)
    _, i_dct = variational_scene_flow(X_t, X_t1, dt, lam, method="dct", tol=tol, return_info=True)
    for info in (i_cg, i_gs):
        hist = info["residual_history"]
        assert len(hist) == info["iterations"] > 1
        assert hist[-1] < tol and hist[0] > tol and info["converged"]
        assert np.isclose(hist[-1], info["residual"], rtol=1e-3)
    assert i_cg["iterations"] < i_gs["iterations"]  # CG is the faster iteration on this problem
    assert i_dct["iterations"] == 0 and len(i_dct["residual_history"]) == 1


def test_max_iter_reached_warns(rng):
    X_t, X_t1 = random_problem(rng, 8, 8)
    for method in ("cg", "gauss_seidel"):
        with pytest.warns(RuntimeWarning, match="max_iter"):
            _, info = variational_scene_flow(X_t, X_t1, 0.1, 1.0, method=method, max_iter=2, return_info=True)
        assert not info["converged"] and info["iterations"] == 2
    with pytest.warns(RuntimeWarning, match="irls_max_iter"):
        _, info = variational_scene_flow(
            X_t, X_t1, 0.1, 1.0, regularizer="charbonnier", irls_max_iter=1, return_info=True
        )
    assert not info["irls_converged"] and info["irls_iterations"] == 1


# --------------------------------------------------------------------------------------------------
# the energy: minimum, gradient, the Euler–Lagrange link
# --------------------------------------------------------------------------------------------------
def test_solution_minimises_the_energy(rng):
    H, W = 5, 6
    X_t, X_t1 = random_problem(rng, H, W)
    mask = rng.random((H, W)) < 0.7
    dt, lam = 0.1, 0.03
    m = mask.astype(float)
    v = variational_scene_flow(X_t, X_t1, dt, lam, method="cg", mask=mask, tol=1e-12)
    e0 = energy(v, X_t, X_t1, dt, lam, m)
    assert np.isclose(variational_energy(v, X_t, X_t1, dt, lam, mask=mask), e0, rtol=1e-12)
    for scale in (1e-3, 1e-1, 1.0):
        for _ in range(5):
            assert energy(v + scale * rng.normal(size=v.shape), X_t, X_t1, dt, lam, m) > e0
    # stationarity: central finite differences of the energy vanish
    h = 1e-4
    for _ in range(6):
        i, j, k = rng.integers(H), rng.integers(W), rng.integers(3)
        vp, vm = v.copy(), v.copy()
        vp[i, j, k] += h
        vm[i, j, k] -= h
        g = (energy(vp, X_t, X_t1, dt, lam, m) - energy(vm, X_t, X_t1, dt, lam, m)) / (2 * h)
        assert abs(g) < 1e-8


def test_discrete_operator_is_the_laplacian_of_a_smooth_field():
    """Interior rows of -L/h^2 are the 5-point Laplacian: O(h^2) consistency with Δv."""
    errs = []
    for N in (16, 32, 64):
        h = 1.0 / N
        x = (np.arange(N) + 0.5) * h
        Xg, Yg = np.meshgrid(x, x, indexing="ij")
        v = np.sin(2 * Xg) * np.exp(Yg) + Xg**3
        lap = -4 * np.sin(2 * Xg) * np.exp(Yg) + np.sin(2 * Xg) * np.exp(Yg) + 6 * Xg
        Lv = -(grid_laplacian(N, N) @ v.ravel()).reshape(N, N) / h**2
        errs.append(np.abs(Lv - lap)[1:-1, 1:-1].max())
    assert errs[0] / errs[1] > 3.5 and errs[1] / errs[2] > 3.5


@pytest.mark.parametrize("method", ["dct", "cg"])
def test_discrete_solution_converges_to_the_euler_lagrange_pde(method):
    r"""Manufactured solution of dt^2 v - λ_c Δv = dt (b - a) with ∂v/∂n = 0 on [0,1]^2.

    The discrete energy is h^-2 times a Riemann sum of the continuous one with lam = λ_c / h^2, so
    the discrete minimiser must converge to the PDE solution (second order here).
    """
    dt, lam_c = 0.1, 2e-3

    def f(s):
        return s**2 * (1 - s) ** 2  # f'(0) = f'(1) = 0

    def f2(s):
        return 2 - 12 * s + 12 * s**2

    errs = []
    for N in (12, 24, 48):
        h = 1.0 / N
        x = (np.arange(N) + 0.5) * h
        Xg, Yg = np.meshgrid(x, x, indexing="ij")
        v_true = np.cos(np.pi * Xg) * np.cos(2 * np.pi * Yg) + f(Xg) + 3 * f(Yg)
        lap = -5 * np.pi**2 * np.cos(np.pi * Xg) * np.cos(2 * np.pi * Yg) + f2(Xg) + 3 * f2(Yg)
        b_minus_a = (dt**2 * v_true - lam_c * lap) / dt
        X_t = np.zeros((N, N, 3))
        X_t1 = np.repeat(b_minus_a[..., None], 3, axis=-1)
        v = variational_scene_flow(X_t, X_t1, dt, lam_c / h**2, method=method, tol=1e-12)
        errs.append(np.abs(v[..., 0] - v_true).max())
    assert errs[-1] < 1e-2
    assert errs[0] / errs[1] > 3.0 and errs[1] / errs[2] > 3.0


# --------------------------------------------------------------------------------------------------
# Charbonnier (robust) smoothness
# --------------------------------------------------------------------------------------------------
def two_region_problem(rng, H=24, W=24, noise=0.002, dt=0.1):
    v_true = np.zeros((H, W, 3))
    v_true[:, : W // 2] = [0.8, 0.0, 0.1]
    v_true[:, W // 2 :] = [-0.6, 0.4, 0.0]
    X_t = rng.normal(size=(H, W, 3)) + np.array([0.0, 0.0, 1.0])
    X_t1 = X_t + v_true * dt + noise * rng.normal(size=(H, W, 3))
    return X_t, X_t1, v_true


def test_charbonnier_preserves_a_motion_boundary(rng):
    X_t, X_t1, v_true = two_region_problem(rng)
    dt, lam, eps = 0.1, 0.1, 0.01  # velocity noise ~0.03 m/s, jumps ~1.5 m/s
    v_q = variational_scene_flow(X_t, X_t1, dt, lam, method="dct")
    v_c = variational_scene_flow(X_t, X_t1, dt, lam, method="dct", regularizer="charbonnier", eps=eps)
    band = slice(12 - 3, 12 + 3)  # three columns each side of the boundary

    def rms(v):
        return np.sqrt(np.mean(np.sum((v[:, band] - v_true[:, band]) ** 2, -1)))

    assert rms(v_c) < 0.2 * rms(v_q)
    # away from the boundary the noise is still smoothed out: error well below the raw data's
    raw = (X_t1 - X_t) / dt
    far = np.sqrt(np.mean(np.sum((v_c[:, :4] - v_true[:, :4]) ** 2, -1)))
    assert far < 0.5 * np.sqrt(np.mean(np.sum((raw[:, :4] - v_true[:, :4]) ** 2, -1)))


def test_charbonnier_irls_decreases_the_robust_energy_to_a_stationary_point(rng):
    H, W = 6, 7
    X_t, X_t1, _ = two_region_problem(rng, H, W, noise=0.01)
    mask = np.ones((H, W), bool)
    mask[2:4, 1:3] = False
    dt, lam, eps = 0.1, 0.05, 0.1
    v, info = variational_scene_flow(
        X_t, X_t1, dt, lam, method="cg", mask=mask, regularizer="charbonnier", eps=eps,
        tol=1e-12, irls_max_iter=500, irls_tol=1e-11, return_info=True,
    )  # fmt: skip
    psi = charbonnier(eps)
    m = mask.astype(float)
    hist = np.array(info["energy_history"])
    assert np.all(np.diff(hist) <= 1e-12 * hist[0])  # majorise-minimise: never increases
    e0 = energy(v, X_t, X_t1, dt, lam, m, psi)
    assert np.isclose(hist[-1], e0, rtol=1e-10)
    assert np.isclose(
        variational_energy(v, X_t, X_t1, dt, lam, mask=mask, regularizer="charbonnier", eps=eps), e0
    )
    # the first iterate is the quadratic solution, whose robust energy is higher
    v_q = variational_scene_flow(X_t, X_t1, dt, lam, method="cg", mask=mask, tol=1e-12)
    assert np.isclose(hist[0], energy(v_q, X_t, X_t1, dt, lam, m, psi), rtol=1e-9)
    assert e0 < hist[0]
    # stationary point of the robust energy (finite differences)
    h = 1e-5
    scale = abs(e0) / np.abs(v).max()
    for _ in range(6):
        i, j, k = rng.integers(H), rng.integers(W), rng.integers(3)
        vp, vm = v.copy(), v.copy()
        vp[i, j, k] += h
        vm[i, j, k] -= h
        g = (energy(vp, X_t, X_t1, dt, lam, m, psi) - energy(vm, X_t, X_t1, dt, lam, m, psi)) / (2 * h)
        assert abs(g) < 1e-6 * scale


def test_charbonnier_with_huge_eps_is_quadratic(rng):
    X_t, X_t1 = random_problem(rng, 6, 8)
    v_q = variational_scene_flow(X_t, X_t1, 0.1, 0.02)
    v_c = variational_scene_flow(X_t, X_t1, 0.1, 0.02, regularizer="charbonnier", eps=1e6, tol=1e-12)
    np.testing.assert_allclose(v_c, v_q, atol=1e-8)


# --------------------------------------------------------------------------------------------------
# input validation (hypothesis)
# --------------------------------------------------------------------------------------------------
GOOD = np.zeros((3, 4, 3))
FAST = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FAST
@given(shape=st.lists(st.integers(0, 5), min_size=1, max_size=4))
def test_wrong_shapes_raise_naming_the_argument(shape):
    arr = np.zeros(shape)
    ok = len(shape) == 3 and shape[2] == 3 and shape[0] >= 1 and shape[1] >= 1
    if ok and tuple(shape) == GOOD.shape:
        return
    with pytest.raises(ValueError, match=r"X_t1.*\(H, W, 3\)|X_t1 must have the same shape"):
        variational_scene_flow(GOOD, arr, 0.1, 1.0)
    if not ok:
        with pytest.raises(ValueError, match=r"X_t .*\(H, W, 3\)|X_t must have shape"):
            variational_scene_flow(arr, arr, 0.1, 1.0)


@FAST
@given(
    i=st.integers(0, 2), j=st.integers(0, 3), k=st.integers(0, 2),
    bad=st.sampled_from([np.inf, -np.inf]), which=st.sampled_from(["X_t", "X_t1"]),
)  # fmt: skip
def test_inf_raises_naming_the_argument(i, j, k, bad, which):
    arrs = {"X_t": GOOD.copy(), "X_t1": GOOD.copy()}
    arrs[which][i, j, k] = bad
    with pytest.raises(ValueError, match=f"{which} contains inf"):
        variational_scene_flow(arrs["X_t"], arrs["X_t1"], 0.1, 1.0, method="cg")


@FAST
@given(dt=st.one_of(st.floats(max_value=0.0), st.just(np.nan), st.just(np.inf)))
def test_bad_dt_raises(dt):
    with pytest.raises(ValueError, match="dt"):
        variational_scene_flow(GOOD, GOOD, dt, 1.0)


@FAST
@given(lam=st.one_of(st.floats(max_value=-1e-300), st.just(np.nan), st.just(np.inf)))
def test_bad_lam_raises(lam):
    with pytest.raises(ValueError, match="lam"):
        variational_scene_flow(GOOD, GOOD, 0.1, lam)


@FAST
@given(name=st.text(max_size=12))
def test_unknown_method_or_regularizer_lists_the_choices(name):
    if name in ("dct", "cg", "gauss_seidel"):
        return
    with pytest.raises(ValueError, match=r"method must be one of \('dct', 'cg', 'gauss_seidel'\)"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, method=name)
    if name not in ("quadratic", "charbonnier"):
        with pytest.raises(ValueError, match=r"regularizer must be one of \('quadratic', 'charbonnier'\)"):
            variational_scene_flow(GOOD, GOOD, 0.1, 1.0, regularizer=name)


@FAST
@given(
    shape=st.sampled_from([(4, 3), (3,), (3, 4, 1), (2, 4)]),
)
def test_bad_mask_shape_raises(shape):
    with pytest.raises(ValueError, match=r"mask must have shape \(3, 4\)"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, method="cg", mask=np.ones(shape, bool))


@FAST
@given(value=st.sampled_from([0.5, 2.0, -1.0, np.nan]))
def test_non_boolean_mask_raises(value):
    mask = np.ones((3, 4))
    mask[1, 2] = value
    with pytest.raises(ValueError, match="mask"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, method="cg", mask=mask)


def test_other_bad_arguments():
    with pytest.raises(ValueError, match="tol"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, tol=0.0)
    with pytest.raises(ValueError, match="tol"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, tol=1.5)
    with pytest.raises(ValueError, match="eps"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, regularizer="charbonnier", eps=0.0)
    with pytest.raises(ValueError, match="max_iter"):
        variational_scene_flow(GOOD, GOOD, 0.1, 1.0, method="cg", max_iter=0)
    with pytest.raises(TypeError, match="X_t"):
        variational_scene_flow(None, GOOD, 0.1, 1.0)
    with pytest.raises(TypeError, match="dt"):
        variational_scene_flow(GOOD, GOOD, "0.1", 1.0)
    with pytest.raises(ValueError, match="a must have shape"):
        solve_component(np.zeros((3, 4, 1)), np.zeros((3, 4)), 0.1, 1.0)
    with pytest.raises(ValueError, match="b must have the same shape"):
        solve_component(np.zeros((3, 4)), np.zeros((3, 5)), 0.1, 1.0)


def test_zero_motion_and_no_warnings(rng):
    X_t, _ = random_problem(rng, 5, 5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for method in METHODS:
            v = variational_scene_flow(X_t, X_t.copy(), 0.1, 1.0, method=method)
            assert np.array_equal(v, np.zeros_like(v))


def test_benchmark_quick_smoke_run():
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_variational.py"
    out = subprocess.run(
        [sys.executable, str(script), "--quick"], capture_output=True, text=True, timeout=120, check=False
    )
    assert out.returncode == 0, out.stderr
    assert "| flowtrack dct |" in out.stdout and "| scipy cg (peer) |" in out.stdout
