r"""A multi-object tracker built from small swappable parts (syllabus section 7).

One call of :meth:`MultiObjectTracker.step` runs the loop of the syllabus' second flowchart:

1. **Predict** every track with the constant-velocity model,
   :math:`\hat x_i \leftarrow F \hat x_i`, :math:`P_i \leftarrow F P_i F^\top + Q` (all tracks at
   once in a :class:`~flowtrack.kalman.BatchKalmanFilter`).
2. **Associate**: build the squared Mahalanobis costs
   :math:`C_{ij} = (z_j - H\hat x_i)^\top S_i^{-1}(z_j - H\hat x_i)`, :math:`S_i = HP_iH^\top + R`,
   gate them at :math:`\gamma = F^{-1}_{\chi^2_d}(p)` and solve the gated assignment
   (:func:`flowtrack.association.assign`: most pairs, then least cost). The default
   :class:`GNNAssociator` minimises :math:`C_{ij} + \ln\det S_i` (the pair's negative
   log-likelihood) so that a newborn, very uncertain track cannot steal the detection of an
   established one; ``GNNAssociator(log_det=False)`` uses :math:`C_{ij}` alone, as the syllabus.
3. **Update** the assigned tracks with their detections (Joseph-form Kalman update).
4. **Manage** births, occlusions and deletions:

   - every unassigned detection starts a *tentative* track (position = detection, velocity = the
     detection's scene-flow velocity if given, else 0 with a large variance);
   - a track becomes *confirmed* once it has ``min_hits`` assigned detections (the birth detection
     counts as the first; :class:`HitCountConfirmer`), or, with :class:`SequentialScoreConfirmer`,
     once its log-likelihood ratio of "object" against "clutter" passes Wald's threshold; a
     tentative track is deleted at its first miss;
   - a confirmed track without a detection is *coasting* (occluded): it is only predicted. It is
     deleted when its consecutive misses exceed ``max_misses``, i.e. at the ``max_misses + 1``-th
     consecutive miss; an occlusion of up to ``max_misses`` frames keeps the track and its id;
   - with ``reacquire_radius`` r, a coasting confirmed track *re-acquires* its object: an unassigned
     detection within r of it (outside its gate: its velocity was learnt while the object was being
     hidden, from a shrinking visible surface, or the visible part jumped) restarts the track from
     that detection's birth state instead of starting a new track, and the track keeps its id
     (nearest pairs first, each track and detection once);
   - with ``birth_exclusion_radius`` r, an unassigned detection within r of a confirmed track that
     was detected in the same frame starts no track: it is another piece of that object.

Track ids come from a counter and are never reused.

Scene flow can enter the filter beyond the birth velocity (issue 15; keyword arguments, off by
default): ``velocity_update=True`` uses each detection's velocity (with its covariance,
``step(..., velocity_covs=)``) as a measurement next to its position and gates the joint innovation;
``p_detect`` and ``clutter_density`` associate by the negative log-likelihood ratio against clutter
(:func:`flowtrack.association.nllr_cost`, the course's one association objective); and
``motion_model="turn_rate"`` predicts with constant speed and yaw rate (:mod:`flowtrack.motion`, an
EKF), so a turning object is extrapolated along its arc; ``step(..., position_covs=)`` gives a
detection its own position covariance (an occluded object's visible centroid is off its centre).
:meth:`MultiObjectTracker.history` gives the per-frame tracks that
:func:`flowtrack.tracking_io.write_tracks_csv` exports.

The parts have tiny interfaces, in the spirit of Stone Soup, so a lesson can swap one:

=================  =========================================================================
part               interface
=================  =========================================================================
predictor          ``predict(kf) -> (z_pred (M,m), S (M,m,m))``
associator         ``associate(z_pred, S, detections) -> (matches (K,2), unmatched_tracks,
                   unmatched_detections)``
updater            ``update(kf, detections, matches) -> None``
initiator          ``initiate(detections (k,d), velocities (k,d) or None) -> (x0 (k,n), P0 (k,n,n))``
deleter            ``delete(hits (M,), misses (M,), confirmed (M,)) -> bool mask (M,)``
confirmer          ``initial_scores(k) -> (k,)``; ``update_scores(scores (M,), matched (K,),
                   log_likelihood (K,), has_velocity (K,), missed, velocities=None (K, d),
                   velocity_covs=None (K, d, d)) -> (M,)``;
                   ``decide(scores (M,), hits (M,)) -> (confirm (M,), reject (M,))``;
                   ``needs_likelihood`` (bool); with ``needs_positions`` (bool, optional) also
                   ``positions`` (K, d), ``anchors`` (M, d) (mean of each track's detections so far),
                   ``anchor_counts`` (M,) and ``position_cov`` (d, d) (the tracker's R)
=================  =========================================================================

Examples
--------
Two objects moving in opposite directions, observed exactly:

>>> import numpy as np
>>> trk = MultiObjectTracker(dt=1.0, q=0.01, r=0.01, dim=2)
>>> for t in range(5):
...     tracks = trk.step(np.array([[t, 0.0], [10.0 - t, 5.0]]))
>>> [(tr.id, tr.status) for tr in tracks]
[(0, 'confirmed'), (1, 'confirmed')]
>>> np.round(tracks[1].velocity, 2)
array([-1.,  0.])
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ._validation import (
    as_array,
    check_psd,
    cholesky,
    nonnegative,
    positive,
    positive_int,
    probability,
    spatial_dim,
)
from .association import assign, chi2_gate, greedy_assign, mahalanobis_from_cholesky
from .confirmation import HitCountConfirmer, SequentialScoreConfirmer, pair_log_likelihood
from .kalman import BatchKalmanFilter, constant_velocity_model

__all__ = [
    "GNNAssociator",
    "GreedyAssociator",
    "HitCountConfirmer",
    "KalmanPredictor",
    "KalmanUpdater",
    "MissCountDeleter",
    "MultiObjectTracker",
    "SequentialScoreConfirmer",
    "SingleDetectionInitiator",
    "Track",
    "pair_log_likelihood",
]

STATUSES = ("tentative", "confirmed", "coasting")


# ----------------------------------------------------------------------------------------------------
# Track
# ----------------------------------------------------------------------------------------------------
@dataclass(slots=True)
class Track:
    """A snapshot of one track after a :meth:`MultiObjectTracker.step`.

    Attributes
    ----------
    id : int
        Track id, unique over the tracker's lifetime (never reused).
    x : numpy.ndarray, shape (2*dim,)
        Posterior state ``[p_1..p_dim, v_1..v_dim]`` (read-only).
    P : numpy.ndarray, shape (2*dim, 2*dim)
        Posterior covariance (read-only).
    status : str
        ``"tentative"`` (not yet confirmed: ``min_hits`` detections, or the confirmer's rule),
        ``"confirmed"`` (confirmed and detected this frame) or ``"coasting"`` (confirmed, missed this
        frame: predicted only).
    hits : int
        Number of detections assigned to the track, the birth detection included.
    misses : int
        Consecutive frames without a detection (0 when detected this frame).
    age : int
        Frames since birth (0 in the birth frame).
    """

    id: int
    x: np.ndarray
    P: np.ndarray
    status: str
    hits: int
    misses: int
    age: int

    @property
    def dim(self) -> int:
        """Number of spatial axes."""
        return self.x.shape[0] // 2

    @property
    def position(self) -> np.ndarray:
        """Estimated position, shape (dim,)."""
        return self.x[: self.dim]

    @property
    def velocity(self) -> np.ndarray:
        """Estimated velocity, shape (dim,)."""
        return self.x[self.dim : 2 * self.dim]

    @property
    def yaw_rate(self) -> float | None:
        """Yaw rate (rad/s) of the turn-rate model (state ``[p, v, omega]``), else None."""
        return float(self.x[-1]) if self.x.shape[0] % 2 else None


# ----------------------------------------------------------------------------------------------------
# parts
# ----------------------------------------------------------------------------------------------------
class KalmanPredictor:
    """Predict every track with the filter's motion model; return the predicted measurements.

    ``predict(kf)`` calls ``kf.predict()`` (one batched time update) and returns
    ``kf.predicted_measurements()``: ``z_pred = H x_i`` (M, m) and ``S_i = H P_i H^T + R`` (M, m, m).
    """

    def predict(self, kf: BatchKalmanFilter):
        kf.predict()
        return kf.predicted_measurements()


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


class KalmanUpdater:
    """Update the matched tracks: ``kf.update(Z, mask)`` with one detection per matched track."""

    def update(self, kf: BatchKalmanFilter, detections: np.ndarray, matches: np.ndarray) -> None:
        M = len(kf)
        if M == 0 or matches.shape[0] == 0:
            return
        Z = np.full((M, kf.dim_z), np.nan)
        Z[matches[:, 0]] = detections[matches[:, 1]]
        mask = np.zeros(M, dtype=bool)
        mask[matches[:, 0]] = True
        kf.update(Z, mask)


class SingleDetectionInitiator:
    r"""Start a track from one detection: position = detection, velocity = flow velocity or 0.

    .. math::  x_0 = \begin{bmatrix} z \\ v \end{bmatrix}, \qquad
               P_0 = \begin{bmatrix} R & 0 \\ 0 & \sigma_v^2 I \end{bmatrix},

    with :math:`v` the detection's scene-flow velocity and :math:`\sigma_v^2` = ``flow_velocity_var``
    when it is given, else (no velocities, or a NaN row) :math:`v = 0` and
    :math:`\sigma_v^2` = ``velocity_var``.

    Parameters
    ----------
    R : numpy.ndarray, shape (dim, dim)
        Measurement noise covariance (the position uncertainty of one detection).
    velocity_var : float
        Velocity variance without a velocity measurement (> 0): covers the speeds expected.
    flow_velocity_var : float
        Velocity variance of a scene-flow velocity (> 0), usually much smaller.
    """

    def __init__(self, R: np.ndarray, velocity_var: float, flow_velocity_var: float):
        self.R = np.asarray(R, dtype=float)
        self.dim = self.R.shape[0]
        self.velocity_var = positive(velocity_var, "velocity_var")
        self.flow_velocity_var = positive(flow_velocity_var, "flow_velocity_var")

    def initiate(self, detections: np.ndarray, velocities: np.ndarray | None):
        """Return ``x0 (k, 2d)`` and ``P0 (k, 2d, 2d)``; a NaN row of ``velocities`` means unknown."""
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
        return x0, P0


class MissCountDeleter:
    """Delete tentative tracks at their first miss and confirmed tracks after ``max_misses`` misses.

    ``delete(hits, misses, confirmed)`` returns the bool mask
    ``(misses > 0 & ~confirmed) | (misses > max_misses)``: a confirmed track survives up to
    ``max_misses`` consecutive misses (coasting) and is deleted at the ``max_misses + 1``-th.
    """

    def __init__(self, max_misses: int = 3):
        self.max_misses = positive_int(max_misses, "max_misses", minimum=0)

    def delete(self, hits: np.ndarray, misses: np.ndarray, confirmed: np.ndarray) -> np.ndarray:
        return ((misses > 0) & ~confirmed) | (misses > self.max_misses)



# ----------------------------------------------------------------------------------------------------
# tracker
# ----------------------------------------------------------------------------------------------------
class MultiObjectTracker:
    r"""Constant-velocity multi-object tracker with gated global-nearest-neighbour association.

    Parameters
    ----------
    dt : float
        Time between frames (> 0).
    q : float
        Acceleration variance of the white-noise-acceleration model (>= 0).
    r : float or array_like, shape (dim, dim)
        Detection (position) noise variance (> 0) or covariance.
    dim : int
        Spatial dimension, 2 or 3 (1 also works).
    gate_prob : float
        Gate probability of the default :class:`GNNAssociator` (``0 < gate_prob < 1``).
    min_hits : int
        Detections needed to confirm a track (>= 1; 1 confirms at birth).
    max_misses : int
        Consecutive misses a confirmed track survives (>= 0); deleted at ``max_misses + 1``.
    velocity_var : float, optional
        Initial velocity variance of a track born without a velocity; default
        :math:`(10\,\bar\sigma_r/\Delta t)^2` (ten noise standard deviations per frame,
        :math:`\bar\sigma_r^2` the mean of ``diag(R)``).
    flow_velocity_var : float, optional
        Initial velocity variance of a track born with a scene-flow velocity; default
        :math:`\bar\sigma_r^2/\Delta t^2`.
    max_history : int, optional
        Keep the posterior of the last ``max_history`` frames for :meth:`trajectories` (default:
        all frames; the memory grows by about ``M * (2d + 4d^2) * 8`` bytes per frame).
    velocity_update : bool, optional
        Use the detections' velocities (scene flow) as measurements in the update, not only to start
        tracks (default False: today's behaviour). A detection with a velocity and a velocity
        covariance updates its track with the stacked position-velocity measurement, one without
        with its position alone (Joseph form, :class:`flowtrack.motion.MotionBatchFilter`), and the
        association scores and gates the joint innovation (chi-square with 2 ``dim`` degrees of
        freedom for such a detection, ``dim`` for the others).
    velocity_cov : float or array_like, shape (dim, dim), optional
        Velocity measurement covariance of the detections for which :meth:`step` gets no
        ``velocity_covs`` (default: ``flow_velocity_var * I``).
    p_detect, clutter_density : float, optional
        Associate by the negative log-likelihood ratio (:func:`flowtrack.association.nllr_cost`,
        ``assign(..., objective="min_cost")``) with detection probability ``p_detect`` and clutter
        density ``clutter_density`` (per m^dim); both or neither. Default: the Mahalanobis
        :class:`GNNAssociator`.
    velocity_clutter_density : float
        Clutter density in velocity space (per (m/s)^dim) for detections that carry a velocity
        (their joint clutter density is the product); default 1.
    motion_model : {"cv", "turn_rate"}
        ``"turn_rate"``: the coordinated-turn model of :mod:`flowtrack.motion` (state
        ``[p, v, omega]``, an EKF), which extrapolates a turning object along its arc.
    q_omega, omega_var : float
        Yaw-rate random walk ((rad/s)^2 per s, default 1) and initial yaw-rate variance ((rad/s)^2,
        default 4) of the turn-rate model.
    turn_axis : array_like, shape (3,), optional
        Normal of the plane of motion (3-D turn-rate model; default z). In the camera frame pass the
        table's (support plane's) normal: the camera's z is its optical axis, and a wrong plane turns
        the velocity the wrong way.
    reacquire_radius : float, optional
        Re-acquisition after an occlusion (m; see the module docstring): a coasting confirmed track
        takes the nearest unassigned detection within this distance and restarts from it, keeping
        its id. Default None: off.
    birth_exclusion_radius : float, optional
        No track is started from a detection within this distance (m) of a confirmed track that was
        detected in the same frame: it is another piece of that object (a part cut off by an
        occluder, a face that moves differently), not a new one. Coasting tracks re-acquire first
        (``reacquire_radius``). Default None: every unassigned detection starts a track.

    With any of ``velocity_update``, ``p_detect`` or ``motion_model="turn_rate"`` the tracker runs on
    a :class:`flowtrack.motion.MotionBatchFilter` and its own association and update (the
    ``predictor``, ``associator`` and ``updater`` parts are then not used; ``initiator`` and
    ``deleter`` are).
    predictor, associator, updater, initiator, deleter, confirmer : optional
        Replacement parts (see the module docstring); defaults :class:`KalmanPredictor`,
        :class:`GNNAssociator` ``(gate_prob)``, :class:`KalmanUpdater`,
        :class:`SingleDetectionInitiator`, :class:`MissCountDeleter` ``(max_misses)``,
        :class:`HitCountConfirmer` ``(min_hits)``. A custom associator brings its own gate
        (``gate_prob`` is then unused), a custom deleter or confirmer its own rule (``min_hits`` is
        then unused); :class:`SequentialScoreConfirmer` confirms by the track score.

    Attributes
    ----------
    kf : BatchKalmanFilter
        The state of all live tracks (rows aligned with :attr:`tracks`).
    frame : int
        Index of the last processed frame (-1 before the first :meth:`step`).

    Notes
    -----
    :meth:`step` returns the *reported* tracks, those with status ``"confirmed"`` or ``"coasting"``
    (what a tracker outputs, as SORT does); :attr:`tracks` lists every live track, tentative ones
    included. :meth:`trajectories` gives each track's posterior ``(frame, x, P)`` over its life.

    Examples
    --------
    >>> import numpy as np
    >>> trk = MultiObjectTracker(dt=0.1, q=1.0, r=1e-4, dim=3, min_hits=2)
    >>> trk.step(np.array([[0.0, 0.0, 1.0]]))      # first sighting: tentative, not reported
    []
    >>> [t.status for t in trk.tracks]
    ['tentative']
    >>> [(t.id, t.status, t.hits) for t in trk.step(np.array([[0.01, 0.0, 1.0]]))]
    [(0, 'confirmed', 2)]
    >>> [(t.id, t.status, t.misses) for t in trk.step(np.empty((0, 3)))]   # occluded
    [(0, 'coasting', 1)]
    """

    def __init__(
        self,
        dt,
        q,
        r,
        dim=2,
        gate_prob=0.99,
        min_hits=2,
        max_misses=3,
        *,
        velocity_var=None,
        flow_velocity_var=None,
        predictor=None,
        associator=None,
        updater=None,
        initiator=None,
        deleter=None,
        confirmer=None,
        max_history=None,
        velocity_update=False,
        velocity_cov=None,
        p_detect=None,
        clutter_density=None,
        velocity_clutter_density=1.0,
        motion_model="cv",
        q_omega=1.0,
        omega_var=4.0,
        turn_axis=None,
        reacquire_radius=None,
        birth_exclusion_radius=None,
    ):
        self.dt = positive(dt, "dt")
        self.reacquire_radius = None if reacquire_radius is None else positive(reacquire_radius,
                                                                               "reacquire_radius")
        self.birth_exclusion_radius = (None if birth_exclusion_radius is None
                                       else positive(birth_exclusion_radius, "birth_exclusion_radius"))
        self.q = nonnegative(q, "q")
        self.dim = spatial_dim(dim, "dim")
        F, H, Q, R = constant_velocity_model(self.dt, self.q, r, self.dim)
        self.min_hits = positive_int(min_hits, "min_hits")
        self.max_misses = positive_int(max_misses, "max_misses", minimum=0)
        self.gate_prob = probability(gate_prob, "gate_prob")
        sr2 = float(np.mean(np.diag(R)))
        velocity_var = (100.0 * sr2 / self.dt**2) if velocity_var is None else velocity_var
        flow_velocity_var = (sr2 / self.dt**2) if flow_velocity_var is None else flow_velocity_var
        self.predictor = predictor if predictor is not None else KalmanPredictor()
        self.associator = associator if associator is not None else GNNAssociator(self.gate_prob)
        self.updater = updater if updater is not None else KalmanUpdater()
        self.initiator = (
            initiator
            if initiator is not None
            else SingleDetectionInitiator(R, velocity_var=velocity_var, flow_velocity_var=flow_velocity_var)
        )
        self.deleter = deleter if deleter is not None else MissCountDeleter(self.max_misses)
        self.confirmer = confirmer if confirmer is not None else HitCountConfirmer(self.min_hits)
        n = 2 * self.dim
        self.kf = BatchKalmanFilter(F, H, Q, R, np.zeros((0, n)), np.eye(n))
        self._ids = np.zeros(0, dtype=np.int64)
        self._hits = np.zeros(0, dtype=np.int64)
        self._misses = np.zeros(0, dtype=np.int64)
        self._age = np.zeros(0, dtype=np.int64)
        self._confirmed = np.zeros(0, dtype=bool)
        self._scores = np.zeros(0)
        # sum and number of each track's detected positions (the static-artefact anchor of the score)
        self._anchor_sum = np.zeros((0, self.dim))
        self._anchor_n = np.zeros(0, dtype=np.int64)
        self._R = np.asarray(R, dtype=float)
        self._next_id = 0
        self.frame = -1
        # one record per frame: (frame, ids (M,), x (M,n), P (M,n,n), status codes (M,))
        if max_history is not None:
            max_history = positive_int(max_history, "max_history")
        self._log: deque[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
        self._log = deque(maxlen=max_history)
        self._counts: deque[np.ndarray] = deque(maxlen=max_history)  # per frame (3, M): hits, misses, age
        self._snapshot: list[Track] = []
        self._flow = None
        if velocity_update or p_detect is not None or clutter_density is not None or motion_model != "cv":
            self._flow = _FlowOptions(self, R, flow_velocity_var, velocity_update, velocity_cov, p_detect,
                                      clutter_density, velocity_clutter_density, motion_model, q_omega,
                                      omega_var, turn_axis)
            self.kf = self._flow.make_filter()

    # -- input ---------------------------------------------------------------------------------------
    def _check_detections(self, detections, velocities):
        d = self.dim
        Z = as_array(detections, "detections")
        if Z.size == 0 and Z.ndim <= 1:
            Z = Z.reshape(0, d)
        if Z.ndim != 2 or Z.shape[1] != d:
            raise ValueError(f"detections must have shape (N, {d}), got {Z.shape}")
        V = None
        if velocities is not None:
            V = as_array(velocities, "velocities", allow_nan=True)
            if V.size == 0 and V.ndim <= 1:
                V = V.reshape(0, d)
            if V.shape != Z.shape:
                raise ValueError(
                    f"velocities must have shape ({Z.shape[0]}, {d}) like detections, got {V.shape}"
                )
        return Z, V

    # -- the loop ------------------------------------------------------------------------------------
    def _reacquire_at_birth(self, Z, x0, P0) -> np.ndarray:
        """Re-acquisition of unassigned detections: each coasting confirmed track takes the nearest
        detection within ``reacquire_radius`` (nearest pairs first) and restarts from its birth state
        ``(x0, P0)``, keeping its id; returns the mask of the detections taken."""
        taken = np.zeros(len(Z), dtype=bool)
        coast = np.flatnonzero(self._confirmed & (self._misses > 0))
        if coast.size == 0 or len(Z) == 0:
            return taken
        x, P = np.array(self.kf.x), np.array(self.kf.P)
        d = self.dim
        D = np.linalg.norm(Z[:, None, :d] - x[None, coast, :d], axis=2)
        used = set()
        for flat in np.argsort(D, axis=None, kind="stable"):
            a, b = divmod(int(flat), coast.size)
            if D[a, b] > self.reacquire_radius:
                break
            if taken[a] or b in used:
                continue
            taken[a] = True
            used.add(b)
            i = coast[b]
            x[i], P[i] = x0[a], P0[a]
            self._misses[i] = 0
            self._hits[i] += 1
            self._anchor_sum[i], self._anchor_n[i] = Z[a], 1
        if taken.any():
            self.kf.x, self.kf.P = x, P
        return taken

    def step(self, detections, velocities=None, velocity_covs=None, position_covs=None) -> list[Track]:
        """Process one frame of detections; return the reported (confirmed or coasting) tracks.

        Parameters
        ----------
        detections : array_like, shape (N, dim)
            Detected object positions in this frame (``N`` may be 0).
        velocities : array_like, shape (N, dim), optional
            Per-detection velocity (e.g. the mean scene flow of the detection's cluster); used
            only to initialise the velocity of tracks born from these detections. A row of NaN
            marks a detection without a velocity (inf is rejected).
        velocity_covs : array_like, shape (N, dim, dim), optional
            Covariance of each velocity (e.g. :func:`flowtrack.motion.detection_velocity_covariances`),
            used with ``velocity_update=True``; a NaN row falls back to ``velocity_cov``.
        position_covs : array_like, shape (N, dim, dim), optional
            Each detection's own position covariance (symmetric positive definite), in place of R
            in its gate, association cost and update (e.g.
            :func:`flowtrack.pipeline.occlusion_position_covariances`: a detection cut by an
            occluder is off the object's centroid along the occluder). Needs the flow-aware filter
            (``velocity_update=True``, ``p_detect`` or the turn-rate model). Tracks born from these
            detections start with R, as any.

        Returns
        -------
        list of Track
            Tracks with status ``"confirmed"`` or ``"coasting"``, in order of id.

        Raises
        ------
        ValueError
            ``detections`` or ``velocities`` of the wrong shape or containing NaN/inf.
        """
        Z, V = self._check_detections(detections, velocities)
        Rv = None
        Rp = None
        if position_covs is not None:
            if self._flow is None:
                raise ValueError("position_covs needs the flow-aware filter: MultiObjectTracker(..., "
                                 "velocity_update=True), p_detect or motion_model='turn_rate'")
            Rp = check_psd(as_array(position_covs, "position_covs", (len(Z), self.dim, self.dim)),
                           "position_covs", strict=True)
        if self._flow is not None:
            Rv = self._flow.velocity_covariances(Z, V, velocity_covs)
        elif velocity_covs is not None:
            raise ValueError("velocity_covs needs MultiObjectTracker(..., velocity_update=True)")
        self.frame += 1
        kf = self.kf
        # 1. predict; 2. associate; 3. update
        if self._flow is None:
            z_pred, S = self.predictor.predict(kf)
            matches, unmatched_tracks, unmatched_dets = self.associator.associate(z_pred, S, Z)
            matches = np.asarray(matches, dtype=np.intp).reshape(-1, 2)
            unmatched_tracks = np.asarray(unmatched_tracks, dtype=np.intp)
            unmatched_dets = np.asarray(unmatched_dets, dtype=np.intp)
            Zj, has_v = Z, np.zeros(Z.shape[0], dtype=bool)
            if self.confirmer.needs_likelihood:
                z_pred, S = np.array(z_pred), np.array(S)  # the prior, kept through the update
            self.updater.update(kf, Z, matches)
        else:
            (matches, unmatched_tracks, unmatched_dets), (z_pred, S, Zj, has_v) = \
                self._flow.predict_associate_update(Z, V, Rv, Rp)
        # 4. bookkeeping: hits, misses, score, confirmation
        matched = matches[:, 0]
        self._hits[matched] += 1
        self._misses[matched] = 0
        self._misses[unmatched_tracks] += 1
        self._age += 1
        confirmer = self.confirmer
        if confirmer.needs_likelihood:
            loglik = pair_log_likelihood(z_pred, S, Zj, matches)  # the prior's predicted density
            dets = matches[:, 1]
            pos = {}
            if getattr(confirmer, "needs_positions", False):
                anchors = self._anchor_sum / np.maximum(self._anchor_n, 1)[:, None]
                pos = dict(positions=Z[dets], anchors=anchors, anchor_counts=self._anchor_n,
                           position_cov=self._R)
            self._scores = confirmer.update_scores(
                self._scores, matched, loglik, has_v[dets], unmatched_tracks,
                velocities=None if V is None else V[dets], velocity_covs=None if Rv is None else Rv[dets],
                **pos)
        self._anchor_sum[matched] += Z[matches[:, 1]]
        self._anchor_n[matched] += 1
        confirm, reject = confirmer.decide(self._scores, self._hits)
        self._confirmed |= confirm
        # where confirmed tracks were detected this frame (no births near them: birth_exclusion_radius)
        held = np.zeros((0, self.dim))
        if self.birth_exclusion_radius is not None:
            held = np.array(self.kf.x)[matched[self._confirmed[matched]], : self.dim]
        # deletions (occlusions beyond max_misses, tentative tracks that missed or were rejected)
        dead = np.asarray(self.deleter.delete(self._hits, self._misses, self._confirmed), dtype=bool)
        dead |= reject & ~self._confirmed
        if dead.any():
            keep = ~dead
            kf.keep(keep)
            (self._ids, self._hits, self._misses, self._age, self._confirmed, self._scores,
             self._anchor_sum, self._anchor_n) = (
                a[keep] for a in (self._ids, self._hits, self._misses, self._age, self._confirmed,
                                  self._scores, self._anchor_sum, self._anchor_n)
            )
        # births from unassigned detections (a coasting track re-acquires the nearest one first)
        if unmatched_dets.size:
            x0, P0 = self.initiator.initiate(Z[unmatched_dets], None if V is None else V[unmatched_dets])
            if self._flow is not None:
                x0, P0 = self._flow.birth_states(x0, P0, None if Rv is None else Rv[unmatched_dets])
            if self.reacquire_radius is not None:
                back = self._reacquire_at_birth(Z[unmatched_dets], x0, P0)
                x0, P0, unmatched_dets = x0[~back], P0[~back], unmatched_dets[~back]
            if len(held) and unmatched_dets.size:
                d2 = ((Z[unmatched_dets][:, None, : self.dim] - held[None]) ** 2).sum(axis=2)
                part = (d2 <= self.birth_exclusion_radius**2).any(axis=1)
                x0, P0, unmatched_dets = x0[~part], P0[~part], unmatched_dets[~part]
        if unmatched_dets.size:
            k = unmatched_dets.size
            kf.append(x0, P0)
            self._ids = np.concatenate([self._ids, np.arange(self._next_id, self._next_id + k)])
            self._next_id += k
            self._hits = np.concatenate([self._hits, np.ones(k, dtype=np.int64)])
            self._misses = np.concatenate([self._misses, np.zeros(k, dtype=np.int64)])
            self._age = np.concatenate([self._age, np.zeros(k, dtype=np.int64)])
            scores0 = confirmer.initial_scores(k)
            self._scores = np.concatenate([self._scores, scores0])
            self._anchor_sum = np.concatenate([self._anchor_sum, Z[unmatched_dets]])
            self._anchor_n = np.concatenate([self._anchor_n, np.ones(k, dtype=np.int64)])
            self._confirmed = np.concatenate(
                [self._confirmed, confirmer.decide(scores0, np.ones(k, dtype=np.int64))[0]])
        # record and report
        xs = kf.x.copy()
        Ps = kf.P.copy()
        xs.flags.writeable = False
        Ps.flags.writeable = False
        codes = np.where(self._confirmed, np.where(self._misses > 0, 2, 1), 0)
        self._log.append((self.frame, self._ids.copy(), xs, Ps, codes))
        self._counts.append(np.stack([self._hits, self._misses, self._age]))
        self._snapshot = list(
            map(
                Track,
                self._ids.tolist(),
                list(xs),
                list(Ps),
                [STATUSES[c] for c in codes.tolist()],
                self._hits.tolist(),
                self._misses.tolist(),
                self._age.tolist(),
            )
        )
        return [t for t in self._snapshot if t.status != "tentative"]

    # -- accessors -----------------------------------------------------------------------------------
    def history(self) -> list[tuple[int, list[Track]]]:
        """Every recorded frame's live tracks, tentative ones included: ``[(frame, [Track, ...]), ...]``.

        The rows that :func:`flowtrack.tracking_io.write_tracks_csv` writes: each ``Track`` as
        :meth:`step` saw it in that frame (state, status, hits, misses, age). With ``max_history``
        only the frames kept are listed.
        """
        out = []
        for (frame, ids, xs, Ps, codes), counts in zip(self._log, self._counts):
            hits, misses, age = counts.tolist()
            out.append((frame, [Track(t, xs[k], Ps[k], STATUSES[c], hits[k], misses[k], age[k])
                                for k, (t, c) in enumerate(zip(ids.tolist(), codes.tolist()))]))
        return out

    @property
    def scores(self) -> dict[int, float]:
        """Each live track's confirmation score after the last :meth:`step` (0 with
        :class:`HitCountConfirmer`; the log-likelihood ratio with :class:`SequentialScoreConfirmer`)."""
        return dict(zip(self._ids.tolist(), self._scores.tolist()))

    @property
    def tracks(self) -> list[Track]:
        """All live tracks after the last :meth:`step`, tentative ones included, in order of id."""
        return list(self._snapshot)

    def trajectories(
        self, include_tentative: bool = False
    ) -> dict[int, list[tuple[int, np.ndarray, np.ndarray]]]:
        """Posterior history of every track: ``{id: [(frame, x (2*dim,), P (2*dim, 2*dim)), ...]}``.

        Parameters
        ----------
        include_tentative : bool
            Also list tracks that were never confirmed (clutter); by default only tracks that were
            confirmed at some frame are returned, with their whole history (tentative frames too).

        Returns
        -------
        dict
            Track id -> list of ``(frame, x, P)`` in frame order, including deleted tracks; the
            arrays are read-only. Frames in which the track coasted hold the prediction. With
            ``max_history`` only the frames kept are listed.
        """
        out: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        ever_confirmed: set[int] = set()
        for frame, ids, xs, Ps, codes in self._log:
            for k, tid in enumerate(ids.tolist()):
                out.setdefault(tid, []).append((frame, xs[k], Ps[k]))
                if codes[k]:
                    ever_confirmed.add(tid)
        if not include_tentative:
            out = {tid: h for tid, h in out.items() if tid in ever_confirmed}
        return out

    def predict_ahead(self, n: int) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        r"""Every live track predicted ``n`` frames past the last :meth:`step`, without updates.

        The tracker's own motion model applied ``n`` times, :math:`x \leftarrow F x`,
        :math:`P \leftarrow F P F^\top + Q` (with the turn-rate model, its EKF prediction), on a copy
        of its filter (the tracker is not changed).

        Parameters
        ----------
        n : int, >= 1
            Frames ahead.

        Returns
        -------
        dict
            Track id -> ``(x (2*dim,), P (2*dim, 2*dim))``, the predicted state and covariance, for
            every live track (tentative ones included, as :attr:`tracks`).

        Examples
        --------
        >>> import numpy as np
        >>> trk = MultiObjectTracker(dt=0.5, q=0.0, r=1e-4, dim=2, min_hits=1)
        >>> _ = trk.step(np.array([[0.0, 0.0]]), velocities=np.array([[1.0, 2.0]]))
        >>> x, P = trk.predict_ahead(4)[0]
        >>> x.round(6).tolist()          # 4 frames of 0.5 s at (1, 2) m/s, q = 0
        [2.0, 4.0, 1.0, 2.0]
        """
        n = positive_int(n, "n")
        x, P = self._predicted_arrays(n)
        return {tid: (x[i].copy(), P[i].copy()) for i, tid in enumerate(self._ids.tolist())}

    def _predicted_arrays(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The live tracks' prior ``n`` frames ahead as stacked arrays ``(x (M, n_x), P (M, n_x, n_x))``,
        rows in the order of :attr:`tracks`; the filter itself is not changed."""
        if self._flow is not None:  # the flow-aware filter (turn-rate or constant velocity)
            return self.kf.predicted(n)
        import copy

        kf = copy.deepcopy(self.kf)
        for _ in range(n):
            kf.predict()
        return kf.x.copy(), kf.P.copy()

    def __repr__(self) -> str:
        counts = {s: sum(t.status == s for t in self._snapshot) for s in STATUSES}
        return (
            f"MultiObjectTracker(dim={self.dim}, frame={self.frame}, "
            + ", ".join(f"{k}={v}" for k, v in counts.items())
            + ")"
        )


# ----------------------------------------------------------------------------------------------------
# scene flow inside the tracker (issue 15): velocity measurements, NLLR association, turn-rate model
# ----------------------------------------------------------------------------------------------------
class _FlowOptions:
    """The tracker's flow-aware predict, associate and update (on a ``MotionBatchFilter``)."""

    def __init__(self, trk, R, flow_velocity_var, velocity_update, velocity_cov, p_detect, clutter_density,
                 velocity_clutter_density, motion_model, q_omega, omega_var, turn_axis):
        from ._validation import check_psd

        d = trk.dim
        self.trk = trk
        self.R = R
        self.velocity_update = bool(velocity_update)
        if velocity_cov is None:
            Rv = float(flow_velocity_var) * np.eye(d)
        else:
            Rv = as_array(velocity_cov, "velocity_cov")
            if Rv.ndim == 0:
                Rv = positive(float(Rv), "velocity_cov") * np.eye(d)
            elif Rv.shape != (d, d):
                raise ValueError(f"velocity_cov must be a number or of shape ({d}, {d}), got {Rv.shape}")
            check_psd(Rv, "velocity_cov", strict=True)
        self.Rv = Rv
        if (p_detect is None) != (clutter_density is None):
            raise ValueError("p_detect and clutter_density must be given together")
        self.nllr = p_detect is not None
        if self.nllr:
            self.p_detect = probability(p_detect, "p_detect")
            self.clutter_density = positive(clutter_density, "clutter_density")
            self.velocity_clutter_density = positive(velocity_clutter_density, "velocity_clutter_density")
        if motion_model not in ("cv", "turn_rate"):
            raise ValueError(f"motion_model must be 'cv' or 'turn_rate', got {motion_model!r}")
        self.motion_model = motion_model
        self.q_omega = nonnegative(q_omega, "q_omega")
        self.omega_var = positive(omega_var, "omega_var")
        self.turn_axis = turn_axis

    def make_filter(self):
        from .motion import MotionBatchFilter

        t = self.trk
        return MotionBatchFilter(t.dt, t.q, self.R, t.dim, model=self.motion_model, q_omega=self.q_omega,
                                 axis=self.turn_axis)

    def velocity_covariances(self, Z, V, velocity_covs):
        """Per-detection velocity covariance (N, d, d), NaN rows where no velocity is used; or None."""
        from .motion import check_velocity_covs

        N, d = Z.shape
        if velocity_covs is not None and V is None:
            raise ValueError("velocity_covs needs velocities")
        if V is None:
            return None
        Rv = np.broadcast_to(self.Rv, (N, d, d)).copy()
        if velocity_covs is not None:
            given = check_velocity_covs(velocity_covs, N, d)
            ok = np.isfinite(given).all(axis=(1, 2))
            Rv[ok] = given[ok]
        Rv[np.isnan(V).any(axis=1)] = np.nan
        return Rv

    def predict_associate_update(self, Z, V, Rv, Rp=None):
        from .association import assign, masked_mahalanobis, nllr_cost

        kf = self.trk.kf
        d = self.trk.dim
        kf.predict()
        M, N = len(kf), len(Z)
        use_v = self.velocity_update and V is not None
        if use_v:
            # joint innovation covariances per pair; a detection without a velocity is scored on its
            # position alone (its velocity components are NaN, which masked_mahalanobis leaves out)
            _, S, m = kf.joint_innovation(Z, V, Rv, Rp)
            has_v = m == 2 * d
            Zj = np.concatenate([Z, np.where(has_v[:, None], V, np.nan)], axis=1)
            z_pred = kf.x[:, : 2 * d].copy()  # the prior (the update below changes kf.x)
        else:
            has_v = np.zeros(N, dtype=bool)
            Zj = Z
            z_pred, S = kf.predicted_measurements()
            if Rp is not None:  # per pair: the track's P with the detection's own covariance
                S = kf.P[:, None, :d, :d] + Rp[None]
        if M == 0 or N == 0:
            matches, ut, ud = assign(np.zeros((M, N)))
        elif self.nllr:
            lam = np.where(has_v, self.clutter_density * self.velocity_clutter_density, self.clutter_density)
            cost = nllr_cost(z_pred, S, Zj, self.p_detect, lam, gate_prob=self.trk.gate_prob)
            matches, ut, ud = assign(cost, objective="min_cost")
        else:
            d2, logdet, dof = masked_mahalanobis(z_pred, S, Zj)
            gates = np.array([chi2_gate(int(k), self.trk.gate_prob) for k in dof])
            cost = np.where(d2 <= gates[None, :], d2 + logdet, np.inf)
            matches, ut, ud = assign(cost)
        if matches.shape[0]:
            Zm = np.full((M, d), np.nan)
            Zm[matches[:, 0]] = Z[matches[:, 1]]
            mask = np.zeros(M, dtype=bool)
            mask[matches[:, 0]] = True
            Rpm = None
            if Rp is not None:
                Rpm = np.broadcast_to(kf.R, (M, d, d)).copy()
                Rpm[matches[:, 0]] = Rp[matches[:, 1]]
            if use_v:
                Vm = np.full((M, d), np.nan)
                Rvm = np.full((M, d, d), np.nan)
                Vm[matches[:, 0]] = V[matches[:, 1]]
                Rvm[matches[:, 0]] = Rv[matches[:, 1]]
                kf.update_joint(Zm, Vm, Rvm, mask, Rpm)
            else:
                kf.update_joint(Zm, None, None, mask, Rpm)
        return (matches, ut, ud), (z_pred, S, Zj, has_v)

    def birth_states(self, x0, P0, Rv):
        """Extend the initiator's ``[p, v]`` states: velocity covariance = the measured one, yaw rate 0."""
        d = self.trk.dim
        if self.velocity_update and Rv is not None:
            ok = np.isfinite(Rv).all(axis=(1, 2))
            P0 = P0.copy()
            P0[ok, d:, d:] = Rv[ok]
        if self.motion_model == "cv":
            return x0, P0
        k, n = x0.shape
        x1 = np.zeros((k, n + 1))
        x1[:, :n] = x0
        P1 = np.zeros((k, n + 1, n + 1))
        P1[:, :n, :n] = P0
        P1[:, n, n] = self.omega_var
        return x1, P1
