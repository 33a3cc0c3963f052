"""Tests of flowtrack.symbolic: each derivation against independent numerical references."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
from scipy.integrate import quad_vec

from flowtrack import symbolic as S
from flowtrack.camera import PinholeCamera, project
from flowtrack.camera import projection_jacobian as camera_jacobian
from flowtrack.kalman import steady_state_covariance
from flowtrack.kalman import white_noise_acceleration_Q as kalman_Q
from oracles import central_difference_jacobian


def _spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.5 * np.eye(n)


# --------------------------------------------------------------------------------------------------
# projection Jacobian
# --------------------------------------------------------------------------------------------------
def test_projection_jacobian_entries_by_hand():
    X, Y, Z, fx, fy, _cx, _cy = S.projection_symbols()
    expected = sp.Matrix([[fx / Z, 0, -fx * X / Z**2], [0, fy / Z, -fy * Y / Z**2]])
    assert sp.simplify(S.projection_jacobian() - expected) == sp.zeros(2, 3)


def test_projection_jacobian_matches_camera_and_finite_differences(rng):
    cam = PinholeCamera(520.0, 480.0, 319.5, 239.5)
    X = np.column_stack([rng.uniform(-1, 1, 20), rng.uniform(-1, 1, 20), rng.uniform(0.5, 3, 20)])
    J = S.projection_jacobian_numeric(X, cam)
    np.testing.assert_allclose(J, camera_jacobian(X, cam), rtol=1e-12)
    fd = central_difference_jacobian(lambda P: project(P, cam), X)
    np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-4)


# --------------------------------------------------------------------------------------------------
# Euler-Lagrange equation
# --------------------------------------------------------------------------------------------------
def test_euler_lagrange_has_the_syllabus_form():
    eq = S.euler_lagrange_scene_flow()
    _L, v, a, b, (x, y), (dt, lam) = S.scene_flow_lagrangian()
    assert eq.rhs == 0
    lap = sp.diff(v, x, 2) + sp.diff(v, y, 2)
    assert sp.simplify(eq.lhs - (2 * dt * (a + v * dt - b) - 2 * lam * lap)) == 0
    # rearranged: dt^2 v - lam Δv = dt (b - a)
    assert sp.simplify(eq.lhs / 2 / dt - (dt * v - lam / dt * lap - (b - a))) == 0


def test_euler_lagrange_is_the_first_variation():
    # For a test function vanishing on the boundary of [0,1]^2,
    # d/de E(v + e phi)|_0 = ∫ EL(v) phi (integration by parts), on concrete fields.
    eq = S.euler_lagrange_scene_flow()
    L, v, a, b, (x, y), (dt, lam) = S.scene_flow_lagrangian()
    eps = sp.Symbol("epsilon")
    v0 = x**2 * y + 3 * x - y**3
    a0, b0 = x * y, y**2 + x
    phi = x * (1 - x) * y * (1 - y) * (1 + 2 * x)
    values = {dt: sp.Rational(1, 3), lam: sp.Rational(7, 5)}

    def concrete(expr, vfield):
        return expr.subs({a: a0, b: b0}).subs(v, vfield).doit().subs(values)

    energy = sp.integrate(concrete(L, v0 + eps * phi), (x, 0, 1), (y, 0, 1))
    variation = sp.diff(energy, eps).subs(eps, 0)
    weak = sp.integrate(sp.expand(concrete(eq.lhs, v0) * phi), (x, 0, 1), (y, 0, 1))
    assert sp.simplify(variation - weak) == 0
    assert variation != 0  # the check is not vacuous


# --------------------------------------------------------------------------------------------------
# process noise
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_discrete_Q_matches_kalman_module_and_kron(rng, dim):
    for _ in range(3):
        dt, q = rng.uniform(0.01, 2.0), rng.uniform(0.1, 5.0)
        Q = S.white_noise_acceleration_Q_numeric(dt, q, dim=dim)
        q1d = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])  # syllabus §6
        np.testing.assert_allclose(Q, np.kron(q1d, np.eye(dim)), rtol=1e-13)
        np.testing.assert_allclose(Q, kalman_Q(dt, q, dim=dim), rtol=1e-13)


def test_Q_state_ordering_is_kron_not_blockdiag():
    Q = S.white_noise_acceleration_Q(2)
    dt, q = sp.symbols("Delta_t q", positive=True)
    q1d = q * sp.Matrix([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    kron = sp.Matrix(4, 4, lambda i, j: q1d[i // 2, j // 2] * (1 if i % 2 == j % 2 else 0))
    assert sp.simplify(Q - kron) == sp.zeros(4, 4)
    assert sp.simplify(Q - sp.diag(q1d, q1d)) != sp.zeros(4, 4)
    # state [px, py, vx, vy]: px-py uncorrelated, px-vx correlated
    assert Q[0, 1] == 0 and sp.simplify(Q[0, 2] - q * dt**3 / 2) == 0


@pytest.mark.parametrize("dim", [1, 2])
def test_continuous_Q_against_quadrature_and_van_loan(rng, dim):
    dt, q = rng.uniform(0.05, 1.5), rng.uniform(0.1, 3.0)
    Q = S.white_noise_acceleration_Q_numeric(dt, q, dim=dim, model="continuous")
    n = 2 * dim
    A = np.zeros((n, n))
    A[:dim, dim:] = np.eye(dim)
    L = np.vstack([np.zeros((dim, dim)), np.eye(dim)])
    Qc = q * L @ L.T

    def integrand(t):
        Phi = scipy.linalg.expm(A * t)
        return Phi @ Qc @ Phi.T

    Q_quad, _ = quad_vec(integrand, 0.0, dt, epsabs=1e-13, epsrel=1e-12)
    np.testing.assert_allclose(Q, Q_quad, rtol=1e-9, atol=1e-14)
    # Van Loan (1978): expm([[-A, Qc], [0, A^T]] dt) = [[., Phi^-1 Q], [0, Phi^T]]
    M = scipy.linalg.expm(np.block([[-A, Qc], [np.zeros((n, n)), A.T]]) * dt)
    Phi = M[n:, n:].T
    np.testing.assert_allclose(Q, Phi @ M[:n, n:], rtol=1e-9, atol=1e-14)
    q1d = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    np.testing.assert_allclose(Q, np.kron(q1d, np.eye(dim)), rtol=1e-12)


# --------------------------------------------------------------------------------------------------
# Kalman gain
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("n", "m"), [(1, 1), (2, 1), (2, 2), (4, 1)])
def test_kalman_gain_matches_formula_and_is_optimal(rng, n, m):
    P, H, R = _spd(rng, n), rng.normal(size=(m, n)), _spd(rng, m)
    K = S.kalman_gain_numeric(P, H, R)
    S_ = H @ P @ H.T + R
    np.testing.assert_allclose(K, np.linalg.solve(S_, H @ P).T, rtol=1e-9, atol=1e-12)

    def trace_post(K):
        A = np.eye(n) - K @ H
        return np.trace(A @ P @ A.T + K @ R @ K.T)

    best = trace_post(K)
    for _ in range(20):
        assert trace_post(K + 1e-3 * rng.normal(size=K.shape)) > best


def test_kalman_gain_symbolic_and_gradient_identity():
    K = S.kalman_gain(2, 2)
    assert sp.simplify(K - S.kalman_gain_closed_form(2, 2)) == sp.zeros(2, 2)
    P, H, R, Ks = S.kalman_matrices(2, 2)
    A = sp.eye(2) - Ks * H
    tr = (A * P * A.T + Ks * R * Ks.T).trace()
    grad = Ks.applyfunc(lambda k: sp.diff(tr, k))
    assert sp.expand(grad - 2 * (Ks * (H * P * H.T + R) - P * H.T)) == sp.zeros(2, 2)


# --------------------------------------------------------------------------------------------------
# posterior (Problem 3)
# --------------------------------------------------------------------------------------------------
def test_posterior_is_gaussian_by_completing_the_square():
    mean, var, (x, mu, p, z, h, r) = S.kalman_posterior()
    log_post = -((x - mu) ** 2) / (2 * p) - (z - h * x) ** 2 / (2 * r)
    log_gauss = -((x - mean) ** 2) / (2 * var)
    assert sp.simplify(sp.diff(log_post - log_gauss, x)) == 0  # differ by a constant only


def test_posterior_matches_filterpy_and_grid_normalisation(rng):
    from filterpy.kalman import KalmanFilter

    for _ in range(5):
        mu, z = rng.normal(size=2)
        p, h, r = rng.uniform(0.2, 3), rng.uniform(0.3, 2), rng.uniform(0.2, 3)
        mean, var = S.kalman_posterior_numeric(mu, p, z, h, r)
        kf = KalmanFilter(dim_x=1, dim_z=1)
        kf.x = np.array([[mu]])
        kf.P = np.array([[p]])
        kf.H = np.array([[h]])
        kf.R = np.array([[r]])
        kf.update(np.array([[z]]))
        assert mean == pytest.approx(kf.x[0, 0], rel=1e-12, abs=1e-12)
        assert var == pytest.approx(kf.P[0, 0], rel=1e-12)
        # brute force: normalise prior x likelihood on a fine grid
        xs = np.linspace(mu - 12 * np.sqrt(p), mu + 12 * np.sqrt(p), 200001)
        dens = np.exp(-((xs - mu) ** 2) / (2 * p) - (z - h * xs) ** 2 / (2 * r))
        w = dens / np.trapezoid(dens, xs)
        m_grid = np.trapezoid(xs * w, xs)
        assert mean == pytest.approx(m_grid, abs=1e-6)
        assert var == pytest.approx(np.trapezoid((xs - m_grid) ** 2 * w, xs), rel=1e-6)


# --------------------------------------------------------------------------------------------------
# steady state
# --------------------------------------------------------------------------------------------------
def test_steady_state_matches_dare_and_iteration(rng):
    for _ in range(10):
        f, h, q, r = rng.uniform(-1.5, 1.5), rng.uniform(0.2, 2), rng.uniform(0.05, 3), rng.uniform(0.05, 3)
        p_inf = S.steady_state_variance_scalar_numeric(f, h, q, r)
        dare = scipy.linalg.solve_discrete_are(
            np.array([[f]]), np.array([[h]]), np.array([[q]]), np.array([[r]])
        )
        assert p_inf == pytest.approx(dare[0, 0], rel=1e-10)
        p = 1.0
        for _ in range(5000):
            p = f**2 * p - f**2 * p**2 * h**2 / (h**2 * p + r) + q
        assert p_inf == pytest.approx(p, rel=1e-9)
        ss = steady_state_covariance([[f]], [[h]], [[q]], [[r]])
        assert p_inf == pytest.approx(ss[0, 0], rel=1e-8)


# --------------------------------------------------------------------------------------------------
# bad inputs
# --------------------------------------------------------------------------------------------------
def test_bad_inputs_name_the_argument():
    cam = PinholeCamera(1.0, 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="X"):
        S.projection_jacobian_numeric([[0.0, 0.0, -1.0]], cam)
    with pytest.raises(ValueError, match="X"):
        S.projection_jacobian_numeric([[0.0, 0.0]], cam)
    with pytest.raises(TypeError, match="cam"):
        S.projection_jacobian_numeric([[0.0, 0.0, 1.0]], "camera")
    with pytest.raises(ValueError, match="dt"):
        S.white_noise_acceleration_Q_numeric(0.0, 1.0)
    with pytest.raises(ValueError, match="q"):
        S.white_noise_acceleration_Q_numeric(1.0, -1.0)
    with pytest.raises(ValueError, match="dim"):
        S.white_noise_acceleration_Q(0)
    with pytest.raises(ValueError, match="model"):
        S.white_noise_acceleration_Q(2, model="singer")
    with pytest.raises(TypeError, match="model"):
        S.white_noise_acceleration_Q_numeric(1.0, 1.0, model=["discrete"])
    with pytest.raises(ValueError, match="P"):
        S.kalman_gain_numeric([[1.0, 2.0], [2.0, 1.0]], [[1.0, 0.0]], [[1.0]])
    with pytest.raises(ValueError, match="H"):
        S.kalman_gain_numeric(np.eye(2), [[1.0, 0.0, 0.0]], [[1.0]])
    with pytest.raises(ValueError, match="R"):
        S.kalman_gain_numeric(np.eye(2), [[1.0, 0.0]], [[0.0]])
    with pytest.raises(ValueError, match="n \\* m"):
        S.kalman_gain(3, 2)
    with pytest.raises(ValueError, match="p"):
        S.kalman_posterior_numeric(0.0, 0.0, 1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="z"):
        S.kalman_posterior_numeric(0.0, 1.0, np.nan, 1.0, 1.0)
    with pytest.raises(ValueError, match="r"):
        S.steady_state_variance_scalar_numeric(1.0, 1.0, 1.0, -2.0)
