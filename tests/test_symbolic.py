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


# ==================================================================================================
# lessons 3, 5, 6 and Problems 4, 5: graph normal equations, permutations, rigid clusters,
# normalised cut, chi-square gate, assignment LP
# ==================================================================================================
def _random_weights(rng, n, p_edge=0.7):
    W = np.triu(rng.uniform(0.1, 2.0, size=(n, n)) * (rng.uniform(size=(n, n)) < p_edge), 1)
    return W + W.T


def test_graph_normal_equations_have_the_syllabus_form():
    ne = S.graph_normal_equations(4)
    N, dt, lam, L = 4, ne.dt, ne.lam, ne.laplacian
    # the Laplacian of the symbolic weights, by hand: rows sum to zero, off-diagonal -w
    assert L * sp.ones(N, 1) == sp.zeros(N, 1) and L[0, 1] == -ne.weights[0, 1]
    LkronI3 = sp.kronecker_product(L, sp.eye(3))
    assert sp.expand(ne.matrix - (dt**2 * sp.eye(3 * N) + lam * LkronI3)) == sp.zeros(3 * N, 3 * N)
    b = sp.Matrix([ne.targets[a, c] - ne.points[a, c] for a in range(N) for c in range(3)])
    assert sp.expand(ne.rhs - dt * b) == sp.zeros(3 * N, 1)
    # the energy is the quadratic with Hessian 2 M and gradient 2 (M v - rhs): Taylor-exact
    v = ne.velocities
    quad = (v.T * ne.matrix * v)[0] - 2 * (ne.rhs.T * v)[0]
    const = ne.energy.subs(dict.fromkeys(v, 0))
    assert sp.expand(ne.energy - (quad + const)) == 0
    # coordinate-major reordering makes it block diagonal with three equal N x N blocks
    Pi = S.commutation_matrix(N, 3)
    K = dt**2 * sp.eye(N) + lam * L
    assert sp.expand(Pi * ne.matrix * Pi.T - sp.diag(K, K, K)) == sp.zeros(3 * N, 3 * N)


def test_graph_normal_equations_on_an_edge_subset():
    ne = S.graph_normal_equations(3, edges=[(1, 0), (1, 2), (2, 1)])  # a chain, given unsorted/duplicated
    assert set(ne.weights) == {(0, 1), (1, 2)}
    w12, w23 = ne.weights[0, 1], ne.weights[1, 2]
    assert ne.laplacian == sp.Matrix([[w12, -w12, 0], [-w12, w12 + w23, -w23], [0, -w23, w23]])
    # no coupling between coordinates: the x-rows only involve x-unknowns
    x_unknowns = {ne.velocities[3 * a] for a in range(3)}
    for a in range(3):
        row = ne.matrix.row(3 * a)
        assert {ne.velocities[k] for k in range(9) if row[k] != 0} <= x_unknowns


@pytest.mark.parametrize("n", [3, 5, 8])
def test_graph_normal_equations_numeric_matches_graph_scene_flow_and_dense_kron(rng, n):
    from flowtrack.sceneflow import graph_scene_flow

    for _ in range(3):
        X = rng.normal(size=(n, 3))
        Y = X + rng.normal(0, 0.1, size=(n, 3))
        W = _random_weights(rng, n)
        dt, lam = rng.uniform(0.05, 0.5), rng.uniform(0.01, 2.0)
        M, b = S.graph_normal_equations_numeric(X, Y, dt, lam, W)
        L = np.diag(W.sum(1)) - W
        dense = dt**2 * np.eye(3 * n) + lam * np.kron(L, np.eye(3))
        np.testing.assert_allclose(M, dense, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(b, dt * (Y - X).ravel(), rtol=1e-13, atol=1e-15)
        V = np.linalg.solve(M, b).reshape(n, 3)
        np.testing.assert_allclose(
            V, graph_scene_flow(X, Y, dt, lam, W=W, solver="splu"), rtol=1e-9, atol=1e-12
        )
        np.testing.assert_allclose(V, graph_scene_flow(X, Y, dt, lam, W=W), rtol=1e-6, atol=1e-8)
        # coordinate-major: three independent N x N solves with one matrix (block diagonal I3 ⊗ L)
        V_cols = scipy.linalg.solve(dt**2 * np.eye(n) + lam * L, dt * (Y - X))
        np.testing.assert_allclose(V, V_cols, rtol=1e-9, atol=1e-12)
        assert np.abs(V - (Y - X) / dt).max() > 1e-3  # the smoothing did something


def test_commutation_matrix_swaps_kronecker_factors(rng):
    for n, d in ((3, 2), (2, 3), (4, 3)):
        A = sp.Matrix(n, n, lambda i, j: sp.Symbol(f"a_{i}{j}"))
        B = sp.Matrix(d, d, lambda i, j: sp.Symbol(f"b_{i}{j}"))
        Pi = S.commutation_matrix(n, d)
        assert Pi * Pi.T == sp.eye(n * d)
        assert Pi * sp.kronecker_product(A, B) * Pi.T == sp.kronecker_product(B, A)
        Pn = np.array(Pi.tolist(), dtype=float)
        V = rng.normal(size=(n, d))
        np.testing.assert_array_equal(Pn @ V.ravel(), V.T.ravel())  # point-major -> coordinate-major
    # not the identity (the test above is not vacuous)
    assert S.commutation_matrix(3, 2) != sp.eye(6)


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("model", ["discrete", "continuous"])
def test_process_noise_orderings(rng, dim, model):
    Q, Q_axis, Pi = S.process_noise_orderings(dim, model)
    assert sp.simplify(Pi * Q * Pi.T - Q_axis) == sp.zeros(2 * dim, 2 * dim)
    if dim > 1:
        assert sp.simplify(Q - Q_axis) != sp.zeros(2 * dim, 2 * dim)  # the orders really differ
    dt, q = rng.uniform(0.05, 1.0), rng.uniform(0.1, 3.0)
    dts, qs = sp.symbols("Delta_t q", positive=True)
    Qn = np.array(Q.subs({dts: dt, qs: q}).tolist(), dtype=float)
    Qa = np.array(Q_axis.subs({dts: dt, qs: q}).tolist(), dtype=float)
    if model == "discrete":
        q1d = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
        np.testing.assert_allclose(Qn, kalman_Q(dt, q, dim=dim), rtol=1e-13)
    else:
        q1d = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    np.testing.assert_allclose(Qn, np.kron(q1d, np.eye(dim)), rtol=1e-13)
    np.testing.assert_allclose(Qa, scipy.linalg.block_diag(*[q1d] * dim), rtol=1e-13)
    # Pi reorders the state: x_axis = Pi x (so its covariance is Pi Q Pi^T)
    Pn = np.array(Pi.tolist(), dtype=float)
    x = np.arange(2 * dim, dtype=float)  # [p1..pd, v1..vd] labelled 0..2d-1
    expect = np.array([[k, dim + k] for k in range(dim)]).ravel()  # [p1, v1, p2, v2, ...]
    np.testing.assert_array_equal(Pn @ x, expect)


@pytest.mark.parametrize("model", ["finite", "instantaneous"])
def test_rigid_mean_velocity_is_the_velocity_at_the_centroid(model):
    res = S.rigid_mean_velocity(5, model)
    at_c = res.field.subs(dict(zip(res.query, res.centroid)), simultaneous=True)
    assert sp.simplify(res.velocity - at_c) == sp.zeros(3, 1)
    point_syms = set().union(*(p.free_symbols for p in res.points))
    assert res.mean.free_symbols & point_syms  # the mean is over the points ...
    assert not res.velocity.free_symbols & point_syms  # ... and depends on them only via c
    # the same statement without elimination: mean of the field = field at the explicit centroid
    c_explicit = sum(res.points, sp.zeros(3, 1)) / len(res.points)
    assert sp.simplify(
        res.mean - res.field.subs(dict(zip(res.query, c_explicit)), simultaneous=True)
    ) == sp.zeros(3, 1)
    if model == "instantaneous":
        v_o, _omega, o = res.parameters
        assert res.velocity.subs(dict(zip(o, res.centroid)), simultaneous=True) == v_o


def test_rigid_mean_velocity_numeric_matches_tracks_from_clusters(rng):
    from scipy.spatial.transform import Rotation

    from flowtrack.clustering import tracks_from_clusters

    points, flow, labels, truth = [], [], [], []
    for k in range(3):
        P = rng.normal(size=(40, 3)) * [0.05, 0.03, 0.02] + rng.uniform(-1, 1, 3)
        R, t, dt = (
            Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix(),
            rng.normal(0, 0.1, 3),
            0.1,
        )
        points.append(P)
        flow.append((P @ R.T + t - P) / dt)
        labels.append(np.full(40, k))
        truth.append((R, t, dt))
    points, flow = np.vstack(points), np.vstack(flow)
    labels = np.concatenate(labels)
    labels[::7] = -1  # some points left out as static: the centroid is that of the others
    for k, (c, v) in enumerate(tracks_from_clusters(points, flow, labels)):
        R, t, dt = truth[k]
        c_ref = points[labels == k].mean(axis=0)
        np.testing.assert_allclose(c, c_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(v, S.rigid_mean_velocity_numeric(c_ref, R, t, dt), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(v, (R @ c_ref + t - c_ref) / dt, rtol=1e-10, atol=1e-12)
        assert np.linalg.norm(v - t / dt) > 1e-3  # not the velocity of the origin
    # instantaneous motion about an arbitrary reference point
    P = rng.normal(size=(30, 3))
    v_o, omega, o = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    V = v_o + np.cross(omega, P - o)
    [(c, v)] = tracks_from_clusters(P, V, np.zeros(30, int))
    np.testing.assert_allclose(v, S.rigid_twist_mean_velocity_numeric(P.mean(0), v_o, omega, o), rtol=1e-10)
    np.testing.assert_allclose(v, v_o + np.cross(omega, P.mean(0) - o), rtol=1e-10)


def test_affinity_threshold_matches_motion_affinity_graph_and_cluster_motion():
    from flowtrack.clustering import cluster_motion, motion_affinity_graph

    d, (m, s) = S.affinity_threshold()
    assert sp.simplify(sp.exp(-(d**2) / s**2) - sp.exp(-m)) == 0 and d.subs({m: 1, s: 2}) == 2
    sigma_v, P = 0.05, np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    for m_val in (0.5, 1.0, 9.0):
        dv = S.affinity_threshold_numeric(m_val, sigma_v)
        W = motion_affinity_graph(P, [[0, 0, 0], [dv, 0, 0]], radius=0.02, sigma_v=sigma_v)
        assert W[0, 1] == pytest.approx(np.exp(-m_val), rel=1e-12)
    # the thresholds of cluster_motion: sigma_v ("connected", m = 1) and 3 sigma_v ("spectral", m = 9)
    for method, m_val in (("connected", 1.0), ("spectral", 9.0)):
        dv = S.affinity_threshold_numeric(m_val, sigma_v)
        for factor, n_expected in ((0.99, 1), (1.01, 2)):
            lab = cluster_motion(
                P, [[0, 0, 0], [factor * dv, 0, 0]], radius=0.02, sigma_v=sigma_v, method=method, min_size=1
            )
            assert len(set(lab.tolist())) == n_expected, (method, factor)


@pytest.mark.parametrize("side", [(0, 1), (2,)])
def test_normalized_cut_is_a_rayleigh_quotient(side):
    nc = S.normalized_cut(4, side)
    assert sp.simplify(nc.rayleigh - nc.ncut) == 0
    assert sp.simplify(nc.constraint) == 0
    L, D = nc.laplacian, nc.degree
    assert L == L.T and L * sp.ones(4, 1) == sp.zeros(4, 1) and D.is_diagonal()  # L = D - W, W symmetric
    # a generic (non-indicator) y does not satisfy the identity: the proof uses the two-valued y
    y_bad = nc.indicator + sp.Matrix([1, 0, 0, 0])
    generic = (y_bad.T * nc.laplacian * y_bad)[0] / (y_bad.T * nc.degree * y_bad)[0]
    vals = {w: k + 1 for k, w in enumerate(nc.weights.values())}
    assert (generic - nc.ncut).subs(vals) != 0


def test_normalized_cut_numeric_against_brute_force_and_the_fiedler_bound(rng):
    import itertools

    n = 6
    for _ in range(2):
        W = _random_weights(rng, n, p_edge=0.8) + 0.01 * (1 - np.eye(n))  # connected
        deg = W.sum(1)
        values = {}
        for bits in itertools.product([0, 1], repeat=n - 1):
            mask = np.array((1, *bits), bool)
            if mask.all():
                continue
            cut = W[mask][:, ~mask].sum()
            brute = cut / deg[mask].sum() + cut / deg[~mask].sum()
            values[tuple(np.flatnonzero(mask))] = brute
            assert S.normalized_cut_numeric(W, np.flatnonzero(mask)) == pytest.approx(brute, rel=1e-12)
        lam = scipy.linalg.eigh(np.diag(deg) - W, np.diag(deg), eigvals_only=True)
        assert lam[0] == pytest.approx(0, abs=1e-10) and lam[1] <= min(values.values()) + 1e-12


def test_fiedler_cut_is_the_best_ncut_and_cluster_motion_on_two_patches():
    # Problem 5's check: two touching 3x2 patches moving differently, 12 points, 2047 cuts
    import itertools

    from flowtrack.clustering import cluster_motion, motion_affinity_graph

    gs = np.stack(np.meshgrid(np.arange(3), np.arange(2)), -1).reshape(-1, 2) * 0.01
    P = np.vstack([gs, gs + np.array([0.03, 0.0])])
    V = np.vstack([np.tile([0.10, 0.0], (6, 1)), np.tile([0.07, 0.03], (6, 1))])
    V = V + np.random.default_rng(0).normal(0, 0.005, V.shape)
    W = motion_affinity_graph(P, V, radius=0.0115, sigma_v=0.05).toarray()
    deg = W.sum(1)

    def ncut(mask):
        cut = W[mask][:, ~mask].sum()
        return cut / deg[mask].sum() + cut / deg[~mask].sum()

    cuts = [np.array((True, *bits)) for bits in itertools.product([False, True], repeat=11) if not all(bits)]
    best = min(cuts, key=ncut)
    np.testing.assert_array_equal(best, np.repeat([True, False], 6))
    lam, U = scipy.linalg.eigh(np.diag(deg) - W, np.diag(deg))
    fiedler = U[:, 1] > 0
    assert np.array_equal(fiedler, best) or np.array_equal(fiedler, ~best)
    assert lam[1] <= ncut(best) + 1e-12
    lab = cluster_motion(P, V, radius=0.0115, sigma_v=0.05, n_clusters=2, method="spectral")
    assert np.array_equal(lab == lab[0], best)


def test_chi2_distribution_derivation():
    g = sp.Symbol("gamma", positive=True)
    for m in (1, 2, 3, 4):
        chi = S.chi2_distribution(m)
        assert chi.mean == m and chi.variance == 2 * m
        # the textbook chi-square density and unit-sphere area (independent formulas)
        textbook = (
            g ** sp.Rational(m - 2, 2)
            * sp.exp(-g / 2)
            / (2 ** sp.Rational(m, 2) * sp.gamma(sp.Rational(m, 2)))
        )
        assert sp.simplify(chi.density.subs(chi.gamma, g) - textbook) == 0
        assert (
            sp.simplify(chi.sphere_area - 2 * sp.pi ** sp.Rational(m, 2) / sp.gamma(sp.Rational(m, 2))) == 0
        )
        assert sp.limit(chi.cdf, chi.gamma, sp.oo) == 1
    p = sp.Symbol("p", positive=True)
    gate2 = S.chi2_gate_closed_form(2)
    assert sp.simplify(sp.exp(gate2 / 2) * (1 - p)) == 1  # gamma = -2 log(1 - p)


def test_chi2_numeric_against_scipy_flowtrack_and_monte_carlo(rng):
    from scipy.special import erfinv
    from scipy.stats import chi2, kstest

    from flowtrack.association import chi2_gate, mahalanobis_cost

    for m in (1, 2, 3, 4, 6):  # (m = 5 works too, but its symbolic integral takes ~2 s)
        for g in (0.01, 0.5, 2.0, 7.0, 20.0):
            assert S.chi2_cdf_numeric(g, m) == pytest.approx(chi2.cdf(g, m), rel=1e-11, abs=1e-15)
        for prob in (0.5, 0.9, 0.99, 0.999):
            gate = S.chi2_gate_numeric(m, prob)
            assert gate == pytest.approx(chi2_gate(m, prob), rel=1e-10)
            assert gate == pytest.approx(chi2.ppf(prob, m), rel=1e-10)
    p = sp.Symbol("p", positive=True)
    f2 = sp.lambdify(p, S.chi2_gate_closed_form(2), "numpy")
    f1 = sp.lambdify(p, S.chi2_gate_closed_form(1), "scipy")
    for prob in (0.9, 0.99):
        assert f2(prob) == pytest.approx(chi2_gate(2, prob), rel=1e-12)
        assert f1(prob) == pytest.approx(2 * erfinv(prob) ** 2, rel=1e-12)
        assert f1(prob) == pytest.approx(chi2_gate(1, prob), rel=1e-10)
    # Monte Carlo: innovations nu ~ N(0, S) through flowtrack's Mahalanobis cost
    n_draw = 20000
    for m in (2, 3):
        A = rng.normal(size=(m, m))
        Sm = A @ A.T + 0.2 * np.eye(m)
        nu = rng.normal(size=(n_draw, m)) @ np.linalg.cholesky(Sm).T
        d2 = mahalanobis_cost(np.zeros((1, m)), Sm[None], nu)[0]
        chi = S.chi2_distribution(m)
        assert abs(d2.mean() - float(chi.mean)) < 5 * np.sqrt(float(chi.variance) / n_draw)
        assert abs(d2.var() - float(chi.variance)) < 0.15 * float(chi.variance)
        gate = S.chi2_gate_numeric(m, 0.95)
        assert abs(np.mean(d2 <= gate) - 0.95) < 5 * np.sqrt(0.95 * 0.05 / n_draw)
        cdf = sp.lambdify(chi.gamma, chi.cdf, "scipy")
        assert kstest(d2, lambda x, f=cdf: np.where(x > 0, f(np.maximum(x, 1e-300)), 0.0)).pvalue > 1e-3


def _matchings(M, N):
    """Every 0/1 (M, N) matrix with at most one 1 per row and per column (brute force)."""
    import itertools

    out = []
    for bits in itertools.product([0, 1], repeat=M * N):
        y = np.array(bits).reshape(M, N)
        if (y.sum(0) <= 1).all() and (y.sum(1) <= 1).all():
            out.append(y)
    return out


def test_assignment_constraints_count_and_total_unimodularity():
    for M, N in ((2, 3), (3, 3), (1, 4), (3, 2)):
        A, Y = S.assignment_constraints(M, N)
        inc = np.zeros((M + N, M * N))
        for i in range(M):
            for j in range(N):
                inc[i, i * N + j] = inc[M + j, i * N + j] = 1  # the bipartite incidence matrix
        np.testing.assert_array_equal(np.array(A.tolist(), dtype=float), inc)
        assert Y.shape == (M, N)
        assert S.assignment_count(M, N) == len(_matchings(M, N))
    assert S.assignment_count(2, 3) == 13
    assert S.is_totally_unimodular(S.assignment_constraints(2, 3)[0])
    assert S.is_totally_unimodular(np.array(S.assignment_constraints(3, 2)[0].tolist(), dtype=float))
    assert not S.is_totally_unimodular(sp.Matrix([[1, 1, 0], [0, 1, 1], [1, 0, 1]]))  # odd cycle, det 2
    assert not S.is_totally_unimodular(sp.Matrix([[1, 0], [0, 2]]))


def test_assignment_lp_against_scipy_hungarian_brute_force_and_assign(rng):
    from scipy.optimize import linear_sum_assignment

    from flowtrack.association import assign, hungarian

    for M, N in ((2, 3), (3, 3), (3, 4)):
        matchings = _matchings(M, N)
        for _ in range(15):
            C = rng.chisquare(2, size=(M, N)) * rng.uniform(0.5, 5)
            # every track matched = rectangular linear assignment
            y = S.assignment_lp_numeric(C)
            assert set(np.unique(y)) <= {0, 1} and (y.sum(1) == 1).all() and (y.sum(0) <= 1).all()
            r, c = linear_sum_assignment(C)
            assert (C * y).sum() == pytest.approx(C[r, c].sum(), rel=1e-12)
            rh, ch = hungarian(C)
            assert (C * y).sum() == pytest.approx(C[rh, ch].sum(), rel=1e-12)
            # gate and reward = brute force over every matching
            gamma = rng.uniform(1, 6)
            y_r = S.assignment_lp_numeric(C, reward=gamma)
            best = min(((C - gamma) * yy).sum() for yy in matchings)
            assert ((C - gamma) * y_r).sum() == pytest.approx(best, rel=1e-12, abs=1e-12)
            # a reward larger than any total cost, and +inf outside the gate = "most pairs, then least cost"
            gated = np.where(C <= gamma, C, np.inf)
            y_a = S.assignment_lp_numeric(gated, reward=1e3)
            matches, _, _ = assign(C, gate=gamma)
            assert y_a.sum() == len(matches)
            assert (C * y_a).sum() == pytest.approx(
                C[matches[:, 0], matches[:, 1]].sum() if len(matches) else 0
            )
    # the literal objective (reward 0, costs >= 0) matches nothing
    assert not S.assignment_lp_numeric(rng.uniform(0, 1, (2, 3)), reward=0.0).any()


def test_new_symbolic_functions_reject_bad_input():
    with pytest.raises(ValueError, match="n_points"):
        S.graph_normal_equations(9)
    with pytest.raises(ValueError, match="edges"):
        S.graph_normal_equations(3, edges=[(0, 0)])
    with pytest.raises(ValueError, match="edges"):
        S.graph_normal_equations(3, edges=[(0, 3)])
    with pytest.raises(TypeError, match="edges"):
        S.graph_normal_equations(3, edges=[0, 1])
    X = np.zeros((3, 3))
    with pytest.raises(ValueError, match="W"):
        S.graph_normal_equations_numeric(X, X, 1.0, 1.0, [[0, 1, 0], [0, 0, 1], [0, 1, 0]])
    with pytest.raises(ValueError, match="W"):
        S.graph_normal_equations_numeric(X, X, 1.0, 1.0, -np.ones((3, 3)))
    with pytest.raises(ValueError, match="points_t"):
        S.graph_normal_equations_numeric(np.zeros((4, 3)), X, 1.0, 1.0, np.ones((3, 3)))
    with pytest.raises(ValueError, match="targets"):
        S.graph_normal_equations_numeric(X, np.zeros((3, 2)), 1.0, 1.0, np.ones((3, 3)))
    with pytest.raises(ValueError, match="dt"):
        S.graph_normal_equations_numeric(X, X, 0.0, 1.0, np.ones((3, 3)))
    with pytest.raises(ValueError, match="lam"):
        S.graph_normal_equations_numeric(X, X, 1.0, -1.0, np.ones((3, 3)))
    with pytest.raises(ValueError, match="d"):
        S.commutation_matrix(2, 0)
    with pytest.raises(ValueError, match="model"):
        S.rigid_mean_velocity(3, "screw")
    with pytest.raises(ValueError, match="R"):
        S.rigid_mean_velocity_numeric([0, 0, 0], np.eye(2), [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match="dt"):
        S.rigid_mean_velocity_numeric([0, 0, 0], np.eye(3), [0, 0, 0], -1.0)
    with pytest.raises(ValueError, match="omega"):
        S.rigid_twist_mean_velocity_numeric([0, 0, 0], [0, 0, 0], [0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="sigma_v"):
        S.affinity_threshold_numeric(1.0, 0.0)
    with pytest.raises(ValueError, match="side_a"):
        S.normalized_cut(4, side_a=(0, 1, 2, 3))
    with pytest.raises(ValueError, match="side_a"):
        S.normalized_cut_numeric(np.ones((3, 3)), [5])
    with pytest.raises(ValueError, match="volume"):
        S.normalized_cut_numeric([[0, 1, 0], [1, 0, 0], [0, 0, 0]], [2])
    with pytest.raises(ValueError, match="m"):
        S.chi2_distribution(0)
    with pytest.raises(ValueError, match="gamma"):
        S.chi2_cdf_numeric(-1.0, 2)
    with pytest.raises(ValueError, match="prob"):
        S.chi2_gate_numeric(2, 1.0)
    with pytest.raises(ValueError, match="n_tracks"):
        S.assignment_constraints(0, 3)
    with pytest.raises(ValueError, match="cost"):
        S.assignment_lp_numeric([[np.nan, 1.0]])
    with pytest.raises(ValueError, match="cost"):
        S.assignment_lp_numeric(np.ones((3, 2)))  # every track matched needs M <= N
    with pytest.raises(ValueError, match="cost"):
        S.assignment_lp_numeric([[np.inf, np.inf], [1.0, np.inf]])  # track 0 has no allowed pair
