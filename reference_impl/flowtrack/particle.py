r"""Bootstrap particle filter (sequential importance resampling) for non-Gaussian tracking.

The belief is a weighted sample :math:`\{(x^{(i)}, w^{(i)})\}_{i=1}^N`,
:math:`p(x_t \mid z_{1:t}) \approx \sum_i w^{(i)} \delta(x_t - x^{(i)})`. With the motion model as
proposal, the Bayes recursion of syllabus section 5 becomes

.. math::
    \text{predict:}\quad & x^{(i)} \sim p(x_t \mid x_{t-1}^{(i)}), \\
    \text{update:}\quad  & w^{(i)} \propto w^{(i)}\, p(z_t \mid x^{(i)}), \quad \textstyle\sum_i w^{(i)} = 1.

Weights are kept as logarithms and normalised with log-sum-exp, so likelihoods far below the
smallest float (a confident measurement far from most particles) do not underflow to 0/0. When the
effective sample size :math:`N_\text{eff} = 1 / \sum_i (w^{(i)})^2` falls below
``resample_threshold * N`` the particles are resampled systematically (one uniform draw, ``N``
evenly spaced pointers into the cumulative weights), which keeps each particle
:math:`\lfloor N w^{(i)} \rfloor` or :math:`\lceil N w^{(i)} \rceil` times and adds the least
resampling noise of the common schemes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ._validation import as_array, nonnegative, positive_int

__all__ = ["ParticleFilter", "systematic_resample"]


def systematic_resample(weights, rng=None) -> np.ndarray:
    r"""Systematic resampling: indices of the particles to keep.

    With :math:`c_i = \sum_{k \le i} w_k` (normalised) and one :math:`u_0 \sim U[0, 1)`, pointer
    :math:`j` takes the particle :math:`i` with :math:`c_{i-1} \le (u_0 + j)/N < c_i`,
    ``j = 0..N-1``; vectorised with :func:`numpy.searchsorted`. Particle ``i`` is kept
    :math:`\lfloor N w_i \rfloor` or :math:`\lceil N w_i \rceil` times.

    Parameters
    ----------
    weights : array_like, shape (N,)
        Non-negative weights with a positive sum (normalised here).
    rng : numpy.random.Generator or int or None
        Random source (or a seed for :func:`numpy.random.default_rng`).

    Returns
    -------
    indices : ndarray of int, shape (N,)
        Non-decreasing.

    Examples
    --------
    >>> systematic_resample([0.5, 0.25, 0.25, 0.0], np.random.default_rng(0))
    array([0, 0, 1, 2])
    """
    w = as_array(weights, "weights", ("N",), min_rows=1)
    if (w < 0).any():
        raise ValueError("weights must be non-negative")
    total = w.sum()
    if not total > 0:
        raise ValueError("weights must have a positive sum")
    rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
    return _systematic_indices(w / total, rng.random())


def _systematic_indices(w: np.ndarray, u0: float, arange: np.ndarray | None = None) -> np.ndarray:
    """Systematic resampling indices for normalised weights ``w`` (N,) and one uniform ``u0``.

    No validation (the callers have checked ``w``); ``arange`` is an optional cached
    ``np.arange(N, dtype=float)``.
    """
    N = w.shape[0]
    c = np.cumsum(w)
    c[-1] = 1.0
    u = np.add(np.arange(N, dtype=float) if arange is None else arange, u0)
    u /= N
    idx = np.searchsorted(c, u, side="right")
    return np.minimum(idx, N - 1, out=idx)


def _gather_rows(p: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``p[idx]`` for a 2-D array, keeping a column-major (Fortran) layout column-major."""
    if p.flags.f_contiguous and not p.flags.c_contiguous:
        out = np.empty((p.shape[1], idx.shape[0]), dtype=p.dtype).T
        for j in range(p.shape[1]):
            np.take(p[:, j], idx, out=out[:, j])
        return out
    return np.take(p, idx, axis=0)


class ParticleFilter:
    r"""Bootstrap particle filter with log-weights and adaptive systematic resampling.

    Parameters
    ----------
    n_particles : int
        Number of particles ``N`` (>= 1).
    transition : callable
        ``transition(particles (N, d), rng) -> (N, d)``: a draw from :math:`p(x_t \mid x_{t-1})`
        for every particle (vectorised).
    likelihood : callable
        ``likelihood(z, particles (N, d)) -> (N,)`` the **log**-likelihood
        :math:`\log p(z \mid x^{(i)})` (``-inf`` allowed for impossible particles). Logs, because
        products of small densities underflow; up to an additive constant is enough.
    init : callable
        ``init(N, rng) -> (N, d)`` draws from the prior :math:`p(x_0)`.
    seed : int or numpy.random.Generator or None
        Seed of the filter's :func:`numpy.random.default_rng` (shared by ``init``, ``transition``
        and resampling), so that a run is reproducible.
    resample_threshold : float
        Resample when :math:`N_\text{eff} <` ``resample_threshold * N``; ``0`` never, ``1`` after
        (almost) every update. In ``[0, 1]``.

    Attributes
    ----------
    particles : ndarray, shape (N, d)
    log_weights : ndarray, shape (N,)
        Normalised (``logsumexp == 0``).
    log_evidence : float or None
        :math:`\log \sum_i w^{(i)} p(z \mid x^{(i)})`, the estimate of :math:`\log p(z_t \mid z_{1:t-1})`
        (up to the constant omitted from ``likelihood``) of the last update.
    resampled : bool
        Whether the last update resampled.
    rng : numpy.random.Generator

    Notes
    -----
    Performance: the filter's own work per step is a handful of passes over ``N`` numbers
    (log-weights, one ``exp``, a dot product for :math:`N_\text{eff}`, a cumulative sum and a
    ``searchsorted`` when resampling); the models usually dominate. Column-wise arithmetic on a
    C-ordered ``(N, d)`` array runs numpy's inner loops over ``d`` (tiny) elements, so models
    written column by column (``p[:, 0] + dt * p[:, 2]`` …) are several times faster on a
    column-major array, e.g. ``np.empty((d, N)).T``; the filter keeps whatever layout ``init`` and
    ``transition`` return (resampling preserves a column-major layout). The filter calls no BLAS on
    length-``N`` vectors (sums of products use ``einsum``): OpenBLAS runs those on several threads
    whose busy-waiting, on a loaded machine, slowed the whole step down several-fold.

    Examples
    --------
    A 1-D random walk, z = x + N(0, 1):

    >>> pf = ParticleFilter(
    ...     5000,
    ...     transition=lambda x, rng: x + rng.normal(size=x.shape),
    ...     likelihood=lambda z, x: -0.5 * (z - x[:, 0]) ** 2,
    ...     init=lambda n, rng: rng.normal(size=(n, 1)),
    ...     seed=0,
    ... )
    >>> pf.predict()
    >>> pf.update(3.0)
    >>> mean, cov = pf.estimate()
    >>> bool(abs(mean[0] - 2.0) < 0.1 and abs(cov[0, 0] - 2 / 3) < 0.1)   # Kalman: 2, 2/3
    True
    """

    def __init__(
        self,
        n_particles: int,
        transition: Callable,
        likelihood: Callable,
        init: Callable,
        seed=None,
        resample_threshold: float = 0.5,
    ):
        self.n_particles = positive_int(n_particles, "n_particles")
        for name, f in (("transition", transition), ("likelihood", likelihood), ("init", init)):
            if not callable(f):
                raise TypeError(f"{name} must be callable, got {type(f).__name__}")
        self.transition, self.likelihood = transition, likelihood
        thr = nonnegative(resample_threshold, "resample_threshold")
        if thr > 1:
            raise ValueError(f"resample_threshold must be in [0, 1], got {thr}")
        self.resample_threshold = thr
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.particles = self._check_particles(init(self.n_particles, self.rng), "init(n, rng)")
        self.log_weights = np.full(self.n_particles, -np.log(self.n_particles))
        self.log_evidence: float | None = None
        self.resampled = False

    def _check_particles(self, p, name: str) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if p.ndim == 1:
            p = p[:, None]
        if p.ndim != 2 or p.shape[0] != self.n_particles:
            raise ValueError(f"{name} must return shape ({self.n_particles}, d), got {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError(f"{name} returned NaN or inf particles")
        return p

    @property
    def weights(self) -> np.ndarray:
        """Normalised weights, shape ``(N,)``."""
        return np.exp(self.log_weights)

    @property
    def effective_sample_size(self) -> float:
        r""":math:`N_\text{eff} = 1 / \sum_i w_i^2` (``N`` for equal weights, 1 for a single particle)."""
        w = np.exp(self.log_weights)
        return float(1.0 / np.einsum("i,i->", w, w))

    def predict(self) -> None:
        """Propagate every particle through ``transition`` (weights unchanged)."""
        p = self.transition(self.particles, self.rng)
        self.particles = self._check_particles(p, "transition(particles, rng)")

    def update(self, z) -> None:
        r"""Reweight by :math:`p(z \mid x^{(i)})`; resample if :math:`N_\text{eff}` drops too low.

        ``z=None`` (missed measurement) leaves the weights unchanged.
        """
        self.resampled = False
        if z is None:
            self.log_evidence = 0.0
            return
        ll = np.asarray(self.likelihood(z, self.particles), dtype=float)
        if ll.shape != (self.n_particles,):
            raise ValueError(
                f"likelihood(z, particles) must return shape ({self.n_particles},), got {ll.shape}"
            )
        lw = self.log_weights + ll
        mx = lw.max()  # NaN propagates into the max
        if np.isnan(mx) or mx == np.inf:
            raise ValueError("likelihood(z, particles) returned NaN or +inf (it must be a log-likelihood)")
        if mx == -np.inf:
            raise ValueError("every particle has zero likelihood for z; the filter has diverged")
        w = self._scratch()
        np.subtract(lw, mx, out=w)  # log-sum-exp by hand: shift by the max, exp, sum
        np.exp(w, out=w)
        s = w.sum()
        w *= 1.0 / s
        log_norm = mx + np.log(s)
        lw -= log_norm
        self.log_evidence = float(log_norm)
        self.log_weights = lw
        if 1.0 / np.einsum("i,i->", w, w) < self.resample_threshold * self.n_particles:
            self._resample_normalised(w)

    def _scratch(self) -> np.ndarray:
        buf = getattr(self, "_buf", None)
        if buf is None or buf.shape[0] != self.n_particles:
            buf = self._buf = np.empty(self.n_particles)
            self._arange = np.arange(self.n_particles, dtype=float)
        return buf

    def _resample_normalised(self, w: np.ndarray) -> None:
        self._scratch()
        idx = _systematic_indices(w, self.rng.random(), self._arange)
        self.particles = _gather_rows(self.particles, idx)
        self.log_weights = np.full(self.n_particles, -np.log(self.n_particles))
        self.resampled = True

    def resample(self, weights=None) -> None:
        """Systematic resampling now (with the current weights by default); weights become uniform."""
        idx = systematic_resample(self.weights if weights is None else weights, self.rng)
        self.particles = _gather_rows(self.particles, idx)
        self.log_weights = np.full(self.n_particles, -np.log(self.n_particles))
        self.resampled = True

    def estimate(self):
        r"""Weighted mean and covariance of the particles.

        Returns
        -------
        mean : ndarray, shape (d,)
            :math:`\sum_i w_i x^{(i)}`.
        cov : ndarray, shape (d, d)
            :math:`\sum_i w_i (x^{(i)} - \mu)(x^{(i)} - \mu)^\top`.
        """
        w = self.weights
        p = self.particles
        mean = np.einsum("ij,i->j", p, w)
        rt = np.subtract(p.T, mean[:, None], order="C")   # (d, N) residuals, rows contiguous
        rw = rt * w
        return mean, np.einsum("in,jn->ij", rw, rt)
