"""Shared pieces of the linear-Gaussian filters (:mod:`flowtrack.kalman`, :mod:`flowtrack.batch_kalman`).

The model validation both filters apply to ``(F, H, Q, R)`` and the error for an innovation
covariance that is not positive definite.
"""

from __future__ import annotations

import numpy as np

from ._validation import as_array, check_psd, check_square, cholesky, not_positive_definite

#: :math:`\log 2\pi`, the constant of a Gaussian log-likelihood.
LOG_2PI = float(np.log(2.0 * np.pi))


def check_model(F, H, Q, R):
    """Validate a linear-Gaussian model ``F (n, n)``, ``H (m, n)`` (``m >= 1``), ``Q``, ``R`` symmetric PSD.

    Returns ``(F, H, Q, R)`` as float arrays with ``Q`` and ``R`` symmetrised; ``ValueError`` naming
    the matrix otherwise.
    """
    F = as_array(F, "F")
    check_square(F, "F")
    if F.ndim != 2:
        raise ValueError(f"F must have shape (n, n), got {F.shape}")
    n = F.shape[0]
    H = as_array(H, "H", ("m", n))
    m = H.shape[0]
    if m == 0:
        raise ValueError(f"H must have shape (m, {n}) with m >= 1, got {H.shape}")
    Q = as_array(Q, "Q", (n, n))
    check_psd(Q, "Q")
    R = as_array(R, "R", (m, m))
    check_psd(R, "R")
    return F, H, 0.5 * (Q + Q.T), 0.5 * (R + R.T)


# the error for an innovation covariance that is not positive definite: "<S_NAME> must be positive
# definite; <S_HINT>"
S_NAME = "S (innovation covariance H P H^T + R)"
S_HINT = "use a positive definite R or P"


def innovation_not_pd() -> ValueError:
    """The ``ValueError`` for an innovation covariance that is not positive definite."""
    return not_positive_definite(S_NAME, S_HINT)


def cholesky_innovation(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor(s) of innovation covariance(s) ``S (..., m, m)``; ``ValueError`` if not PD."""
    return cholesky(S, S_NAME, hint=S_HINT)
