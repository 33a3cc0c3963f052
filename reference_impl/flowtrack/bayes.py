r"""Grid (histogram) Bayes filter: the recursion of syllabus section 5, computed literally.

The belief :math:`b(x) = p(x_t \mid z_{1:t})` is stored as density values :math:`b_i` at the nodes
:math:`x_i` of a regular grid in 1-D or 2-D with cell volume :math:`\Delta V`, so that
:math:`\sum_i b_i \Delta V = 1`. The two integrals of the Bayes filter become sums:

.. math::
    \text{predict:}\quad & \bar b_i = \sum_j p(x_i \mid x_j)\, b_j\, \Delta V
        \;\approx\; \int p(x_t \mid x_{t-1})\, p(x_{t-1} \mid z_{1:t-1})\, dx_{t-1}, \\
    \text{update:}\quad  & b_i = \frac{p(z_t \mid x_i)\, \bar b_i}
                                       {\sum_k p(z_t \mid x_k)\, \bar b_k\, \Delta V}.

The prediction sum is evaluated literally (``O(N^2)`` kernel evaluations, in blocks to bound memory),
or, for a random-walk kernel :math:`p(x' \mid x) = \mathcal N(x' - x; 0, Q)` that depends only on
:math:`x' - x`, as the equivalent discrete convolution. Mass carried off the grid by the prediction is
lost; the predicted belief is renormalised (i.e. conditioned on staying in the domain) and the lost
fraction is kept in :attr:`GridBayesFilter.lost_mass`. Choose the grid to cover the belief with margin.

For a linear-Gaussian model this agrees with the Kalman filter up to discretisation error, which for
Gaussians sampled at spacing below their standard deviation is tiny (the sum is a trapezoid rule on a
smooth, rapidly decaying integrand).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg
import scipy.signal

from ._validation import as_array, check_symmetric, cholesky, positive

__all__ = ["GridBayesFilter", "gaussian_likelihood", "linear_gaussian_kernel"]

_LOG_2PI = float(np.log(2.0 * np.pi))


def _whitener(cov: np.ndarray, name: str):
    """``L⁻¹`` and the log normaliser of N(0, cov); ``ValueError`` unless ``cov`` is symmetric PD.

    The Cholesky factorisation ``cov = L Lᵀ`` is the (strict) definiteness check.
    """
    check_symmetric(cov, name)
    L = cholesky(cov, name, hint="a grid needs a proper density")
    Linv = scipy.linalg.solve_triangular(L, np.eye(cov.shape[0]), lower=True)
    log_norm = -float(np.log(np.diag(L)).sum()) - 0.5 * cov.shape[0] * _LOG_2PI
    return Linv, log_norm


def linear_gaussian_kernel(F, Q) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    r"""Transition density :math:`p(x' \mid x) = \mathcal N(x'; F x, Q)` as a kernel function.

    Parameters
    ----------
    F : array_like, shape (d, d)
        Linear dynamics.
    Q : array_like, shape (d, d)
        Process noise covariance, positive definite.

    Returns
    -------
    kernel : callable
        ``kernel(x_new (A, d), x_old (B, d)) -> (A, B)`` array of :math:`p(x'_a \mid x_b)`.

    Examples
    --------
    >>> k = linear_gaussian_kernel([[1.0]], [[1.0]])
    >>> k(np.array([[0.0], [1.0]]), np.array([[0.0]])).round(4)
    array([[0.3989],
           [0.242 ]])
    """
    F = as_array(F, "F")
    if F.ndim != 2 or F.shape[0] != F.shape[1]:
        raise ValueError(f"F must have shape (d, d), got {F.shape}")
    d = F.shape[0]
    Q = as_array(Q, "Q", (d, d))
    return _gaussian_kernel(F, Q, *_whitener(Q, "Q"))


def _gaussian_kernel(F: np.ndarray, Q: np.ndarray, Linv: np.ndarray, log_norm: float):
    """The kernel of :func:`linear_gaussian_kernel` from validated ``F, Q`` and ``Q``'s whitener."""
    A_old = Linv @ F

    def kernel(x_new: np.ndarray, x_old: np.ndarray) -> np.ndarray:
        a = np.asarray(x_new, dtype=float) @ Linv.T
        b = np.asarray(x_old, dtype=float) @ A_old.T
        d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T)
        return np.exp(log_norm - 0.5 * np.maximum(d2, 0.0))

    kernel.F, kernel.Q = F, Q  # type: ignore[attr-defined]
    return kernel


def gaussian_likelihood(H, R) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    r"""Measurement density :math:`p(z \mid x) = \mathcal N(z; H x, R)` as a likelihood function.

    Parameters
    ----------
    H : array_like, shape (m, d)
    R : array_like, shape (m, m)
        Positive definite.

    Returns
    -------
    likelihood : callable
        ``likelihood(z (m,), x (N, d)) -> (N,)``.

    Examples
    --------
    >>> lik = gaussian_likelihood([[1.0, 0.0]], [[1.0]])
    >>> lik(np.array([0.0]), np.array([[0.0, 5.0], [1.0, 0.0]])).round(4)
    array([0.3989, 0.242 ])
    """
    H = as_array(H, "H")
    if H.ndim != 2:
        raise ValueError(f"H must have shape (m, d), got {H.shape}")
    m = H.shape[0]
    R = as_array(R, "R", (m, m))
    Linv, log_norm = _whitener(R, "R")

    def likelihood(z: np.ndarray, x: np.ndarray) -> np.ndarray:
        z = as_array(z, "z", (m,))
        r = (z[None, :] - np.asarray(x, dtype=float) @ H.T) @ Linv.T
        return np.exp(log_norm - 0.5 * (r * r).sum(1))

    return likelihood


class GridBayesFilter:
    r"""Histogram Bayes filter on a regular 1-D or 2-D grid (syllabus section 5, literally).

    Parameters
    ----------
    axes : array_like (n0,) or sequence of 1 or 2 array_like
        Grid coordinates per state dimension, each strictly increasing and uniformly spaced.
        The state dimension ``d`` is the number of axes; the grid has shape ``(n0[, n1])``.
    prior : array_like of the grid's shape, or callable
        Prior density at the nodes, or ``prior(x (N, d)) -> (N,)``. Normalised here.
    transition : callable or array_like
        Either a kernel ``transition(x_new (A, d), x_old (B, d)) -> (A, B)`` giving the density
        :math:`p(x' \mid x)` (e.g. :func:`linear_gaussian_kernel`), evaluated by an explicit sum over
        the grid; or a covariance ``Q`` (``(d, d)`` array, or a scalar variance) for the random walk
        :math:`x' = x + w`, :math:`w \sim \mathcal N(0, Q)`, evaluated by discrete convolution.
    likelihood : callable
        ``likelihood(z, x (N, d)) -> (N,)`` the measurement density :math:`p(z \mid x_i)`
        (e.g. :func:`gaussian_likelihood`).
    block_size : int
        Maximum number of kernel entries evaluated at once by the explicit sum.

    Attributes
    ----------
    belief : ndarray, grid shape
        Density values :math:`b_i` (``(belief * cell_volume).sum() == 1``).
    points : ndarray, shape (N, d)
        Grid nodes in C order (``belief.ravel()`` matches).
    cell_volume : float
        :math:`\Delta V`, product of the spacings.
    lost_mass : float
        Fraction of mass the last prediction moved off the grid.
    log_evidence : float or None
        :math:`\log \sum_i p(z \mid x_i) \bar b_i \Delta V \approx \log p(z_t \mid z_{1:t-1})` of
        the last update.

    Examples
    --------
    A 1-D random walk, Q = R = 1, prior N(0, 1): after one predict/update with z = 3 the
    Kalman answer is mean 2, variance 2/3.

    >>> x = np.linspace(-10, 12, 2201)
    >>> prior = np.exp(-0.5 * x**2)
    >>> gbf = GridBayesFilter(x, prior, transition=1.0, likelihood=gaussian_likelihood([[1.0]], [[1.0]]))
    >>> gbf.predict()
    >>> gbf.update([3.0])
    >>> mean, cov = gbf.mean(), gbf.cov()
    >>> bool(np.allclose(mean, [2.0]) and np.allclose(cov, [[2.0 / 3.0]]))
    True
    """

    def __init__(
        self,
        axes,
        prior,
        transition,
        likelihood: Callable,
        block_size: int = 4_000_000,
    ):
        self.axes = self._axes(axes)
        self.dim = len(self.axes)
        self.shape = tuple(len(a) for a in self.axes)
        self.spacing = np.array([a[1] - a[0] for a in self.axes])
        self.cell_volume = float(np.prod(self.spacing))
        mesh = np.meshgrid(*self.axes, indexing="ij")
        self.points = np.stack([g.ravel() for g in mesh], axis=1)
        self.block_size = int(positive(block_size, "block_size"))
        if callable(transition):
            self._kernel = transition
            self._rw_kernel = None
        else:
            Q = as_array(transition, "transition")
            if Q.ndim == 0:
                Q = positive(float(Q), "transition") * np.eye(self.dim)
            if Q.shape != (self.dim, self.dim):
                raise ValueError(
                    "transition must be a callable kernel or a covariance of shape "
                    f"({self.dim}, {self.dim}), got shape {Q.shape}"
                )
            self._kernel = None
            self._rw_kernel = self._random_walk_kernel(Q)
        if not callable(likelihood):
            raise TypeError(f"likelihood must be callable, got {type(likelihood).__name__}")
        self.likelihood = likelihood
        if callable(prior):
            b = as_array(prior(self.points), "prior(x)", (len(self.points),)).reshape(self.shape)
        else:
            b = as_array(prior, "prior", self.shape)
        self.belief = self._normalise(b, "prior")
        self.lost_mass = 0.0
        self.log_evidence: float | None = None

    # -- construction helpers ------------------------------------------------------------------------
    @staticmethod
    def _axes(axes) -> list[np.ndarray]:
        if isinstance(axes, np.ndarray) and axes.ndim == 1:
            axes = [axes]
        elif isinstance(axes, Sequence) and len(axes) > 0 and np.ndim(axes[0]) == 0:
            axes = [axes]
        if not isinstance(axes, Sequence | np.ndarray) or not 1 <= len(axes) <= 2:
            raise ValueError("axes must be one 1-D array or a sequence of one or two 1-D arrays")
        out = []
        for k, a in enumerate(axes):
            a = as_array(a, f"axes[{k}]", ("n",))
            if len(a) < 3:
                raise ValueError(f"axes[{k}] must have at least 3 points, got {len(a)}")
            h = np.diff(a)
            if (h <= 0).any() or not np.allclose(h, h[0], rtol=1e-6, atol=0):
                raise ValueError(f"axes[{k}] must be strictly increasing and uniformly spaced")
            out.append(a)
        return out

    def _random_walk_kernel(self, Q: np.ndarray) -> np.ndarray:
        """Kernel N(Δ; 0, Q) sampled on all grid offsets Δ (shape (2n0-1[, 2n1-1])).

        ``ValueError`` naming ``transition`` unless ``Q`` is symmetric positive definite.
        """
        whitener = _whitener(Q, "transition")
        offsets = [np.arange(-(n - 1), n) * h for n, h in zip(self.shape, self.spacing)]
        mesh = np.meshgrid(*offsets, indexing="ij")
        pts = np.stack([g.ravel() for g in mesh], axis=1)
        k = _gaussian_kernel(np.eye(self.dim), Q, *whitener)(pts, np.zeros((1, self.dim)))[:, 0]
        return k.reshape(mesh[0].shape)

    def _normalise(self, b: np.ndarray, name: str) -> np.ndarray:
        if (b < 0).any():
            raise ValueError(f"{name} must be non-negative")
        total = float(b.sum()) * self.cell_volume
        if not np.isfinite(total) or total <= 0:
            raise ValueError(f"{name} has zero (or non-finite) mass on the grid")
        return b / total

    # -- the recursion ------------------------------------------------------------------------------
    def predict(self) -> None:
        r"""Prediction integral :math:`\bar b_i = \sum_j p(x_i \mid x_j) b_j \Delta V`, renormalised."""
        b = self.belief
        if self._rw_kernel is not None:
            pred = scipy.signal.fftconvolve(b, self._rw_kernel, mode="same") * self.cell_volume
            pred = np.maximum(pred, 0.0)  # FFT round-off
        else:
            N = len(self.points)
            flat = b.ravel()
            pred = np.zeros(N)
            step = max(1, self.block_size // N)
            src = np.flatnonzero(flat > 0)  # cells with no mass contribute nothing
            for start in range(0, len(src), step):
                j = src[start : start + step]
                K = np.asarray(self._kernel(self.points, self.points[j]), dtype=float)
                if K.shape != (N, len(j)):
                    raise ValueError(
                        f"transition(x_new, x_old) must return shape ({N}, {len(j)}), got {K.shape}"
                    )
                pred += K @ flat[j]
            pred = pred.reshape(self.shape) * self.cell_volume
        mass = float(pred.sum()) * self.cell_volume
        self.lost_mass = max(0.0, 1.0 - mass)
        self.belief = self._normalise(pred, "predicted belief")

    def update(self, z) -> None:
        r"""Bayes rule :math:`b_i \propto p(z \mid x_i)\,\bar b_i`, normalised; ``None`` skips it."""
        if z is None:
            self.log_evidence = 0.0
            return
        lik = np.asarray(self.likelihood(z, self.points), dtype=float)
        if lik.shape != (len(self.points),) and lik.shape != self.shape:
            raise ValueError(f"likelihood(z, x) must return shape ({len(self.points)},), got {lik.shape}")
        if not np.isfinite(lik).all() or (lik < 0).any():
            raise ValueError("likelihood(z, x) must be finite and non-negative")
        post = lik.reshape(self.shape) * self.belief
        evidence = float(post.sum()) * self.cell_volume
        if evidence <= 0:
            raise ValueError("z has zero likelihood everywhere the belief has mass; widen the grid")
        self.log_evidence = float(np.log(evidence))
        self.belief = post / evidence

    # -- moments ------------------------------------------------------------------------------------
    def mean(self) -> np.ndarray:
        r"""Belief mean :math:`\sum_i x_i b_i \Delta V`, shape ``(d,)``."""
        w = self.belief.ravel() * self.cell_volume
        return w @ self.points

    def cov(self) -> np.ndarray:
        r"""Belief covariance :math:`\sum_i (x_i-\mu)(x_i-\mu)^\top b_i \Delta V`, shape ``(d, d)``."""
        w = self.belief.ravel() * self.cell_volume
        r = self.points - w @ self.points
        return (r * w[:, None]).T @ r

    def marginal(self, axis: int) -> np.ndarray:
        """Marginal density along ``axis`` (shape ``(n_axis,)``), integrating out the other axis."""
        if axis not in range(self.dim):
            raise ValueError(f"axis must be in 0..{self.dim - 1}, got {axis}")
        other = tuple(k for k in range(self.dim) if k != axis)
        return self.belief.sum(axis=other) * float(np.prod(self.spacing[list(other)]))
