r"""The pipeline's settings and the rules derived from them (part of :mod:`flowtrack.pipeline`).

- :class:`PipelineConfig` holds every threshold of the frames → tracks pipeline in metres and
  seconds. They were set on 10 Hz input; the flow interval below keeps them meaning the same at any
  frame rate.
- :func:`track_confirmer` turns ``PipelineConfig.confirmation`` into the tracker's confirmation part:
  Wald's sequential test on the track score, whose clutter hypothesis takes the velocity of static
  clutter as :math:`\mathcal N(0, (s/2)^2 I)` with :math:`s` = ``rgbd_min_speed``, or ``min_hits``
  detections.
- :func:`flow_step` and :func:`flow_partners` choose the frame each frame's scene flow is measured
  against: :math:`k = \max(1, \operatorname{round}(\text{flow\_interval} / \Delta t))` frames on (the
  last :math:`k` frames backwards), so that a pair spans at least ``flow_interval`` seconds.

Import these names from :mod:`flowtrack.pipeline`, which exports (and documents) them.
"""

from __future__ import annotations

from dataclasses import dataclass

from .._validation import positive, positive_int

__all__ = ["PipelineConfig", "flow_partners", "flow_step", "track_confirmer"]


@dataclass(frozen=True)
class PipelineConfig:
    """Tuning of the pipeline (metres, seconds)."""

    lam: float = 1.0  #: graph smoothness weight
    k: int = 8  #: neighbours of the kNN graph
    rematch_iterations: int = 5  #: passes of graph flow with re-matched correspondences
    cluster_radius: float = 0.03  #: spatial radius of the motion graph
    sigma_v: float = 0.05  #: motion-similarity scale (m/s)
    min_speed: float = 0.02  #: slower points are static background (m/s)
    min_cluster_points: int = 50  #: smaller motion clusters are flow noise, sent to the background
    icp_threshold: float = 0.02  #: ICP correspondence distance (m)
    max_points: int = 30000  #: random subsample of each cloud, for speed
    #: real input: the voxel cloud's subsample keeps every point whose RGB-D flow is at least this fast
    #: (m/s) before the random subsample fills the rest of ``max_points``
    #: (:func:`moving_first_subsample`); None (the default): a plain random subsample. A 640x480
    #: Kinect-like view holds 110k-170k voxels, mostly walls and floor, so a random 30 000 keeps about a
    #: quarter of each object's points and a far or thin object can fall under ``min_cluster_points``
    #: (0.02 recovers every object of training sequence 2008). It stays off: on the training split of
    #: benchmarks/_evalscenes.py the denser moving points also turned leaked flow on far walls and
    #: split objects into tracks (mean MOTA 0.44 against 0.52, worst -0.77 against -0.08), since the
    #: cluster and detection thresholds were chosen for the random subsample's density
    moving_first_speed: float | None = None
    track_q: float = 0.1  #: acceleration variance of the tracker's constant-velocity model ((m/s²)²)
    track_r: float = 1e-4  #: detection (cluster centroid) variance (m²): 1 cm standard deviation
    min_hits: int = 2  #: detections that confirm a track
    #: frames a confirmed track may coast through an occlusion. The demo's scenes hide an object for up
    #: to 9 frames (the occlusion scenario's object 1 behind the static box, 0.9 s at 10 Hz); 12 keeps its
    #: track and id through that with a margin. A coasting track's position standard deviation after k
    #: frames grows like sqrt(q (k dt)^3 / 3): 16 cm after 9 frames, 24 cm after 12 with the defaults.
    max_misses: int = 12
    plane_threshold: float = 0.006  #: RANSAC inlier distance of the support planes (table, walls), m
    max_planes: int = 2  #: support planes removed before detection (each >= plane_min_share of the cloud)
    plane_min_share: float = 0.08
    min_detection_points: int = 30  #: smaller pieces of a cluster off the planes are not detections
    gate_prob: float = 0.99  #: tracker's chi-square gate probability
    voxel: float = 0.01  #: voxel size for real clouds (open3d), 0 = off
    max_depth: float = 4.0  #: real input: farther points are dropped (m)
    #: motion clustering of a given (RGB-D) flow: slower points are static. The dense RGB-D flow is
    #: noisier on static surfaces than graph smoothing (median about 1 mm per frame, one point in eight
    #: above 2 mm at 10 Hz on the demo's scene), so its threshold is higher than ``min_speed``.
    rgbd_min_speed: float = 0.04
    rgbd_sigma_v: float = 0.02  #: motion-similarity scale of the clustering of a given flow (m/s)
    #: floor of the velocity standard deviation per axis (m/s) of a detection whose velocity is its
    #: cluster's mean flow (:func:`flowtrack.motion.detection_velocity_covariances`' ``min_std``). The
    #: demo measures the visible centroid's velocity instead, with ``visible_velocity_std``
    velocity_min_std: float = 0.02
    #: the velocity covariance the demo gives a detection's visible-centroid velocity u
    #: (:func:`visible_centroid_velocities`) describes that estimate, a difference of two centroids of depth
    #: pixels labelled through the flow: ``C_e + (visible_velocity_std**2 + f**2 (v . v) 100 / n) I + k (u -
    #: v)(u - v)^T`` with C_e the flow's scatter about its cluster's rigid motion over n_eff = 25 points (the
    #: noise the warped labels inherit; it grows with the sensor's noise), v the piece's mean flow, n its
    #: points, f = ``visible_velocity_speed_fraction`` and k = ``extent_change_inflation``. The middle term is
    #: the error the whole piece shares, which no residual can see: the labelling of its outline, surface
    #: revealed or lost as the outline sweeps the speed times dt per frame, which no warped point marks. The
    #: errors are heavy-tailed (synthetic scenes: median 5 mm/s, 95th percentile 54-66 mm/s, the worst where a
    #: piece is cut in two), so no Gaussian fits both ends. 0.01 m/s was chosen on the crossing, mixed,
    #: occlusion and turning scenes of seeds 10-12 (normalised squared error e^T C^-1 e against the true
    #: visible-centroid velocity: mean 2.8 for the dof 3, 5 % outside the 95 % ellipsoid; k kept at 4) and
    #: gives a mean of 4.6 (6 % outside) on seeds 0-2 (benchmarks/bench_tracking.py); the 0.02 m/s used before
    #: gave means of 1.0 and 2.0 with medians of 0.05 and 0.04. The medians stay below 2.37 (0.15): no
    #: Gaussian fits both the common few-mm/s errors and the tail
    visible_velocity_std: float = 0.01
    #: f above, the share of the speed a small piece's outline sweep adds (scaled by sqrt(100 / n));
    #: off by default. On seeds 10-12 f = 0.1 with ``visible_velocity_std`` 0.002 fitted better (mean 3.0,
    #: median 0.24; 3.6 and 0.25 on seeds 0-2), but n counts cloud points, so the term depends on the
    #: sampling: on the TUM-layout boxes of ``tests/test_tum_input.py`` (30 Hz, 1 cm voxels) it cost
    #: two ID switches more (3 against 1)
    visible_velocity_speed_fraction: float = 0.0
    #: radius (m) within which a depth pixel takes the label of its nearest cloud point (or flow-warped
    #: cloud point) in :func:`visible_centroid_velocities`; about twice the subsampled cloud's spacing
    centroid_radius: float = 0.01
    #: inflation k of a detection's velocity covariance by the visible-extent change,
    #: ``C + k (u - v)(u - v)^T`` (:func:`visible_centroid_velocities`): k = 4 treats the gap between
    #: the visible centroid's velocity u and the material flow v as a two-standard-deviation error
    extent_change_inflation: float = 4.0
    #: how a tentative track is confirmed: ``"score"`` by its sequential log-likelihood-ratio score
    #: (:class:`flowtrack.tracking.SequentialScoreConfirmer`, :func:`track_confirmer`), ``"hits"`` by
    #: ``min_hits`` detections (:class:`flowtrack.tracking.HitCountConfirmer`)
    confirmation: str = "score"
    track_p_detect: float = 0.9  #: detection probability P_D of the track score
    #: clutter (false detection) density of the track score, per m³: about one false detection per
    #: frame in the ~1 m³ the camera sees of the table
    track_clutter_density: float = 1.0
    #: Wald's alpha: probability that a clutter sequence is confirmed (per tentative track)
    track_false_confirm: float = 1e-4
    track_missed_confirm: float = 0.1  #: Wald's beta: probability that an object's sequence is rejected
    #: standard deviation (m) of a static artefact's position jitter beyond ``track_r``: with a number, the
    #: score's clutter hypothesis also holds "a static artefact at a fixed place" (depth-edge artefacts
    #: detected at the same place frame after frame; :class:`flowtrack.tracking.SequentialScoreConfirmer`'s
    #: ``static_position_cov``); None: uniform clutter only. Off by default: on Kinect-like TUM-layout
    #: scenes 0.01 removes the static-artefact tracks (mixed seed 0: MOTA 0.667 -> 0.739, false positives
    #: 8 -> 0) but confirms objects that re-appear after an occlusion later (occlusion seed 0: 0.725 ->
    #: 0.652), and position-only tracks (no velocity evidence) hardly confirm at all
    track_static_position_std: float | None = None
    #: shortest time (s) over which scene flow is measured. The thresholds above were set on 10 Hz
    #: input, where an object moves a few mm per frame pair; a 30 Hz sensor (the TUM sequences) moves it a
    #: third as far while the flow's noise per pair stays about 1 mm, so static surfaces cross
    #: ``rgbd_min_speed`` and objects break up. Input faster than ``1 / flow_interval`` pairs every frame
    #: with the frame ``k = round(flow_interval / dt)`` on (:func:`flow_partners`) and coasts tracks for
    #: ``max_misses * k`` frames, so the same thresholds hold in m/s and seconds at any frame rate
    flow_interval: float = 0.1
    #: let colour decide where geometry cannot tell a piece's motion from standing still
    #: (:func:`detection_pieces`' ``images``): a turning box sweeps its faces over themselves and a box
    #: sliding along its own face stays on that plane, so geometry calls them static; their texture
    #: (or shading) moves. It also keeps the far, slow object of the synthetic crossing scene while the
    #: near one cuts it; that piece's centroid is off the object's, which ``occlusion_position_scale``
    #: accounts for (without it the flow-aided tracker switched identities twice on crossing seed 0)
    colour_check: bool = True
    #: re-acquisition radius (m) of the tracker (:class:`flowtrack.tracking.MultiObjectTracker`'s
    #: ``reacquire_radius``): a track confirmed within this distance of a coasting one is that object
    #: back from an occlusion. An object being hidden shows a shrinking visible surface whose centroid
    #: slides, so its track may coast off its path and miss the object's return; 0.15 m is about a
    #: tabletop object's size. None: off. Chosen on the training split of benchmarks/_evalscenes.py
    #: (seeds 2000-2011, `flowtrack demo --input`, every non-tentative row scored): with
    #: ``track_coast_per_hit`` it keeps ID switches at 4 in all (17 without re-acquisition)
    track_reacquire_radius: float | None = 0.15
    #: a confirmed track coasts at most this many misses per detection it had (and never more than
    #: ``max_misses`` flow intervals; :class:`flowtrack.tracking.MissCountDeleter`'s ``coast_per_hit``).
    #: On the training split of benchmarks/_evalscenes.py most false positives were tracks confirmed
    #: by two detections of a fast object, lost at once and coasted 36 frames (30 Hz) along the
    #: velocity of those two detections: 1.0 took the false positives there from 1026 to 190 rows
    #: (with re-acquisition; 2 and 3 left 266 and 307). None: ``max_misses`` only
    track_coast_per_hit: float | None = 1.0
    #: no track starts from a detection this close (m) to a confirmed track detected in the same frame
    #: (:class:`flowtrack.tracking.MultiObjectTracker`'s ``birth_exclusion_radius``): a second piece of
    #: an object (cut by an occluder, or a face that moves differently) must not become a second track.
    #: 5 cm: two tabletop objects' visible centroids are farther apart than that. (0.15 m, an object's
    #: size, also removed the small objects of the synthetic occlusion scenes passing near others:
    #: MOTA 0.889 -> 0.733.) None: off
    track_birth_exclusion_radius: float | None = 0.05
    #: a missed confirmed track whose predicted position the depth image sees more than this far (m)
    #: behind is not hidden but gone, and is deleted (:class:`FreeSpace`, the tracker's
    #: ``seen_through``) after more than ``track_max_seen_through`` such misses in a row (counted in
    #: flow intervals, as ``max_misses``). None: off, a missed track coasts whatever the sensor saw.
    #: Chosen on the training split of benchmarks/_evalscenes.py (every non-tentative row scored):
    #: the coasting rows of tracks whose object had left or stopped were a third of the false
    #: positives there, and 0.1 m with 0 took the false positives from 118 to 59 rows and the mean
    #: MOTA from 0.524 to 0.567 (fast sequence 2005: 0.339 -> 0.562; no ID switch added: a far
    #: sphere's track deleted as it slid behind an occluder is revived with its id, see the
    #: tracker's ``reacquire_radius``). 0.2 m: mean 0.557; max 1 (3 frames at 30 Hz): mean 0.552
    track_free_space_margin: float | None = 0.1
    track_max_seen_through: int = 0
    #: two pieces are one rigid object (:func:`detection_pieces`' ``rigid_merge`` and ``occluders``) when the
    #: rigid motion fitted to both adds at most this residual (m/s, in quadrature) to their own fits; two
    #: pieces of equal size that move differently add about half their relative speed
    rigid_merge_tolerance: float = 0.015
    #: pieces split by a nearer occluder (:func:`detection_pieces`' ``occluders``) are merged when they are
    #: one rigid object, their closest points are at most this far apart (m), ...
    occlusion_max_gap: float = 0.25
    #: ... and the surface between them is nearer by more than this (m); also how much nearer a surface
    #: must be to hide a point in the colour test and to cut a piece in occlusion_position_covariances
    occlusion_margin: float = 0.02
    #: a detection cut by a nearer surface (:func:`occlusion_position_covariances`) has its position
    #: variance widened toward that surface by (this × its visible extent there)²: the hidden part is
    #: unknown, and one as large as the visible one moves the centroid by half the extent. None: off
    occlusion_position_scale: float | None = 0.5


def track_confirmer(cfg: PipelineConfig):
    r"""The tracker's confirmation part for ``cfg.confirmation`` (``"score"`` or ``"hits"``).

    ``"score"``: :class:`flowtrack.tracking.SequentialScoreConfirmer` with :math:`P_D` =
    ``track_p_detect``, :math:`\lambda_c` = ``track_clutter_density``, :math:`\alpha` =
    ``track_false_confirm``, :math:`\beta` = ``track_missed_confirm`` and static clutter's velocity
    covariance :math:`\Sigma_c = (s/2)^2 I` with :math:`s` = ``rgbd_min_speed``: the motion
    clustering keeps points faster than :math:`s`, about two standard deviations of the flow noise
    on static surfaces, so the clutter it lets through (depth-edge artefacts, flying pixels) moves
    at :math:`\mathcal N(0, (s/2)^2 I)` plus its own measurement noise; with
    ``track_static_position_std`` :math:`\sigma_s`, a static artefact at a fixed place is part of the
    clutter hypothesis too (``static_position_cov`` :math:`= \sigma_s^2 I`). ``"hits"``:
    :class:`flowtrack.tracking.HitCountConfirmer` ``(min_hits)``.

    Examples
    --------
    >>> c = track_confirmer(PipelineConfig())
    >>> type(c).__name__, round(c.confirm_threshold, 2), c.clutter_velocity_cov, c.static_position_cov
    ('SequentialScoreConfirmer', 9.1, 0.0004, None)
    >>> track_confirmer(PipelineConfig(track_static_position_std=0.01)).static_position_cov
    0.0001
    >>> type(track_confirmer(PipelineConfig(confirmation="hits"))).__name__
    'HitCountConfirmer'
    """
    from ..tracking import HitCountConfirmer, SequentialScoreConfirmer

    if cfg.confirmation == "hits":
        return HitCountConfirmer(cfg.min_hits)
    if cfg.confirmation != "score":
        raise ValueError(f"confirmation must be 'score' or 'hits', got {cfg.confirmation!r}")
    return SequentialScoreConfirmer(cfg.track_p_detect, cfg.track_clutter_density,
                                    false_confirm=cfg.track_false_confirm,
                                    missed_confirm=cfg.track_missed_confirm,
                                    clutter_velocity_cov=(cfg.rgbd_min_speed / 2.0) ** 2,
                                    static_position_cov=None if cfg.track_static_position_std is None
                                    else cfg.track_static_position_std ** 2)


def flow_step(dt: float, interval: float = 0.1) -> int:
    r"""Frames between the two frames of a flow pair: :math:`k = \max(1, \operatorname{round}(\text{interval}
    / \Delta t))` (:func:`flow_partners`; the demo also coasts tracks ``max_misses`` times this).

    >>> flow_step(0.1), flow_step(1 / 30), flow_step(0.5)
    (1, 3, 1)
    """
    return max(1, round(positive(interval, "interval") / positive(dt, "dt")))


def flow_partners(n: int, dt: float, interval: float = 0.1) -> list[int]:
    r"""The frame each of ``n`` frames is paired with for scene flow, at least ``interval`` apart in time.

    With :math:`k = \max(1, \operatorname{round}(\text{interval} / \Delta t))`, frame t is paired with
    t + k while that exists, and the last k frames with t − k (the flow of that pair, negated, is the
    velocity at t: every frame gets detections, the last one included). In a sequence shorter than
    2k frames a frame with neither is paired with its farthest frame. The velocity of a pair is the
    mean over its interval, :math:`(X_{t+k} - X_t) / (k\,\Delta t)`: its noise falls like 1/k and a constant
    velocity is unchanged.

    Parameters
    ----------
    n : int, >= 2
        Frames.
    dt : float, > 0
        Frame interval (s).
    interval : float, > 0
        Shortest flow interval (s), :attr:`PipelineConfig.flow_interval`.

    Returns
    -------
    list of int
        Partner of each frame; ``partner[t] - t`` is the signed pair length in frames.

    Examples
    --------
    >>> flow_partners(5, dt=0.1)                  # 10 Hz: the next frame, the last one backwards
    [1, 2, 3, 4, 3]
    >>> flow_partners(8, dt=1 / 30)               # 30 Hz: three frames on
    [3, 4, 5, 6, 7, 2, 3, 4]
    >>> flow_partners(3, dt=1 / 30)               # too short for k = 3
    [2, 2, 0]
    """
    n = positive_int(n, "n", minimum=2)
    k = flow_step(dt, interval)
    out = []
    for t in range(n):
        if t + k <= n - 1:
            out.append(t + k)
        elif t - k >= 0:
            out.append(t - k)
        else:
            out.append(n - 1 if n - 1 - t >= t else 0)
    return out
