"""flowtrack.motion: Kabsch rigid motion from flow, the turn-rate model (EKF), the joint update."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterPyKF
from scipy.spatial.transform import Rotation

from flowtrack.kalman import constant_velocity_model
from flowtrack.motion import (
    MotionBatchFilter,
    detection_velocity_covariances,
    kabsch,
    rigid_motion_from_flow,
    turn_rate_jacobian,
    turn_rate_predict,
    turn_rate_Q,
)


# ----------------------------------------------------------------------------------------------
# Kabsch
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(5))
def test_kabsch_matches_scipy_align_vectors(seed):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(30, 3))
    R_true = Rotation.random(random_state=seed).as_matrix()
    Y = X @ R_true.T + rng.normal(size=3) + 0.05 * rng.normal(size=X.shape)
    w = rng.uniform(0.2, 2.0, size=30)
    R, t = kabsch(X, Y, weights=w)
    mx, my = w @ X / w.sum(), w @ Y / w.sum()
    rot, _ = Rotation.align_vectors(Y - my, X - mx, weights=w)  # a ≈ R b
    np.testing.assert_allclose(R, rot.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(t, my - R @ mx, atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


def test_kabsch_never_returns_a_reflection():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(20, 3))
    R, _ = kabsch(X, -X)  # the best orthogonal map is -I (a reflection): Kabsch must give a rotation
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    # brute check: no rotation on a fine grid does better than the result (same objective)
    def cost(Rm):
        return np.sum((X @ Rm.T - (-X) - ((X @ Rm.T).mean(0) - (-X).mean(0))) ** 2)
    grid = Rotation.random(2000, random_state=1).as_matrix()
    assert cost(R) <= min(cost(g) for g in grid) + 1e-9


def test_kabsch_2d_against_brute_force_angle():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(15, 2))
    th = 0.7
    Rt = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    Y = X @ Rt.T + [0.3, -0.2] + 0.05 * rng.normal(size=X.shape)
    R, _ = kabsch(X, Y)
    angles = np.linspace(-np.pi, np.pi, 200001)
    Xc, Yc = X - X.mean(0), Y - Y.mean(0)
    # objective of the angle: -sum(y . R x) = -(cos a * sum(xx yx + xy yy) + sin a * sum(xx yy - xy yx))
    a = np.sum(Xc[:, 0] * Yc[:, 0] + Xc[:, 1] * Yc[:, 1])
    b = np.sum(Xc[:, 0] * Yc[:, 1] - Xc[:, 1] * Yc[:, 0])
    best = angles[np.argmax(a * np.cos(angles) + b * np.sin(angles))]
    assert np.arctan2(R[1, 0], R[0, 0]) == pytest.approx(best, abs=1e-4)


@pytest.mark.parametrize(
    "args, match",
    [
        ((np.zeros((4, 4)), np.zeros((4, 4))), "X must have shape"),
        ((np.zeros((4, 3)), np.zeros((5, 3))), "Y"),
        ((np.zeros((4, 3)), np.full((4, 3), np.nan)), "Y"),
    ],
)
def test_kabsch_rejects_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        kabsch(*args)


def test_kabsch_rejects_bad_weights():
    with pytest.raises(ValueError, match="weights"):
        kabsch(np.eye(3), np.eye(3), weights=[-1.0, 1.0, 1.0])


# ----------------------------------------------------------------------------------------------
# rigid motion from flow
# ----------------------------------------------------------------------------------------------
def test_rigid_motion_from_exact_flow_recovers_the_motion():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(40, 3)) * 0.05 + [0.1, 0.0, 0.8]
    dt = 0.1
    rotvec = np.array([0.02, -0.01, 0.08])  # over dt
    R_true = Rotation.from_rotvec(rotvec).as_matrix()
    t_true = np.array([0.01, 0.002, -0.003])
    v = (X @ R_true.T + t_true - X) / dt
    m = rigid_motion_from_flow(X, v, dt, min_std=0.0)
    np.testing.assert_allclose(m.R, R_true, atol=1e-10)
    np.testing.assert_allclose(m.t, t_true, atol=1e-10)
    np.testing.assert_allclose(m.angular_velocity, rotvec / dt, atol=1e-8)
    np.testing.assert_allclose(m.velocity, v.mean(0), atol=1e-10)  # mean flow = centroid velocity
    np.testing.assert_allclose(m.velocity_at(X[3]), v[3], atol=1e-10)
    assert m.residual_rms < 1e-10
    assert m.yaw_rate([0.0, 0.0, 2.0]) == pytest.approx(0.8, abs=1e-8)


def test_velocity_covariance_matches_monte_carlo():
    """With independent flow noise (n_max >= n) the reported covariance is the spread of the estimate."""
    rng = np.random.default_rng(7)
    X = rng.normal(size=(30, 3)) * 0.04
    dt, sigma = 0.1, np.array([0.02, 0.01, 0.03])
    v_true = np.cross([0.0, 0.0, 0.5], X) + np.array([0.1, 0.0, 0.0])
    est, covs = [], []
    for _ in range(1500):
        v = v_true + sigma * rng.normal(size=X.shape)
        m = rigid_motion_from_flow(X, v, dt, max_effective_points=10**6, min_std=0.0)
        est.append(m.velocity)
        covs.append(m.velocity_cov)
    emp = np.cov(np.array(est).T)
    mean_cov = np.mean(covs, axis=0)
    np.testing.assert_allclose(np.diag(mean_cov), sigma**2 / 30, rtol=0.15)
    np.testing.assert_allclose(np.diag(emp), np.diag(mean_cov), rtol=0.15)
    tol = 4 * sigma.max() / np.sqrt(30 * 1500)
    np.testing.assert_allclose(np.array(est).mean(0), v_true.mean(0), atol=tol)


def test_velocity_covariance_floor_and_effective_points():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(200, 3))
    v = np.tile([0.1, 0.0, 0.0], (200, 1)) + 0.01 * rng.normal(size=(200, 3))
    a = rigid_motion_from_flow(X, v, 0.1, max_effective_points=200, min_std=0.0).velocity_cov
    b = rigid_motion_from_flow(X, v, 0.1, max_effective_points=20, min_std=0.0).velocity_cov
    np.testing.assert_allclose(b, 10.0 * a, rtol=1e-12)  # 1/20 instead of 1/200
    c = rigid_motion_from_flow(X, v, 0.1, max_effective_points=20, min_std=0.05).velocity_cov
    np.testing.assert_allclose(c - b, 0.05**2 * np.eye(3), atol=1e-15)


def test_speed_fraction_models_an_error_shared_by_the_whole_cluster():
    """A cluster whose flow is off by one common factor (1 + e), e ~ N(0, a^2), along its motion (plus
    small independent noise): its residuals cannot see e, the speed-fraction term does. Monte Carlo
    NEES of the fitted velocity against the truth: about 3 (the dof; the residuals here are independent,
    so n_eff = n) with speed_fraction = a, far above without it."""
    rng = np.random.default_rng(3)
    a, u_true = 0.1, np.array([0.2, 0.05, 0.0])
    X = rng.normal(scale=0.05, size=(300, 3))
    nees = {0.0: [], a: []}
    for _ in range(400):
        flow = (1 + a * rng.normal()) * u_true + 0.003 * rng.normal(size=X.shape)
        for frac in nees:
            m = rigid_motion_from_flow(X, flow, 0.1, speed_fraction=frac, min_std=0.0,
                                       max_effective_points=300)
            e = m.velocity - u_true
            nees[frac].append(e @ np.linalg.solve(m.velocity_cov, e))
    assert 2.5 < np.mean(nees[a]) < 3.5, np.mean(nees[a])
    assert np.mean(nees[0.0]) > 30
    # the term itself: a^2 u u^T on top of the residual covariance
    flow = u_true + 0.003 * rng.normal(size=X.shape)
    m0 = rigid_motion_from_flow(X, flow, 0.1)
    m1 = rigid_motion_from_flow(X, flow, 0.1, speed_fraction=0.3)
    np.testing.assert_allclose(m1.velocity_cov - m0.velocity_cov, 0.09 * np.outer(m0.velocity, m0.velocity),
                               atol=1e-15)
    with pytest.raises(ValueError, match="speed_fraction"):
        rigid_motion_from_flow(X, flow, 0.1, speed_fraction=-0.1)


def test_rigid_motion_2d():
    rng = np.random.default_rng(4)
    X = rng.normal(size=(20, 2))
    w = 0.3
    v = w * X @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + [0.05, 0.02]  # instantaneous rotation + shift
    m = rigid_motion_from_flow(X, v, 1e-5)
    assert m.angular_velocity.shape == (1,)
    assert m.angular_velocity[0] == pytest.approx(w, rel=1e-4)


def test_rigid_motion_rejects_bad_input():
    with pytest.raises(ValueError, match="at least 4 rows"):
        rigid_motion_from_flow(np.zeros((3, 3)), np.zeros((3, 3)), 0.1)
    with pytest.raises(ValueError, match="flow"):
        rigid_motion_from_flow(np.zeros((5, 3)), np.zeros((5, 2)), 0.1)
    with pytest.raises(ValueError, match="dt"):
        rigid_motion_from_flow(np.zeros((5, 3)), np.zeros((5, 3)), 0.0)


def test_detection_velocity_covariances_per_cluster():
    rng = np.random.default_rng(5)
    A = rng.normal(size=(50, 3)) * 0.02
    B = rng.normal(size=(60, 3)) * 0.02 + [0.5, 0.0, 0.0]
    X = np.concatenate([A, B, rng.normal(size=(10, 3)) + 3.0])
    lab = np.r_[np.zeros(50, int), np.ones(60, int), -np.ones(10, int)]
    V = np.zeros_like(X)
    V[:50] = 0.01 * rng.normal(size=(50, 3))
    V[50:110] = 0.05 * rng.normal(size=(60, 3))
    C = detection_velocity_covariances(X, lab, V, np.array([[0.49, 0.0, 0.0], [0.0, 0.01, 0.0]]), 0.1,
                                       max_effective_points=10**6, min_std=0.0)
    np.testing.assert_allclose(C[0], rigid_motion_from_flow(B, V[50:110], 0.1, max_effective_points=10**6,
                                                            min_std=0.0).velocity_cov)
    assert np.trace(C[0]) > 5 * np.trace(C[1])  # the noisier cluster is the less certain


# ----------------------------------------------------------------------------------------------
# the turn-rate model
# ----------------------------------------------------------------------------------------------
def _fd_jacobian(x, T, axis=None, h=1e-6):
    J = np.zeros((len(x), len(x)))
    for k in range(len(x)):
        e = np.zeros(len(x))
        e[k] = h
        J[:, k] = (turn_rate_predict(x + e, T, axis) - turn_rate_predict(x - e, T, axis)) / (2 * h)
    return J


def test_turn_rate_model_matches_the_sympy_derivation():
    from flowtrack.symbolic.motion import turn_rate_model_numeric

    rng = np.random.default_rng(0)
    for w in (0.9, -2.0, 0.05, 1e-2):
        x = np.r_[rng.normal(size=6), w]
        f_sym, J_sym = turn_rate_model_numeric(x, 0.37)
        np.testing.assert_allclose(turn_rate_predict(x, 0.37), f_sym, atol=1e-12)
        np.testing.assert_allclose(turn_rate_jacobian(x, 0.37), J_sym, atol=1e-10)


def test_turn_rate_limit_is_constant_velocity_symbolically():
    import sympy as sp

    from flowtrack.symbolic.motion import turn_rate_limits, turn_rate_model

    x, _, _ = turn_rate_model()
    fl, Jl = turn_rate_limits()
    T = sp.Symbol("T", positive=True)
    # the limit of f at w -> 0 (its last entry, w itself, -> 0): the constant-velocity model
    cv = sp.Matrix([x[0] + T * x[3], x[1] + T * x[4], x[2] + T * x[5], x[3], x[4], x[5], 0])
    assert sp.simplify(fl - cv) == sp.zeros(7, 1)
    # dp/dw at w = 0 is (T^2 / 2) K v: the yaw rate stays observable from positions
    assert sp.simplify(Jl[0, 6] + T**2 * x[4] / 2) == 0
    assert sp.simplify(Jl[1, 6] - T**2 * x[3] / 2) == 0
    F = sp.eye(6)
    F[:3, 3:] = T * sp.eye(3)
    assert sp.simplify(Jl[:6, :6] - F) == sp.zeros(6, 6)


@pytest.mark.parametrize("w", [1.3, -0.4, 1e-4, 1e-9, 0.0])
def test_turn_rate_jacobian_matches_finite_differences(w):
    rng = np.random.default_rng(1)
    x = np.r_[rng.normal(size=6), w]
    np.testing.assert_allclose(turn_rate_jacobian(x, 0.5), _fd_jacobian(x, 0.5), atol=1e-7)
    axis = np.array([0.2, -0.9, 0.4])
    np.testing.assert_allclose(turn_rate_jacobian(x, 0.5, axis), _fd_jacobian(x, 0.5, axis), atol=1e-7)


def test_turn_rate_predict_is_continuous_at_zero_rate():
    x = np.array([0.1, 0.2, 0.3, 0.5, -0.4, 0.1, 0.0])
    F = constant_velocity_model(0.5, 0.0, 1.0, 3)[0]
    np.testing.assert_allclose(turn_rate_predict(x, 0.5)[:6], F @ x[:6], atol=1e-15)
    for w in (1e-2, 1e-3 * 0.999 / 0.5, 1e-3 * 1.001 / 0.5, 1e-6):  # both sides of the series switch
        xw = x.copy()
        xw[6] = w
        fw = turn_rate_predict(xw, 0.5)
        # exact closed form, evaluated in extended precision
        th = np.longdouble(w) * np.longdouble(0.5)
        A = (1 - np.cos(th)) / np.longdouble(w)
        B = np.longdouble(0.5) - np.sin(th) / np.longdouble(w)
        vx, vy = np.longdouble(x[3]), np.longdouble(x[4])
        px = np.longdouble(x[0]) + np.longdouble(0.5) * vx - A * vy - B * vx
        assert float(abs(np.longdouble(fw[0]) - px)) < 1e-14


def test_turn_rate_coefficients_are_accurate_at_every_angle_against_50_digit_arithmetic():
    """sin, 1 - cos, A, B, dA/dw, dB/dw within 1e-13 (relative) of their exact values, on both sides of
    the series switch and far from it: the closed form T - sin(wT)/w alone is off by ~1e-10 at
    wT = 1e-3 (cancellation), a two-term series by ~1e-15 at 1e-3 but 1e-6 at 0.3."""
    import mpmath

    from flowtrack.motion import _SERIES, _coefficients

    mpmath.mp.dps = 50

    def exact(w, T):
        w, T = mpmath.mpf(w), mpmath.mpf(T)
        th = w * T
        s, omc = mpmath.sin(th), 1 - mpmath.cos(th)
        return [s, omc, omc / w, T - s / w, (T * s * w - omc) / w**2, (s - T * w * mpmath.cos(th)) / w**2]

    thetas = np.r_[np.logspace(-7, 0.6, 120), _SERIES * (1 - 1e-12), _SERIES * (1 + 1e-12), 1e-3, 1.01e-3]
    worst = 0.0
    for T in (0.1, 0.8):
        for th in thetas:
            for w in (th / T, -th / T):
                for got, want in zip(_coefficients(np.array([w]), T), exact(w, T)):
                    worst = max(worst, float(abs((mpmath.mpf(float(got[0])) - want) / want)))
    assert worst < 1e-13, worst
    # and at w = 0 exactly: the constant-velocity limit, A = B = dB = 0, dA = T^2 / 2
    s, omc, A, B, dA, dB = _coefficients(np.zeros(1), 0.5)
    assert s[0] == omc[0] == A[0] == B[0] == dB[0] == 0.0 and dA[0] == 0.125


def test_turn_rate_predicts_a_circle_exactly():
    rho, w, T = 0.13, 1.0, 0.1
    phi = 0.3
    p = np.array([rho * np.cos(phi), rho * np.sin(phi), 0.05])
    v = rho * w * np.array([-np.sin(phi), np.cos(phi), 0.0])
    x = np.r_[p, v, w]
    for k in range(1, 20):
        x = turn_rate_predict(x, T)
        ph = phi + w * T * k
        np.testing.assert_allclose(x[:3], [rho * np.cos(ph), rho * np.sin(ph), 0.05], atol=1e-14)


def test_turn_rate_general_axis_is_the_z_model_in_rotated_coordinates():
    rng = np.random.default_rng(2)
    Rm = Rotation.random(random_state=2).as_matrix()
    n = Rm @ [0.0, 0.0, 1.0]
    x = np.r_[rng.normal(size=6), 0.8]
    B = np.zeros((7, 7))
    B[:3, :3] = B[3:6, 3:6] = Rm
    B[6, 6] = 1.0
    np.testing.assert_allclose(turn_rate_predict(x, 0.4, n), B @ turn_rate_predict(B.T @ x, 0.4), atol=1e-13)
    np.testing.assert_allclose(turn_rate_jacobian(x, 0.4, n), B @ turn_rate_jacobian(B.T @ x, 0.4) @ B.T,
                               atol=1e-13)


def test_turn_rate_2d_is_the_3d_model_in_the_plane():
    x3 = np.array([0.1, 0.2, 0.0, 0.3, -0.1, 0.0, 0.7])
    x2 = x3[[0, 1, 3, 4, 6]]
    in_plane = [0, 1, 3, 4, 6]
    np.testing.assert_allclose(turn_rate_predict(x2, 0.3), turn_rate_predict(x3, 0.3)[in_plane], atol=1e-15)
    np.testing.assert_allclose(turn_rate_jacobian(x2, 0.3), _fd_jacobian(x2, 0.3), atol=1e-7)


def test_turn_rate_rejects_bad_state():
    with pytest.raises(ValueError, match="x must have shape"):
        turn_rate_predict(np.zeros(6), 0.1)
    with pytest.raises(ValueError, match="axis"):
        turn_rate_predict(np.zeros(7), 0.1, axis=[0.0, 0.0, 0.0])


def test_turn_rate_Q_blocks():
    from flowtrack.kalman import white_noise_acceleration_Q

    Q = turn_rate_Q(0.1, 2.0, 0.5, dim=3)
    np.testing.assert_allclose(Q[:6, :6], white_noise_acceleration_Q(0.1, 2.0, 3))
    assert Q[6, 6] == pytest.approx(0.05)
    assert not Q[6, :6].any()


# ----------------------------------------------------------------------------------------------
# the batch filter: EKF predict, joint position-velocity update
# ----------------------------------------------------------------------------------------------
def _random_spd(rng, n, scale=1.0):
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n))


@pytest.mark.parametrize("model", ["cv", "turn_rate"])
def test_joint_update_matches_filterpy_and_the_dense_posterior(model):
    rng = np.random.default_rng(11)
    d = 3
    R = _random_spd(rng, d, 1e-4)
    kf = MotionBatchFilter(0.1, 0.5, R, d, model=model)
    n = kf.n
    M = 4
    x0 = rng.normal(size=(M, n))
    P0 = np.stack([_random_spd(rng, n, 0.01) for _ in range(M)])
    kf.append(x0, P0)
    Z = rng.normal(size=(M, d))
    V = rng.normal(size=(M, d))
    V[1] = np.nan  # track 1: position only
    Rv = np.stack([_random_spd(rng, d, 1e-3) for _ in range(M)])
    Rv[1] = np.nan
    mask = np.array([True, True, True, False])  # track 3 not detected
    kf.update_joint(Z, V, Rv, mask)
    for i in range(M):
        if not mask[i]:
            np.testing.assert_allclose(kf.x[i], x0[i])
            np.testing.assert_allclose(kf.P[i], P0[i])
            continue
        if i == 1:
            H = np.zeros((d, n))
            H[:, :d] = np.eye(d)
            Rs, z = R, Z[i]
        else:
            H = np.zeros((2 * d, n))
            H[:, : 2 * d] = np.eye(2 * d)
            Rs = np.zeros((2 * d, 2 * d))
            Rs[:d, :d], Rs[d:, d:] = R, Rv[i]
            z = np.r_[Z[i], V[i]]
        ref = FilterPyKF(dim_x=n, dim_z=len(z))
        ref.x, ref.P, ref.H, ref.R = x0[i].copy(), P0[i].copy(), H, Rs
        ref.update(z)
        np.testing.assert_allclose(kf.x[i], ref.x, atol=1e-10)
        np.testing.assert_allclose(kf.P[i], ref.P, atol=1e-12)
        # dense oracle: the Gaussian posterior by block (information-form) inversion
        Pi = np.linalg.inv(np.linalg.inv(P0[i]) + H.T @ np.linalg.solve(Rs, H))
        xi = Pi @ (np.linalg.solve(P0[i], x0[i]) + H.T @ np.linalg.solve(Rs, z))
        np.testing.assert_allclose(kf.x[i], xi, atol=1e-8)
        np.testing.assert_allclose(kf.P[i], Pi, atol=1e-10)


def test_ekf_predict_propagates_with_the_jacobian():
    rng = np.random.default_rng(3)
    kf = MotionBatchFilter(0.1, 0.5, 1e-4 * np.eye(3), 3, model="turn_rate", q_omega=0.2)
    x0 = np.r_[rng.normal(size=6), 0.6]
    P0 = _random_spd(rng, 7, 0.01)
    kf.append(x0[None], P0[None])
    kf.predict()
    J = _fd_jacobian(x0, 0.1)
    np.testing.assert_allclose(kf.x[0], turn_rate_predict(x0, 0.1), atol=1e-15)
    np.testing.assert_allclose(kf.P[0], J @ P0 @ J.T + turn_rate_Q(0.1, 0.5, 0.2, 3), atol=1e-8)


def test_cv_filter_predict_matches_constant_velocity_model():
    rng = np.random.default_rng(4)
    F, _, Q, R = constant_velocity_model(0.1, 0.5, 1e-4, 3)
    kf = MotionBatchFilter(0.1, 0.5, R, 3, model="cv")
    x0 = rng.normal(size=(2, 6))
    P0 = np.stack([_random_spd(rng, 6, 0.01) for _ in range(2)])
    kf.append(x0, P0)
    x5, P5 = kf.predicted(5)
    xr, Pr = x0.copy(), P0.copy()
    for _ in range(5):
        xr = xr @ F.T
        Pr = F @ Pr @ F.T + Q
    np.testing.assert_allclose(x5, xr, atol=1e-14)
    np.testing.assert_allclose(P5, Pr, atol=1e-14)
    np.testing.assert_allclose(kf.x, x0)  # predicted() leaves the filter alone


def test_joint_innovation_shapes_and_blocks():
    rng = np.random.default_rng(5)
    kf = MotionBatchFilter(0.1, 0.5, 1e-4 * np.eye(2), 2, model="cv")
    kf.append(rng.normal(size=(3, 4)), np.stack([_random_spd(rng, 4, 0.01) for _ in range(3)]))
    Z = rng.normal(size=(2, 2))
    V = np.array([[0.1, 0.2], [np.nan, np.nan]])
    Rv = np.stack([0.01 * np.eye(2), np.full((2, 2), np.nan)])
    nu, S, m = kf.joint_innovation(Z, V, Rv)
    assert nu.shape == (3, 2, 4) and S.shape == (3, 2, 4, 4) and m.tolist() == [4, 2]
    np.testing.assert_allclose(S[1, 0], kf.P[1] + np.diag([1e-4, 1e-4, 0.01, 0.01]))
    np.testing.assert_allclose(nu[2, 0], np.r_[Z[0], V[0]] - kf.x[2])


# ----------------------------------------------------------------------------------------------
# the turning scenario of flowtrack.synth
# ----------------------------------------------------------------------------------------------
def test_turning_scenario_is_a_rotation_about_a_vertical_axis_and_the_flow_fit_finds_it():
    from flowtrack.synth import ArcTrajectory, make_scene

    scene = make_scene(n_objects=1, n_frames=5, image_size=(60, 80), noise=0.0, seed=0, scenario="turning")
    tr = scene.trajectories[1]
    assert isinstance(tr, ArcTrajectory)
    T_wc = scene.camera_pose
    centres = np.array([(T_wc @ f.gt_poses[1])[:3, 3] for f in scene.frames])
    np.testing.assert_allclose(np.linalg.norm(centres[:, :2] - [0.0, 0.2], axis=1), 0.13, atol=1e-12)
    phi = np.unwrap(np.arctan2(centres[:, 1] - 0.2, centres[:, 0]))
    np.testing.assert_allclose(np.diff(phi), 1.0 * scene.dt, atol=1e-12)  # 1 rad/s
    # the body turns with its path: from the exact flow, the rigid fit gives 1 rad/s about the table normal
    up = np.linalg.inv(T_wc)[:3, :3] @ [0.0, 0.0, 1.0]
    f = scene.frames[2]
    m = f.labels == 1
    fit = rigid_motion_from_flow(f.gt_points[m], f.gt_flow[m], scene.dt, min_std=0.0)
    assert fit.yaw_rate(up) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(fit.angular_velocity, up * 1.0, atol=1e-9)
    # and the turn-rate model, started from the centre's state, follows the centre's arc
    T_cw = np.linalg.inv(T_wc)
    c0, c1 = (T_cw @ np.r_[centres[0], 1.0])[:3], (T_cw @ np.r_[centres[4], 1.0])[:3]
    v0 = np.linalg.inv(T_wc)[:3, :3] @ np.r_[0.13 * 1.0 * np.array([-np.sin(phi[0]), np.cos(phi[0])]), 0.0]
    np.testing.assert_allclose(turn_rate_predict(np.r_[c0, v0, 1.0], 4 * scene.dt, up)[:3], c1, atol=1e-12)


def test_rotation_spread_is_the_spread_of_the_rigid_velocity_over_the_cluster():
    rng = np.random.default_rng(8)
    X = rng.normal(size=(40, 3)) * [0.03, 0.02, 0.01]
    w = np.array([0.0, 0.0, 0.8])
    v = np.cross(w, X) + np.array([0.1, 0.0, 0.0])
    a = rigid_motion_from_flow(X, v, 1e-5, min_std=0.0)
    b = rigid_motion_from_flow(X, v, 1e-5, min_std=0.0, rotation_spread=True)
    # independent: the empirical covariance of the (exactly rigid) velocities themselves
    np.testing.assert_allclose(b.velocity_cov - a.velocity_cov, np.cov(v.T, bias=True), atol=1e-8)
