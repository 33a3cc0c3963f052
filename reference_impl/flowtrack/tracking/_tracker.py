r"""The tracker's loop: :class:`MultiObjectTracker`, the :class:`Track` it reports and the
:class:`FlowOptions` that choose its flow-aware parts (part of :mod:`flowtrack.tracking`).

:meth:`MultiObjectTracker.step` runs one frame of the syllabus' second flowchart through its parts
(:mod:`flowtrack.tracking`'s ``_parts``): predict every track, :math:`x_i \leftarrow f(x_i)`,
:math:`P_i \leftarrow F P_i F^\top + Q`; predict the measurements, :math:`\hat z_i = H x_i`,
:math:`S_{ij} = H P_i H^\top + R_j`; gate and associate; update the matched tracks (Joseph form);
count hits and misses and confirm; delete; start tracks from the unmatched detections (with
re-acquisition of coasting tracks and no births beside a detected confirmed track). One path for
every configuration: the options only choose the parts.

Import these names from :mod:`flowtrack.tracking`, which exports (and documents) them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields

import numpy as np

from .._validation import as_array, check_psd, nonnegative, positive, positive_int, probability, spatial_dim
from ..confirmation import HitCountConfirmer, pair_log_likelihood
from ..kalman import constant_velocity_model
from ._parts import (
    Associator,
    Confirmer,
    Deleter,
    Detections,
    FlowUpdater,
    GNNAssociator,
    Initiator,
    KalmanPredictor,
    KalmanUpdater,
    MaskedGNNAssociator,
    MeasurementPrediction,
    MissCountDeleter,
    MotionPredictor,
    NLLRAssociator,
    Predictor,
    SingleDetectionInitiator,
    Updater,
)

__all__ = ["FlowOptions", "MultiObjectTracker", "STATUSES", "Track"]

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
# the flow options
# ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FlowOptions:
    """How scene flow enters :class:`MultiObjectTracker` beyond the birth velocity (default: not at all).

    The same options are keyword arguments of the tracker; pass either this or them. Any option
    that is on makes the tracker run the flow-aware parts (on a
    :class:`flowtrack.motion.MotionBatchFilter`) instead of the position-only ones.

    Attributes
    ----------
    velocity_update : bool
        Use the detections' velocities as measurements (:class:`FlowUpdater`).
    velocity_cov : float or array_like, shape (dim, dim), optional
        Velocity measurement covariance of the detections without ``velocity_covs`` (default: the
        tracker's ``flow_velocity_var`` ``I``).
    p_detect, clutter_density : float, optional
        Associate by the negative log-likelihood ratio (:class:`NLLRAssociator`); both or neither.
    velocity_clutter_density : float
        Clutter density in velocity space (per (m/s)^dim) of detections with a velocity.
    motion_model : {"cv", "turn_rate"}
        The motion model of the :class:`MotionPredictor`.
    q_omega, omega_var : float
        Yaw-rate random walk ((rad/s)² per s) and initial yaw-rate variance ((rad/s)²) of the
        turn-rate model.
    turn_axis : array_like, shape (3,), optional
        Normal of the plane of motion of the 3-D turn-rate model (default z).
    measured_omega_var : float, optional
        Initial yaw-rate variance ((rad/s)²) of a track born from a detection with a measured yaw rate
        (``step(..., yaw_rates=)``); default ``omega_var``.
    """

    velocity_update: bool = False
    velocity_cov: float | np.ndarray | None = None
    p_detect: float | None = None
    clutter_density: float | None = None
    velocity_clutter_density: float = 1.0
    motion_model: str = "cv"
    q_omega: float = 1.0
    omega_var: float = 4.0
    turn_axis: np.ndarray | None = None
    measured_omega_var: float | None = None

    @property
    def on(self) -> bool:
        """Whether any option is on (the tracker then runs the flow-aware parts)."""
        return (bool(self.velocity_update) or self.p_detect is not None or self.clutter_density is not None
                or self.motion_model != "cv")


def _unchanged(value, default) -> bool:
    """Whether a keyword still has its default (None, or an equal number / string / bool)."""
    if value is default:
        return True
    return default is not None and isinstance(value, (bool, int, float, str)) and value == default


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
        Gate probability of the default associator (``0 < gate_prob < 1``).
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
    flow : FlowOptions, optional
        The flow options below as one object (then leave their keywords alone).
    velocity_update : bool, optional
        Use the detections' velocities (scene flow) as measurements in the update, not only to start
        tracks (default False). A detection with a velocity and a velocity
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
    measured_omega_var : float, optional
        Initial yaw-rate variance ((rad/s)^2) of a turn-rate track born from a detection that carries
        a measured yaw rate (``step(..., yaw_rates=)``); default ``omega_var``.
    reacquire_radius : float, optional
        Re-acquisition after an occlusion (m; see the module docstring): a coasting confirmed track
        takes the nearest unassigned detection within this distance and restarts from it, keeping
        its id. A track deleted because the sensor saw through it (``max_seen_through``) is kept for
        this too while its coasting budget lasts (``max_misses`` less its misses), its position
        carried on at its velocity: a detection within this distance of it revives it, confirmed,
        with its id (a small object lost from view for a moment was taken for gone). Default None:
        off.
    birth_exclusion_radius : float, optional
        No track is started from a detection within this distance (m) of a confirmed track that was
        detected in the same frame: it is another piece of that object (a part cut off by an
        occluder, a face that moves differently), not a new one. Coasting tracks re-acquire first
        (``reacquire_radius``). Default None: every unassigned detection starts a track.
    max_seen_through : int, default 0
        A confirmed track is deleted when the sensor has seen through its predicted position on more
        than this many consecutive misses (:meth:`step`'s ``seen_through``; unused without it).
    predictor, associator, updater, initiator, deleter, confirmer : optional
        Parts (see the module docstring) in place of the ones the options choose. Without flow
        options: :class:`KalmanPredictor`, :class:`GNNAssociator` ``(gate_prob)``,
        :class:`KalmanUpdater`, :class:`SingleDetectionInitiator`; with any of ``velocity_update``,
        ``p_detect`` or ``motion_model="turn_rate"``: :class:`MotionPredictor` ``(motion_model)``,
        :class:`MaskedGNNAssociator` ``(gate_prob)`` or :class:`NLLRAssociator` ``(p_detect, ...)``,
        :class:`FlowUpdater` ``(velocity_cov)`` and a :class:`SingleDetectionInitiator` with the
        turn-rate model's yaw-rate state; always :class:`MissCountDeleter` ``(max_misses)`` and
        :class:`HitCountConfirmer` ``(min_hits)``. A custom associator brings its own gate
        (``gate_prob`` is then unused), a custom deleter or confirmer its own rule (``min_hits`` is
        then unused); :class:`SequentialScoreConfirmer` confirms by the track score. The predictor
        makes the filter, so the updater must work on it (:class:`FlowUpdater` needs a
        :class:`MotionPredictor`) and the initiator must start its states.

    Attributes
    ----------
    kf : BatchKalmanFilter or flowtrack.motion.MotionBatchFilter
        The state of all live tracks (rows aligned with :attr:`tracks`), made by the predictor.
    flow : FlowOptions
        The flow options.
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

    The flow options choose the flow-aware parts; the same tracker from parts:

    >>> a = MultiObjectTracker(0.1, 1.0, 1e-4, dim=3, flow=FlowOptions(velocity_update=True))
    >>> type(a.predictor).__name__, type(a.updater).__name__, type(a.associator).__name__
    ('MotionPredictor', 'FlowUpdater', 'MaskedGNNAssociator')
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
        predictor: Predictor | None = None,
        associator: Associator | None = None,
        updater: Updater | None = None,
        initiator: Initiator | None = None,
        deleter: Deleter | None = None,
        confirmer: Confirmer | None = None,
        max_history=None,
        flow: FlowOptions | None = None,
        velocity_update=False,
        velocity_cov=None,
        p_detect=None,
        clutter_density=None,
        velocity_clutter_density=1.0,
        motion_model="cv",
        q_omega=1.0,
        omega_var=4.0,
        turn_axis=None,
        measured_omega_var=None,
        reacquire_radius=None,
        birth_exclusion_radius=None,
        max_seen_through=0,
    ):
        self.dt = positive(dt, "dt")
        self.reacquire_radius = None if reacquire_radius is None else positive(reacquire_radius,
                                                                               "reacquire_radius")
        self.birth_exclusion_radius = (None if birth_exclusion_radius is None
                                       else positive(birth_exclusion_radius, "birth_exclusion_radius"))
        self.q = nonnegative(q, "q")
        self.dim = spatial_dim(dim, "dim")
        _, _, _, R = constant_velocity_model(self.dt, self.q, r, self.dim)
        self.min_hits = positive_int(min_hits, "min_hits")
        self.max_misses = positive_int(max_misses, "max_misses", minimum=0)
        self.max_seen_through = positive_int(max_seen_through, "max_seen_through", minimum=0)
        self.gate_prob = probability(gate_prob, "gate_prob")
        sr2 = float(np.mean(np.diag(R)))
        velocity_var = (100.0 * sr2 / self.dt**2) if velocity_var is None else velocity_var
        flow_velocity_var = (sr2 / self.dt**2) if flow_velocity_var is None else flow_velocity_var
        keywords = FlowOptions(velocity_update, velocity_cov, p_detect, clutter_density,
                               velocity_clutter_density, motion_model, q_omega, omega_var, turn_axis,
                               measured_omega_var)
        if flow is None:
            flow = keywords
        elif not all(_unchanged(getattr(keywords, f.name), f.default) for f in fields(FlowOptions)):
            raise ValueError("give the flow options either as flow=FlowOptions(...) or as keywords, not both")
        self.flow = flow
        default = self._default_parts(flow, R, velocity_var, flow_velocity_var)
        self.predictor = predictor if predictor is not None else default["predictor"]
        self.associator = associator if associator is not None else default["associator"]
        self.updater = updater if updater is not None else default["updater"]
        self.initiator = initiator if initiator is not None else default["initiator"]
        self.deleter = deleter if deleter is not None else MissCountDeleter(self.max_misses)
        self.confirmer = confirmer if confirmer is not None else HitCountConfirmer(self.min_hits)
        self.kf = self.predictor.new_filter(self.dt, self.q, R, self.dim)
        n_state = np.shape(self.kf.x)[1]
        n_born = np.shape(self.initiator.initiate(np.zeros((0, self.dim)), None)[0])[1]
        if n_born != n_state:
            raise ValueError(f"the initiator starts states of {n_born} components, the predictor's filter "
                             f"holds {n_state}")
        self._ids = np.zeros(0, dtype=np.int64)
        self._hits = np.zeros(0, dtype=np.int64)
        self._misses = np.zeros(0, dtype=np.int64)
        # consecutive misses at which the sensor saw through the track's position (step's seen_through)
        self._seen = np.zeros(0, dtype=np.int64)
        self._age = np.zeros(0, dtype=np.int64)
        self._confirmed = np.zeros(0, dtype=bool)
        self._scores = np.zeros(0)
        # sum and number of each track's detected positions (the static-artefact anchor of the score)
        self._anchor_sum = np.zeros((0, self.dim))
        self._anchor_n = np.zeros(0, dtype=np.int64)
        self._R = np.asarray(R, dtype=float)
        # tracks deleted because the sensor saw through them, kept for re-acquisition (reacquire_radius)
        # while their coasting budget lasts: ids, positions (carried on at their velocities, as a
        # coasting track's), velocities, frames left, hits
        self._gone_ids = np.zeros(0, dtype=np.int64)
        self._gone_pos = np.zeros((0, self.dim))
        self._gone_vel = np.zeros((0, self.dim))
        self._gone_left = np.zeros(0, dtype=np.int64)
        self._gone_hits = np.zeros(0, dtype=np.int64)
        self._next_id = 0
        self.frame = -1
        # one record per frame: (frame, ids (M,), x (M,n), P (M,n,n), status codes (M,))
        if max_history is not None:
            max_history = positive_int(max_history, "max_history")
        self._log: deque[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
        self._log = deque(maxlen=max_history)
        self._counts: deque[np.ndarray] = deque(maxlen=max_history)  # per frame (3, M): hits, misses, age
        self._snapshot: list[Track] = []

    def _default_parts(self, flow: FlowOptions, R, velocity_var, flow_velocity_var) -> dict:
        """The predictor, associator, updater and initiator the flow options choose."""
        if not flow.on:
            return {"predictor": KalmanPredictor(), "associator": GNNAssociator(self.gate_prob),
                    "updater": KalmanUpdater(),
                    "initiator": SingleDetectionInitiator(R, velocity_var, flow_velocity_var)}
        omega_var = positive(flow.omega_var, "omega_var")
        turn_rate = flow.motion_model == "turn_rate"
        initiator = SingleDetectionInitiator(R, velocity_var, flow_velocity_var,
                                             yaw_rate_var=omega_var if turn_rate else None,
                                             measured_yaw_rate_var=flow.measured_omega_var)
        if (flow.p_detect is None) != (flow.clutter_density is None):
            raise ValueError("p_detect and clutter_density must be given together")
        velocity_cov = float(flow_velocity_var) if flow.velocity_cov is None else flow.velocity_cov
        updater = FlowUpdater(self.dim, velocity_cov, velocity_update=flow.velocity_update)
        if flow.p_detect is not None:
            associator = NLLRAssociator(flow.p_detect, flow.clutter_density, dim=self.dim,
                                        velocity_clutter_density=flow.velocity_clutter_density,
                                        gate_prob=self.gate_prob)
        else:
            associator = MaskedGNNAssociator(self.gate_prob)
        predictor = MotionPredictor(flow.motion_model, flow.q_omega, flow.turn_axis)
        return {"predictor": predictor, "associator": associator, "updater": updater, "initiator": initiator}

    # -- input ---------------------------------------------------------------------------------------
    def _detections(self, detections, velocities, velocity_covs, position_covs, yaw_rates=None) -> Detections:
        """One frame's input checked: shapes, NaN/inf, symmetric positive (semi-)definite covariances."""
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
        Rv = None
        if velocity_covs is not None:
            from ..motion import check_velocity_covs

            if V is None:
                raise ValueError("velocity_covs needs velocities")
            Rv = check_velocity_covs(velocity_covs, len(Z), d)
        Rp = None
        if position_covs is not None:
            Rp = check_psd(as_array(position_covs, "position_covs", (len(Z), d, d)), "position_covs",
                           strict=True)
        W = None
        if yaw_rates is not None:
            W = as_array(yaw_rates, "yaw_rates", (len(Z),), allow_nan=True)
        return Detections(Z, V, Rv, Rp, W)

    # -- the loop ------------------------------------------------------------------------------------
    def step(self, detections, velocities=None, velocity_covs=None, position_covs=None, *,
             yaw_rates=None, seen_through=None) -> list[Track]:
        """Process one frame of detections; return the reported (confirmed or coasting) tracks.

        Parameters
        ----------
        detections : array_like, shape (N, dim)
            Detected object positions in this frame (``N`` may be 0).
        velocities : array_like, shape (N, dim), optional
            Per-detection velocity (e.g. the mean scene flow of the detection's cluster); it starts
            the velocity of tracks born from these detections and, with ``velocity_update=True``, is
            measured. A row of NaN marks a detection without a velocity (inf is rejected).
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
        yaw_rates : array_like, shape (N,), optional
            Each detection's measured yaw rate (rad/s about the turn axis: the angular velocity of the
            rigid motion fitted to its flow, :meth:`flowtrack.motion.RigidMotion.yaw_rate`); NaN: none.
            A track of the turn-rate model born from such a detection starts with it (variance
            ``measured_omega_var``) instead of 0; the constant-velocity model has no yaw rate and
            ignores it.
        seen_through : callable, optional
            The sensor's free space this frame: ``seen_through(positions (K, dim)) -> bool (K,)``, True
            where the sensor saw past the position, so that an object there would have been in view
            (e.g. :class:`flowtrack.pipeline.FreeSpace`: the depth image reads a surface well behind
            it). It is asked about the confirmed tracks that missed this frame, at their predicted
            positions; one whose position was seen through on more than ``max_seen_through``
            consecutive misses is deleted: it is not occluded but gone (it left, stopped, or was never
            there), and coasting it would report an object where the sensor sees none. Without it
            (the default) a missed track coasts for ``max_misses`` frames whatever the sensor saw.

        Returns
        -------
        list of Track
            Tracks with status ``"confirmed"`` or ``"coasting"``, in order of id.

        Raises
        ------
        ValueError
            ``detections`` or ``velocities`` of the wrong shape or containing NaN/inf; covariances of
            the wrong shape or not positive (semi-)definite; ``velocity_covs`` or ``position_covs``
            the updater cannot use. Nothing has changed then (the frame is not counted).
        """
        dets = self.updater.check(self._detections(detections, velocities, velocity_covs, position_covs,
                                                   yaw_rates))
        self.frame += 1
        # 1. predict every track
        self.predictor.predict(self.kf)
        # 2. gate and associate the detections with the tracks' predicted measurements
        predicted = self.updater.predict_measurements(self.kf, dets)
        matches, missed, unmatched = self._associate(predicted)
        # 3. update the matched tracks with their detections
        self.updater.update(self.kf, dets, matches)
        # 4. count hits and misses, score and confirm
        reject = self._confirm(dets, predicted, matches, missed)
        # 5. delete the tracks that ended (where confirmed tracks were detected is kept for the births)
        held = self._detected_confirmed(matches[:, 0])
        self._look_through(seen_through)
        self._delete(reject)
        # 6. start tracks from the unmatched detections
        self._initiate(dets.subset(unmatched), held)
        return self._record()

    # -- the steps -----------------------------------------------------------------------------------
    def _associate(self, predicted: MeasurementPrediction):
        """The associator's matching as int arrays (a custom associator may return lists)."""
        matches, missed, unmatched = self.associator.associate(predicted.z_pred, predicted.S,
                                                                predicted.measurements)
        return (np.asarray(matches, dtype=np.intp).reshape(-1, 2), np.asarray(missed, dtype=np.intp),
                np.asarray(unmatched, dtype=np.intp))

    def _confirm(self, dets: Detections, predicted: MeasurementPrediction, matches, missed) -> np.ndarray:
        """Hits, misses, ages and scores after this frame's matches; confirm tracks; return the mask
        of the tracks the confirmer rejects."""
        matched, j = matches[:, 0], matches[:, 1]
        self._hits[matched] += 1
        self._misses[matched] = 0
        self._misses[missed] += 1
        self._age += 1
        confirmer = self.confirmer
        if confirmer.needs_likelihood:
            # the density of each match under its track's prior predicted measurement
            loglik = pair_log_likelihood(predicted.z_pred, predicted.S, predicted.measurements, matches)
            pos = {}
            if confirmer.needs_positions:
                anchors = self._anchor_sum / np.maximum(self._anchor_n, 1)[:, None]
                pos = dict(positions=dets.positions[j], anchors=anchors, anchor_counts=self._anchor_n,
                           position_cov=self._R)
            V, Rv = dets.velocities, dets.velocity_covs
            self._scores = confirmer.update_scores(
                self._scores, matched, loglik, predicted.has_velocity[j], missed,
                velocities=None if V is None else V[j], velocity_covs=None if Rv is None else Rv[j], **pos)
        self._anchor_sum[matched] += dets.positions[j]
        self._anchor_n[matched] += 1
        confirm, reject = confirmer.decide(self._scores, self._hits)
        self._confirmed |= confirm
        return reject

    def _look_through(self, seen_through) -> None:
        """Count, per track, the consecutive misses at which ``seen_through`` saw past its position."""
        if seen_through is None:
            self._seen[:] = 0
            return
        ask = np.flatnonzero(self._confirmed & (self._misses > 0))
        seen = np.zeros(len(self._ids), dtype=bool)
        if ask.size:
            answer = np.asarray(seen_through(np.array(self.kf.x)[ask, : self.dim]))
            if answer.shape != (ask.size,) or answer.dtype != bool:
                raise TypeError(f"seen_through must return a bool array of shape ({ask.size},), got "
                                f"{answer.dtype} {answer.shape}")
            seen[ask] = answer
        self._seen = np.where(seen, self._seen + 1, 0)

    def _detected_confirmed(self, matched) -> np.ndarray:
        """Positions (K, dim) of the confirmed tracks detected this frame (only with
        ``birth_exclusion_radius``: no births near them)."""
        if self.birth_exclusion_radius is None:
            return np.zeros((0, self.dim))
        return np.array(self.kf.x)[matched[self._confirmed[matched]], : self.dim]

    def _delete(self, reject) -> None:
        """Drop the tracks the deleter ends (occlusions beyond ``max_misses``, tentative tracks that
        missed) and the tentative ones the confirmer rejects."""
        dead = np.asarray(self.deleter.delete(self._hits, self._misses, self._confirmed), dtype=bool)
        dead |= reject & ~self._confirmed
        gone = self._confirmed & (self._seen > self.max_seen_through)
        dead |= gone
        if self.reacquire_radius is not None:
            self._bury(gone)
        if dead.any():
            keep = ~dead
            self.kf.keep(keep)
            (self._ids, self._hits, self._misses, self._seen, self._age, self._confirmed, self._scores,
             self._anchor_sum, self._anchor_n) = (
                a[keep] for a in (self._ids, self._hits, self._misses, self._seen, self._age,
                                  self._confirmed, self._scores, self._anchor_sum, self._anchor_n)
            )

    def _bury(self, gone) -> None:
        """Keep the tracks ``gone`` (seen through) for re-acquisition, for what is left of their
        coasting budget; age the ones kept before."""
        keep = self._gone_left > 1
        self._gone_ids, self._gone_vel = self._gone_ids[keep], self._gone_vel[keep]
        self._gone_pos = self._gone_pos[keep] + self.dt * self._gone_vel
        self._gone_left, self._gone_hits = self._gone_left[keep] - 1, self._gone_hits[keep]
        budget = self.max_misses - self._misses[gone]
        if np.any(budget > 0):
            g = np.flatnonzero(gone)[budget > 0]
            x = np.array(self.kf.x)[g]
            self._gone_ids = np.concatenate([self._gone_ids, self._ids[g]])
            self._gone_pos = np.concatenate([self._gone_pos, x[:, : self.dim]])
            self._gone_vel = np.concatenate([self._gone_vel, x[:, self.dim: 2 * self.dim]])
            self._gone_left = np.concatenate([self._gone_left, budget[budget > 0]])
            self._gone_hits = np.concatenate([self._gone_hits, self._hits[g]])

    def _revive(self, Z, x0, P0) -> np.ndarray:
        """Re-acquisition of a track deleted because the sensor saw through it (it was lost, not
        gone: a small object missed for a few frames): an unassigned detection within
        ``reacquire_radius`` of where it was deleted restarts it from the detection's birth state, as
        confirmed, with its id (nearest pairs first); returns the mask of the detections taken."""
        taken = np.zeros(len(Z), dtype=bool)
        if len(self._gone_ids) == 0 or len(Z) == 0:
            return taken
        D = np.linalg.norm(Z[:, None, : self.dim] - self._gone_pos[None], axis=2)
        pairs: list[tuple[int, int]] = []  # (detection, grave), nearest first
        for flat in np.argsort(D, axis=None, kind="stable"):
            i, j = divmod(int(flat), len(self._gone_ids))
            if D[i, j] > self.reacquire_radius:
                break
            if taken[i] or any(j == g for _, g in pairs):
                continue
            taken[i] = True
            pairs.append((i, j))
        if not pairs:
            return taken
        a = np.array([i for i, _ in pairs])
        b = np.array([j for _, j in pairs])
        k = len(a)
        self.kf.append(x0[a], P0[a])
        self._ids = np.concatenate([self._ids, self._gone_ids[b]])
        self._hits = np.concatenate([self._hits, self._gone_hits[b] + 1])
        self._misses = np.concatenate([self._misses, np.zeros(k, dtype=np.int64)])
        self._seen = np.concatenate([self._seen, np.zeros(k, dtype=np.int64)])
        self._age = np.concatenate([self._age, np.zeros(k, dtype=np.int64)])
        self._scores = np.concatenate([self._scores, self.confirmer.initial_scores(k)])
        self._anchor_sum = np.concatenate([self._anchor_sum, Z[a]])
        self._anchor_n = np.concatenate([self._anchor_n, np.ones(k, dtype=np.int64)])
        self._confirmed = np.concatenate([self._confirmed, np.ones(k, dtype=bool)])
        keep = np.ones(len(self._gone_ids), dtype=bool)
        keep[b] = False
        self._gone_ids, self._gone_pos, self._gone_vel = (self._gone_ids[keep], self._gone_pos[keep],
                                                          self._gone_vel[keep])
        self._gone_left, self._gone_hits = self._gone_left[keep], self._gone_hits[keep]
        return taken

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

    def _initiate(self, new: Detections, held: np.ndarray) -> None:
        """Start tracks from the unmatched detections ``new``: a coasting track re-acquires the
        nearest one first (``reacquire_radius``), none starts near ``held`` (``birth_exclusion_radius``)."""
        if len(new) == 0:
            return
        Z = new.positions
        if new.yaw_rates is None:  # a custom initiator need not know yaw rates
            x0, P0 = self.initiator.initiate(Z, new.velocities, new.velocity_covs)
        else:
            x0, P0 = self.initiator.initiate(Z, new.velocities, new.velocity_covs, yaw_rates=new.yaw_rates)
        if self.reacquire_radius is not None:
            back = self._reacquire_at_birth(Z, x0, P0)
            x0, P0, Z = x0[~back], P0[~back], Z[~back]
            back = self._revive(Z, x0, P0)
            x0, P0, Z = x0[~back], P0[~back], Z[~back]
        if len(held) and len(Z):
            d2 = ((Z[:, None, : self.dim] - held[None]) ** 2).sum(axis=2)
            part = (d2 <= self.birth_exclusion_radius**2).any(axis=1)
            x0, P0, Z = x0[~part], P0[~part], Z[~part]
        k = len(Z)
        if k == 0:
            return
        self.kf.append(x0, P0)
        self._ids = np.concatenate([self._ids, np.arange(self._next_id, self._next_id + k)])
        self._next_id += k
        self._hits = np.concatenate([self._hits, np.ones(k, dtype=np.int64)])
        self._misses = np.concatenate([self._misses, np.zeros(k, dtype=np.int64)])
        self._seen = np.concatenate([self._seen, np.zeros(k, dtype=np.int64)])
        self._age = np.concatenate([self._age, np.zeros(k, dtype=np.int64)])
        scores0 = self.confirmer.initial_scores(k)
        self._scores = np.concatenate([self._scores, scores0])
        self._anchor_sum = np.concatenate([self._anchor_sum, Z])
        self._anchor_n = np.concatenate([self._anchor_n, np.ones(k, dtype=np.int64)])
        self._confirmed = np.concatenate(
            [self._confirmed, self.confirmer.decide(scores0, np.ones(k, dtype=np.int64))[0]])

    def _record(self) -> list[Track]:
        """Log this frame's tracks (:meth:`history`, :meth:`trajectories`); return the reported ones."""
        # in order of id (a revived track sits after younger ones in the filter)
        o = np.argsort(self._ids, kind="stable")
        xs = self.kf.x[o]
        Ps = self.kf.P[o]
        xs.flags.writeable = False
        Ps.flags.writeable = False
        codes = np.where(self._confirmed, np.where(self._misses > 0, 2, 1), 0)[o]
        ids, hits, misses, age = self._ids[o], self._hits[o], self._misses[o], self._age[o]
        self._log.append((self.frame, ids, xs, Ps, codes))
        self._counts.append(np.stack([hits, misses, age]))
        self._snapshot = list(
            map(
                Track,
                ids.tolist(),
                list(xs),
                list(Ps),
                [STATUSES[c] for c in codes.tolist()],
                hits.tolist(),
                misses.tolist(),
                age.tolist(),
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
        x, P = self.predictor.predict_ahead(self.kf, n)
        return {tid: (x[i].copy(), P[i].copy()) for i, tid in enumerate(self._ids.tolist())}

    def __repr__(self) -> str:
        counts = {s: sum(t.status == s for t in self._snapshot) for s in STATUSES}
        return (
            f"MultiObjectTracker(dim={self.dim}, frame={self.frame}, "
            + ", ".join(f"{k}={v}" for k, v in counts.items())
            + ")"
        )
