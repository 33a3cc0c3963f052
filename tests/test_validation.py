"""The shared validation helpers, and the code that now goes through them (Cholesky, gates, caches)."""

import numpy as np
import pytest
from scipy.stats import chi2

from flowtrack._batch_kernels import batched_cho_solve, batched_cholesky
from flowtrack._validation import (
    check_psd,
    check_symmetric,
    cholesky,
    not_positive_definite,
    probability,
    spatial_dim,
)
from flowtrack.association import chi2_gate, mahalanobis_cost
from flowtrack.bayes import GridBayesFilter, gaussian_likelihood, linear_gaussian_kernel
from flowtrack.kalman import BatchKalmanFilter, KalmanFilter, constant_velocity_model
from flowtrack.tracking import GNNAssociator, MultiObjectTracker


def random_spd(rng, n, k=(), jitter=0.5):
    A = rng.normal(size=(*k, n, n))
    return A @ np.swapaxes(A, -1, -2) + jitter * np.eye(n)


# ----------------------------------------------------------------------------- scalars


@pytest.mark.parametrize("value", [0.5, 1e-12, 1 - 1e-12, np.float32(0.25), np.float64(0.99), 0.75])
def test_probability_accepts_open_interval(value):
    assert probability(value, "p") == float(value)


@pytest.mark.parametrize("value", [0, 0.0, 1, 1.0, -0.1, 1.5, np.nan, np.inf, -np.inf])
def test_probability_rejects_outside_open_interval(value):
    with pytest.raises(ValueError, match="p"):
        probability(value, "p")


@pytest.mark.parametrize("value", [True, "0.5", None, [0.5]])
def test_probability_rejects_non_real(value):
    with pytest.raises(TypeError, match="gate_prob"):
        probability(value, "gate_prob")


def test_spatial_dim():
    assert [spatial_dim(d) for d in (1, 2, 3)] == [1, 2, 3]
    for bad in (0, 4, -1):
        with pytest.raises(ValueError, match="dim"):
            spatial_dim(bad)
    with pytest.raises(TypeError, match="dim"):
        spatial_dim(2.0)


# ----------------------------------------------------------------------------- matrices


def test_check_symmetric_single_and_batched(rng):
    S = random_spd(rng, 3, (4,))
    assert check_symmetric(S, "S") is S
    bad = S.copy()
    bad[2, 0, 1] += 1e-3
    with pytest.raises(ValueError, match="S must be symmetric"):
        check_symmetric(bad, "S")
    with pytest.raises(ValueError, match="S must be square"):
        check_symmetric(np.zeros((2, 3)), "S")


def test_check_symmetric_tolerance_is_relative_to_the_scale():
    A = np.array([[1e6, 1.0], [1.0 + 1e-5, 1e6]])  # 1e-5 < 1e-10 * 1e6 + 1e-8 * 1
    check_symmetric(A, "A")
    with pytest.raises(ValueError, match="A"):
        check_symmetric(A, "A", atol=1e-12)


def test_check_psd_still_checks_symmetry_then_definiteness():
    with pytest.raises(ValueError, match="Q must be symmetric"):
        check_psd(np.array([[1.0, 0.5], [0.0, 1.0]]), "Q")
    with pytest.raises(ValueError, match="Q must be positive semi-definite"):
        check_psd(np.array([[1.0, 2.0], [2.0, 1.0]]), "Q")
    with pytest.raises(ValueError, match="Q must be positive definite"):
        check_psd(np.diag([1.0, 0.0]), "Q", strict=True)
    check_psd(np.diag([1.0, 0.0]), "Q")


def test_check_psd_accepts_an_empty_stack():
    # a frame without detections gives (0, 3, 3) position covariances: nothing to fail (the demo used to
    # stop there with "position_covs must be positive definite (smallest eigenvalue 0)")
    for strict in (False, True):
        assert check_psd(np.zeros((0, 3, 3)), "R", strict=strict).shape == (0, 3, 3)


def test_cholesky_matches_numpy_single_and_batched(rng):
    S = random_spd(rng, 3, (5,))
    np.testing.assert_array_equal(cholesky(S, "S"), np.linalg.cholesky(S))
    np.testing.assert_array_equal(cholesky(S[0], "S"), np.linalg.cholesky(S[0]))


@pytest.mark.parametrize("S", [np.diag([1.0, 0.0]), np.array([[1.0, 2.0], [2.0, 1.0]]), -np.eye(2)[None]])
def test_cholesky_raises_value_error_naming_the_argument(S):
    with pytest.raises(ValueError, match=r"^R must be positive definite$"):
        cholesky(S, "R")
    with pytest.raises(ValueError, match=r"^R must be positive definite; use another R$"):
        cholesky(S, "R", hint="use another R")


def test_not_positive_definite_message():
    assert str(not_positive_definite("S")) == "S must be positive definite"
    assert str(not_positive_definite("S", "why")) == "S must be positive definite; why"


# ----------------------------------------------------------------------------- users of the helpers


@pytest.mark.parametrize("dim", [1, 2, 3, 4, 6, 10])
@pytest.mark.parametrize("prob", [1e-9, 1e-4, 0.01, 0.5, 0.9, 0.99, 0.999, 0.99999, 1 - 1e-9])
def test_chi2_gate_is_scipy_stats_chi2_ppf_exactly(dim, prob):
    assert chi2_gate(dim, prob) == float(chi2.ppf(prob, dim))


def test_chi2_gate_prob_validation():
    for bad in (0.0, 1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="prob"):
            chi2_gate(2, bad)
    for bad in (True, "0.9", None):
        with pytest.raises(TypeError, match="prob"):
            chi2_gate(2, bad)


def test_association_module_does_not_import_scipy_stats():
    import subprocess
    import sys

    code = "import sys, flowtrack.tracking; print('scipy.stats' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_mahalanobis_cost_errors():
    z = np.zeros((1, 2))
    with pytest.raises(ValueError, match="S must be symmetric"):
        mahalanobis_cost(z, np.array([[[1.0, 0.5], [0.0, 1.0]]]), z)
    with pytest.raises(ValueError, match="S must be positive definite"):
        mahalanobis_cost(z, -np.eye(2)[None], z)


def test_tracker_probability_and_dim_errors():
    with pytest.raises(ValueError, match="gate_prob"):
        MultiObjectTracker(0.1, 1.0, 1.0, gate_prob=0.0)
    with pytest.raises(ValueError, match="gate_prob"):
        GNNAssociator(gate_prob=1.0)
    with pytest.raises(TypeError, match="gate_prob"):
        GNNAssociator(gate_prob="high")
    with pytest.raises(ValueError, match="dim must be 1, 2 or 3"):
        MultiObjectTracker(0.1, 1.0, 1.0, dim=4)
    with pytest.raises(ValueError, match="S must be positive definite"):
        GNNAssociator().associate(np.zeros((1, 2)), -np.eye(2)[None], np.zeros((1, 2)))


def test_bayes_definiteness_errors_name_the_argument():
    x = np.linspace(0, 1, 11)
    lik = gaussian_likelihood([[1.0]], [[1.0]])
    with pytest.raises(ValueError, match="transition must be positive definite"):
        GridBayesFilter(x, np.ones(11), np.array([[0.0]]), lik)
    with pytest.raises(ValueError, match="transition must be symmetric"):
        GridBayesFilter([x, x], np.ones((11, 11)), np.array([[1.0, 0.5], [0.0, 1.0]]), lik)
    with pytest.raises(ValueError, match="Q must be positive definite"):
        linear_gaussian_kernel(np.eye(2), np.diag([1.0, 0.0]))
    with pytest.raises(ValueError, match="R must be symmetric"):
        gaussian_likelihood(np.eye(2), np.array([[1.0, 0.5], [0.0, 1.0]]))


def test_kalman_filter_not_pd_innovation_covariance():
    kf = KalmanFilter([[1.0]], [[1.0]], [[0.0]], [[0.0]], [0.0], [[0.0]])
    with pytest.raises(ValueError, match=r"innovation covariance .* must be positive definite"):
        kf.update([1.0])


# ----------------------------------------------------------------------------- BatchKalmanFilter


@pytest.mark.parametrize("m", [5, 6, 8])
def test_batched_cho_solve_large_m(rng, m):
    S = random_spd(rng, m, (7,))
    B = rng.normal(size=(7, m, 3))
    X = batched_cho_solve(batched_cholesky(S), B)
    np.testing.assert_allclose(X, np.linalg.solve(S, B), rtol=1e-10, atol=1e-12)


def test_batched_cholesky_not_pd_message():
    for m in (2, 5):
        S = np.broadcast_to(-np.eye(m), (3, m, m)).copy()
        with pytest.raises(ValueError, match="must be positive definite; use a positive definite R or P"):
            batched_cholesky(S)


def _filter(rng, M=6, dim=2):
    F, H, Q, R = constant_velocity_model(0.1, 1.0, 0.3, dim)
    n = 2 * dim
    return BatchKalmanFilter(F, H, Q, R, rng.normal(size=(M, n)), random_spd(rng, n, (M,)))


def test_len_is_M(rng):
    bkf = _filter(rng, M=4)
    assert len(bkf) == bkf.M == 4
    bkf.keep([0, 2])
    assert len(bkf) == bkf.M == 2


def test_gating_then_update_equals_update_alone(rng):
    """predicted_measurements() caches S for update(); the result must be bit-for-bit unchanged."""
    a, b = _filter(np.random.default_rng(1)), _filter(np.random.default_rng(1))
    for _ in range(5):
        a.predict()
        b.predict()
        z_pred, S = a.predicted_measurements()
        Z = z_pred + rng.normal(size=z_pred.shape)
        mask = rng.random(len(a)) < 0.7
        S[:] = np.nan  # the returned S is a copy: writing into it cannot reach the filter
        a.update(Z, mask)
        b.update(Z, mask)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)
        np.testing.assert_array_equal(a.S, b.S)
        np.testing.assert_array_equal(a.log_likelihood, b.log_likelihood)


@pytest.mark.parametrize("change", ["predict", "update", "keep", "append", "x", "P"])
def test_predicted_measurements_follow_every_state_change(rng, change):
    bkf = _filter(rng, M=5)
    bkf.predicted_measurements()  # fill the cache
    if change == "predict":
        bkf.predict()
    elif change == "update":
        bkf.update(rng.normal(size=(5, 2)))
    elif change == "keep":
        bkf.keep([4, 0, 2])
    elif change == "append":
        bkf.append(rng.normal(size=(2, 4)), random_spd(rng, 4, (2,)))
    elif change == "x":
        bkf.x = rng.normal(size=bkf.x.shape)
    else:
        bkf.P = random_spd(rng, 4, (5,))
    z_pred, S = bkf.predicted_measurements()
    H, R = bkf.H, bkf.R
    np.testing.assert_allclose(z_pred, bkf.x @ H.T, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(S, H @ bkf.P @ H.T + R, rtol=1e-13, atol=1e-13)


def test_single_track_predicted_measurements_are_copies(rng):
    bkf = _filter(rng, M=1)
    _, S = bkf.predicted_measurements()
    S += 1.0
    _, S2 = bkf.predicted_measurements()
    np.testing.assert_allclose(S2, bkf.H @ bkf.P @ bkf.H.T + bkf.R, rtol=1e-13)


def test_model_arrays_are_read_only_and_assignment_is_honoured(rng):
    bkf = _filter(rng, M=3)
    for name in "FHQR":
        with pytest.raises(ValueError, match="read-only"):
            getattr(bkf, name)[0, 0] = 1.0
    F, H, Q, R = constant_velocity_model(0.2, 2.0, 0.5, 2)
    ref = BatchKalmanFilter(F, H, Q, R, bkf.x, bkf.P)
    bkf.predicted_measurements()
    bkf.F, bkf.Q, bkf.R = F, Q, R
    for f in (bkf, ref):
        f.predict()
        f.update(np.zeros((3, 2)))
    np.testing.assert_array_equal(bkf.x, ref.x)
    np.testing.assert_array_equal(bkf.P, ref.P)
    with pytest.raises(ValueError, match="Q"):
        bkf.Q = -np.eye(4)
    with pytest.raises(ValueError, match="F"):
        bkf.F = np.eye(3)
