"""Particle filter and systematic resampling: properties and agreement with the Kalman filter."""

from __future__ import annotations

import filterpy.monte_carlo.resampling as fp_resampling
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FPKalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from flowtrack.particle import ParticleFilter, systematic_resample


@settings(max_examples=60, deadline=None)
@given(
    w=arrays(np.float64, st.integers(1, 200), elements=st.floats(0.0, 1.0)),
    seed=st.integers(0, 2**32 - 1),
)
def test_systematic_resample_counts_are_floor_or_ceil(w, seed):
    if w.sum() <= 0:
        w = w + 1.0
    idx = systematic_resample(w, np.random.default_rng(seed))
    N = len(w)
    assert idx.shape == (N,) and np.all(np.diff(idx) >= 0)
    counts = np.bincount(idx, minlength=N)
    expect = N * w / w.sum()
    assert np.all(counts >= np.floor(expect - 1e-9)) and np.all(counts <= np.ceil(expect + 1e-9))
    assert np.all(counts[w == 0] == 0)


@pytest.mark.parametrize("seed", range(5))
def test_systematic_resample_matches_filterpy(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    w = rng.random(500) ** 3
    w /= w.sum()
    u0 = np.random.default_rng(seed + 100).random()
    monkeypatch.setattr(fp_resampling, "random", lambda: u0)
    expect = fp_resampling.systematic_resample(w)
    got = systematic_resample(w, np.random.default_rng(seed + 100))  # first draw is u0
    np.testing.assert_array_equal(got, expect)


def test_systematic_resample_is_unbiased():
    w = np.array([0.05, 0.15, 0.3, 0.5])
    rng = np.random.default_rng(0)
    counts = np.mean([np.bincount(systematic_resample(w, rng), minlength=4) for _ in range(4000)], axis=0)
    np.testing.assert_allclose(counts, 4 * w, atol=0.03)


def _cv_problem(seed):
    dt, q, r = 0.5, 0.5, 0.4
    F = np.array([[1.0, dt], [0.0, 1.0]])
    G = np.array([[dt**2 / 2], [dt]])
    Q = q * G @ G.T + 1e-3 * np.eye(2)
    H, R = np.array([[1.0, 0.0]]), np.array([[r]])
    x0, P0 = np.array([0.0, 1.0]), np.diag([1.0, 0.5])
    LQ = np.linalg.cholesky(Q)
    rng = np.random.default_rng(seed)
    truth, zs = x0 + np.linalg.cholesky(P0) @ rng.normal(size=2), []
    for _ in range(12):
        truth = F @ truth + LQ @ rng.normal(size=2)
        zs.append(H @ truth + np.sqrt(r) * rng.normal(size=1))

    def transition(p, rng):
        return p @ F.T + rng.standard_normal(p.shape) @ LQ.T

    def likelihood(z, p):
        return -0.5 * (z[0] - p[:, 0]) ** 2 / r

    def init(n, rng):
        return x0 + rng.standard_normal((n, 2)) @ np.linalg.cholesky(P0).T

    kf = FPKalmanFilter(dim_x=2, dim_z=1)
    kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = F, H, Q, R, x0.reshape(2, 1), P0.copy()
    return transition, likelihood, init, kf, zs


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_first_update_mean_within_importance_sampling_error(seed):
    """One predict/update from the prior: |mean − Kalman| < 4·sqrt(var / N_eff)."""
    transition, likelihood, init, kf, zs = _cv_problem(seed)
    pf = ParticleFilter(20_000, transition, likelihood, init, seed=seed, resample_threshold=0.0)
    pf.predict()
    kf.predict()
    pf.update(zs[0])
    kf.update(zs[0])
    mean, cov = pf.estimate()
    sd = np.sqrt(np.diag(kf.P) / pf.effective_sample_size)
    assert np.all(np.abs(mean - kf.x.ravel()) < 4 * sd)
    np.testing.assert_allclose(cov, kf.P, rtol=0.05, atol=0.01 * np.abs(kf.P).max())


@pytest.mark.parametrize("seed", [0, 1])
def test_posterior_mean_matches_kalman_over_a_track(seed):
    """12 steps with resampling and a missed measurement; the Monte-Carlo error is measured from
    R independent replicas (resampling history makes var/N_eff an underestimate)."""
    transition, likelihood, init, kf, zs = _cv_problem(seed)
    R, N = 16, 4000
    pfs = [ParticleFilter(N, transition, likelihood, init, seed=1000 * seed + k) for k in range(R)]
    n_resampled = 0
    for t, z in enumerate(zs):
        z = None if t == 5 else z
        kf.predict()
        kf.update(z)
        means, covs = [], []
        for pf in pfs:
            pf.predict()
            pf.update(z)
            n_resampled += pf.resampled
            m, c = pf.estimate()
            means.append(m)
            covs.append(c)
        means = np.array(means)
        se = means.std(axis=0, ddof=1) / np.sqrt(R)
        assert np.all(np.abs(means.mean(axis=0) - kf.x.ravel()) < 5 * se), (t, means.mean(0), kf.x)
        np.testing.assert_allclose(np.mean(covs, axis=0), kf.P, rtol=0.05, atol=0.01 * np.abs(kf.P).max())
    assert n_resampled > 0


def reweight_extended(log_w_prev, ll):
    """Posterior weights, N_eff and log evidence computed directly (no log-sum-exp shift) in long double:
    w_i = w_prev_i exp(ll_i) / sum_j w_prev_j exp(ll_j),  N_eff = 1 / sum_i w_i^2."""
    u = np.exp(np.asarray(log_w_prev, np.longdouble)) * np.exp(np.asarray(ll, np.longdouble))
    total = u.sum()
    assert total > 0, "the long-double oracle underflowed"
    w = u / total
    return w, 1 / np.sum(w * w), np.log(total)


# exp(-3000) underflows a double but not an x87 / IEEE-quad long double
_EXTENDED = np.finfo(np.longdouble).minexp < -5000


@pytest.mark.parametrize(
    "offset",
    [0.0, pytest.param(-3000.0, marks=pytest.mark.skipif(not _EXTENDED, reason="long double == double"))],
)
def test_resampling_only_below_threshold(offset):
    transition, likelihood, init, _, zs = _cv_problem(3)
    seen = set()
    for thr in (0.0, 0.5, 1.0):
        pf = ParticleFilter(
            2000, transition, lambda z, p: likelihood(z, p) + offset, init, seed=1, resample_threshold=thr
        )
        for z in zs[:6]:
            pf.predict()
            ll = likelihood(z, pf.particles) + offset
            w, ess, log_ev = reweight_extended(pf.log_weights, ll)
            pf.update(z)
            assert pf.log_evidence == pytest.approx(float(log_ev), rel=1e-12, abs=1e-9)
            assert pf.resampled == (ess < thr * 2000)
            seen.add((thr, pf.resampled))
            if pf.resampled:
                np.testing.assert_allclose(pf.weights, 1 / 2000)
                assert pf.effective_sample_size == pytest.approx(2000)
            else:
                np.testing.assert_allclose(pf.weights, w.astype(float), rtol=1e-10, atol=1e-300)
                assert pf.effective_sample_size == pytest.approx(float(ess), rel=1e-10)
    assert {(0.0, False), (1.0, True)} <= seen  # both branches are exercised
    assert {(0.5, False), (0.5, True)} <= seen  # and the threshold itself decides


def test_seeded_runs_are_reproducible_and_logs_do_not_underflow():
    transition, likelihood, init, _, zs = _cv_problem(4)
    runs = []
    for _ in range(2):
        pf = ParticleFilter(500, transition, lambda z, p: 1e-3 * likelihood(z, p) - 1e4, init, seed=42)
        for z in zs[:4]:
            pf.predict()
            pf.update(z)
        runs.append(pf.particles.copy())
    # same seed, same particles: resampling picks the same indices, the values agree to rounding
    np.testing.assert_allclose(runs[0], runs[1], rtol=1e-12, atol=1e-12 * np.abs(runs[0]).max())
    # a likelihood of exp(-2000) for most particles still gives finite, normalised weights
    pf = ParticleFilter(100, transition, lambda z, p: -2000.0 * (p[:, 0] - z) ** 2, init, seed=0)
    pf.update(0.3)
    assert np.isfinite(pf.log_weights).all() and pf.weights.sum() == pytest.approx(1.0)


def test_bad_inputs():
    def tr(p, rng):
        return p

    def lik(z, p):
        return np.zeros(len(p))

    def init(n, rng):
        return np.zeros((n, 2))

    with pytest.raises(ValueError, match="n_particles"):
        ParticleFilter(0, tr, lik, init)
    with pytest.raises(ValueError, match="resample_threshold"):
        ParticleFilter(10, tr, lik, init, resample_threshold=1.5)
    with pytest.raises(TypeError, match="transition"):
        ParticleFilter(10, None, lik, init)
    with pytest.raises(ValueError, match="init"):
        ParticleFilter(10, tr, lik, lambda n, rng: np.zeros((n + 1, 2)))
    pf = ParticleFilter(10, tr, lambda z, p: np.full(len(p), np.nan), init)
    with pytest.raises(ValueError, match="likelihood"):
        pf.update(0.0)
    pf = ParticleFilter(10, tr, lambda z, p: np.full(len(p), -np.inf), init)
    with pytest.raises(ValueError, match="zero likelihood"):
        pf.update(0.0)
    pf = ParticleFilter(10, lambda p, rng: p[:5], lik, init)
    with pytest.raises(ValueError, match="transition"):
        pf.predict()
    for w in ([], [-1.0, 2.0], [0.0, 0.0], [np.nan, 1.0]):
        with pytest.raises(ValueError, match="weights"):
            systematic_resample(w, 0)
