r"""A multi-object tracker built from small swappable parts (syllabus section 7).

One call of :meth:`MultiObjectTracker.step` runs the loop of the syllabus' second flowchart, one
part per box:

1. **Predict** every track with the motion model (the *predictor*): by default constant velocity,
   :math:`\hat x_i \leftarrow F \hat x_i`, :math:`P_i \leftarrow F P_i F^\top + Q` (all tracks at
   once in a :class:`~flowtrack.kalman.BatchKalmanFilter`).
2. **Gate and associate**: the *updater* predicts each track's measurement, :math:`\hat z_i = H\hat
   x_i`, :math:`S_i = HP_iH^\top + R`; the *associator* builds the squared Mahalanobis costs
   :math:`C_{ij} = (z_j - \hat z_i)^\top S_i^{-1}(z_j - \hat z_i)`, gates them at
   :math:`\gamma = F^{-1}_{\chi^2_d}(p)` and solves the gated assignment
   (:func:`flowtrack.association.assign`: most pairs, then least cost). The default
   :class:`GNNAssociator` minimises :math:`C_{ij} + \ln\det S_i` (the pair's negative
   log-likelihood) so that a newborn, very uncertain track cannot steal the detection of an
   established one; ``GNNAssociator(log_det=False)`` uses :math:`C_{ij}` alone, as the syllabus.
3. **Update** the assigned tracks with their detections (the *updater*: Joseph-form Kalman update).
4. **Confirm** (the *confirmer*): a track becomes *confirmed* once it has ``min_hits`` assigned
   detections (the birth detection counts as the first; :class:`HitCountConfirmer`), or, with
   :class:`SequentialScoreConfirmer`, once its log-likelihood ratio of "object" against "clutter"
   passes Wald's threshold.
5. **Delete** (the *deleter*): a tentative track is deleted at its first miss; a confirmed track
   without a detection is *coasting* (occluded): it is only predicted, and deleted when its
   consecutive misses exceed ``max_misses``, i.e. at the ``max_misses + 1``-th consecutive miss; an
   occlusion of up to ``max_misses`` frames keeps the track and its id. A miss is not always an
   occlusion: given the sensor's free space (``step(..., seen_through=)``, e.g.
   :class:`flowtrack.pipeline.FreeSpace` from the depth image), a coasting track whose predicted
   position the sensor saw through (a surface well behind it, nothing in front) on more than
   ``max_seen_through`` consecutive misses is deleted: its object is gone, not hidden (with
   ``reacquire_radius`` it can still be revived with its id, below).
6. **Initiate** (the *initiator*): every unassigned detection starts a *tentative* track (position
   = detection, velocity = the detection's scene-flow velocity if given, else 0 with a large
   variance), except that

   - with ``reacquire_radius`` r, a coasting confirmed track *re-acquires* its object: an unassigned
     detection within r of it (outside its gate: its velocity was learnt while the object was being
     hidden, from a shrinking visible surface, or the visible part jumped) restarts the track from
     that detection's birth state instead of starting a new track, and the track keeps its id
     (nearest pairs first, each track and detection once); a track deleted because the sensor saw
     through it is kept for this as long as it could have coasted, and comes back confirmed, with
     its id;
   - with ``birth_exclusion_radius`` r, an unassigned detection within r of a confirmed track that
     was detected in the same frame starts no track: it is another piece of that object.

Track ids come from a counter and are never reused.

Scene flow can enter the filter beyond the birth velocity (:class:`FlowOptions`, or the same
keyword arguments; off by default): ``velocity_update=True`` uses each detection's velocity (with its
covariance, ``step(..., velocity_covs=)``) as a measurement next to its position and gates the joint
innovation; ``p_detect`` and ``clutter_density`` associate by the negative log-likelihood ratio
against clutter (:func:`flowtrack.association.nllr_cost`, the course's one association objective);
and ``motion_model="turn_rate"`` predicts with constant speed and yaw rate (:mod:`flowtrack.motion`,
an EKF), so a turning object is extrapolated along its arc; ``step(..., position_covs=)`` gives a
detection its own position covariance (an occluded object's visible centroid is off its centre).
These options only choose other parts for the same loop: :class:`MotionPredictor`,
:class:`FlowUpdater`, :class:`MaskedGNNAssociator` or :class:`NLLRAssociator`, and a
:class:`SingleDetectionInitiator` that takes the measured velocity covariance (and a yaw-rate state,
started from the detection's measured yaw rate, ``step(..., yaw_rates=)``, when it has one).
:meth:`MultiObjectTracker.history` gives the per-frame tracks that
:func:`flowtrack.tracking_io.write_tracks_csv` exports.

The parts have tiny interfaces, in the spirit of Stone Soup, so a lesson can swap one. Each is a
:class:`typing.Protocol` (:class:`Predictor`, :class:`Updater`, :class:`Associator`,
:class:`Initiator`, :class:`Deleter`, :class:`Confirmer`), so any object with these methods plugs in
(M tracks, N detections, d spatial axes, n state components, m measured components; a frame's
detections travel as :class:`Detections`):

=================  =========================================================================
part               interface
=================  =========================================================================
predictor          ``new_filter(dt, q, R (d,d), dim) -> filter``; ``predict(kf) -> None``;
                   ``predict_ahead(kf, n) -> (x (M,n), P (M,n,n))``
updater            ``check(Detections) -> Detections``;
                   ``predict_measurements(kf, Detections) -> MeasurementPrediction`` (``z_pred (M,m)``,
                   ``S (M,m,m) or (M,N,m,m)``, ``measurements (N,m)``, ``has_velocity (N,)``);
                   ``update(kf, Detections, matches (K,2)) -> None``
associator         ``associate(z_pred, S, measurements) -> (matches (K,2), unmatched_tracks,
                   unmatched_detections)``
initiator          ``initiate(positions (k,d), velocities (k,d) or None, velocity_covs (k,d,d) or None)
                   -> (x0 (k,n), P0 (k,n,n))``; also ``yaw_rates=`` (k,) when ``step`` got them
deleter            ``delete(hits (M,), misses (M,), confirmed (M,)) -> bool mask (M,)``
confirmer          ``initial_scores(k) -> (k,)``; ``update_scores(scores (M,), matched (K,),
                   log_likelihood (K,), has_velocity (K,), missed, velocities=None (K, d),
                   velocity_covs=None (K, d, d)) -> (M,)``;
                   ``decide(scores (M,), hits (M,)) -> (confirm (M,), reject (M,))``;
                   ``needs_likelihood`` (bool); with ``needs_positions`` (bool) also
                   ``positions`` (K, d), ``anchors`` (M, d) (mean of each track's detections so far),
                   ``anchor_counts`` (M,) and ``position_cov`` (d, d) (the tracker's R)
=================  =========================================================================

**Where the code lives.** This module is the tracker's face: it exports every name above, and the
API reference documents them here. The code lives in two private modules beside it: ``_tracker``
(:class:`Track`, :class:`FlowOptions`, :class:`MultiObjectTracker`: the loop) and ``_parts`` (the
Protocols and the parts that plug into the loop); the confirmers are :mod:`flowtrack.confirmation`'s.

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

from ..confirmation import HitCountConfirmer, SequentialScoreConfirmer, pair_log_likelihood
from ._parts import (
    Associator,
    Confirmer,
    Deleter,
    Detections,
    FlowUpdater,
    GNNAssociator,
    GreedyAssociator,
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
from ._tracker import FlowOptions, MultiObjectTracker, Track

__all__ = [
    "Associator",
    "Confirmer",
    "Deleter",
    "Detections",
    "FlowOptions",
    "FlowUpdater",
    "GNNAssociator",
    "GreedyAssociator",
    "HitCountConfirmer",
    "Initiator",
    "KalmanPredictor",
    "KalmanUpdater",
    "MaskedGNNAssociator",
    "MeasurementPrediction",
    "MissCountDeleter",
    "MotionPredictor",
    "MultiObjectTracker",
    "NLLRAssociator",
    "Predictor",
    "SequentialScoreConfirmer",
    "SingleDetectionInitiator",
    "Track",
    "Updater",
    "pair_log_likelihood",
]
