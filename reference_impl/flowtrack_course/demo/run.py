"""The demo's run: :func:`run_demo` orchestrates the library pipeline (:mod:`flowtrack.pipeline`),
the tracker, the metrics, the figures and the report."""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from flowtrack.motion import detection_velocity_covariances
from flowtrack.pipeline import (
    METHODS,
    RGBD_METHOD,
    FreeSpace,
    detection_pieces,
    flow_partners,
    flow_step,
    occlusion_position_covariances,
    open3d_threads,
    rgbd_cloud_flow,
    scene_flow_and_clusters,
    track_confirmer,
    visible_centroid_velocities,
)
from flowtrack.sceneflow import scene_flow_metrics
from flowtrack.tracking_io import write_tracks_csv
from flowtrack.validation import positive_int

from ..report import render_markdown, write_report
from .config import DEFAULT_NOISE, DemoConfig
from .figures import (
    plot_clusters,
    plot_flow_field,
    plot_motorcycle,
    plot_trajectories,
    plot_tud_campus,
    write_gif,
)
from .inputs import FrameCloud, frame_cloud, load_input, surface_centroids
from .reproduce import reproduce_command
from .sections import echo_summary, report_sections

__all__ = [
    "DemoConfig", "FlowPair", "assign_tracks", "cluster_purity", "detection_measurements", "json_default",
    "json_number",
    "motorcycle_section", "pooled_metrics", "run_demo", "tracking_ablation_section",
]


@dataclass
class FlowPair:
    """Everything estimated for one frame pair (t, t+1)."""

    index: int
    points: np.ndarray
    gt_flow: np.ndarray | None
    labels_gt: np.ndarray | None
    flows: dict[str, np.ndarray] = field(default_factory=dict)
    clusters: np.ndarray | None = None
    seconds: dict[str, float] = field(default_factory=dict)


def cluster_purity(truth, clusters) -> float:
    """Share of points whose cluster's majority true label is their own (−1 clusters count as one).

    Over-segmenting a rigid body into several clusters costs nothing here (each piece still moves
    rigidly), while merging two motions does, which is what matters for rigid flow per cluster.
    """
    truth = np.asarray(truth)
    clusters = np.asarray(clusters)
    good = 0
    for c in np.unique(clusters):
        _, counts = np.unique(truth[clusters == c], return_counts=True)
        good += counts.max()
    return float(good / len(truth))


def motorcycle_section(cfg: DemoConfig, seed: int = 0, figure: Path | str | None = None) -> dict:
    """The same methods on real geometry: the Middlebury Motorcycle cloud with known motions.

    With ``figure`` a PNG of the true and the estimated (rigid per cluster) flow is written there.
    """
    from sklearn.metrics import adjusted_rand_score

    from flowtrack.datasets import motorcycle_flow_case

    case = motorcycle_flow_case(seed=seed)
    # a sparser cloud (about 1 cm between points) moving faster (about 4 cm per frame)
    cfg = replace(cfg, cluster_radius=0.05, icp_threshold=0.05)
    flows, clusters, seconds = scene_flow_and_clusters(case["points_t"], case["points_t1"], case["dt"], cfg)
    gt = case["gt_flow"]
    if figure is not None:
        plot_motorcycle(case, flows["rigid per cluster"], Path(figure))
    metrics = {
        m: {"all": (every := scene_flow_metrics(f, gt, dt=case["dt"])), "moving": every}
        for m, f in flows.items()
    }
    return {
        "points": len(gt),
        "scene_flow": metrics,
        "clustering_adjusted_rand_index": float(adjusted_rand_score(case["labels_t"], clusters)),
        "clustering_purity": cluster_purity(case["labels_t"], clusters),
        "clusters": int(clusters.max() + 1),
        "seconds": seconds,
    }


def pooled_metrics(pairs: list[FlowPair], dt: float) -> dict[str, dict[str, dict[str, float]]]:
    """FlowNet3D metrics of each method, on all points and on the moving points only.

    Velocities are turned into per-frame displacements (``dt``) so the thresholds are in metres. On
    static points the relative criteria are degenerate (zero ground truth), hence the moving-only set.
    """
    gt = np.concatenate([p.gt_flow for p in pairs])
    moving = np.linalg.norm(gt, axis=1) > 0
    out = {}
    for m in [m for m in (*METHODS, RGBD_METHOD) if m in pairs[0].flows]:
        pred = np.concatenate([p.flows[m] for p in pairs])
        out[m] = {
            "all": scene_flow_metrics(pred, gt, dt=dt),
            "moving": scene_flow_metrics(pred, gt, moving, dt=dt),
        }
    return out


def assign_tracks(tracks: dict[int, np.ndarray], truth: dict[int, np.ndarray], gate: float) -> dict[int, int]:
    """Track id → object id by least total distance among pairs closer than ``gate``."""
    from scipy.optimize import linear_sum_assignment

    if not tracks or not truth:
        return {}
    ti, oi = list(tracks), list(truth)
    C = np.array([[np.linalg.norm(tracks[a] - truth[b]) for b in oi] for a in ti])
    r, c = linear_sum_assignment(np.where(C <= gate, C, 1e6))
    return {ti[i]: oi[j] for i, j in zip(r, c) if C[i, j] <= gate}


def detection_measurements(inp, t: int, X, clusters, flow, next_points, cfg: DemoConfig,
                           partner: int | None = None, *, yaw_axis=None):
    """Detections of frame ``t`` with their velocity measurements: ``(Z (K, 3), U (K, 3), C (K, 3, 3),
    R (K, 3, 3) or None)``.

    ``Z`` are the pieces' centroids (:func:`flowtrack.pipeline.detection_pieces`); ``U`` the velocity
    of each piece's visible-surface centroid and ``C`` its covariance: the flow's scatter about its
    cluster's rigid motion (:func:`flowtrack.motion.detection_velocity_covariances`, ``min_std =
    visible_velocity_std``) plus ``visible_velocity_speed_fraction**2 (v . v) 100 / n I`` for a piece of
    n points with mean flow v (see :class:`flowtrack.pipeline.PipelineConfig`), widened by the
    visible-extent change
    (:func:`flowtrack.pipeline.visible_centroid_velocities`, ``radius = centroid_radius``, at least the
    voxel size of a real cloud; ``inflation = extent_change_inflation``). ``R`` is each detection's
    position covariance, ``track_r`` widened toward a nearer surface that cuts the piece
    (:func:`flowtrack.pipeline.occlusion_position_covariances`, ``scale = occlusion_position_scale``;
    None when that is None). The benchmark (``benchmarks/bench_tracking.py``) builds its detections
    with this function too.

    ``flow`` and ``next_points`` belong to the pair (``t``, ``partner``) (default ``t + 1``; see
    :func:`flowtrack.pipeline.flow_partners`): ``flow`` is the velocity toward frame ``partner``
    over the time between the two frames (``DemoInput.interval``: their timestamps for real
    input). For a backward pair (``partner < t``) the returned ``U`` is negated, so it is always the
    velocity at frame ``t`` forward in time.

    With ``yaw_axis`` (a unit 3-vector, e.g. the table's normal in the camera frame) a fifth array
    ``W (K,)`` follows: each piece's yaw rate about that axis, the angular velocity of the rigid motion
    fitted to its flow (Kabsch, :func:`flowtrack.motion.rigid_motion_from_flow`), for
    ``MultiObjectTracker.step(..., yaw_rates=)``.
    """
    s = t + 1 if partner is None else int(partner)
    if s == t:
        raise ValueError(f"partner must differ from t={t}")
    dt = abs(inp.interval(t, s))
    if not dt > 0:
        raise ValueError(f"frames {t} and {s} have the same timestamp; timestamps must increase")
    depth_t, depth_t1 = inp.depth[t], inp.depth[s]
    if inp.scene is None:  # the real cloud drops points beyond max_depth: so do its pixels
        depth_t = np.where(depth_t <= cfg.max_depth, depth_t, 0.0)
        depth_t1 = np.where(depth_t1 <= cfg.max_depth, depth_t1, 0.0)
    colour = (inp.rgb[t], inp.rgb[s], inp.camera, depth_t1) if cfg.colour_check else None
    pieces = detection_pieces(X, clusters, flow, cfg, next_points=next_points, dt=dt,
                              min_speed=cfg.rgbd_min_speed, images=colour,
                              occluders=(depth_t, inp.camera), rigid_merge=True)
    Z = np.array([X[p].mean(axis=0) for p in pieces]).reshape(-1, 3)
    # the covariance of the visible centroid's velocity itself (see PipelineConfig.visible_velocity_std):
    # the flow's scatter about its cluster's rigid motion, which the warped labels inherit (a point of
    # the piece's main cluster stands for the piece: a piece merged across an occluder has its centroid
    # in the gap, maybe nearest to the occluder's points), plus the error the whole piece shares
    rep = []
    for p in pieces:
        labs, counts = np.unique(clusters[p], return_counts=True)
        rep.append(X[p[np.flatnonzero(clusters[p] == labs[np.argmax(counts)])[0]]])
    rep = np.array(rep).reshape(-1, 3)
    C = detection_velocity_covariances(X, clusters, flow, rep, dt, min_std=cfg.visible_velocity_std)
    for k, p in enumerate(pieces):
        C[k] += (cfg.visible_velocity_speed_fraction**2 * float(np.sum(flow[p].mean(axis=0) ** 2))
                 * 100.0 / len(p)) * np.eye(3)
    radius = cfg.centroid_radius if inp.scene is not None else max(cfg.centroid_radius, cfg.voxel)
    U, C = visible_centroid_velocities(X, pieces, flow, depth_t, depth_t1, inp.camera, dt, radius=radius,
                                       velocity_covs=C, inflation=cfg.extent_change_inflation)
    Rz = None
    if cfg.occlusion_position_scale is not None:
        Rz = occlusion_position_covariances(X, pieces, depth_t, inp.camera, cfg.track_r,
                                            scale=cfg.occlusion_position_scale, margin=cfg.occlusion_margin)
    sign = 1.0 if s > t else -1.0
    if yaw_axis is None:
        return Z, sign * U, C, Rz
    from flowtrack.motion import rigid_motion_from_flow

    W = np.array([sign * rigid_motion_from_flow(X[p], flow[p], dt).yaw_rate(yaw_axis) for p in pieces])
    return Z, sign * U, C, Rz, W


@open3d_threads(1)
def run_demo(
    out: Path | str = "out",
    n_objects: int = 3,
    n_frames: int | None = 24,
    image_size: tuple[int, int] = (240, 320),
    seed: int = 0,
    noise: float = DEFAULT_NOISE,
    config: DemoConfig | None = None,
    progress: bool = True,
    echo=print,
    *,
    scenario: str = "mixed",
    predict_ahead: int = 5,
    input_dir: Path | str | None = None,
    input_options: dict | None = None,
    real_data: bool = True,
    gif: bool = True,
) -> dict:
    """Run the demo; write figures, ``tracks.gif``, ``tracks.csv``, ``metrics.json``, ``metrics.md``,
    ``report.html``.

    The scene flow that clustering and the tracker use is the dense variational RGB-D flow of each
    frame pair (:func:`flowtrack.pipeline.rgbd_cloud_flow`), for the synthetic scene and for real
    input alike. Each detection carries the velocity of its visible-surface centroid and that
    velocity's covariance, widened by the visible-extent change
    (:func:`detection_measurements`); the tracker updates with position and velocity
    (``velocity_update=True``, constant-velocity model).

    ``tracks.csv`` (:func:`flowtrack.tracking_io.write_tracks_csv`) holds every live track of every
    processed frame (tentative and coasting included), camera frame of that frame, metres and m/s,
    ``frame`` its index in the input. The synthetic scene processes frames 0 … n−2, each paired with
    the next one; real input processes every frame it reads, each paired with the frame
    ``flow_interval`` later (the last ones with the frame that long before,
    :func:`flowtrack.pipeline.flow_partners`), and with ``step`` frame k read is input frame k·step.
    With ground truth, ``metrics.json["tracking_ablation"]``
    compares position-only and flow-aided tracking on the same detections
    (:func:`flowtrack.tracking_eval.tracking_ablation`); real input has None there.

    Parameters
    ----------
    out : path
        Output folder (created).
    n_objects, image_size, seed, noise, scenario
        The synthetic scene (:func:`flowtrack.synth.make_scene`); ignored with ``input_dir``.
    n_frames : int, >= 2, optional
        Frames the pipeline processes (at most this many with ``input_dir``; None: 24 synthetic frames,
        or every frame of ``input_dir``).
    config : DemoConfig, optional
    predict_ahead : int, >= 1
        Horizon N (frames) of the final prediction of every track.
    input_dir : path, optional
        A real sequence instead of the synthetic one (:mod:`flowtrack.rgbd_io`); ``input_options``
        are passed to :func:`~flowtrack.rgbd_io.load_tum_sequence` (or, with ``stereo=True``, to
        :func:`~flowtrack.rgbd_io.load_stereo_sequence`): ``intrinsics``, ``depth_scale``, ...
    real_data : bool
        Add the Motorcycle (scene flow) and TUD-Campus (tracking) sections.
    gif : bool
        Write the animated ``tracks.gif``.

    Returns
    -------
    dict
        The summary that is also written to ``metrics.json``; its ``"reproduce"`` is the command that
        runs this call again (shown in the report, see :func:`reproduce_command`).

    Notes
    -----
    Two runs with the same arguments give identical results, bit for bit, on one machine: open3d is
    limited to one thread while the demo runs (:func:`open3d_threads`; the previous limit is
    restored afterwards). With open3d's default of one thread per core, its RANSAC plane fit
    (``segment_plane`` in :func:`support_planes`) is not repeatable although its generator is
    seeded: the threads draw the random samples from that one generator in whatever order they get
    to it, so which planes are tried, the best plane and its inliers change from run to run. The
    support planes removed before detection then differ by a few points, the detections (centroids
    of what is left) and track positions by 1e-5 to 1e-4 m, MOTP by about 1e-5 m, the tracks'
    velocities and predictions by up to 1e-4 (m/s, m); the scene-flow metrics never moved. open3d's
    ICP also adds up its residuals in a timing-dependent order (its RMSE, which the convergence test
    reads, moves in the last bits); its transforms were repeatable in hundreds of trials, and with
    one thread this too is settled. scipy's ``cKDTree`` queries with ``workers=-1`` are
    deterministic (every query point is answered on its own), and so are the graph solves and the
    clustering. The single thread costs about 3 % of the demo's time on two cores (ICP +0.2 s,
    RANSAC +0.1 s over 23 frame pairs). open3d is imported before the run's clock starts (the thread
    limit needs it), so ``total_seconds`` leaves its import out.
    """
    cfg = config or DemoConfig()
    if n_frames is None and input_dir is None:
        n_frames = 24
    if n_frames is not None:
        n_frames = positive_int(n_frames, "n_frames", minimum=2)  # scene flow needs a frame pair
    predict_ahead = positive_int(predict_ahead, "predict_ahead")
    seed = positive_int(seed, "seed", minimum=0)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out must be a folder, got the file {out}")
    started = time.perf_counter()
    inp = load_input(input_dir, n_frames, n_objects, image_size, seed, noise, predict_ahead, scenario,
                      input_options)
    out.mkdir(parents=True, exist_ok=True)
    scene, cam, dt = inp.scene, inp.camera, inp.dt
    rng = np.random.default_rng(seed)

    from flowtrack.tracking import MissCountDeleter, MultiObjectTracker

    # max_misses counts flow intervals: input faster than 1 / flow_interval coasts as long in seconds
    max_misses = cfg.max_misses * flow_step(dt, cfg.flow_interval)
    tracker_options = dict(min_hits=cfg.min_hits, max_misses=max_misses,
                           gate_prob=cfg.gate_prob, reacquire_radius=cfg.track_reacquire_radius,
                           birth_exclusion_radius=cfg.track_birth_exclusion_radius,
                           max_seen_through=cfg.track_max_seen_through * flow_step(dt, cfg.flow_interval),
                           confirmer=track_confirmer(cfg),
                           deleter=MissCountDeleter(max_misses, coast_per_hit=cfg.track_coast_per_hit))
    tracker = MultiObjectTracker(dt=dt, q=cfg.track_q, r=cfg.track_r, dim=3, velocity_update=True,
                                 **tracker_options)
    # a detection needs min_detection_points subsampled points (off the planes): ground truth ignores
    # objects with fewer visible pixels than that (as MOT benchmarks ignore heavily occluded people)
    n_valid = int(np.count_nonzero(inp.depth[0] > 0))
    min_pixels = int(np.ceil(cfg.min_detection_points * max(1.0, n_valid / cfg.max_points)))
    pairs: list[FlowPair] = []
    snapshots, hyp, gt_frames, n_detections = [], [], [], []
    # per-frame detections, velocities, their covariances, position covariances, free space
    Zs, Vs, Cs, Rs, Fs = [], [], [], [], []
    # the synthetic scene is rendered past the processed frames: every frame pairs with the next one.
    # Real input pairs every frame with one at least flow_interval later (the last ones backwards),
    # so that the last frame is tracked too and the thresholds mean the same at 30 Hz as at 10 Hz.
    if scene is not None:
        n_track, partners, span = inp.n - 1, [t + 1 for t in range(inp.n - 1)], 1
    else:
        n_track, partners = inp.n, flow_partners(inp.n, dt, cfg.flow_interval)
        span = max(abs(p - t) for t, p in enumerate(partners))
    clouds: dict[int, FrameCloud] = {}

    def cloud(i: int):  # each frame's cloud is drawn once, in frame order (the subsample's rng)
        for j in range(max(clouds, default=-1) + 1, i + 1):
            # real input: the flow of frame j's own pair is estimated with its cloud, which keeps
            # every voxel that moves (PipelineConfig.moving_first_speed)
            clouds[j] = frame_cloud(inp, j, cfg, rng, partner=None if scene is not None else partners[j])
        return clouds[i]

    for t in tqdm(range(n_track), desc="flowtrack demo", unit="frame", disable=not progress):
        s_ = partners[t]
        own = cloud(t)
        X = own.points
        nxt = cloud(s_)
        for j in [j for j in clouds if j < t - span]:
            del clouds[j]
        pair_dt = abs(inp.interval(t, s_))  # the flow below is the velocity toward frame s_ over pair_dt
        pair = FlowPair(t, X, own.gt_flow, own.labels)
        if own.flow is not None:  # estimated with the cloud, for the pair (t, s_)
            rgbd, t_rgbd = own.flow, own.flow_seconds
        else:
            t0 = time.perf_counter()
            rgbd = rgbd_cloud_flow(inp.rgb[t], inp.depth[t], inp.rgb[s_], inp.depth[s_], cam, pair_dt, X)
            t_rgbd = time.perf_counter() - t0
        pair.flows, pair.clusters, pair.seconds = scene_flow_and_clusters(X, nxt.points, pair_dt, cfg,
                                                                          flow=rgbd)
        pair.seconds[RGBD_METHOD] = t_rgbd
        t0 = time.perf_counter()
        # the geometric static test needs the next surface at an even density
        Z, V, C, Rz = detection_measurements(inp, t, X, pair.clusters, rgbd, nxt.surface, cfg, partner=s_)
        pair.seconds["detection"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        # the depth image tells a hidden object (coast on) from a gone one (delete the track)
        free = (None if cfg.track_free_space_margin is None
                else FreeSpace(inp.depth[t], cam, margin=cfg.track_free_space_margin))
        reported = tracker.step(Z, V, C, position_covs=Rz, seen_through=free)
        pair.seconds["tracker step"] = time.perf_counter() - t0
        Zs.append(Z)
        Vs.append(V)
        Cs.append(C)
        Rs.append(Rz)
        Fs.append(free)
        n_detections.append(len(Z))
        snapshots.append([(tr.id, tr.position.copy(), tr.P[:3, :3].copy(), tr.status) for tr in reported])
        hyp.append({tr.id: tr.position.copy() for tr in reported if tr.misses == 0})
        if scene is not None:
            gt_frames.append(surface_centroids(scene.frames[t], min_pixels))
        if s_ > t:  # a backward pair's flows point into the past: they stay out of the flow figures
            pairs.append(pair)
    # per-track rows (position, covariance, status) and per-object true positions, in frame order
    hist: dict[int, list] = {}
    for snap in snapshots:
        for tid, *row in snap:
            hist.setdefault(tid, []).append(row)
    gt_hist: dict[int, list] = {}
    for gt_t in gt_frames:
        for k, p in gt_t.items():
            gt_hist.setdefault(k, []).append(p)
    last = n_track - 1
    # tracker frame k = input frame k (or the k-th frame read with --step)
    write_tracks_csv(out / "tracks.csv", tracker,
                     frames=inp.frame_index[:n_track] if inp.frame_index else None)

    # prediction N frames ahead: the tracker's own filter, predicted without updates
    ahead = tracker.predict_ahead(predict_ahead)
    velocity = {tr.id: tr.velocity.copy() for tr in tracker.tracks}
    preds = []
    truth_future, truth_now, centres_future = {}, {}, {}
    if scene is not None:
        fut = scene.frames[last + predict_ahead]
        truth_future = surface_centroids(fut, min_pixels)
        centres_future = scene.object_centroids(last + predict_ahead)
        truth_now = dict(gt_frames[-1])  # the surface centroids of frame `last`
        for k, c in scene.object_centroids(last).items():
            truth_now.setdefault(k, c)
    final = {tid: pos for tid, pos, _, _ in snapshots[-1]} if snapshots else {}
    owner = assign_tracks(final, truth_now, 2 * cfg.mot_max_dist)
    for tid, pos, _, status in snapshots[-1] if snapshots else []:
        x_ahead, P_ahead = ahead[tid]
        m, P = x_ahead[:3].copy(), P_ahead[:3, :3].copy()
        rec = {"track": tid, "status": status, "ahead": predict_ahead, "from_frame": last,
               "to_frame": last + predict_ahead, "last_position": pos.tolist(), "predicted": m.tolist(),
               "covariance": P.tolist(), "velocity": velocity[tid].tolist()}
        k = owner.get(tid)
        if k is not None:
            truth = truth_future.get(k, centres_future[k])
            e = truth - m
            rec.update(object=k, truth=truth.tolist(), truth_is_surface_centroid=k in truth_future,
                       error=float(np.linalg.norm(e)),
                       error_constant_position=float(np.linalg.norm(truth - pos)),
                       error_object_centre=float(np.linalg.norm(centres_future[k] - m)),
                       mahalanobis=float(np.sqrt(e @ np.linalg.solve(P, e))))
        preds.append(rec)

    # metrics
    summary: dict = {
        "input": inp.name,
        "camera": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy, "width": cam.width,
                   "height": cam.height},
        "dt": dt,
        "frames": inp.n,
        "config": asdict(cfg),
        "points_per_cloud": len(pairs[0].points),
        "detections_per_frame": float(np.mean(n_detections)),
    }
    if scene is not None:
        from sklearn.metrics import adjusted_rand_score

        from flowtrack.metrics import clear_mot

        summary["scene"] = {"scenario": scenario, "n_objects": n_objects, "n_frames": inp.n,
                            "frames_rendered": len(scene.frames), "image_size": list(image_size),
                            "seed": seed,
                            "noise_m": noise}
        summary["scene_flow"] = pooled_metrics(pairs, dt)
        summary["clustering_adjusted_rand_index"] = float(np.mean(
            [adjusted_rand_score(np.maximum(p.labels_gt, 0), p.clusters + 1) for p in pairs]))
        mot = clear_mot(gt_frames, hyp, cfg.mot_max_dist)
        summary["tracking"] = {k: json_number(v) for k, v in mot.items()
                               if isinstance(v, (int, float, np.integer, np.floating))}
        summary["tracking"].update(max_dist_m=cfg.mot_max_dist, min_visible_pixels=min_pixels,
                                   ground_truth="centroid of each object's visible noiseless surface")
        summary["tracking_ablation"] = tracking_ablation_section(scene, Zs, Vs, Cs, dt, cfg, min_pixels,
                                                                 predict_ahead, tracker_options,
                                                                 position_covs=Rs, seen_through=Fs)
    else:
        summary["scene_flow"] = None
        summary["tracking"] = None
        summary["tracking_ablation"] = None
    summary["tracks"] = {str(tid): len(rows) for tid, rows in hist.items()}
    summary["predict_ahead"] = predict_ahead
    summary["prediction"] = preds
    scored = [p for p in preds if "error" in p]
    if scored:
        summary["prediction_mean_error_m"] = float(np.mean([p["error"] for p in scored]))
        summary["prediction_mean_error_constant_position_m"] = float(
            np.mean([p["error_constant_position"] for p in scored]))
    summary["seconds_per_pair"] = {k: float(np.mean([p.seconds[k] for p in pairs])) for k in pairs[0].seconds}

    # figures
    figures = {name: out / f"{name}.png" for name in ("flow_field", "clusters_3d", "trajectories")}
    plot_flow_field(inp, pairs[0], figures["flow_field"])
    plot_clusters(inp, pairs[0], figures["clusters_3d"])
    plot_trajectories(inp, hist, gt_hist, preds, figures["trajectories"])
    if gif:
        figures["tracks"] = out / "tracks.gif"
        write_gif(inp, snapshots, figures["tracks"])
    real = tud = None
    if real_data:
        figures["motorcycle"] = out / "motorcycle_flow.png"
        real = motorcycle_section(cfg, seed=seed, figure=figures["motorcycle"])
        from flowtrack.datasets import track_tud_campus

        tud, centres, hyp = track_tud_campus(seed=seed, return_frames=True)
        figures["tud_campus"] = out / "tud_campus_tracks.png"
        plot_tud_campus(centres, hyp, tud["max_dist"], figures["tud_campus"])
        summary["motorcycle"] = real
        summary["tud_campus_tracking"] = {k: json_number(v) for k, v in tud.items()}
    summary["figures"] = {k: str(v) for k, v in figures.items()}
    summary["reproduce"] = reproduce_command(
        out, n_objects=n_objects, n_frames=n_frames, image_size=image_size, seed=seed, noise=noise,
        config=cfg, scenario=scenario, predict_ahead=predict_ahead, input_dir=input_dir,
        input_options=input_options, real_data=real_data, gif=gif)
    summary["total_seconds"] = time.perf_counter() - started

    sections = report_sections(inp, summary, figures, real, tud)
    (out / "metrics.json").write_text(json.dumps(summary, indent=2, default=json_default))
    (out / "metrics.md").write_text(render_markdown("flowtrack demo: metrics", sections))
    write_report(out / "report.html", "flowtrack demo report", sections,
                 intro="RGB-D frames → point clouds → scene flow → motion clusters → tracks → "
                       "prediction: the "
                 "syllabus' first flowchart, run end to end by flowtrack demo. Every figure is "
                 "embedded; this "
                 "file opens offline.")
    summary["total_seconds"] = time.perf_counter() - started
    echo_summary(echo, inp, summary, sections, out)
    return summary


def tracking_ablation_section(scene, detections, velocities, velocity_covs, dt, cfg, min_pixels: int,
                              ahead: int, tracker_options: dict, position_covs=None,
                              seen_through=None) -> dict:
    """Position-only vs flow-aided tracking on the demo's own detections
    (:func:`flowtrack.tracking_eval.tracking_ablation`).

    The truth is the centroid of each object's visible surface in every rendered frame (the frames
    past the last processed one score the ``ahead``-frame predictions); the flow-aided run is the
    demo's tracker (position and RGB-D velocity with the per-detection covariances, and the
    detections' position covariances ``position_covs`` when given); both runs get the sensor's free
    space ``seen_through`` (per frame, when given).
    """
    from flowtrack.tracking_eval import tracking_ablation

    truth = [surface_centroids(f, min_pixels) for f in scene.frames]
    res = tracking_ablation(detections, velocities, velocity_covs, truth, dt, q=cfg.track_q, r=cfg.track_r,
                            ahead=ahead, max_dist=cfg.mot_max_dist, tracker_options=tracker_options,
                            position_covs=position_covs, seen_through=seen_through)
    return {k: {m: json_number(v) for m, v in r.items()} for k, r in res.items()}


def json_number(v):
    """numpy scalars as Python numbers (for JSON and tables)."""
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, np.integer):
        return int(v)
    return v


def json_default(o):
    """``json.dumps``' ``default``: numpy arrays and scalars, paths."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
