r"""The syllabus' first flowchart as library steps: frames → clouds → scene flow → clusters → detections.

What the demo app (``flowtrack demo``) and lesson 6 share. Per frame pair :math:`(t, t+1)`:

1. :func:`cloud_from_depth` back-projects a depth image, :math:`X = Z\,K^{-1}(u, v, 1)^\top`
   (optionally thinned by open3d's voxel grid to an even density);
2. :func:`scene_flow_and_clusters` estimates scene flow by four point-cloud methods (:data:`METHODS`:
   nearest neighbour, graph, graph with re-matching, rigid ICP per motion cluster) and the motion
   clusters of the re-matched graph flow — or, given the dense RGB-D flow of the pair
   (:func:`rgbd_cloud_flow`: :func:`flowtrack.rgbd_flow.rgbd_point_flow` at the cloud's points, the
   row :data:`RGBD_METHOD`), the motion clusters of that flow, which sees the tangential motion
   that nearest neighbours miss;
3. :func:`detections_from_clusters` removes the support planes (:func:`support_planes`, open3d
   RANSAC) and turns each remaining connected piece of a cluster into a detection: its centroid
   :math:`\bar X` and mean rigid velocity :math:`\bar v` (the mean of a rigid motion's flow over a
   piece is the flow of its centroid, exactly). :func:`detection_pieces`, which finds the pieces,
   can also skip pieces whose points do not move together (``min_speed``: depth-edge artefacts),
   pieces that geometry *and* colour call static (``images``), and merge the pieces of an object
   split by a nearer occluder (``occluders``);
4. :func:`visible_centroid_velocities` gives each detection the velocity of what it measures, the
   centroid of the object's *visible* surface, and a velocity covariance inflated where the visible
   extent changes (below);
5. :meth:`flowtrack.tracking.MultiObjectTracker.step` takes the detections (and velocities), and
   :meth:`~flowtrack.tracking.MultiObjectTracker.predict_ahead` predicts every track N frames.

**The velocity of a visible centroid.** A detection is the centroid :math:`c_t` of the visible
surface :math:`S_t` of an object, so a track follows :math:`c_t`, not a point of the body. The mean
flow :math:`\bar v` of the piece is the velocity of the *material* at :math:`c_t`; the centroid moves
differently whenever :math:`S_t` changes: with :math:`P \subset S_t` the points that stay visible,
:math:`P'` the same points moved by the flow, :math:`H = S_t \setminus P` the surface hidden and
:math:`A` the surface revealed, :math:`S_{t+1} = P' \cup A` and

.. math::
    \frac{c_{t+1} - c_t}{\Delta t} = \bar v_P + \frac{\bar X_P - c_t}{\Delta t}
    + \frac{|A|}{|P| + |A|}\,\frac{\bar Y_A - \bar Y_{P'}}{\Delta t},

(:math:`\bar v_P` the mean flow of the persisting points, :math:`\bar X_P` their centroid at t,
:math:`\bar Y` centroids at t+1). Only when nothing is hidden or revealed (:math:`H = A = \emptyset`)
is this the mean flow. While an object slides behind an occluder, leaves or enters the image, or
turns a face away, the last two terms are a few cm/s, as large as the flow's own error, and a filter
fed :math:`\bar v` extrapolates the visible centroid wrongly even with the true flow.
:func:`visible_centroid_velocities` measures the left side directly, at full resolution: every
valid pixel of depth image t is labelled with the detection of its nearest cloud point
:math:`X_i` and every pixel of depth image t+1 with the detection of its nearest *flow-warped*
point :math:`X_i + v_i\,\Delta t` (static points included, so a pixel belongs to an object only
when the object is its nearest neighbour; farther than ``radius`` from every point: no label).
The flow thus supplies the correspondence; a pixel that becomes hidden has no counterpart at t+1,
a revealed one next to the object's warped surface joins it. Then

.. math::
    u = \frac{\operatorname{mean}\{B_{t+1}(p) : \ell_{t+1}(p) = k\}
            - \operatorname{mean}\{B_t(p) : \ell_t(p) = k\}}{\Delta t},
    \qquad
    C_u = C_v + \kappa\,(u - \bar v)(u - \bar v)^\top ,

with :math:`B_t(p)` the back-projection of pixel p. :math:`C_v` is the flow-residual covariance
(:func:`flowtrack.motion.detection_velocity_covariances`); the gap :math:`u - \bar v` between the
visible centroid's and the material's velocity is the *measured* visible-extent change, and
:math:`\kappa` (``extent_change_inflation``, 4: the gap as a two-standard-deviation error) widens
the covariance along it. Without a change the gap is the pixel-sampling noise (a few mm/s) and
:math:`u \approx \bar v`; with one, the filter learns the centroid's motion yet gates and coasts
with the object's (an object hidden while it slowed would otherwise reappear outside its gate).

**The position of an occluded centroid.** The same surface change moves the detection itself:
while a nearer surface hides part of an object, the visible centroid sits toward the visible side,
off the object's centroid by up to half the hidden extent, and a cut object is two pieces whose
centroids are both off. :func:`occlusion_position_covariances` widens such a detection's position
covariance along the occluder's direction, :math:`R_k = R + (s\,e_k)^2\hat u_k\hat u_k^\top`
(:math:`e_k` the piece's extent along it), and the tracker gates, associates and updates each
detection with its own :math:`R_k` (``MultiObjectTracker.step(..., position_covs=)``), so the track
of the whole object keeps the piece instead of the piece starting a new identity.

**Any frame rate.** The thresholds (speeds in m/s, coasting in frames) were set at 10 Hz. A faster
sensor moves an object less per frame while the flow's noise per frame pair stays the same, so
:func:`flow_partners` pairs every frame with the one ``flow_interval`` (0.1 s) later — a 30 Hz
sequence pairs frame t with t + 3, and its last three frames with t − 3 (velocity negated) — and the
demo coasts ``max_misses`` flow intervals.

Examples
--------
>>> import numpy as np
>>> from flowtrack.camera import PinholeCamera
>>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=1.5, cy=1.0, width=4, height=3)
>>> depth = np.full((3, 4), 2.0)
>>> depth[0, 0] = 0.0                                   # no measurement
>>> cloud_from_depth(depth, cam).shape
(11, 3)
>>> cloud_from_depth(depth, cam, max_depth=1.5).shape   # everything farther than 1.5 m dropped
(0, 3)
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ._graph import as_labels
from ._validation import as_array, nonnegative, positive, positive_int
from .camera import backproject, project
from .clustering import cluster_motion, drop_small_clusters
from .rgbd_flow import grey_image, rgbd_point_flow
from .sceneflow import iterative_graph_scene_flow, nearest_neighbor_targets, rigid_flow_per_cluster

__all__ = [
    "METHODS",
    "PipelineConfig",
    "RGBD_METHOD",
    "cloud_from_depth",
    "detection_pieces",
    "detections_from_clusters",
    "flow_partners",
    "flow_step",
    "occlusion_position_covariances",
    "open3d_threads",
    "rgbd_cloud_flow",
    "scene_flow_and_clusters",
    "track_confirmer",
    "subsample",
    "support_planes",
    "visible_centroid_velocities",
]

#: The scene-flow methods of :func:`scene_flow_and_clusters`, in the order of the demo's tables.
METHODS = ("nearest-neighbour", "graph", "graph + re-matching", "rigid per cluster")
#: The row of :func:`scene_flow_and_clusters` given the RGB-D flow (:func:`rgbd_cloud_flow`).
RGBD_METHOD = "variational RGB-D"


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
    #: floor of a detection's velocity standard deviation per axis (m/s) in the tracker's velocity update
    #: (:func:`flowtrack.motion.detection_velocity_covariances`' ``min_std``). The flow residuals of a
    #: cluster measure its noise, not the estimator's error shared by the whole object (smoothing over
    #: its outline, a visible surface whose centroid slides under occlusion): the RGB-D flow's
    #: moving-point EPE3D is about 2.7 mm per frame (0.027 m/s) on the demo's scene.
    velocity_min_std: float = 0.02
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
    #: tabletop object's size. None: off
    track_reacquire_radius: float | None = None
    #: no track starts from a detection this close (m) to a confirmed track detected in the same frame
    #: (:class:`flowtrack.tracking.MultiObjectTracker`'s ``birth_exclusion_radius``): a second piece of
    #: an object (cut by an occluder, or a face that moves differently) must not become a second track.
    #: 5 cm: two tabletop objects' visible centroids are farther apart than that. (0.15 m, an object's
    #: size, also removed the small objects of the synthetic occlusion scenes passing near others:
    #: MOTA 0.889 -> 0.733.) None: off
    track_birth_exclusion_radius: float | None = 0.05
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
    from .tracking import HitCountConfirmer, SequentialScoreConfirmer

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


def subsample(n: int, max_points: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of a random subset of ``max_points`` of ``range(n)`` (all of them if fewer).

    Examples
    --------
    >>> subsample(5, 10, np.random.default_rng(0))
    array([0, 1, 2, 3, 4])
    >>> idx = subsample(100, 10, np.random.default_rng(0))
    >>> len(idx), bool(np.all(np.diff(idx) > 0))
    (10, True)
    """
    if n <= max_points:
        return np.arange(n)
    return np.sort(rng.choice(n, size=max_points, replace=False))


def cloud_from_depth(depth, camera, *, max_depth: float | None = None, voxel: float = 0.0) -> np.ndarray:
    r"""The point cloud of a depth image: :math:`X = Z\,K^{-1}(u, v, 1)^\top` for every valid pixel.

    Parameters
    ----------
    depth : array_like, shape (H, W)
        Depth Z in metres; 0, negative or non-finite values mark pixels without a measurement.
    camera : flowtrack.camera.PinholeCamera
    max_depth : float, optional
        Farther pixels are dropped too (m).
    voxel : float
        With ``voxel > 0`` the cloud is thinned by open3d's voxel grid of that size (m): one point
        (the mean) per occupied voxel, an even density for real sensors. 0 keeps every pixel.

    Returns
    -------
    ndarray, shape (N, 3)
        Camera coordinates; without ``voxel`` the valid pixels in row-major order (the order of a
        synthetic frame's ground truth, :attr:`flowtrack.synth.Frame.points`).
    """
    Z = np.asarray(depth, dtype=np.float64)
    if Z.ndim != 2:
        raise ValueError(f"depth must be an (H, W) image, got shape {Z.shape}")
    voxel = nonnegative(voxel, "voxel")
    valid = np.isfinite(Z) & (Z > 0)
    if max_depth is not None:
        valid &= Z <= positive(max_depth, "max_depth")
    P = backproject(np.where(valid, Z, 0.0), camera)[valid]
    if voxel > 0 and len(P):
        import open3d as o3d

        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
        P = np.asarray(pc.voxel_down_sample(voxel).points)
    return P


def rgbd_cloud_flow(rgb_t, depth_t, rgb_t1, depth_t1, camera, dt, points, **options) -> np.ndarray:
    r"""Velocities of a cloud of frame t from the dense RGB-D scene flow of the pair (t, t+1).

    :func:`flowtrack.rgbd_flow.rgbd_point_flow` gives the velocity of the back-projection
    :math:`X_p` of every valid pixel of ``depth_t``; each of ``points`` gets the velocity of the
    nearest :math:`X_p` (a k-d tree). For a cloud of back-projected pixels (:func:`cloud_from_depth`
    without ``voxel``, or any subset of it) that nearest point is the pixel itself, so the velocity
    is exactly the estimator's; for a voxel-thinned cloud it is the velocity of the pixel closest to
    the voxel's mean.

    Parameters
    ----------
    rgb_t, depth_t, rgb_t1, depth_t1, camera, dt
        As for :func:`flowtrack.sceneflow.rgbd_scene_flow` (images uint8 (H, W, 3) or grey (H, W),
        depth in metres with 0 = invalid).
    points : array_like, shape (N, 3)
        A cloud of frame t in the camera frame (metres).
    **options
        Options of :func:`~flowtrack.sceneflow.rgbd_scene_flow`.

    Returns
    -------
    ndarray, shape (N, 3)
        Velocities (m/s) in the camera frame of frame t.
    """
    from scipy.spatial import cKDTree

    P = as_array(points, "points", ("N", 3))
    X, v = rgbd_point_flow(rgb_t, depth_t, rgb_t1, depth_t1, camera, dt, **options)
    if len(P) == 0:
        return np.empty((0, 3))
    _, nn = cKDTree(X).query(P, workers=-1)
    return v[nn]


def scene_flow_and_clusters(X, Y, dt: float, config: PipelineConfig | None = None, flow=None):
    """Every scene-flow method of :data:`METHODS` on one pair of clouds, and the motion clusters.

    No index correspondence between the clouds is needed.

    Parameters
    ----------
    X, Y : ndarray, shape (N, 3) and (M, 3)
        The clouds at t and t + dt.
    dt : float
    config : PipelineConfig, optional
    flow : ndarray, shape (N, 3), optional
        A scene flow of ``X`` estimated from more than the clouds — the dense RGB-D flow
        (:func:`rgbd_cloud_flow`). With it the motion clusters (and hence the rigid ICP per cluster)
        come from this flow instead of the re-matched graph flow (thresholds ``rgbd_min_speed`` and
        ``rgbd_sigma_v``), and it is returned as the row :data:`RGBD_METHOD`.

    Returns
    -------
    flows : dict
        Method → (N, 3) velocities of ``X``'s points: the :data:`METHODS` in their order, then
        :data:`RGBD_METHOD` when ``flow`` is given.
    clusters : ndarray, shape (N,) int
        Motion-cluster labels of ``X`` (−1 static; clusters smaller than ``min_cluster_points``
        sent to −1).
    seconds : dict
        The seconds each stage took.
    """
    cfg = config if config is not None else PipelineConfig()
    if flow is not None:
        flow = as_array(flow, "flow", (len(X), 3))
    flows = {}
    t0 = time.perf_counter()
    flows["nearest-neighbour"] = (nearest_neighbor_targets(X, Y) - X) / dt
    t1 = time.perf_counter()
    # the first re-matching pass is the plain graph flow on nearest-neighbour targets
    flows["graph + re-matching"], passes = iterative_graph_scene_flow(
        X, Y, dt, cfg.lam, k=cfg.k, iterations=cfg.rematch_iterations, return_passes=True
    )
    flows["graph"] = passes[0]
    t3 = time.perf_counter()
    if flow is None:
        labels = cluster_motion(X, flows["graph + re-matching"], cfg.cluster_radius, cfg.sigma_v,
                                min_speed=cfg.min_speed, method="connected")
    else:
        labels = cluster_motion(X, flow, cfg.cluster_radius, cfg.rgbd_sigma_v, min_speed=cfg.rgbd_min_speed,
                                method="connected")
    clusters = drop_small_clusters(labels, cfg.min_cluster_points)
    t4 = time.perf_counter()
    flows["rigid per cluster"] = rigid_flow_per_cluster(X, Y, clusters, dt, cfg.icp_threshold)
    t5 = time.perf_counter()
    seconds = {
        "nearest-neighbour": t1 - t0,
        "graph, all passes": t3 - t1,
        "clustering": t4 - t3,
        "rigid per cluster": t5 - t4,
    }
    out = {m: flows[m] for m in METHODS}
    if flow is not None:
        out[RGBD_METHOD] = flow
    return out, clusters, seconds


@contextmanager
def open3d_threads(n: int) -> Iterator[None]:
    """Limit open3d to ``n`` CPU threads inside a ``with`` block; the previous limit is restored after.

    open3d runs its loops on several threads (oneTBB from 0.20 on, OpenMP before), and the result
    of some depends on their timing: ``segment_plane`` (RANSAC) hands out the random samples of one
    seeded generator in whatever order the threads ask for them, so the best plane and its inliers
    change from run to run, and ``registration_icp`` adds up its residuals in a timing-dependent
    order. With one thread both are repeatable bit for bit. The limit holds for the whole process:
    ``open3d.utility.set_max_threads`` (open3d >= 0.20), else (0.19, OpenMP) threadpoolctl's limit of
    the OpenMP runtimes, which also holds for the other libraries that use them. Also a decorator.

    Parameters
    ----------
    n : int, >= 1

    Examples
    --------
    >>> import open3d as o3d
    >>> if hasattr(o3d.utility, "get_max_threads"):
    ...     before = o3d.utility.get_max_threads()
    ...     with open3d_threads(1):
    ...         assert o3d.utility.get_max_threads() == 1
    ...     assert o3d.utility.get_max_threads() == before
    """
    import open3d as o3d

    n = positive_int(n, "n")
    if not hasattr(o3d.utility, "set_max_threads"):  # open3d 0.19: OpenMP
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=n, user_api="openmp"):
            yield
        return
    previous = o3d.utility.get_max_threads()
    o3d.utility.set_max_threads(n)
    try:
        yield
    finally:
        o3d.utility.set_max_threads(0)  # no limit: the automatic default ...
        if o3d.utility.get_max_threads() != previous:  # ... unless a limit had been set before
            o3d.utility.set_max_threads(previous)


def support_planes(points, config: PipelineConfig | None = None) -> np.ndarray:
    """Mask of the points on the largest planes (table, walls): open3d RANSAC, up to ``max_planes``.

    A plane counts when it holds at least ``plane_min_share`` of the points; inliers are within
    ``plane_threshold`` of it (both from ``config``). Returns a bool array of shape (N,). The RANSAC
    samples come from open3d's generator seeded with 0 and drawn by one thread
    (:func:`open3d_threads`), so the same points always give the same mask.
    """
    import open3d as o3d

    cfg = config if config is not None else PipelineConfig()
    P = np.asarray(points, dtype=np.float64)
    on = np.zeros(len(P), dtype=bool)
    rest = np.arange(len(P))
    with open3d_threads(1):
        o3d.utility.random.seed(0)
        for _ in range(cfg.max_planes):
            if len(rest) < 3:
                break
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P[rest]))
            _, inl = pc.segment_plane(cfg.plane_threshold, 3, 200)
            if len(inl) < cfg.plane_min_share * len(P):
                break
            inl = np.asarray(inl, dtype=np.intp)
            on[rest[inl]] = True
            rest = np.delete(rest, inl)
    return on


def detection_pieces(points, clusters, flow, config: PipelineConfig | None = None, next_points=None,
                     dt: float | None = None, *, min_speed: float | None = None,
                     images=None, occluders=None, rigid_merge: bool = False) -> list[np.ndarray]:
    r"""The point sets of :func:`detections_from_clusters`' detections, in the same order.

    Parameters are those of :func:`detections_from_clusters`, and:

    min_speed : float, optional
        A piece whose *mean* flow is slower than this (m/s) is skipped. The motion clustering keeps
        points faster than its threshold one by one; the flow noise of a depth-edge artefact (flying
        pixels, dropouts flickering at a step in depth) is fast point by point but points every way,
        so its mean is near zero, while an object's points move together, :math:`|\bar v| \approx
        \overline{|v|}`. Pass the clustering's own threshold (the demo: ``rgbd_min_speed``).
    images : tuple (rgb_t, rgb_next, camera), optional
        With ``next_points``: the colour images of the two frames (uint8 (H, W, 3) or grey (H, W))
        and the camera. Where geometry leans to static but cannot tell (the moved points' median
        distance to the next cloud at most 1.5 times the static ones'), colour decides: the piece is
        skipped as static only when the median grey-level difference between each point's pixel at
        t and its static position :math:`\pi(X_i)` in the next image is no larger than at its moved
        position :math:`\pi(X_i + v_i\,\Delta t)`. Geometry alone cannot see a textured surface slide along
        itself (a box pushed along its long face stays on that face's plane, and a turning box
        sweeps its faces over themselves); its texture can. A fourth element, the next frame's
        depth image (metres, 0 = none), leaves out the points whose static pixel is covered there
        by a surface more than ``occlusion_margin`` nearer: a moving object that passes over a
        static surface changes that surface's colour without moving it.
    rigid_merge : bool
        Merge touching pieces (closest points within ``cluster_radius``) that one rigid motion
        explains: a turning object's faces move at different velocities, so the motion clustering
        (by velocity similarity) may split it. Pieces a and b are merged when the rigid motion fitted
        to their union's flow (:func:`flowtrack.motion.rigid_motion_from_flow`) adds at most
        ``rigid_merge_tolerance`` (m/s) to the residuals of their own fits,
        :math:`\sqrt{e_{ab}^2 - (n_a e_a^2 + n_b e_b^2)/(n_a + n_b)}` with :math:`e` the residual rms:
        a noisy flow leaves large residuals in every fit, but only two motions add to them (two
        pieces of equal size whose velocities differ by :math:`\Delta` add about
        :math:`|\Delta|/2`).
    occluders : tuple (depth_t, camera), optional
        The depth image of frame t (metres, 0 = none) and the camera: pieces split by something in
        front of them are merged into one detection. An object partly hidden by a nearer one shows
        two pieces with one rigid motion (not one velocity: a turning box's two ends move apart);
        pieces a and b are merged when their closest points are at most ``occlusion_max_gap``
        apart, between the image projections of those points the depth image, once the pieces' own
        surface at either end is passed, is nearer than both points by more than
        ``occlusion_margin`` along at least half of the segment, and one rigid motion explains
        both (as for ``rigid_merge``, ``rigid_merge_tolerance``); merges are transitive.

    Returns
    -------
    list of ndarray of int
        Indices into ``points`` of each detection's piece; detection k is
        ``(points[pieces[k]].mean(0), flow[pieces[k]].mean(0))``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    cfg = config if config is not None else PipelineConfig()
    P = as_array(points, "points", ("N", 3))
    clusters = as_labels(clusters, "clusters", len(P), min_label=-1)
    flow = as_array(flow, "flow", (len(P), 3))
    tree = None
    if next_points is not None:
        if dt is None:
            raise ValueError("dt must be given with next_points")
        dt = positive(dt, "dt")
        tree = cKDTree(as_array(next_points, "next_points", ("M", 3)))
    if min_speed is not None:
        min_speed = nonnegative(min_speed, "min_speed")
    grey = None
    if images is not None:
        if tree is None:
            raise ValueError("images need next_points and dt")
        if len(images) not in (3, 4):
            raise ValueError("images must be (rgb_t, rgb_next, camera[, depth_next])")
        d1 = None
        if len(images) == 4 and images[3] is not None:
            d1 = np.asarray(images[3], dtype=np.float64)
        grey = (grey_image(images[0], "images[0]"), grey_image(images[1], "images[1]"), images[2], d1)
        if grey[0].shape != grey[1].shape:
            raise ValueError(f"images[0] and images[1] must have the same size, got {grey[0].shape} and "
                             f"{grey[1].shape}")
    keep = (clusters >= 0) & ~support_planes(P, cfg)
    pieces = []
    for c in np.unique(clusters[keep]):
        idx = np.flatnonzero(keep & (clusters == c))
        if len(idx) < cfg.min_detection_points:
            continue
        pairs = cKDTree(P[idx]).query_pairs(cfg.cluster_radius, output_type="ndarray")
        A = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(idx), len(idx)))
        _, comp = connected_components(A, directed=False)
        for j in np.unique(comp):
            piece = idx[comp == j]
            if len(piece) >= cfg.min_detection_points:
                if min_speed is not None and np.linalg.norm(flow[piece].mean(axis=0)) < min_speed:
                    continue
                if tree is not None:
                    d_static = np.median(tree.query(P[piece])[0])
                    d_moving = np.median(tree.query(P[piece] + dt * flow[piece])[0])
                    # colour decides only where geometry cannot: both hypotheses fit about as well
                    ambiguous = d_moving <= 1.5 * d_static
                    if d_static <= d_moving and (grey is None or not ambiguous or _colour_static(
                            grey, P[piece], flow[piece], dt, cfg.occlusion_margin)):
                        continue
                pieces.append(piece)
    if rigid_merge and len(pieces) > 1:
        pieces = _merge_rigid(P, pieces, flow, dt if dt is not None else 0.1, cfg)
    if occluders is not None and len(pieces) > 1:
        if len(occluders) != 2:
            raise ValueError("occluders must be (depth_t, camera)")
        depth = np.asarray(occluders[0], dtype=np.float64)
        if depth.ndim != 2:
            raise ValueError(f"occluders[0] must be a depth image of shape (H, W), got {depth.shape}")
        pieces = _merge_occluded(P, pieces, flow, depth, occluders[1], cfg, dt if dt is not None else 0.1)
    return pieces


def _groups(n: int, pairs) -> list[list[int]]:
    """The connected components of ``n`` nodes joined by ``pairs``, each sorted, in order of their
    smallest member (scipy's ``connected_components``, as for the pieces themselves)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.array(pairs, dtype=np.intp).reshape(-1, 2)
    _, comp = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)),
                                   directed=False)
    return sorted((np.flatnonzero(comp == c).tolist() for c in np.unique(comp)), key=min)


def _rigid_rms(P, flow, idx, dt) -> float:
    """Residual rms (m/s) of the rigid motion fitted to the flow of the points ``idx``."""
    from .motion import rigid_motion_from_flow

    return rigid_motion_from_flow(P[idx], flow[idx], dt).residual_rms


def _one_rigid_motion(P, flow, a, b, rms_a, rms_b, dt, tol) -> bool:
    r"""Whether one rigid motion explains pieces ``a`` and ``b``: the residual it adds to their own
    fits, :math:`\sqrt{e_{ab}^2 - (n_a e_a^2 + n_b e_b^2)/(n_a + n_b)}`, is at most ``tol`` (m/s)."""
    union = np.concatenate([a, b])
    pooled = (len(a) * rms_a**2 + len(b) * rms_b**2) / len(union)
    return bool(_rigid_rms(P, flow, union, dt) ** 2 - pooled <= tol**2)


def _merge_rigid_pairs(P, pieces, flow, dt, cfg, near) -> list[np.ndarray]:
    """Merge the pieces a, b for which ``near(tree_a, b)`` holds and one rigid motion explains both
    (``rigid_merge_tolerance``); merges are transitive."""
    from scipy.spatial import cKDTree

    own = [_rigid_rms(P, flow, p, dt) for p in pieces]
    trees = [cKDTree(P[p]) for p in pieces]
    pairs = [(a, b) for a in range(len(pieces)) for b in range(a + 1, len(pieces))
             if near(trees[a], a, b) and _one_rigid_motion(P, flow, pieces[a], pieces[b], own[a], own[b], dt,
                                                           cfg.rigid_merge_tolerance)]
    return [np.sort(np.concatenate([pieces[i] for i in g])) for g in _groups(len(pieces), pairs)]


def _merge_rigid(P, pieces, flow, dt, cfg) -> list[np.ndarray]:
    def touching(tree, a, b):  # closest points within cluster_radius
        gap = tree.query(P[pieces[b]], distance_upper_bound=cfg.cluster_radius)[0].min()
        return gap <= cfg.cluster_radius

    return _merge_rigid_pairs(P, pieces, flow, dt, cfg, touching)


def _occluded_between(xa, xb, depth, cam, margin: float) -> bool:
    """Whether the image segment between the projections of ``xa`` and ``xb`` is covered by a surface
    nearer than both (after the pieces' own surface at either end)."""
    H, W = depth.shape
    ua, ub = project(np.array([xa, xb]), cam)
    n = int(np.ceil(np.hypot(*(ub - ua))))
    if n < 3:
        return False
    uv = ua + np.linspace(0.0, 1.0, n + 1)[1:-1, None] * (ub - ua)
    c = np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)
    r = np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1)
    z = depth[r, c]
    nearer = (z > 0) & (z < min(xa[2], xb[2]) - margin)
    hits = np.flatnonzero(nearer)
    if len(hits) == 0:
        return False
    inner = nearer[hits[0]: hits[-1] + 1]  # the pieces' own surface at the ends is passed
    valid = (z[hits[0]: hits[-1] + 1] > 0)
    return bool(len(inner) >= 0.5 * len(z) and inner[valid].mean() >= 0.8)


def _merge_occluded(P, pieces, flow, depth, cam, cfg, dt) -> list[np.ndarray]:
    def split_by_occluder(tree, a, b):  # closest points near enough, a nearer surface between them
        d, j = tree.query(P[pieces[b]])
        ib = int(np.argmin(d))
        return d[ib] <= cfg.occlusion_max_gap and _occluded_between(
            P[pieces[a]][j[ib]], P[pieces[b]][ib], depth, cam, cfg.occlusion_margin)

    return _merge_rigid_pairs(P, pieces, flow, dt, cfg, split_by_occluder)


def _pixels(Y, cam, shape, offset=(0.0, 0.0)):
    """Column, row (nearest pixel) of the projections of ``Y`` moved by ``offset`` px, and whether
    each lies in front of the camera and inside an image of ``shape`` (outside: column and row -1)."""
    H, W = shape
    ok = Y[:, 2] > 1e-6
    u = np.full(len(Y), -1)
    r = np.full(len(Y), -1)
    u[ok], r[ok] = np.round(project(Y[ok], cam) + offset).astype(int).T
    ok &= (u >= 0) & (u < W) & (r >= 0) & (r < H)
    return np.where(ok, u, -1), np.where(ok, r, -1), ok


def _colour_static(grey, X, v, dt, margin: float) -> bool:
    """Whether the pixels of ``X`` at t match the next image at least as well at their static
    positions as at their moved ones (median absolute grey difference, nearest pixel); with the next
    depth image, points whose static pixel is covered by a surface nearer by more than ``margin``
    there do not count."""
    g0, g1, cam, d1 = grey
    u0, r0, ok0 = _pixels(X, cam, g0.shape)
    u1, r1, ok1 = _pixels(X + dt * v, cam, g0.shape)
    ok = ok0 & ok1
    if d1 is not None:  # something moved in front of the static pixel: its colour says nothing
        z1 = np.where(ok, d1[r0, u0], 0.0)
        ok &= ~((z1 > 0) & (z1 < X[:, 2] - margin))
    if not ok.any():
        return True
    ref = g0[r0[ok], u0[ok]]
    e_static = np.median(np.abs(g1[r0[ok], u0[ok]] - ref))
    e_moving = np.median(np.abs(g1[r1[ok], u1[ok]] - ref))
    return bool(e_static <= e_moving)


def detections_from_clusters(points, clusters, flow, config: PipelineConfig | None = None, next_points=None,
                             dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    r"""Object detections from motion clusters: centroid and mean velocity of each object piece.

    Graph smoothing spreads an object's motion into the table it stands on (the kNN graph links
    them at the contact), and a translation parallel to a plane leaves that plane unchanged, so the
    table next to an object cannot be told apart from it by geometry. The support planes are
    therefore removed (:func:`support_planes`) and each cluster's remaining points are split into
    spatially connected pieces (radius ``cluster_radius``); every piece with at least
    ``min_detection_points`` points is a detection :math:`(\bar X, \bar v)` (the pieces themselves:
    :func:`detection_pieces`).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    clusters : ndarray, shape (N,) int
        Motion-cluster labels, −1 static.
    flow : ndarray, shape (N, 3)
        Velocities whose per-piece mean initialises a track (the rigid flow of each cluster: the
        mean of a rigid motion's flow is the flow of the centroid).
    config : PipelineConfig, optional
    next_points : ndarray, shape (M, 3), optional
        The cloud of frame t+1; with it (and ``dt``) a piece must be better explained as moving
        than as static: the median distance from :math:`X_i + v_i\,\Delta t` to the nearest point
        of the next cloud must be smaller than that from :math:`X_i` itself. Static surface that a
        cluster reached through noisy points (and whose rigid flow is therefore the cluster's, not
        its own) fails this test and is skipped.
    dt : float, optional

    Returns
    -------
    centroids, velocities : ndarray, shape (K, 3)
    """
    P = as_array(points, "points", ("N", 3))
    flow = as_array(flow, "flow", (len(P), 3))
    pieces = detection_pieces(P, clusters, flow, config, next_points, dt)
    Z = [P[piece].mean(axis=0) for piece in pieces]
    V = [flow[piece].mean(axis=0) for piece in pieces]
    return np.array(Z).reshape(-1, 3), np.array(V).reshape(-1, 3)


def _piece_index(piece, k: int, n: int) -> np.ndarray:
    """``pieces[k]`` as an index array into ``n`` points (ValueError naming it otherwise)."""
    idx = np.asarray(piece)
    if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer) or (idx.size and (
            idx.min() < 0 or idx.max() >= n)):
        raise ValueError(f"pieces[{k}] must be a 1-D int array of indices into points (0 .. {n - 1})")
    return idx


#: the 8 directions (unit image vectors) :func:`occlusion_position_covariances` looks along
_RING = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=float)
_RING /= np.linalg.norm(_RING, axis=1)[:, None]


def occlusion_position_covariances(points, pieces, depth_t, camera, r, *, scale: float = 0.5,
                                   margin: float = 0.02, offset: int = 4, min_fraction: float = 0.03):
    r"""Position covariance of each detection, widened toward a nearer surface that cuts it.

    A detection is the centroid of the *visible* part of an object. When a nearer surface hides part
    of the object, the centroid lies off the object's by up to half the hidden extent, along the
    image direction of the occluder, and a track that follows the whole object sees the detection
    jump by a few cm as the occluder passes (or as the object is cut in two pieces). The detection
    is then a measurement of the object's position with a larger error *along that direction*:

    .. math::
        R_k = R + (s\, e_k)^2\, \hat u_k \hat u_k^\top ,

    with :math:`\hat u_k` the unit 3-D direction (camera frame, at constant depth) of the image
    direction toward the occluder, :math:`e_k` the piece's extent along :math:`\hat u_k` and s
    (``scale``) the fraction of it taken as one standard deviation (0.5: a hidden part as large as
    the visible one). Point :math:`X_i` of a piece touches an occluder when one of the 8 pixels
    ``offset`` px from its projection (along the image axes and diagonals) holds a surface nearer than
    :math:`z_i - \text{margin}`; :math:`\hat u_k` is the sum of those directions over the piece's
    touching points, lifted to 3-D as :math:`(u_x/f_x,\ u_y/f_y,\ 0)` normalised. A piece with fewer
    than ``min_fraction`` of its points (or fewer than 3) touching keeps R.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        The cloud of frame t (camera frame, metres).
    pieces : sequence of array_like of int
        Indices into ``points`` of each detection (:func:`detection_pieces`); K pieces.
    depth_t : array_like, shape (H, W)
        The depth image of frame t (metres; 0 or non-finite: no surface).
    camera : flowtrack.camera.PinholeCamera
    r : float or array_like, shape (3, 3)
        The detections' position variance (m², e.g. ``track_r``) or covariance R.
    scale : float, >= 0
        s.
    margin : float, >= 0
        How much nearer (m) a surface must be to count as an occluder.
    offset : int, >= 1
        Pixels between a point's projection and the pixels looked at.
    min_fraction : float in [0, 1]

    Returns
    -------
    ndarray, shape (K, 3, 3)

    Examples
    --------
    A plate 1 m away, 19 cm wide (columns at x = -0.095 … 0.095 m); a wall 0.5 m away then covers
    the image right of x = 0.1 m. The plate touches it on its right: its variance along x grows by
    (0.5 · 0.19 m)² = 0.009 m²:

    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=29.5, cy=19.5, width=60, height=40)
    >>> x = (np.arange(60) - 29.5) / 100.0                      # x of each column at 1 m
    >>> depth = np.where((x > -0.1) & (x < 0.1), 1.0, 2.0)[None, :].repeat(40, axis=0)
    >>> P = cloud_from_depth(depth, cam)
    >>> plate = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> np.round(occlusion_position_covariances(P, [plate], depth, cam, 1e-4)[0].diagonal(), 4).tolist()
    [0.0001, 0.0001, 0.0001]
    >>> depth[:, x > 0.1] = 0.5
    >>> np.round(occlusion_position_covariances(P, [plate], depth, cam, 1e-4)[0].diagonal(), 4).tolist()
    [0.0091, 0.0001, 0.0001]
    """
    X = as_array(points, "points", ("N", 3))
    D = np.asarray(depth_t, dtype=np.float64)
    if D.ndim != 2:
        raise ValueError(f"depth_t must be a depth image of shape (H, W), got {D.shape}")
    D = np.where(np.isfinite(D), D, 0.0)
    R = np.asarray(r, dtype=np.float64)
    if R.ndim == 0:
        R = positive(float(R), "r") * np.eye(3)
    R = as_array(R, "r", (3, 3))
    scale = nonnegative(scale, "scale")
    margin = nonnegative(margin, "margin")
    offset = positive_int(offset, "offset")
    min_fraction = nonnegative(min_fraction, "min_fraction")
    if min_fraction > 1:
        raise ValueError(f"min_fraction must be in [0, 1], got {min_fraction}")
    out = np.broadcast_to(R, (len(pieces), 3, 3)).copy()
    for k, piece in enumerate(pieces):
        P = X[_piece_index(piece, k, len(X))]
        P = P[P[:, 2] > 1e-6]
        if len(P) < 3:
            continue
        toward = np.zeros((len(P), 2))
        touch = np.zeros(len(P), dtype=bool)
        for o in _RING:
            u, v, inside = _pixels(P, camera, D.shape, offset * o)
            z = np.where(inside, D[v, u], 0.0)
            nearer = (z > 0) & (z < P[:, 2] - margin)
            toward[nearer] += o
            touch |= nearer
        if touch.sum() < 3 or touch.mean() < min_fraction:
            continue
        u = toward[touch].sum(axis=0) / np.array([camera.fx, camera.fy])
        if not np.linalg.norm(u) > 1e-12:
            continue  # surrounded evenly: no direction
        u3 = np.array([u[0], u[1], 0.0]) / np.linalg.norm(u)
        along = P @ u3
        out[k] += (scale * (along.max() - along.min())) ** 2 * np.outer(u3, u3)
    return out


def visible_centroid_velocities(points, pieces, flow, depth_t, depth_t1, camera, dt, *, radius: float = 0.01,
                                velocity_covs=None, inflation: float = 4.0, min_pixels: int = 10):
    r"""Velocity of each detection's visible-surface centroid over a frame pair, and its covariance.

    The method and its maths are in the module docstring (*The velocity of a visible centroid*):
    the pixels of ``depth_t`` take the label of their nearest point of ``points``, those of
    ``depth_t1`` the label of their nearest flow-warped point ``points + dt * flow`` (within
    ``radius``, else none); detection k's velocity is the difference of the centroids of its
    back-projected pixels divided by ``dt``,
    :math:`u_k = (\bar B_{t+1}[\ell_{t+1} = k] - \bar B_t[\ell_t = k])/\Delta t` (:math:`\bar B` the mean
    back-projection of the pixels with that label),
    and with ``velocity_covs`` its covariance is
    :math:`C_k + \kappa (u_k - \bar v_k)(u_k - \bar v_k)^\top`, :math:`\bar v_k` the piece's mean flow.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        The cloud of frame t (camera frame, metres); any subset of ``depth_t``'s back-projection
        or a voxel-thinned version of it.
    pieces : sequence of array_like of int
        Indices into ``points`` of each detection (:func:`detection_pieces`); K pieces.
    flow : array_like, shape (N, 3)
        Velocities of ``points`` (m/s), e.g. :func:`rgbd_cloud_flow`.
    depth_t, depth_t1 : array_like, shape (H, W)
        The depth images of frames t and t+1 (metres; 0 / non-finite = no measurement).
    camera : flowtrack.camera.PinholeCamera
    dt : float, > 0
    radius : float, > 0
        Farthest a pixel may be from its nearest (warped) cloud point and still take its label (m).
    velocity_covs : array_like, shape (K, 3, 3), optional
        Covariance of each piece's mean flow (:func:`flowtrack.motion.detection_velocity_covariances`);
        a NaN row stays NaN.
    inflation : float, >= 0
        :math:`\kappa`.
    min_pixels : int, >= 1
        A detection with fewer labelled pixels in either frame keeps its mean flow (and covariance).

    Returns
    -------
    velocities : ndarray, shape (K, 3)
    covariances : ndarray, shape (K, 3, 3) or None
        None without ``velocity_covs``.

    Examples
    --------
    A plate 1 m away slides along x at 0.1 m/s (10 px per frame at fx = 100), its flow exact.
    Unhidden, its visible centroid moves with it; with a nearer wall covering x > 0.12 m the plate's
    leading columns vanish, its visible centroid slows down, and the gap to the flow widens the
    covariance along x:

    >>> import numpy as np
    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=29.5, cy=19.5, width=60, height=40)
    >>> def frame(x0, wall):
    ...     X = (np.arange(60) - 29.5) / 100.0                     # x of each column at 1 m
    ...     on = (X > x0) & (X < x0 + 0.2)
    ...     d = np.where(on, 1.0, 2.0)[None, :].repeat(40, axis=0)
    ...     return np.where((X > 0.12)[None, :] & wall, 0.5, d)   # the wall, 0.5 m away
    >>> d0 = frame(-0.2, False)
    >>> P = cloud_from_depth(d0, cam)
    >>> piece = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> flow = np.zeros_like(P)
    >>> flow[piece] = [0.1, 0.0, 0.0]
    >>> u, _ = visible_centroid_velocities(P, [piece], flow, d0, frame(-0.1, False), cam, 1.0)
    >>> np.round(u, 6).tolist()
    [[0.1, 0.0, 0.0]]
    >>> d0 = frame(-0.05, True)
    >>> P = cloud_from_depth(d0, cam)
    >>> piece = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> flow = np.zeros_like(P)
    >>> flow[piece] = [0.1, 0.0, 0.0]
    >>> u, C = visible_centroid_velocities(P, [piece], flow, d0, frame(0.05, True), cam, 1.0,
    ...                                    velocity_covs=np.eye(3)[None] * 1e-4, inflation=4.0)
    >>> (np.round(u, 6) + 0.0).tolist(), np.round(C[0].diagonal(), 6).tolist()
    ([[0.05, 0.0, 0.0]], [0.0101, 0.0001, 0.0001])
    """
    from scipy.spatial import cKDTree

    X = as_array(points, "points", ("N", 3))
    V = as_array(flow, "flow", X.shape)
    dt = positive(dt, "dt")
    radius = positive(radius, "radius")
    inflation = nonnegative(inflation, "inflation")
    min_pixels = positive_int(min_pixels, "min_pixels")
    D0 = np.asarray(depth_t, dtype=np.float64)
    D1 = np.asarray(depth_t1, dtype=np.float64)
    if D0.ndim != 2 or D1.shape != D0.shape:
        raise ValueError(f"depth_t and depth_t1 must be (H, W) images of one shape, got {D0.shape} and "
                         f"{D1.shape}")
    K = len(pieces)
    lab = np.full(len(X), -1, dtype=np.intp)
    for k, piece in enumerate(pieces):
        lab[_piece_index(piece, k, len(X))] = k
    Cin = None
    if velocity_covs is not None:
        from .motion import check_velocity_covs

        Cin = check_velocity_covs(velocity_covs, K, 3)
    mean_flow = np.array([V[np.asarray(p)].mean(axis=0) if len(p) else np.full(3, np.nan)
                          for p in pieces]).reshape(K, 3)
    U = mean_flow.copy()
    if K and len(X):
        B0, B1 = cloud_from_depth(D0, camera), cloud_from_depth(D1, camera)
        if len(B0) and len(B1):
            d0, n0 = cKDTree(X).query(B0, workers=-1)
            d1, n1 = cKDTree(X + dt * V).query(B1, workers=-1)
            l0 = np.where(d0 <= radius, lab[n0], -1)
            l1 = np.where(d1 <= radius, lab[n1], -1)
            n_0 = np.bincount(l0 + 1, minlength=K + 1)[1:]
            n_1 = np.bincount(l1 + 1, minlength=K + 1)[1:]
            s0 = np.stack([np.bincount(l0 + 1, weights=B0[:, i], minlength=K + 1)[1:] for i in range(3)], 1)
            s1 = np.stack([np.bincount(l1 + 1, weights=B1[:, i], minlength=K + 1)[1:] for i in range(3)], 1)
            ok = (n_0 >= min_pixels) & (n_1 >= min_pixels)
            U[ok] = (s1[ok] / n_1[ok, None] - s0[ok] / n_0[ok, None]) / dt
    if Cin is None:
        return U, None
    gap = U - mean_flow
    C = Cin + inflation * gap[:, :, None] * gap[:, None, :]
    return U, C
