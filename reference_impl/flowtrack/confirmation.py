r"""Track confirmation: when a tentative track becomes a confirmed one (a part of
:class:`flowtrack.tracking.MultiObjectTracker`).

:class:`HitCountConfirmer` confirms after ``min_hits`` detections (the tracker's default);
:class:`SequentialScoreConfirmer` by the track's sequential log-likelihood-ratio score (Wald's
SPRT), built from the same terms as the association's :func:`flowtrack.association.nllr_cost`;
:func:`pair_log_likelihood` gives the predicted density of each matched detection. Both classes
are importable from :mod:`flowtrack.tracking` too.
"""

from __future__ import annotations

import numpy as np

from ._validation import as_array, nonnegative, positive, positive_int, probability

__all__ = ["HitCountConfirmer", "SequentialScoreConfirmer", "pair_log_likelihood"]

class HitCountConfirmer:
    """Confirm a track once it has ``min_hits`` assigned detections (the birth detection included).

    The tracker's default confirmation (M-of-M logic with M = ``min_hits``, as SORT). It keeps no
    score (``needs_likelihood = False``; the scores stay 0) and never rejects a track: a tentative
    track ends through the deleter (at its first miss).
    """

    needs_likelihood = False
    needs_positions = False

    def __init__(self, min_hits: int = 2):
        self.min_hits = positive_int(min_hits, "min_hits")

    def initial_scores(self, k: int) -> np.ndarray:
        return np.zeros(k)

    def update_scores(self, scores, matched, log_likelihood, has_velocity, missed, velocities=None,
                      velocity_covs=None) -> np.ndarray:
        return scores

    def decide(self, scores: np.ndarray, hits: np.ndarray):
        return hits >= self.min_hits, np.zeros(hits.shape, dtype=bool)


class SequentialScoreConfirmer:
    r"""Confirm a track by its sequential log-likelihood-ratio score (Wald's SPRT).

    The track score of Blackman and Popoli (*Design and Analysis of Modern Tracking Systems*, 1999,
    §6.2; Stone Soup's score-based initiators): the log of the likelihood ratio of "this sequence of
    detections comes from one object" (:math:`H_1`) against "it is clutter or unrelated new objects"
    (:math:`H_0`), accumulated frame by frame. At birth :math:`L_0 = \ln(\beta_{NT}/\beta_{FT})`
    (``birth_log_ratio``: the ratio of new-object to clutter density, 0 when they are the same
    :math:`\lambda_c`, as in the association). Each later frame adds

    .. math::  \Delta L = \begin{cases}
               \ln P_D + \ln \mathcal N(z; \hat z, S) - \ln \lambda_c & \text{detected (matched)},\\
               \ln (1 - P_D) & \text{missed,}
               \end{cases}

    the same terms as the association's :func:`flowtrack.association.nllr_cost`
    (:math:`\Delta L = -C_{ij} + \ln(1 - P_D)` for a match): :math:`\mathcal N(z; \hat z, S)` is the
    predicted density of the detection over its measured components (position, and velocity when
    the detection carries scene flow, then :math:`\lambda_c` = ``clutter_density`` :math:`\times`
    ``velocity_clutter_density``).

    **Static clutter.** Clutter that comes out of a motion segmentation is not uniform in velocity:
    it is static surface whose flow noise passed the speed threshold (depth-edge artefacts, flying
    pixels), so its measured velocity is :math:`v \sim \mathcal N(0, \Sigma_c + R_v)`, with
    :math:`\Sigma_c` = ``clutter_velocity_cov`` the flow noise of static surfaces and :math:`R_v` the
    detection's own velocity covariance. With ``clutter_velocity_cov`` given, that density replaces
    the constant ``velocity_clutter_density``:

    .. math::  \lambda_c(z, v) = \lambda_c\,\mathcal N(v; 0, \Sigma_c + R_v),

    so a detection moving no faster than the flow noise brings no evidence of an object from its
    velocity (the ratio :math:`\mathcal N(v; \hat v, S_v) / \mathcal N(v; 0, \Sigma_c + R_v)` is about 1
    for a track whose velocity is about 0), while an object moving well above the noise gains
    :math:`\tfrac12 v^\top(\Sigma_c + R_v)^{-1}v` per frame. A static artefact detected at the same
    place frame after frame then has to reach :math:`T_c` on its position term alone.

    **Static artefacts' positions.** The velocity term does not stop an artefact detected at the
    same place frame after frame: its small position innovations beat a uniform :math:`\lambda_c`.
    With ``static_position_cov`` :math:`\Sigma_s` given, :math:`H_0` also contains "a static artefact
    at an unknown fixed place :math:`p`", its detections :math:`z_k \sim \mathcal N(p, R + \Sigma_s)`
    (:math:`R` the tracker's position noise, :math:`\Sigma_s` the artefact's own jitter). With a flat
    prior on :math:`p` (the birth detection's density is :math:`\lambda_c` under both :math:`H_0`'s, so
    :math:`L_0` is unchanged), the predictive density of the :math:`k`-th detection given the
    :math:`n = k - 1` earlier ones is

    .. math::  f_s(z_k) = \mathcal N\!\left(z_k;\ \bar z_n,\ (1 + \tfrac1n)(R + \Sigma_s)\right),
               \qquad \bar z_n = \tfrac1n \textstyle\sum_{i<k} z_i

    (the anchor :math:`\bar z_n` is the mean of the track's earlier detections). The position part
    of the clutter density becomes the larger of the two alternatives,

    .. math::  \lambda_c(z) = \max\left(\lambda_c,\ f_s(z)\right),

    a generalised likelihood ratio over :math:`H_0`'s two members taken frame by frame. Since
    :math:`\sum_k \ln(f_1 / \max(f_a, f_b)) \le \min(\sum_k \ln f_1/f_a, \sum_k \ln f_1/f_b)`, the score
    is never above either sequence's log-ratio, so a sequence that would not confirm against the
    uniform clutter or against the static artefact alone does not confirm here (Wald's
    :math:`\alpha` bound holds against each member). A static artefact's own prediction is no sharper
    than :math:`f_s` (its Kalman filter adds velocity uncertainty to the same anchor), so its score
    gains at most :math:`\ln P_D < 0` per detection and never confirms; an object moving away from
    its anchor makes :math:`f_s` vanish and gains the usual terms.

    Wald's test with a false-confirmation probability :math:`\alpha`
    (``false_confirm``: a clutter sequence is confirmed) and a missed-confirmation probability
    :math:`\beta` (``missed_confirm``: an object's sequence is rejected) confirms when

    .. math::  L \ge T_c = \ln\frac{1 - \beta}{\alpha}

    and rejects (deletes the tentative track) when :math:`L \le T_d = \ln\frac{\beta}{1 - \alpha}`;
    Wald's inequalities bound the error rates by :math:`\alpha/(1-\beta)` and :math:`\beta/(1-\alpha)`
    when the two hypotheses' models hold. A confirmed track is not rejected again (the deleter ends
    it). A noise cluster that is detected again nearby, but whose velocity jumps from frame to frame,
    gets large velocity innovations and does not accumulate score; an object confirms as soon as
    its first detections agree with its own prediction.

    Parameters
    ----------
    p_detect : float
        :math:`P_D`, ``0 < p_detect < 1``.
    clutter_density : float
        :math:`\lambda_c` of the position (per m^dim) (> 0).
    velocity_clutter_density : float
        Density of a clutter detection's velocity (per (m/s)^dim) (> 0), for detections with a
        velocity; default 1. Not used with ``clutter_velocity_cov``.
    clutter_velocity_cov : float or array_like, shape (dim, dim), optional
        :math:`\Sigma_c`: static clutter's velocity covariance ((m/s)^2; a number means
        :math:`\sigma^2 I`); the velocity clutter density is then
        :math:`\mathcal N(v; 0, \Sigma_c + R_v)` per detection.
    false_confirm, missed_confirm : float
        :math:`\alpha` and :math:`\beta`, each in (0, 1) with :math:`\alpha + \beta < 1`.
    birth_log_ratio : float
        :math:`L_0`, default 0.
    static_position_cov : float or array_like, shape (dim, dim), optional
        :math:`\Sigma_s`: a static artefact's position jitter beyond the measurement noise (m^2; a
        number means :math:`\sigma^2 I`). With it, the clutter density of a detection's position is
        :math:`\max(\lambda_c, f_s(z))` (above); ``update_scores`` then needs ``positions``,
        ``anchors``, ``anchor_counts`` and ``position_cov``.

    Attributes
    ----------
    confirm_threshold, reject_threshold : float
        :math:`T_c` and :math:`T_d`.

    Examples
    --------
    >>> c = SequentialScoreConfirmer(p_detect=0.9, clutter_density=1.0, false_confirm=0.01,
    ...                              missed_confirm=0.1)
    >>> round(c.confirm_threshold, 4), round(c.reject_threshold, 4)   # ln(0.9 / 0.01), ln(0.1 / 0.99)
    (4.4998, -2.2925)
    >>> s = c.update_scores(c.initial_scores(1), np.array([0]), np.array([5.0]), np.array([False]),
    ...                     np.array([], dtype=int))
    >>> round(float(s[0]), 4)                                          # ln 0.9 + 5 - ln 1
    4.8946
    >>> [m.tolist() for m in c.decide(s, np.array([2]))]
    [[True], [False]]
    """

    needs_likelihood = True

    def __init__(self, p_detect: float, clutter_density: float, velocity_clutter_density: float = 1.0,
                 false_confirm: float = 1e-3, missed_confirm: float = 0.1, birth_log_ratio: float = 0.0,
                 clutter_velocity_cov=None, static_position_cov=None):
        self.p_detect = probability(p_detect, "p_detect")
        self.clutter_density = positive(clutter_density, "clutter_density")
        self.velocity_clutter_density = positive(velocity_clutter_density, "velocity_clutter_density")
        self.false_confirm = probability(false_confirm, "false_confirm")
        self.missed_confirm = probability(missed_confirm, "missed_confirm")
        if self.false_confirm + self.missed_confirm >= 1.0:
            raise ValueError("false_confirm + missed_confirm must be < 1, got "
                             f"{self.false_confirm} + {self.missed_confirm}")
        self.clutter_velocity_cov = _cov_option(clutter_velocity_cov, "clutter_velocity_cov")
        self.static_position_cov = _cov_option(static_position_cov, "static_position_cov")
        #: the tracker passes detections' positions and the tracks' anchors to update_scores
        self.needs_positions = self.static_position_cov is not None
        self.birth_log_ratio = float(birth_log_ratio)
        if not np.isfinite(self.birth_log_ratio):
            raise ValueError("birth_log_ratio must be finite")
        self.confirm_threshold = float(np.log((1.0 - self.missed_confirm) / self.false_confirm))
        self.reject_threshold = float(np.log(self.missed_confirm / (1.0 - self.false_confirm)))

    def initial_scores(self, k: int) -> np.ndarray:
        """:math:`L_0` for ``k`` newborn tracks, shape (k,)."""
        return np.full(k, self.birth_log_ratio)

    def update_scores(self, scores, matched, log_likelihood, has_velocity, missed, velocities=None,
                      velocity_covs=None, positions=None, anchors=None, anchor_counts=None,
                      position_cov=None) -> np.ndarray:
        r"""Add :math:`\Delta L` to the rows ``matched`` (with :math:`\ln\mathcal N` = ``log_likelihood``,
        shape (K,)) and ``missed``; return the new scores (M,).

        ``velocities`` (K, d) and ``velocity_covs`` (K, d, d), the matched detections' velocity
        measurements and covariances, are needed (for the rows with ``has_velocity``) only with
        ``clutter_velocity_cov``. ``positions`` (K, d) (the matched detections' positions),
        ``anchors`` (M, d) and ``anchor_counts`` (M,) (the mean and number of each track's earlier
        detections) and ``position_cov`` (d, d) (the measurement noise :math:`R`) are needed only
        with ``static_position_cov``."""
        out = np.array(scores, dtype=float, copy=True)
        log_lam = np.full(len(matched), np.log(self.clutter_density))
        has_velocity = np.asarray(has_velocity, dtype=bool)
        if self.clutter_velocity_cov is None:
            log_lam[has_velocity] += np.log(self.velocity_clutter_density)
        elif has_velocity.any():
            if velocities is None or velocity_covs is None:
                raise ValueError("clutter_velocity_cov needs the detections' velocities and velocity_covs")
            v = np.asarray(velocities, dtype=float)[has_velocity]
            d = v.shape[1]
            cov = np.asarray(velocity_covs, dtype=float)[has_velocity] + (
                self.clutter_velocity_cov * np.eye(d) if np.ndim(self.clutter_velocity_cov) == 0
                else self.clutter_velocity_cov)
            L = np.linalg.cholesky(cov)
            w = np.linalg.solve(L, v[..., None])[..., 0]
            log_lam[has_velocity] += -0.5 * ((w**2).sum(axis=1) + d * np.log(2.0 * np.pi)) - np.log(
                np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
        if self.static_position_cov is not None and len(matched):
            if positions is None or anchors is None or anchor_counts is None or position_cov is None:
                raise ValueError("static_position_cov needs positions, anchors, anchor_counts and "
                                 "position_cov")
            z = np.asarray(positions, dtype=float)
            d = z.shape[1]
            n = np.asarray(anchor_counts, dtype=float)[matched]
            if np.any(n < 1):
                raise ValueError("anchor_counts must be >= 1 for matched tracks (the birth detection counts)")
            Rs = np.asarray(position_cov, dtype=float) + (
                self.static_position_cov * np.eye(d) if np.ndim(self.static_position_cov) == 0
                else self.static_position_cov)
            cov = (1.0 + 1.0 / n)[:, None, None] * Rs
            L = np.linalg.cholesky(cov)
            w = np.linalg.solve(L, (z - np.asarray(anchors, dtype=float)[matched])[..., None])[..., 0]
            log_fs = -0.5 * ((w**2).sum(axis=1) + d * np.log(2.0 * np.pi)) - np.log(
                np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
            log_lam += np.maximum(log_fs - np.log(self.clutter_density), 0.0)
        out[matched] += np.log(self.p_detect) + log_likelihood - log_lam
        out[missed] += np.log1p(-self.p_detect)
        return out

    def decide(self, scores: np.ndarray, hits: np.ndarray):
        """``(confirm, reject)`` masks (M,): :math:`L \\ge T_c`, :math:`L \\le T_d`."""
        return scores >= self.confirm_threshold, scores <= self.reject_threshold


def _cov_option(cov, name):
    """None, a nonnegative number, or a (d, d) PSD matrix."""
    if cov is None:
        return None
    from ._validation import check_psd

    cov = as_array(cov, name)
    if cov.ndim == 0:
        return nonnegative(float(cov), name)
    if cov.ndim != 2 or cov.shape[0] != cov.shape[1]:
        raise ValueError(f"{name} must be a number or (dim, dim), got {cov.shape}")
    check_psd(cov, name)
    return cov


def pair_log_likelihood(z_pred, S, Z, matches) -> np.ndarray:
    r""":math:`\ln \mathcal N(z_j; \hat z_i, S_{ij})` over the measured components of each matched pair.

    Parameters
    ----------
    z_pred : numpy.ndarray, shape (M, m)
    S : numpy.ndarray, shape (M, m, m) or (M, N, m, m)
    Z : numpy.ndarray, shape (N, m)
        NaN marks unmeasured components (only the measured ones count: the marginal density).
    matches : numpy.ndarray of int, shape (K, 2)
        ``(track row, detection row)`` pairs.

    Returns
    -------
    numpy.ndarray, shape (K,)
        :math:`-\tfrac12\left(d^2 + \ln\det(2\pi S_{oo})\right)` per pair.

    Examples
    --------
    >>> z_pred, S = np.zeros((1, 2)), np.diag([4.0, 1.0])[None]
    >>> Z = np.array([[2.0, np.nan]])           # the second component unmeasured
    >>> pair_log_likelihood(z_pred, S, Z, np.array([[0, 0]])).round(4)   # -(1 + ln(8 pi)) / 2
    array([-2.1121])
    """
    K = matches.shape[0]
    out = np.empty(K)
    for k, (i, j) in enumerate(matches.tolist()):
        z = Z[j]
        o = ~np.isnan(z)
        Sij = S[i, j] if S.ndim == 4 else S[i]
        Soo = Sij[np.ix_(o, o)]
        L = np.linalg.cholesky(Soo)
        w = np.linalg.solve(L, z[o] - z_pred[i, o])
        out[k] = -0.5 * (w @ w + 2.0 * np.log(np.diag(L)).sum() + o.sum() * np.log(2.0 * np.pi))
    return out
