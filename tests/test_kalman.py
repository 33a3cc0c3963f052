"""Tests of flowtrack.kalman against independent oracles (filterpy, scipy, closed forms)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter as FPKalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import mahalanobis as scipy_mahalanobis

from flowtrack.kalman import (
    BatchKalmanFilter,
    KalmanFilter,
    KalmanFilterCV2D,
    constant_velocity_model,
    steady_state_covariance,
    white_noise_acceleration_Q,
)

SYLLABUS_DETECTIONS = [(0.0, 0.0), (0.9, 0.1), (2.1, 0.2), (3.0, 0.1)]


# ---------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------
def random_spd(rng, n, scale=1.0):
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T / n + 0.1 * np.eye(n))


def random_model(rng, n, m):
    F = rng.normal(size=(n, n))
    F *= 0.95 / max(abs(np.linalg.eigvals(F)))  # stable
    H = rng.normal(size=(m, n))
    return F, H, random_spd(rng, n, 0.3), random_spd(rng, m, 0.5)


def filterpy_filter(F, H, Q, R, x0, P0):
    f = FPKalmanFilter(dim_x=F.shape[0], dim_z=H.shape[0])
    f.F, f.H, f.Q, f.R = F.copy(), H.copy(), Q.copy(), R.copy()
    f.x = np.asarray(x0, float).reshape(-1, 1).copy()
    f.P = np.asarray(P0, float).copy()
    return f


def close(a, b, tol=1e-10):
    np.testing.assert_allclose(a, b, rtol=tol, atol=tol)


class SyllabusKalmanFilterCV2D:
    """Verbatim copy of the syllabus' section-8 class (blkdiag Q, non-Joseph update)."""

    def __init__(self, dt=0.1, process_var=1.0, meas_var=4.0, Q=None):
        self.dt = dt
        self.F = np.array([[1.0, 0.0, dt, 0.0], [0.0, 1.0, 0.0, dt], [0.0, 0.0, 1.0, 0.0], [0, 0, 0, 1.0]])
        self.H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
        q = process_var
        dt2 = dt * dt
        dt3 = dt2 * dt
        dt4 = dt2 * dt2
        Q1d = np.array([[0.25 * dt4, 0.5 * dt3], [0.5 * dt3, dt2]])
        self.Q = q * np.block([[Q1d, np.zeros((2, 2))], [np.zeros((2, 2)), Q1d]]) if Q is None else Q
        self.R = meas_var * np.eye(2)
        self.x = np.zeros((4, 1))
        self.P = np.eye(4) * 1e3

    def predict(self):
        self.x = self.F @ self.x
        self.P = self.F @ self.P @ self.F.T + self.Q

    def update(self, z):
        z = np.asarray(z, dtype=float).reshape(2, 1)
        y = z - (self.H @ self.x)
        S = self.H @ self.P @ self.H.T + self.R
        K = self.P @ self.H.T @ np.linalg.inv(S)
        self.x = self.x + (K @ y)
        self.P = (np.eye(4) - K @ self.H) @ self.P

    def position(self):
        return self.x[0, 0], self.x[1, 0]


# ---------------------------------------------------------------------------------------------------
# Q and the CV model
# ---------------------------------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(
    dt=st.floats(1e-3, 10.0),
    q=st.floats(0.0, 100.0),
    dim=st.integers(1, 3),
)
def test_white_noise_Q_matches_filterpy_derivative_order(dt, q, dim):
    Q = white_noise_acceleration_Q(dt, q, dim)
    ref = Q_discrete_white_noise(dim=2, dt=dt, var=q, block_size=dim, order_by_dim=False)
    assert Q.shape == (2 * dim, 2 * dim)
    close(Q, ref, 1e-12)
    # and entry by entry from the state labels [p_1..p_d, v_1..v_d]: same axis -> the 1-D entry, else 0
    close(Q, wna_Q_from_labels(dt, q, dim), 1e-12)
    assert np.linalg.eigvalsh(Q).min() >= -1e-12 * max(1.0, np.abs(Q).max())


def wna_Q_from_labels(dt, q, dim):
    """Q[i, j] = q c(order_i, order_j) when state i and j are on the same axis, 0 otherwise."""
    c = {(0, 0): dt**4 / 4, (0, 1): dt**3 / 2, (1, 0): dt**3 / 2, (1, 1): dt**2}
    labels = [(0, axis) for axis in range(dim)] + [(1, axis) for axis in range(dim)]  # (order, axis)
    Q = np.zeros((2 * dim, 2 * dim))
    for i, (oi, ai) in enumerate(labels):
        for j, (oj, aj) in enumerate(labels):
            Q[i, j] = q * c[(oi, oj)] if ai == aj else 0.0
    return Q


def test_wna_entries_are_the_integrated_piecewise_constant_acceleration():
    """The table c of the label oracle, derived in sympy: a constant acceleration a over one step moves
    the state by g a, g = (double integral of 1, integral of 1), so Q_1D = q g g^T."""
    import sympy

    t, s, u, q, a = sympy.symbols("dt s u q a", positive=True)
    g = sympy.Matrix(
        [sympy.integrate(sympy.integrate(1, (u, 0, s)), (s, 0, t)), sympy.integrate(1, (s, 0, t))]
    )
    # check g against a dynamic model: x' = [[0, 1], [0, 0]] x + [0, 1] a, from x = 0 over dt
    A = sympy.Matrix([[0, 1], [0, 0]])
    x_dt = sympy.integrate((A * (t - s)).exp() * sympy.Matrix([0, a]), (s, 0, t))
    assert sympy.simplify(x_dt - g * a) == sympy.zeros(2, 1)
    Q1d = q * g * g.T
    for dt_val, q_val, dim in [(0.1, 1.0, 2), (0.7, 3.5, 3), (2.0, 0.25, 1)]:
        want = np.array(Q1d.subs({t: dt_val, q: q_val}).evalf(), dtype=float)
        got = wna_Q_from_labels(dt_val, q_val, dim)
        for axis in range(dim):
            idx = [axis, dim + axis]
            close(got[np.ix_(idx, idx)], want, 1e-14)


@pytest.mark.parametrize("dim", [2, 3])
def test_white_noise_Q_is_not_the_syllabus_blkdiag(dim):
    dt, q = 0.1, 1.0
    Q = white_noise_acceleration_Q(dt, q, dim)
    Q1d = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    wrong = scipy.linalg.block_diag(*[Q1d] * dim)
    assert not np.allclose(Q, wrong)
    # blkdiag is right only for the axis-major order [px, vx, py, vy, ...]
    perm = np.arange(2 * dim).reshape(2, dim).T.ravel()  # axis-major -> derivative-major index
    close(Q[np.ix_(perm, perm)], wrong, 1e-15)
    # the syllabus' matrix couples px with py, which are independent axes
    assert wrong[0, 1] != 0 and Q[0, 1] == 0


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_constant_velocity_model_moves_positions(rng, dim):
    dt, q, r = 0.25, 2.0, 0.5
    F, H, Q, R = constant_velocity_model(dt, q, r, dim)
    p, v = rng.normal(size=dim), rng.normal(size=dim)
    close(F @ np.r_[p, v], np.r_[p + v * dt, v], 1e-14)
    close(H @ np.r_[p, v], p, 0)
    close(Q, Q_discrete_white_noise(2, dt, q, block_size=dim, order_by_dim=False), 1e-14)
    close(R, r * np.eye(dim), 0)
    _, _, _, R2 = constant_velocity_model(dt, q, np.diag(np.arange(1.0, dim + 1)), dim)
    close(R2, np.diag(np.arange(1.0, dim + 1)), 0)


# ---------------------------------------------------------------------------------------------------
# KalmanFilter vs filterpy
# ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n,m", [(2, 1), (3, 2), (4, 2), (5, 3), (6, 1), (6, 3)])
def test_kalman_filter_matches_filterpy(n, m):
    rng = np.random.default_rng(100 * n + m)
    F, H, Q, R = random_model(rng, n, m)
    x0, P0 = rng.normal(size=n), random_spd(rng, n, 2.0)
    kf = KalmanFilter(F, H, Q, R, x0, P0)
    fp = filterpy_filter(F, H, Q, R, x0, P0)
    for t in range(30):
        kf.predict()
        fp.predict()
        close(kf.x, fp.x.ravel())
        close(kf.P, fp.P)
        missed = t % 7 == 3
        z = None if missed else rng.normal(size=m)
        kf.update(z)
        fp.update(z)
        close(kf.x, fp.x.ravel())
        close(kf.P, fp.P)
        if missed:
            assert kf.innovation is None and kf.K is None and kf.log_likelihood == 0.0
        else:
            close(kf.innovation, fp.y.ravel())
            close(kf.S, fp.S)
            close(kf.K, fp.K)
            close(kf.log_likelihood, fp.log_likelihood)


def test_missed_measurement_leaves_prediction(rng):
    F, H, Q, R = random_model(rng, 4, 2)
    kf = KalmanFilter(F, H, Q, R, rng.normal(size=4), np.eye(4))
    kf.predict()
    x, P = kf.x.copy(), kf.P.copy()
    kf.update(None)
    assert np.array_equal(kf.x, x) and np.array_equal(kf.P, P)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 3))
def test_update_equals_information_form(seed, n, m):
    """Posterior from the information form P⁺⁻¹ = P⁻¹ + HᵀR⁻¹H, x⁺ = P⁺(P⁻¹x + HᵀR⁻¹z)."""
    rng = np.random.default_rng(seed)
    F, H, Q, R = random_model(rng, n, m)
    x0, P0, z = rng.normal(size=n), random_spd(rng, n), rng.normal(size=m)
    kf = KalmanFilter(F, H, Q, R, x0, P0)
    kf.update(z)
    Pinv = np.linalg.inv(P0) + H.T @ np.linalg.solve(R, H)
    P_post = np.linalg.inv(Pinv)
    x_post = P_post @ (np.linalg.solve(P0, x0) + H.T @ np.linalg.solve(R, z))
    close(kf.P, P_post, 1e-8)
    close(kf.x, x_post, 1e-8)
    # log-likelihood of z under the predictive N(H x0, H P0 Hᵀ + R)
    from scipy.stats import multivariate_normal

    close(kf.log_likelihood, multivariate_normal(H @ x0, H @ P0 @ H.T + R).logpdf(z), 1e-9)


def test_mahalanobis_matches_scipy(rng):
    F, H, Q, R = random_model(rng, 4, 2)
    kf = KalmanFilter(F, H, Q, R, rng.normal(size=4), random_spd(rng, 4))
    kf.predict()
    z = rng.normal(size=2)
    S = H @ kf.P @ H.T + R
    d = scipy_mahalanobis(z, H @ kf.x, np.linalg.inv(S))
    close(kf.mahalanobis(z), d)
    close(kf.mahalanobis(z, squared=True), d**2)
    z_pred, S2 = kf.predicted_measurement()
    close(z_pred, H @ kf.x)
    close(S2, S)


def test_accepts_column_measurement(rng):
    kf = KalmanFilterCV2D()
    kf.predict()
    kf.update(np.array([[1.0], [2.0]]))
    kf2 = KalmanFilterCV2D()
    kf2.predict()
    kf2.update([1.0, 2.0])
    assert np.array_equal(kf.x, kf2.x)


# ---------------------------------------------------------------------------------------------------
# the syllabus' class
# ---------------------------------------------------------------------------------------------------
def test_cv2d_on_syllabus_detections_matches_filterpy():
    dt, q, r = 0.1, 1.0, 4.0
    kf = KalmanFilterCV2D(dt=dt, process_var=q, meas_var=r)
    fp = FPKalmanFilter(dim_x=4, dim_z=2)
    fp.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    fp.H = np.array([[1, 0, 0, 0], [0, 1, 0, 0.0]])
    fp.Q = Q_discrete_white_noise(dim=2, dt=dt, var=q, block_size=2, order_by_dim=False)
    fp.R = r * np.eye(2)
    fp.x = np.zeros((4, 1))
    fp.P = 1e3 * np.eye(4)
    fixed = SyllabusKalmanFilterCV2D(dt, q, r, Q=fp.Q.copy())  # syllabus code, correct Q
    wrong = SyllabusKalmanFilterCV2D(dt, q, r)  # syllabus code as printed
    for z in SYLLABUS_DETECTIONS:
        for f in (kf, fp, fixed, wrong):
            f.predict()
            f.update(z)
        close(kf.x, fp.x.ravel())
        close(kf.P, fp.P, 1e-9)
        close(kf.position(), fixed.position(), 1e-9)  # textbook update == Joseph form
    assert isinstance(kf.position()[0], float)
    # The blkdiag Q of the printed code gives a different answer. With P0 = 1e3·I dominating Q
    # over four steps the gap is small (~1e-5 in position, ~3e-4 in vy) but 10^5 times the
    # 1e-10 agreement above, so this test tells the two Q's apart.
    assert np.abs(np.subtract(kf.position(), wrong.position())).max() > 1e-5
    assert np.abs(kf.x[2:] - wrong.x.ravel()[2:]).max() > 1e-4
    # over a longer track the wrong Q matters more: posterior covariances differ at O(Q)
    for _ in range(200):
        for f in (kf, wrong):
            f.predict()
            f.update(SYLLABUS_DETECTIONS[-1])
    assert np.abs(kf.P - wrong.P).max() > 1e-2 * np.abs(kf.P).max()


# ---------------------------------------------------------------------------------------------------
# numerical robustness
# ---------------------------------------------------------------------------------------------------
def test_covariance_stays_symmetric_pd_over_1e5_steps():
    """Ill-conditioned CV model (tiny R, huge P0, missed measurements) for 10^5 predict/update steps."""
    F, H, Q, R = constant_velocity_model(0.01, 1e-4, 1e-8, dim=2)
    rng = np.random.default_rng(7)
    kf = KalmanFilter(F, H, Q, R, np.zeros(4), 1e6 * np.eye(4))
    Z = rng.normal(scale=1e-4, size=(100_000, 2))
    missed = rng.random(100_000) < 0.1
    min_eig = np.inf
    for t in range(100_000):
        kf.predict()
        kf.update(None if missed[t] else Z[t])
        if t % 1000 == 999:
            assert np.array_equal(kf.P, kf.P.T)
            min_eig = min(min_eig, np.linalg.eigvalsh(kf.P).min())
    assert min_eig > 0
    assert np.isfinite(kf.x).all()


# ---------------------------------------------------------------------------------------------------
# BatchKalmanFilter
# ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n,m", [(4, 2), (3, 1), (6, 3), (6, 4)])
def test_batch_matches_loop_of_single_filters(n, m):
    rng = np.random.default_rng(n * 10 + m)
    F, H, Q, R = random_model(rng, n, m)
    M = 17
    x0 = rng.normal(size=(M, n))
    P0 = np.stack([random_spd(rng, n) for _ in range(M)])
    bkf = BatchKalmanFilter(F, H, Q, R, x0, P0)
    singles = [KalmanFilter(F, H, Q, R, x0[i], P0[i]) for i in range(M)]
    for t in range(25):
        bkf.predict()
        for f in singles:
            f.predict()
        z_pred, S = bkf.predicted_measurements()
        for i, f in enumerate(singles):
            zp, Si = f.predicted_measurement()
            close(z_pred[i], zp)
            close(S[i], Si)
        Z = rng.normal(size=(len(singles), m))
        mask = rng.random(len(singles)) < 0.6
        Z[~mask] = np.nan  # rows not updated may be NaN
        bkf.update(Z, mask=mask)
        for i, f in enumerate(singles):
            f.update(Z[i] if mask[i] else None)
            close(bkf.x[i], f.x)
            close(bkf.P[i], f.P)
            close(bkf.log_likelihood[i], f.log_likelihood)
            if mask[i]:
                close(bkf.innovation[i], f.innovation)
            else:
                assert np.isnan(bkf.innovation[i]).all()
        if t == 10:  # track management: drop some, add some
            keep = np.flatnonzero(rng.random(len(singles)) < 0.7)
            bkf.keep(keep)
            singles = [singles[i] for i in keep]
            new_x = rng.normal(size=(3, n))
            idx = bkf.append(new_x, np.eye(n))
            assert list(idx) == list(range(len(singles), len(singles) + 3))
            singles += [KalmanFilter(F, H, Q, R, xi, np.eye(n)) for xi in new_x]
        assert len(bkf) == len(singles)


@pytest.mark.parametrize("rows", [[0, 2], [3, 1], [1, 2]])
def test_batch_selection_H_matches_single_filters(rows, rng):
    # H = rows of the identity takes the slicing path of BatchKalmanFilter.update
    F, _, Q, _ = constant_velocity_model(0.1, 1.0, 0.5, dim=2)
    H = np.eye(4)[rows]
    R = random_spd(rng, 2)
    M = 7
    x0 = rng.normal(size=(M, 4))
    bkf = BatchKalmanFilter(F, H, Q, R, x0, np.eye(4))
    singles = [KalmanFilter(F, H, Q, R, x, np.eye(4)) for x in x0]
    for _ in range(6):
        bkf.predict()
        Z = rng.normal(size=(M, 2))
        mask = rng.random(M) < 0.7
        P_before = bkf.P.copy()
        bkf.update(Z, mask)
        assert np.array_equal(bkf.P[~mask], P_before[~mask])  # unmeasured tracks untouched
        for i, f in enumerate(singles):
            f.predict()
            f.update(Z[i] if mask[i] else None)
            close(bkf.x[i], f.x)
            close(bkf.P[i], f.P)
            close(bkf.log_likelihood[i], f.log_likelihood)


def test_batch_full_update_and_shared_P0(rng):
    F, H, Q, R = constant_velocity_model(0.1, 1.0, 0.5, dim=3)
    x0 = rng.normal(size=(5, 6))
    bkf = BatchKalmanFilter(F, H, Q, R, x0, np.eye(6))
    fps = [filterpy_filter(F, H, Q, R, x, np.eye(6)) for x in x0]
    for _ in range(5):
        bkf.predict()
        Z = rng.normal(size=(5, 3))
        bkf.update(Z)
        for i, f in enumerate(fps):
            f.predict()
            f.update(Z[i])
            close(bkf.x[i], f.x.ravel())
            close(bkf.P[i], f.P)


def test_batch_empty_then_append_and_keep_mask():
    F, H, Q, R = constant_velocity_model(0.1, 1.0, 0.5)
    bkf = BatchKalmanFilter(F, H, Q, R, np.zeros((0, 4)), 10 * np.eye(4))
    bkf.predict()
    bkf.update(np.zeros((0, 2)))
    assert len(bkf) == 0
    idx = bkf.append(np.ones(4))  # default P0 = the constructor's
    assert list(idx) == [0]
    close(bkf.P[0], 10 * np.eye(4), 0)
    bkf.append(np.zeros((2, 4)), np.eye(4))
    bkf.keep(np.array([True, False, True]))
    assert len(bkf) == 2
    close(bkf.x[0], np.ones(4), 0)
    bkf.keep([])
    assert len(bkf) == 0 and bkf.P.shape == (0, 4, 4)


def test_batch_long_run_stays_pd():
    F, H, Q, R = constant_velocity_model(0.01, 1e-4, 1e-8, dim=2)
    rng = np.random.default_rng(3)
    M = 50
    bkf = BatchKalmanFilter(F, H, Q, R, np.zeros((M, 4)), 1e6 * np.eye(4))
    for _ in range(2000):
        bkf.predict()
        bkf.update(rng.normal(scale=1e-4, size=(M, 2)), mask=rng.random(M) < 0.9)
    assert np.array_equal(bkf.P, np.swapaxes(bkf.P, 1, 2))
    assert np.linalg.eigvalsh(bkf.P).min() > 0


# ---------------------------------------------------------------------------------------------------
# steady state
# ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_steady_state_matches_scipy_and_converged_filter(seed):
    rng = np.random.default_rng(seed)
    n, m = 2 + seed, 1 + seed % 3
    F, H, Q, R = random_model(rng, n, m)
    P = steady_state_covariance(F, H, Q, R)
    close(P, scipy.linalg.solve_discrete_are(F.T, H.T, Q, R), 1e-10)
    # the Riccati equation itself
    S = H @ P @ H.T + R
    close(P, F @ P @ F.T - F @ P @ H.T @ np.linalg.solve(S, H @ P @ F.T) + Q, 1e-9)
    # a filter run to convergence (filterpy), predicted covariance
    fp = filterpy_filter(F, H, Q, R, np.zeros(n), 10 * np.eye(n))
    for _ in range(3000):
        fp.predict()
        fp.update(np.zeros(m))
    fp.predict()
    close(P, fp.P, 1e-8)
    # the covariance recursion written out here (Joseph update), iterated until it stops moving
    close(P, iterate_riccati(F, H, Q, R, 10 * np.eye(n)), 1e-8)
    # the stabilising solution: the predicted-error dynamics F (I - K H) are stable
    K = P @ H.T @ np.linalg.inv(S)
    assert max(abs(np.linalg.eigvals(F @ (np.eye(n) - K @ H)))) < 1
    assert np.linalg.eigvalsh(P).min() > 0


def iterate_riccati(F, H, Q, R, P0, tol=1e-13, max_iter=100_000):
    """Predicted covariance of  predict -> update -> predict ... , iterated to a fixed point."""
    n = F.shape[0]
    P = F @ P0 @ F.T + Q
    for _ in range(max_iter):
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        A = np.eye(n) - K @ H
        P_post = A @ P @ A.T + K @ R @ K.T
        P_new = F @ P_post @ F.T + Q
        if np.abs(P_new - P).max() <= tol * max(1.0, np.abs(P).max()):
            return P_new
        P = P_new
    raise AssertionError("the covariance recursion did not converge")


@pytest.mark.parametrize(
    ("f", "h", "q", "r"), [(1.0, 1.0, 1.0, 1.0), (0.5, 2.0, 0.3, 0.7), (1.3, 1.0, 0.1, 2.0)]
)
def test_steady_state_scalar_closed_form(f, h, q, r):
    """Scalar DARE  h² P² + (r (1 - f²) - q h²) P - q r = 0: the positive root."""
    b = r * (1 - f**2) - q * h**2
    root = (-b + np.sqrt(b**2 + 4 * h**2 * q * r)) / (2 * h**2)
    close(steady_state_covariance([[f]], [[h]], [[q]], [[r]])[0, 0], root, 1e-12)
    F, H, Q, R = (np.array([[v]]) for v in (f, h, q, r))
    close(iterate_riccati(F, H, Q, R, np.eye(1)), [[root]])


def test_steady_state_cv_model_against_converged_cv_filter():
    F, H, Q, R = constant_velocity_model(0.1, 1.0, 4.0, dim=2)
    P = steady_state_covariance(F, H, Q, R)
    kf = KalmanFilterCV2D(0.1, 1.0, 4.0)
    for _ in range(5000):
        kf.predict()
        kf.update([0.0, 0.0])
    kf.predict()
    close(P, kf.P, 1e-7)
    close(P, iterate_riccati(F, H, Q, R, 1e3 * np.eye(4)), 1e-9)


def test_steady_state_rejects_undetectable_and_unexcited():
    # unstable mode 1.1 invisible to H
    with pytest.raises(ValueError, match="detectable"):
        steady_state_covariance(np.diag([1.1, 0.5]), [[0.0, 1.0]], np.eye(2), [[1.0]])
    # unit-circle mode with no process noise (F = 1, Q = 0): P -> 0 but not stabilising
    with pytest.raises(ValueError, match="F, Q"):
        steady_state_covariance([[1.0]], [[1.0]], [[0.0]], [[1.0]])
    with pytest.raises(ValueError, match="R"):
        steady_state_covariance([[0.5]], [[1.0]], [[1.0]], [[0.0]])


# ---------------------------------------------------------------------------------------------------
# bad inputs
# ---------------------------------------------------------------------------------------------------
GOOD = dict(
    F=np.eye(2), H=np.array([[1.0, 0.0]]), Q=np.eye(2), R=np.eye(1), x0=np.zeros(2), P0=np.eye(2)
)


@pytest.mark.parametrize(
    "name,value",
    [
        ("F", np.ones((2, 3))),
        ("F", np.array([[np.nan, 0], [0, 1]])),
        ("H", np.ones((1, 3))),
        ("Q", np.array([[1.0, 2.0], [2.0, 1.0]])),  # indefinite
        ("Q", np.array([[1.0, 0.5], [0.0, 1.0]])),  # not symmetric
        ("Q", np.eye(3)),
        ("R", -np.eye(1)),
        ("R", np.eye(2)),
        ("x0", np.zeros(3)),
        ("x0", np.array([0.0, np.inf])),
        ("P0", np.diag([1.0, -1.0])),
        ("P0", np.ones((2, 3))),
    ],
)
def test_bad_inputs_name_the_argument(name, value):
    kwargs = dict(GOOD, **{name: value})
    with pytest.raises(ValueError, match=name):
        KalmanFilter(**kwargs)
    if name != "x0" or value.shape == (3,):
        bkwargs = dict(kwargs, x0=np.atleast_2d(kwargs["x0"]))
        with pytest.raises(ValueError, match=name):
            BatchKalmanFilter(**bkwargs)


def test_bad_measurements_and_parameters():
    kf = KalmanFilter(**GOOD)
    for z in ([np.nan], [1.0, 2.0], [[1.0, 2.0]]):
        with pytest.raises(ValueError, match="z"):
            kf.update(z)
    with pytest.raises(ValueError, match="z"):
        kf.mahalanobis([np.inf])
    for dt in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="dt"):
            white_noise_acceleration_Q(dt, 1.0)
        with pytest.raises(ValueError, match="dt"):
            KalmanFilterCV2D(dt=dt)
    with pytest.raises(ValueError, match="q"):
        white_noise_acceleration_Q(0.1, -1.0)
    with pytest.raises(ValueError, match="dim"):
        constant_velocity_model(0.1, 1.0, 1.0, dim=4)
    with pytest.raises(ValueError, match="r"):
        constant_velocity_model(0.1, 1.0, 0.0)
    with pytest.raises(ValueError, match="meas_var"):
        KalmanFilterCV2D(meas_var=-1.0)
    bkf = BatchKalmanFilter(GOOD["F"], GOOD["H"], GOOD["Q"], GOOD["R"], np.zeros((3, 2)), np.eye(2))
    with pytest.raises(ValueError, match="Z"):
        bkf.update(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="Z"):
        bkf.update([[0.0], [np.nan], [1.0]])
    bkf.update([[0.0], [np.nan], [1.0]], mask=np.array([True, False, True]))  # NaN ignored
    with pytest.raises(ValueError, match="mask"):
        bkf.update(np.zeros((3, 1)), mask=[1, 0, 1])
    with pytest.raises(ValueError, match="x0"):
        bkf.append(np.zeros(3))
    with pytest.raises(ValueError, match="P0"):
        bkf.append(np.zeros(2), -np.eye(2))
    with pytest.raises(ValueError, match="indices"):
        bkf.keep([5])


def test_batch_state_views_are_read_only():
    """x and P are built on access: an in-place edit could not reach the filter, so it must raise."""
    from flowtrack.kalman import BatchKalmanFilter, constant_velocity_model

    F, H, Q, R = constant_velocity_model(0.1, 1.0, 0.5)
    bkf = BatchKalmanFilter(F, H, Q, R, np.zeros((3, 4)), np.eye(4))
    with pytest.raises(ValueError, match="read-only"):
        bkf.x[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        bkf.P[0, 0, 0] = 1.0
    bkf.x = np.ones((3, 4))
    assert (bkf.x == 1.0).all()
