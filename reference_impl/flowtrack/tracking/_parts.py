r"""The parts of :class:`flowtrack.tracking.MultiObjectTracker`: their interfaces and implementations.

One tracker step is the syllabus' second flowchart, and each box is a part with a small interface,
in the spirit of Stone Soup (whose predictors hold the motion model and whose updaters hold the
measurement model and predict the measurements the association compares):

=============  ========================================================================================
part           does
=============  ========================================================================================
predictor      makes the filter that holds every track's state (the motion model), predicts it one
               frame, :math:`x_i \leftarrow f(x_i)`, :math:`P_i \leftarrow F_i P_i F_i^\top + Q`, and
               :math:`n` frames ahead without changing it
updater        checks what a frame's detections carry (:class:`Detections`) and completes it, predicts
               the measurement of every (track, detection) pair, :math:`\hat z_i = H x_i`,
               :math:`S_{ij} = H P_i H^\top + R_j`, and updates the matched tracks (Joseph form)
associator     gates the pairs and assigns detections to tracks from :math:`(\hat z, S, z)`
initiator      starts a track from an unmatched detection
deleter        says which tracks end (misses)
confirmer      says which tentative tracks become confirmed (hits, or the track score)
=============  ========================================================================================

Each interface is a :class:`typing.Protocol` (:class:`Predictor`, :class:`Updater`,
:class:`Associator`, :class:`Initiator`, :class:`Deleter`, :class:`Confirmer`): any object with
those methods plugs in, and ``isinstance(part, Updater)`` checks that it has them. Two sets are
provided. The default, position-only parts run a :class:`flowtrack.kalman.BatchKalmanFilter` with
the constant-velocity model: :class:`KalmanPredictor`, :class:`KalmanUpdater`,
:class:`GNNAssociator` (or :class:`GreedyAssociator`), :class:`SingleDetectionInitiator`,
:class:`MissCountDeleter`. The flow-aware parts run a :class:`flowtrack.motion.MotionBatchFilter`
and let scene flow into the filter: :class:`MotionPredictor` (constant velocity, or constant speed
and yaw rate), :class:`FlowUpdater` (each detection's velocity as a second measurement, each
detection's own position covariance), :class:`MaskedGNNAssociator` (the GNN over the components
each detection measures) and :class:`NLLRAssociator` (the negative log-likelihood ratio against
clutter); the initiator is :class:`SingleDetectionInitiator` with the measured velocity covariance
and, for the turn-rate model, a yaw-rate state.

A helper module of :mod:`flowtrack.tracking`, which exports (and documents) every name here.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from .._validation import as_array, check_psd, cholesky, nonnegative, positive, positive_int, probability
from ..association import (
    assign,
    chi2_gate,
    greedy_assign,
    mahalanobis_from_cholesky,
    masked_mahalanobis,
    nllr_cost,
)
from ..kalman import BatchKalmanFilter, constant_velocity_model

__all__ = [
    "Associator",
    "Confirmer",
    "Deleter",
    "Detections",
    "FlowUpdater",
    "GNNAssociator",
    "GreedyAssociator",
    "Initiator",
    "KalmanPredictor",
    "KalmanUpdater",
    "MaskedGNNAssociator",
    "MeasurementPrediction",
    "MissCountDeleter",
    "MotionPredictor",
    "NLLRAssociator",
    "Predictor",
    "SingleDetectionInitiator",
    "Updater",
]


# ----------------------------------------------------------------------------------------------------
# what the parts pass each other
# ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Detections:
    """One frame's detections, checked by :meth:`~flowtrack.tracking.MultiObjectTracker.step`.

    Attributes
    ----------
    positions : numpy.ndarray, shape (N, d)
        Detected positions.
    velocities : numpy.ndarray, shape (N, d), or None
        Each detection's velocity (scene flow); a NaN row: none.
    velocity_covs : numpy.ndarray, shape (N, d, d), or None
        Covariance of each velocity, a NaN row where there is none. After :meth:`Updater.check`:
        the covariances the updater measures the velocities with, or None when it does not use them.
    position_covs : numpy.ndarray, shape (N, d, d), or None
        Each detection's own position covariance (None: the filter's ``R`` for all).
    yaw_rates : numpy.ndarray, shape (N,), or None
        Each detection's measured yaw rate (rad/s about the turn axis, e.g. the Kabsch angular velocity
        of its flow); NaN: none. A track of the turn-rate model born from the detection starts with it.
    """

    positions: np.ndarray
    velocities: np.ndarray | None = None
    velocity_covs: np.ndarray | None = None
    position_covs: np.ndarray | None = None
    yaw_rates: np.ndarray | None = None

    def __len__(self) -> int:
        return self.positions.shape[0]

    def subset(self, rows: np.ndarray) -> Detections:
        """The detections ``rows`` (an index array), every field alike."""
        return Detections(*(None if a is None else a[rows] for a in
                            (self.positions, self.velocities, self.velocity_covs, self.position_covs,
                             self.yaw_rates)))


class MeasurementPrediction(NamedTuple):
    """What :meth:`Updater.predict_measurements` gives the associator (and the track score).

    ``z_pred`` (M, m) the predicted measurements; ``S`` (M, m, m) their innovation covariances, or
    (M, N, m, m) one per (track, detection) pair; ``measurements`` (N, m) the detections' measurement
    vectors, NaN in the components a detection does not measure; ``has_velocity`` (N,) bool, the
    detections measured with their velocity.
    """

    z_pred: np.ndarray
    S: np.ndarray
    measurements: np.ndarray
    has_velocity: np.ndarray


# ----------------------------------------------------------------------------------------------------
# the interfaces
# ----------------------------------------------------------------------------------------------------
@runtime_checkable
class Predictor(Protocol):
    """The motion model: the filter of every track's state, and its time update."""

    def new_filter(self, dt: float, q: float, R: np.ndarray, dim: int):
        """An empty filter (no tracks) for frame interval ``dt``, acceleration variance ``q`` and
        position noise ``R`` (dim, dim); it has ``x`` (M, n), ``P`` (M, n, n), ``append(x0, P0)``,
        ``keep(mask)``, ``len()`` and what the updater uses."""

    def predict(self, kf) -> None:
        """Predict every track one frame (in place)."""

    def predict_ahead(self, kf, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Every track's prior ``(x (M, n_x), P (M, n_x, n_x))`` ``n`` frames ahead; ``kf`` unchanged."""


@runtime_checkable
class Updater(Protocol):
    """The measurement model: what a detection measures, the measurement prediction and the update."""

    def check(self, detections: Detections) -> Detections:
        """Reject what this updater cannot use (``ValueError`` naming it) and fill in its defaults;
        called before the tracker changes anything."""

    def predict_measurements(self, kf, detections: Detections) -> MeasurementPrediction:
        """The predicted measurements of the (predicted) tracks and the detections' measurements."""

    def update(self, kf, detections: Detections, matches: np.ndarray) -> None:
        """Update the tracks ``matches[:, 0]`` with the detections ``matches[:, 1]`` (in place)."""


@runtime_checkable
class Associator(Protocol):
    """Gating and assignment."""

    def associate(self, z_pred: np.ndarray, S: np.ndarray, detections: np.ndarray):
        """``(matches (K, 2), unmatched_tracks, unmatched_detections)`` from a
        :class:`MeasurementPrediction`'s ``z_pred``, ``S`` and ``measurements`` (array-likes of int)."""


@runtime_checkable
class Initiator(Protocol):
    """Track birth."""

    def initiate(self, detections: np.ndarray, velocities: np.ndarray | None = None,
                 velocity_covs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """States ``x0 (k, n)`` and covariances ``P0 (k, n, n)`` of tracks born from ``k`` detections
        (positions (k, d); velocities and their covariances as in :class:`Detections`, or None). The
        tracker passes ``yaw_rates=`` (k,) as well when :meth:`MultiObjectTracker.step` got them; an
        initiator that starts yaw-rate states should accept it."""


@runtime_checkable
class Deleter(Protocol):
    """Track deletion."""

    def delete(self, hits: np.ndarray, misses: np.ndarray, confirmed: np.ndarray) -> np.ndarray:
        """Bool mask (M,) of the tracks to delete, from their hits, consecutive misses and status."""


@runtime_checkable
class Confirmer(Protocol):
    """Track confirmation (see :mod:`flowtrack.confirmation`)."""

    #: whether :meth:`update_scores` needs each match's log-likelihood
    needs_likelihood: bool
    #: whether :meth:`update_scores` needs ``positions``, ``anchors``, ``anchor_counts``, ``position_cov``
    needs_positions: bool

    def initial_scores(self, k: int) -> np.ndarray:
        """Scores (k,) of newborn tracks."""

    def update_scores(self, scores, matched, log_likelihood, has_velocity, missed, velocities=None,
                      velocity_covs=None, **positions) -> np.ndarray:
        """The scores (M,) after this frame's matches (rows ``matched``) and misses (rows ``missed``)."""

    def decide(self, scores: np.ndarray, hits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(confirm, reject)`` bool masks (M,)."""


# ----------------------------------------------------------------------------------------------------
# position-only parts (BatchKalmanFilter, constant velocity)
# ----------------------------------------------------------------------------------------------------
class KalmanPredictor:
    """The constant-velocity model on a :class:`flowtrack.kalman.BatchKalmanFilter` (the default).

    ``new_filter`` builds the filter of :func:`flowtrack.kalman.constant_velocity_model` (state
    ``[p, v]``); ``predict(kf)`` is one batched time update ``kf.predict()``.
    """

    def new_filter(self, dt: float, q: float, R: np.ndarray, dim: int) -> BatchKalmanFilter:
        F, H, Q, R = constant_velocity_model(dt, q, R, dim)
        n = 2 * dim
        return BatchKalmanFilter(F, H, Q, R, np.zeros((0, n)), np.eye(n))

    def predict(self, kf) -> None:
        kf.predict()

    def predict_ahead(self, kf, n: int) -> tuple[np.ndarray, np.ndarray]:
        ahead = copy.deepcopy(kf)
        for _ in range(n):
            ahead.predict()
        return ahead.x.copy(), ahead.P.copy()


class KalmanUpdater:
    """Position measurements with the filter's ``R``: ``z_pred = H x_i``, ``S_i = H P_i H^T + R`` and
    the Joseph-form update ``kf.update(Z, mask)`` of the matched tracks (the default).

    It measures positions only: a frame with ``velocity_covs`` or ``position_covs`` is rejected
    (:class:`FlowUpdater` uses them); ``velocities`` only start tracks.
    """

    def check(self, detections: Detections) -> Detections:
        if detections.position_covs is not None:
            raise ValueError("position_covs needs the flow-aware filter: MultiObjectTracker(..., "
                             "velocity_update=True), p_detect or motion_model='turn_rate'")
        if detections.velocity_covs is not None:
            raise ValueError("velocity_covs needs MultiObjectTracker(..., velocity_update=True)")
        return detections

    def predict_measurements(self, kf, detections: Detections) -> MeasurementPrediction:
        z_pred, S = kf.predicted_measurements()  # copies: they stay the prior through the update
        return MeasurementPrediction(z_pred, S, detections.positions, np.zeros(len(detections), dtype=bool))

    def update(self, kf, detections: Detections, matches: np.ndarray) -> None:
        M = len(kf)
        if M == 0 or matches.shape[0] == 0:
            return
        Z = np.full((M, kf.dim_z), np.nan)
        Z[matches[:, 0]] = detections.positions[matches[:, 1]]
        mask = np.zeros(M, dtype=bool)
        mask[matches[:, 0]] = True
        kf.update(Z, mask)


class GNNAssociator:
    r"""Global nearest neighbour: Mahalanobis gate, then the optimal gated assignment.

    A pair ``(i, j)`` is admissible when its squared Mahalanobis distance
    :math:`d^2_{ij} = (z_j - \hat z_i)^\top S_i^{-1} (z_j - \hat z_i)` is at most the gate
    :math:`\gamma = F^{-1}_{\chi^2_m}(p)`. Among admissible pairs the assignment minimises the sum of

    .. math::  C_{ij} = d^2_{ij} + \ln\det S_i \quad (\texttt{log\_det=True, default}), \qquad
               C_{ij} = d^2_{ij} \quad (\texttt{log\_det=False}),

    i.e. (up to a constant) :math:`-2 \ln \mathcal N(z_j; \hat z_i, S_i)`, the negative log-likelihood
    of the pair. The :math:`\ln\det S_i` term matters when tracks have very different
    uncertainties: a track born last frame (velocity unknown, large :math:`S`) makes *every* nearby
    detection look close in Mahalanobis terms, and with :math:`d^2` alone it steals the detection of
    an established track whose detection was, by chance, just outside that track's gate one frame
    earlier (an identity switch). When all :math:`S_i` are equal the two costs give the same matching.

    Parameters
    ----------
    gate_prob : float
        Probability that a correct detection falls inside the gate, ``0 < gate_prob < 1``.
    log_det : bool
        Add :math:`\ln\det S_i` to the assignment cost (default ``True``); ``False`` uses the pure
        squared Mahalanobis distance of the syllabus.

    Notes
    -----
    ``gate(m)`` returns the threshold, ``assigner(cost, gate)`` the matching
    (:func:`flowtrack.association.assign`); subclasses override one (see :class:`GreedyAssociator`).
    """

    def __init__(self, gate_prob: float = 0.99, log_det: bool = True):
        self.gate_prob = probability(gate_prob, "gate_prob")
        self.log_det = bool(log_det)
        self._gates: dict[int, float] = {}

    def gate(self, m: int) -> float:
        """The gate for ``m``-dimensional measurements (cached)."""
        if m not in self._gates:
            self._gates[m] = chi2_gate(m, self.gate_prob)
        return self._gates[m]

    def assigner(self, cost: np.ndarray, gate: float):
        """Most admissible pairs, then least cost (:func:`flowtrack.association.assign`)."""
        return assign(cost, gate, validate=False)

    def associate(self, z_pred: np.ndarray, S: np.ndarray, detections: np.ndarray):
        """Return ``(matches (K, 2), unmatched_tracks, unmatched_detections)``."""
        M, N = z_pred.shape[0], detections.shape[0]
        gate = self.gate(detections.shape[1])
        if M == 0 or N == 0:
            return self.assigner(np.zeros((M, N)), gate)
        L = cholesky(S, "S")
        d2 = mahalanobis_from_cholesky(z_pred, L, detections, validate=False)
        if not self.log_det:
            return self.assigner(d2, gate)
        logdet = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)
        cost = np.where(d2 <= gate, d2 + logdet[:, None], np.inf)
        return self.assigner(cost, np.inf)


class GreedyAssociator(GNNAssociator):
    """Like :class:`GNNAssociator` but matches greedily, cheapest admissible pair first.

    Parameters are those of :class:`GNNAssociator`.

    The assignment of :func:`flowtrack.association.greedy_assign`; a lesson swaps it in to show
    where greedy matching loses pairs or swaps identities.
    """

    def assigner(self, cost: np.ndarray, gate: float):
        return greedy_assign(cost, gate, validate=False)


class SingleDetectionInitiator:
    r"""Start a track from one detection: position = detection, velocity = flow velocity or 0.

    .. math::  x_0 = \begin{bmatrix} z \\ v \end{bmatrix}, \qquad
               P_0 = \begin{bmatrix} R & 0 \\ 0 & \Sigma_v \end{bmatrix},

    with :math:`v` the detection's scene-flow velocity and :math:`\Sigma_v` its measured covariance
    (``velocity_covs``) when given, else ``flow_velocity_var`` :math:`I`; without a velocity (none
    given, or a NaN row) :math:`v = 0` and :math:`\Sigma_v` = ``velocity_var`` :math:`I`. With
    ``yaw_rate_var`` the state is the turn-rate model's :math:`[p, v, \omega]`: :math:`\omega` is the
    detection's measured yaw rate (``yaw_rates``, e.g. the Kabsch angular velocity of its flow about
    the turn axis) with variance ``measured_yaw_rate_var``, or 0 with variance ``yaw_rate_var``
    without one (none given, or NaN).

    Parameters
    ----------
    R : numpy.ndarray, shape (dim, dim)
        Measurement noise covariance (the position uncertainty of one detection).
    velocity_var : float
        Velocity variance without a velocity measurement (> 0): covers the speeds expected.
    flow_velocity_var : float
        Velocity variance of a scene-flow velocity without a covariance (> 0), usually much smaller.
    yaw_rate_var : float, optional
        Initial yaw-rate variance ((rad/s)², > 0) of the turn-rate model's state without a measured
        yaw rate; None: ``[p, v]``.
    measured_yaw_rate_var : float, optional
        Initial variance ((rad/s)², > 0) of a measured yaw rate; default ``yaw_rate_var``.
    """

    def __init__(self, R: np.ndarray, velocity_var: float, flow_velocity_var: float,
                 yaw_rate_var: float | None = None, measured_yaw_rate_var: float | None = None):
        self.R = np.asarray(R, dtype=float)
        self.dim = self.R.shape[0]
        self.velocity_var = positive(velocity_var, "velocity_var")
        self.flow_velocity_var = positive(flow_velocity_var, "flow_velocity_var")
        self.yaw_rate_var = None if yaw_rate_var is None else positive(yaw_rate_var, "omega_var")
        self.measured_yaw_rate_var = (self.yaw_rate_var if measured_yaw_rate_var is None
                                      else positive(measured_yaw_rate_var, "measured_omega_var"))

    def initiate(self, detections: np.ndarray, velocities: np.ndarray | None = None,
                 velocity_covs: np.ndarray | None = None, yaw_rates: np.ndarray | None = None):
        """Return ``x0 (k, n)`` and ``P0 (k, n, n)``; a NaN row of ``velocities`` (or of
        ``velocity_covs``) or a NaN yaw rate means unknown (n = 2d, or 2d + 1 with ``yaw_rate_var``;
        ``yaw_rates`` (k,) is used only then)."""
        k, d = detections.shape
        x0 = np.zeros((k, 2 * d))
        x0[:, :d] = detections
        P0 = np.zeros((k, 2 * d, 2 * d))
        P0[:, :d, :d] = self.R
        var = np.full(k, self.velocity_var)
        if velocities is not None:
            known = ~np.isnan(velocities).any(axis=1)
            x0[known, d:] = velocities[known]
            var[known] = self.flow_velocity_var
        P0[:, d:, d:] = var[:, None, None] * np.eye(d)
        if velocity_covs is not None:
            measured = np.isfinite(velocity_covs).all(axis=(1, 2))
            P0[measured, d:, d:] = velocity_covs[measured]
        if self.yaw_rate_var is None:
            return x0, P0
        n = 2 * d
        x1 = np.zeros((k, n + 1))
        x1[:, :n] = x0
        P1 = np.zeros((k, n + 1, n + 1))
        P1[:, :n, :n] = P0
        P1[:, n, n] = self.yaw_rate_var
        if yaw_rates is not None:
            w = np.asarray(yaw_rates, dtype=float).reshape(k)
            measured = np.isfinite(w)
            x1[measured, n] = w[measured]
            P1[measured, n, n] = self.measured_yaw_rate_var
        return x1, P1


class MissCountDeleter:
    r"""Delete tentative tracks at their first miss and confirmed tracks after ``max_misses`` misses.

    ``delete(hits, misses, confirmed)`` returns the bool mask
    ``(misses > 0 & ~confirmed) | (misses > max_misses)``: a confirmed track survives up to
    ``max_misses`` consecutive misses (coasting) and is deleted at the ``max_misses + 1``-th.

    With ``coast_per_hit`` :math:`c` a confirmed track coasts at most :math:`\min(\text{max\_misses},
    c \cdot \text{hits})` frames: a track seen twice and lost has a velocity from two detections, and
    coasting it for long reports a position that drifts off along that velocity (every coasting row is
    a claim of where an object is). An object hidden for long was seen for long first.

    >>> d = MissCountDeleter(max_misses=10, coast_per_hit=1.0)
    >>> d.delete(np.array([2, 20, 20]), np.array([3, 3, 11]), np.array([True, True, True])).tolist()
    [True, False, True]
    """

    def __init__(self, max_misses: int = 3, coast_per_hit: float | None = None):
        self.max_misses = positive_int(max_misses, "max_misses", minimum=0)
        self.coast_per_hit = None if coast_per_hit is None else positive(coast_per_hit, "coast_per_hit")

    def delete(self, hits: np.ndarray, misses: np.ndarray, confirmed: np.ndarray) -> np.ndarray:
        limit = self.max_misses
        if self.coast_per_hit is not None:
            limit = np.minimum(limit, self.coast_per_hit * np.asarray(hits))
        return ((misses > 0) & ~confirmed) | (misses > limit)


# ----------------------------------------------------------------------------------------------------
# flow-aware parts (MotionBatchFilter): velocity measurements, NLLR association, turn-rate model
# ----------------------------------------------------------------------------------------------------
class MotionPredictor:
    r"""The motion models of :class:`flowtrack.motion.MotionBatchFilter`: constant velocity (state
    ``[p, v]``) or constant speed and yaw rate (``[p, v, omega]``, an EKF, which extrapolates a turning
    object along its arc).

    Parameters
    ----------
    motion_model : {"cv", "turn_rate"}
    q_omega : float, >= 0
        Yaw-rate random walk of the turn-rate model ((rad/s)² per s).
    turn_axis : array_like, shape (3,), optional
        Normal of the plane of motion of the 3-D turn-rate model (default z); in the camera frame,
        the table's normal.
    """

    def __init__(self, motion_model: str = "cv", q_omega: float = 1.0, turn_axis=None):
        if motion_model not in ("cv", "turn_rate"):
            raise ValueError(f"motion_model must be 'cv' or 'turn_rate', got {motion_model!r}")
        self.motion_model = motion_model
        self.q_omega = nonnegative(q_omega, "q_omega")
        self.turn_axis = turn_axis

    def new_filter(self, dt: float, q: float, R: np.ndarray, dim: int):
        from ..motion import MotionBatchFilter

        return MotionBatchFilter(dt, q, R, dim, model=self.motion_model, q_omega=self.q_omega,
                                 axis=self.turn_axis)

    def predict(self, kf) -> None:
        kf.predict()

    def predict_ahead(self, kf, n: int) -> tuple[np.ndarray, np.ndarray]:
        return kf.predicted(n)


class FlowUpdater:
    r"""Positions with each detection's own covariance and, with ``velocity_update``, scene-flow
    velocities as a second measurement (on a :class:`flowtrack.motion.MotionBatchFilter`).

    A detection with a velocity :math:`z_v` and its covariance :math:`R_v` updates its track with the
    stacked measurement :math:`[z; z_v] = [H_p; H_v]\,x + r`, :math:`r \sim \mathcal N(0,
    \mathrm{blockdiag}(R_j, R_v))`, one without a velocity with its position alone (Joseph form);
    :math:`R_j` is the detection's ``position_covs`` row, or the filter's ``R``. The predicted
    measurements are then per (track, detection) pair: :math:`\hat z_i = [\hat p_i; \hat v_i]` and
    :math:`S_{ij} = H_j P_i H_j^\top + \mathrm{blockdiag}(R_j, R_{v,j})` on the components detection
    j measures (the others NaN in its measurement vector).

    Parameters
    ----------
    dim : int
        Spatial dimension.
    velocity_cov : float or array_like, shape (dim, dim)
        Velocity measurement covariance of the detections that come without ``velocity_covs``.
    velocity_update : bool
        Use the velocities as measurements (default True); False: positions only, with their own
        covariances.
    """

    def __init__(self, dim: int, velocity_cov, velocity_update: bool = True):
        self.dim = positive_int(dim, "dim")
        Rv = as_array(velocity_cov, "velocity_cov")
        if Rv.ndim == 0:
            Rv = positive(float(Rv), "velocity_cov") * np.eye(self.dim)
        elif Rv.shape != (self.dim, self.dim):
            raise ValueError(f"velocity_cov must be a number or of shape ({self.dim}, {self.dim}), "
                             f"got {Rv.shape}")
        check_psd(Rv, "velocity_cov", strict=True)
        self.velocity_cov = Rv
        self.velocity_update = bool(velocity_update)

    def check(self, detections: Detections) -> Detections:
        """Each velocity's covariance: its ``velocity_covs`` row where finite, else ``velocity_cov``;
        NaN where the detection has no velocity; None without ``velocity_update`` or velocities."""
        V = detections.velocities
        if not self.velocity_update or V is None:
            return replace(detections, velocity_covs=None)
        N, d = len(detections), self.dim
        Rv = np.broadcast_to(self.velocity_cov, (N, d, d)).copy()
        if detections.velocity_covs is not None:
            given = detections.velocity_covs
            ok = np.isfinite(given).all(axis=(1, 2))
            Rv[ok] = given[ok]
        Rv[np.isnan(V).any(axis=1)] = np.nan
        return replace(detections, velocity_covs=Rv)

    def predict_measurements(self, kf, detections: Detections) -> MeasurementPrediction:
        Z, V, Rv, Rp = (detections.positions, detections.velocities, detections.velocity_covs,
                        detections.position_covs)
        d = self.dim
        if Rv is not None:
            # joint innovation covariances per pair; a detection without a velocity is scored on its
            # position alone (its velocity components are NaN, which the associators leave out)
            _, S, m = kf.joint_innovation(Z, V, Rv, Rp)
            has_v = m == 2 * d
            Zj = np.concatenate([Z, np.where(has_v[:, None], V, np.nan)], axis=1)
            return MeasurementPrediction(kf.x[:, : 2 * d].copy(), S, Zj, has_v)  # x copied: the prior
        z_pred, S = kf.predicted_measurements()
        if Rp is not None:  # per pair: the track's P with the detection's own covariance
            S = kf.P[:, None, :d, :d] + Rp[None]
        return MeasurementPrediction(z_pred, S, Z, np.zeros(len(Z), dtype=bool))

    def update(self, kf, detections: Detections, matches: np.ndarray) -> None:
        if matches.shape[0] == 0:
            return
        Z, V, Rv, Rp = (detections.positions, detections.velocities, detections.velocity_covs,
                        detections.position_covs)
        M, d = len(kf), self.dim
        Zm = np.full((M, d), np.nan)
        Zm[matches[:, 0]] = Z[matches[:, 1]]
        mask = np.zeros(M, dtype=bool)
        mask[matches[:, 0]] = True
        Rpm = None
        if Rp is not None:
            Rpm = np.broadcast_to(kf.R, (M, d, d)).copy()
            Rpm[matches[:, 0]] = Rp[matches[:, 1]]
        if Rv is None:
            kf.update_joint(Zm, None, None, mask, Rpm)
            return
        Vm = np.full((M, d), np.nan)
        Rvm = np.full((M, d, d), np.nan)
        Vm[matches[:, 0]] = V[matches[:, 1]]
        Rvm[matches[:, 0]] = Rv[matches[:, 1]]
        kf.update_joint(Zm, Vm, Rvm, mask, Rpm)


class MaskedGNNAssociator(GNNAssociator):
    r""":class:`GNNAssociator` over the components each detection measures, with per-pair ``S``.

    :math:`d^2_{ij}` and :math:`\ln\det S_{ij}` are taken on the measured components :math:`o_j` of
    detection j (:func:`flowtrack.association.masked_mahalanobis`), and each detection is gated at
    :math:`F^{-1}_{\chi^2_{|o_j|}}(p)`: a detection with a velocity is gated on its joint
    position-velocity innovation (2 ``dim`` degrees of freedom), one without on its position. The
    association of :class:`FlowUpdater`'s measurements. Parameters are those of :class:`GNNAssociator`.
    """

    def associate(self, z_pred: np.ndarray, S: np.ndarray, detections: np.ndarray):
        M, N = z_pred.shape[0], detections.shape[0]
        if M == 0 or N == 0:
            return self.assigner(np.zeros((M, N)), np.inf)
        d2, logdet, dof = masked_mahalanobis(z_pred, S, detections)
        gates = np.array([self.gate(int(k)) for k in dof])
        cost = np.where(d2 <= gates[None, :], d2 + logdet if self.log_det else d2, np.inf)
        return self.assigner(cost, np.inf)


class NLLRAssociator:
    r"""Associate by the negative log-likelihood ratio against clutter (the course's one association
    objective, :func:`flowtrack.association.nllr_cost`).

    .. math::  C_{ij} = -\ln \frac{P_D\, \mathcal N(z_j; \hat z_i, S_{ij})}{(1 - P_D)\, \lambda_j}

    inside the chi-square gate of each detection's measured components, and the matching of least
    total cost (``assign(..., objective="min_cost")``: a pair is taken only when it is likelier than
    "missed and clutter"). :math:`\lambda_j` is the clutter density in detection j's measurement
    space: ``clutter_density`` (per m^dim) for a position, times ``velocity_clutter_density`` (per
    (m/s)^dim) for a position with a velocity.

    Parameters
    ----------
    p_detect : float, 0 < p_detect < 1
    clutter_density : float, > 0
    dim : int
        Spatial dimension: a detection measuring more than ``dim`` components carries a velocity.
    velocity_clutter_density : float, > 0
    gate_prob : float, 0 < gate_prob < 1
    """

    def __init__(self, p_detect: float, clutter_density: float, *, dim: int,
                 velocity_clutter_density: float = 1.0, gate_prob: float = 0.99):
        self.p_detect = probability(p_detect, "p_detect")
        self.clutter_density = positive(clutter_density, "clutter_density")
        self.velocity_clutter_density = positive(velocity_clutter_density, "velocity_clutter_density")
        self.dim = positive_int(dim, "dim")
        self.gate_prob = probability(gate_prob, "gate_prob")

    def associate(self, z_pred: np.ndarray, S: np.ndarray, detections: np.ndarray):
        M, N = z_pred.shape[0], detections.shape[0]
        if M == 0 or N == 0:
            return assign(np.zeros((M, N)))
        has_v = (~np.isnan(detections)).sum(axis=1) > self.dim
        lam = np.where(has_v, self.clutter_density * self.velocity_clutter_density, self.clutter_density)
        cost = nllr_cost(z_pred, S, detections, self.p_detect, lam, gate_prob=self.gate_prob)
        return assign(cost, objective="min_cost")
