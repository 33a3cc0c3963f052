r"""Scoring a tracker run, and the position-only vs flow-aided ablation.

:func:`run_tracker` feeds per-frame detections (optionally with velocities and their covariances)
to a :class:`~flowtrack.tracking.MultiObjectTracker` and records, per frame, the reported positions
and each track's prediction ``ahead`` frames later. :func:`score_run` turns that into CLEAR-MOT /
IDF1 (:func:`flowtrack.metrics.clear_mot`) and the mean ``ahead``-frames prediction error: for every
frame ``t`` and every ground-truth object matched (by ``clear_mot``) to a track at ``t``, the
distance between the track's prediction made at ``t`` and the object's true position at
``t + ahead``, averaged over all such pairs, in millimetres.

:func:`tracking_ablation` runs the same detections twice — ``"position_only"``: the tracker sees
positions only; ``"flow_aided"``: tracks start with the detections' scene-flow velocity and are
updated with position and velocity (``velocity_update=True``, per-detection covariances when given)
— and returns ``{"position_only": {...}, "flow_aided": {...}}`` with ``mota``, ``idf1``,
``id_switches`` and ``prediction_error_mm`` each (plus a few counts).

Examples
--------
Two objects crossing, detected exactly with their velocities:

>>> import numpy as np
>>> Z = [np.array([[0.01 * t, 0.0, 1.0], [0.2 - 0.01 * t, 0.0, 1.0]]) for t in range(12)]
>>> V = [np.array([[0.1, 0.0, 0.0], [-0.1, 0.0, 0.0]])] * 12
>>> truth = [{1: z[0], 2: z[1]} for z in Z]
>>> res = tracking_ablation(Z, V, None, truth, dt=0.1, q=0.1, r=1e-4, ahead=2)
>>> sorted(res), res["flow_aided"]["id_switches"], res["flow_aided"]["prediction_error_mm"] < 1.0
(['flow_aided', 'position_only'], 0, True)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._validation import positive, positive_int
from .metrics import clear_mot
from .tracking import MultiObjectTracker

__all__ = ["run_tracker", "score_run", "tracking_ablation"]


def run_tracker(tracker: MultiObjectTracker, detections: Sequence, velocities: Sequence | None = None,
                velocity_covs: Sequence | None = None, *, ahead: int = 5,
                position_covs: Sequence | None = None, yaw_rates: Sequence | None = None,
                seen_through: Sequence | None = None) -> dict:
    """Step ``tracker`` through the frames; record reported positions and ``ahead``-frame predictions.

    Parameters
    ----------
    tracker : MultiObjectTracker
    detections : sequence of array_like, shape (N_t, dim)
    velocities : sequence of array_like, shape (N_t, dim), optional
    velocity_covs : sequence of array_like, shape (N_t, dim, dim), optional
    ahead : int, >= 1
    position_covs : sequence of (array_like, shape (N_t, dim, dim), or None), optional
        Each detection's position covariance (``step(..., position_covs=)``; a None entry: the
        tracker's R for that frame).
    yaw_rates : sequence of (array_like, shape (N_t,), or None), optional
        Each detection's measured yaw rate (``step(..., yaw_rates=)``).
    seen_through : sequence of (callable or None), optional
        The sensor's free space per frame (``step(..., seen_through=)``, e.g.
        :class:`flowtrack.pipeline.FreeSpace`).

    Returns
    -------
    dict
        ``hyp``: per frame ``{track id: position}`` of the reported tracks detected in that frame
        (``misses == 0``, as the demo scores them); ``pred``: per frame ``{track id: position
        predicted ahead frames later}`` for the same tracks; ``tracks``: per frame the list of live
        tracks (tentative included, for :func:`flowtrack.tracking_io.write_tracks_csv`).
    """
    ahead = positive_int(ahead, "ahead")
    T = len(detections)
    for name, seq in (("velocities", velocities), ("velocity_covs", velocity_covs),
                      ("position_covs", position_covs), ("yaw_rates", yaw_rates),
                      ("seen_through", seen_through)):
        if seq is not None and len(seq) != T:
            raise ValueError(f"{name} must have one entry per frame ({T}), got {len(seq)}")
    hyp, pred, tracks = [], [], []
    d = tracker.dim
    for t in range(T):
        V = None if velocities is None else velocities[t]
        given = {"velocity_covs": None if velocity_covs is None else velocity_covs[t],
                 "position_covs": None if position_covs is None else position_covs[t],
                 "yaw_rates": None if yaw_rates is None else yaw_rates[t],
                 "seen_through": None if seen_through is None else seen_through[t]}
        reported = tracker.step(detections[t], V, **{k: v for k, v in given.items() if v is not None})
        live = tracker.tracks
        ahead_of = tracker.predict_ahead(ahead)
        now = [tr for tr in reported if tr.misses == 0]
        hyp.append({tr.id: tr.position.copy() for tr in now})
        pred.append({tr.id: ahead_of[tr.id][0][:d].copy() for tr in now})
        tracks.append(live)
    return {"hyp": hyp, "pred": pred, "tracks": tracks, "ahead": ahead}


def score_run(run: dict, truth: Sequence[dict], max_dist: float) -> dict:
    """CLEAR-MOT / IDF1 of a :func:`run_tracker` result and its mean prediction error (mm).

    ``truth`` has one ``{object id: position}`` per frame, at least as many frames as the run; its
    frames beyond the run's are used only as the future of the predictions. Besides ``mota``,
    ``idf1``, ``id_switches`` and ``prediction_error_mm``: ``fp``, ``fn``, ``tracks`` (ids ever
    reported as detected) and ``spurious_tracks`` (of those, ids never matched to any object within
    ``max_dist``: tracks of clutter).
    """
    max_dist = positive(max_dist, "max_dist")
    T = len(run["hyp"])
    if len(truth) < T:
        raise ValueError(f"truth must have at least {T} frames, got {len(truth)}")
    mot, matches, _ = clear_mot(list(truth[:T]), run["hyp"], max_dist, return_matches=True)
    ahead = run["ahead"]
    reported = {tid for frame in run["hyp"] for tid in frame}
    matched = {tid for frame in matches for tid in frame.values()}
    errs = []
    for t in range(T):
        if t + ahead >= len(truth):
            break
        fut = truth[t + ahead]
        for obj, tid in matches[t].items():
            if obj in fut and tid in run["pred"][t]:
                errs.append(float(np.linalg.norm(np.asarray(fut[obj]) - run["pred"][t][tid])))
    return {
        "mota": float(mot["mota"]),
        "idf1": float(mot["idf1"]),
        "id_switches": int(mot["id_switches"]),
        "prediction_error_mm": 1000.0 * float(np.mean(errs)) if errs else float("nan"),
        "predictions_scored": len(errs),
        "fp": int(mot["fp"]),
        "tracks": len(reported),
        "spurious_tracks": len(reported - matched),
        "fn": int(mot["fn"]),
        "ahead": ahead,
    }


def tracking_ablation(detections, velocities, velocity_covs, truth, dt, *, q, r, dim=3, ahead=5,
                      max_dist=0.1, tracker_options=None, flow_options=None, position_covs=None,
                      yaw_rates=None, seen_through=None) -> dict:
    r"""Position-only vs flow-aided tracking on the same detections.

    Parameters
    ----------
    detections : sequence of array_like, shape (N_t, dim)
        Per frame.
    velocities : sequence of array_like, shape (N_t, dim)
        Scene-flow velocity of each detection (NaN row: none).
    velocity_covs : sequence of array_like, shape (N_t, dim, dim), or None
        Their covariances (e.g. :func:`flowtrack.motion.detection_velocity_covariances`); None uses
        the tracker's ``velocity_cov`` for all.
    truth : sequence of dict
        ``{object id: position}`` per frame (frames beyond the detections' only score predictions).
    dt, q, r, dim
        The tracker's (:class:`~flowtrack.tracking.MultiObjectTracker`).
    ahead : int
        Prediction horizon in frames.
    max_dist : float
        CLEAR-MOT match distance (m).
    tracker_options : dict, optional
        Further :class:`~flowtrack.tracking.MultiObjectTracker` arguments for both runs
        (``min_hits``, ``max_misses``, ``gate_prob``, ...).
    flow_options : dict, optional
        Extra arguments of the flow-aided run only (e.g. ``p_detect``, ``clutter_density``,
        ``motion_model``, ``velocity_cov``).
    position_covs : sequence of (array_like, shape (N_t, dim, dim), or None), optional
        The detections' position covariances (e.g.
        :func:`flowtrack.pipeline.occlusion_position_covariances`), used by the flow-aided run only
        (its filter takes per-detection covariances); position-only tracking keeps ``r``.
    yaw_rates : sequence of (array_like, shape (N_t,), or None), optional
        The detections' measured yaw rates, for the flow-aided run (its turn-rate tracks start from
        them).
    seen_through : sequence of (callable or None), optional
        The sensor's free space per frame (:class:`flowtrack.pipeline.FreeSpace`), for both runs: the
        same evidence that a coasting track's object is gone.

    Returns
    -------
    dict
        ``{"position_only": {...}, "flow_aided": {...}}``, each from :func:`score_run`.
    """
    base = dict(tracker_options or {})
    flow = {"velocity_update": True, **(flow_options or {})}
    runs = {
        "position_only": run_tracker(MultiObjectTracker(dt, q, r, dim, **base), detections, ahead=ahead,
                                     seen_through=seen_through),
        "flow_aided": run_tracker(MultiObjectTracker(dt, q, r, dim, **base, **flow), detections, velocities,
                                  velocity_covs, ahead=ahead, position_covs=position_covs,
                                  yaw_rates=yaw_rates, seen_through=seen_through),
    }
    return {k: score_run(v, truth, max_dist) for k, v in runs.items()}
