"""Grid Bayes filter vs the Kalman filter (linear-Gaussian) and closed-form mixtures."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FPKalmanFilter
from scipy.stats import multivariate_normal, norm

from flowtrack.bayes import GridBayesFilter, gaussian_likelihood, linear_gaussian_kernel


def filterpy_filter(F, H, Q, R, x0, P0):
    f = FPKalmanFilter(dim_x=F.shape[0], dim_z=H.shape[0])
    f.F, f.H, f.Q, f.R = F, H, Q, R
    f.x = np.asarray(x0, float).reshape(-1, 1)
    f.P = np.asarray(P0, float)
    return f


@pytest.mark.parametrize("transition", ["convolution", "explicit"])
def test_1d_random_walk_matches_kalman(transition):
    q, r, x0, p0 = 0.3, 0.5, 0.2, 1.5
    x = np.linspace(-12, 14, 1301)
    trans = q if transition == "convolution" else linear_gaussian_kernel([[1.0]], [[q]])
    gbf = GridBayesFilter(x, norm(x0, np.sqrt(p0)).pdf(x), trans, gaussian_likelihood([[1.0]], [[r]]))
    kf = filterpy_filter(np.eye(1), np.eye(1), np.array([[q]]), np.array([[r]]), [x0], [[p0]])
    for z in [0.5, 1.1, None, 0.7, 1.6, None, None, 2.2]:
        gbf.predict()
        kf.predict()
        gbf.update(None if z is None else [z])
        kf.update(None if z is None else np.array([z]))
        np.testing.assert_allclose(gbf.mean(), kf.x.ravel(), atol=1e-8)
        np.testing.assert_allclose(gbf.cov(), kf.P, rtol=1e-7)
        if z is not None:
            assert gbf.log_evidence == pytest.approx(kf.log_likelihood, abs=1e-7)


def test_explicit_sum_equals_convolution_for_random_walk(rng):
    axes = [np.linspace(-3, 3, 31), np.linspace(-2, 2, 21)]
    prior = rng.random((31, 21))
    Q = np.array([[0.3, 0.1], [0.1, 0.2]])
    lik = gaussian_likelihood(np.eye(2), 0.5 * np.eye(2))
    a = GridBayesFilter(axes, prior, Q, lik)
    b = GridBayesFilter(axes, prior, linear_gaussian_kernel(np.eye(2), Q), lik, block_size=1000)
    for z in ([0.1, 0.2], [0.4, -0.1]):
        a.predict()
        b.predict()
        np.testing.assert_allclose(a.belief, b.belief, rtol=1e-9, atol=1e-12)
        assert a.lost_mass == pytest.approx(b.lost_mass, abs=1e-12)
        a.update(z)
        b.update(z)
    np.testing.assert_allclose(a.belief, b.belief, rtol=1e-9, atol=1e-12)


def test_2d_constant_velocity_matches_kalman():
    """State [p, v] on a 2-D grid; full-rank Q (a grid needs a proper transition density)."""
    dt = 0.5
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = np.array([[0.1, 0.02], [0.02, 0.1]])
    H, R = np.array([[1.0, 0.0]]), np.array([[0.25]])
    x0, P0 = np.array([0.0, 0.5]), np.diag([0.4, 0.3])
    axes = [np.arange(-3.0, 4.6, 0.12), np.arange(-3.0, 4.0, 0.12)]
    gbf = GridBayesFilter(
        axes, multivariate_normal(x0, P0).pdf, linear_gaussian_kernel(F, Q), gaussian_likelihood(H, R)
    )
    kf = filterpy_filter(F, H, Q, R, x0, P0)
    for z in [0.3, 0.9, 1.1]:
        gbf.predict()
        kf.predict()
        gbf.update([z])
        kf.update(np.array([z]))
        np.testing.assert_allclose(gbf.mean(), kf.x.ravel(), atol=2e-4)
        np.testing.assert_allclose(gbf.cov(), kf.P, atol=2e-4)
        assert gbf.log_evidence == pytest.approx(kf.log_likelihood, abs=1e-3)
        # marginals integrate to one
        assert gbf.marginal(1).sum() * 0.12 == pytest.approx(1.0, abs=1e-9)


def test_prediction_of_bimodal_prior_is_closed_form_mixture():
    """Random walk on a Gaussian mixture: the prediction is the mixture with variances + q."""
    x = np.linspace(-15, 15, 3001)
    w, mu, var, q = np.array([0.3, 0.7]), np.array([-3.0, 2.0]), np.array([0.5, 1.0]), 0.8
    prior = sum(wk * norm(m, np.sqrt(v)).pdf(x) for wk, m, v in zip(w, mu, var))
    gbf = GridBayesFilter(x, prior, q, lambda z, pts: np.ones(len(pts)))
    gbf.predict()
    expect = sum(wk * norm(m, np.sqrt(v + q)).pdf(x) for wk, m, v in zip(w, mu, var))
    np.testing.assert_allclose(gbf.belief, expect, atol=1e-10)
    # a non-Gaussian update: a likelihood flat on x > z and zero elsewhere keeps one mode
    step = GridBayesFilter(x, prior, q, lambda z, pts: (pts[:, 0] > z).astype(float))
    step.update(0.0)
    assert step.belief[x < 0].max() == 0.0
    assert step.mean()[0] > 1.0


def test_bad_inputs():
    x = np.linspace(0, 1, 11)
    lik = gaussian_likelihood([[1.0]], [[1.0]])
    with pytest.raises(ValueError, match="axes"):
        GridBayesFilter(np.r_[0.0, 0.1, 0.3], np.ones(3), 1.0, lik)
    with pytest.raises(ValueError, match="prior"):
        GridBayesFilter(x, np.ones(10), 1.0, lik)
    with pytest.raises(ValueError, match="prior"):
        GridBayesFilter(x, -np.ones(11), 1.0, lik)
    with pytest.raises(ValueError, match="prior"):
        GridBayesFilter(x, np.r_[np.nan, np.ones(10)], 1.0, lik)
    with pytest.raises(ValueError, match="transition"):
        GridBayesFilter(x, np.ones(11), -1.0, lik)
    with pytest.raises(ValueError, match="transition"):
        GridBayesFilter(x, np.ones(11), np.eye(2), lik)
    with pytest.raises(ValueError, match="Q"):
        linear_gaussian_kernel(np.eye(2), np.diag([1.0, 0.0]))
    with pytest.raises(ValueError, match="R"):
        gaussian_likelihood(np.eye(2), -np.eye(2))
    with pytest.raises(TypeError, match="likelihood"):
        GridBayesFilter(x, np.ones(11), 1.0, "gauss")
    gbf = GridBayesFilter(x, np.ones(11), 1.0, lambda z, p: np.zeros(len(p)))
    with pytest.raises(ValueError, match="zero likelihood"):
        gbf.update(0.0)
    gbf = GridBayesFilter(x, np.ones(11), 1.0, lik)
    with pytest.raises(ValueError, match="z"):
        gbf.update([np.nan])
