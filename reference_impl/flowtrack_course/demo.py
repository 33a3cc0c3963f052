r"""The main job: an RGB-D sequence through the syllabus' whole first flowchart.

RGB-D frames → point clouds (back-projection) → scene flow → motion clusters → multi-object
tracking (detections = cluster centroids, velocities from the flow) → a prediction of every track
some frames ahead. On the default synthetic sequence (:func:`flowtrack.synth.make_scene`,
scenario ``"mixed"``: a tall object crossing in front of another, a third one hidden behind a static
box for a while) everything is scored against the exact ground truth; ``--input DIR`` runs the same
pipeline on a real sequence in the TUM RGB-D layout (or a stereo pair with disparity, see
:mod:`flowtrack.rgbd_io`), without ground truth. ``flowtrack demo`` calls :func:`run_demo`, which
writes figures, an animated GIF, ``metrics.json``, ``metrics.md`` and a self-contained
``report.html``.

Per frame pair :math:`(t, t+1)`:

1. back-project both depth images, :math:`X = Z\,K^{-1}(u, v, 1)^\top` (open3d's voxel grid thins
   real clouds to an even density);
2. scene flow by four methods (nearest neighbour, graph, graph with re-matching, rigid ICP per
   motion cluster); the metrics table compares them;
3. motion clusters of the re-matched graph flow (connected components of the motion graph);
4. one :meth:`~flowtrack.tracking.MultiObjectTracker.step` with the cluster centroids
   :math:`\bar X_c` as detections and their mean rigid flow :math:`\bar v_c` as velocities (the
   mean of a rigid motion's flow over a cluster is the flow of its centroid, exactly).

Finally each reported track is predicted ``predict_ahead`` frames with the tracker's own Kalman
filter and no updates, :math:`x \leftarrow F^N x`, :math:`P \leftarrow F P F^\top + Q` (N times),
and compared with where the object really is then (frames rendered for this but never shown to the
pipeline).
"""

from __future__ import annotations

import copy
import json
import numbers
import shlex
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from flowtrack._graph import as_labels
from flowtrack._validation import as_array, positive, positive_int
from flowtrack.camera import backproject, optical_flow_from_scene_flow, project, projection_jacobian
from flowtrack.clustering import cluster_motion, drop_small_clusters
from flowtrack.sceneflow import (
    iterative_graph_scene_flow,
    nearest_neighbor_targets,
    rigid_flow_per_cluster,
    scene_flow_metrics,
)
from flowtrack.synth import make_scene

from .report import Figure, Section, Table, render_markdown, write_report

__all__ = [
    "DemoConfig", "FlowPair", "METHODS", "detect_objects", "estimate_clouds", "run_demo", "support_planes",
]

METHODS = ("nearest-neighbour", "graph", "graph + re-matching", "rigid per cluster")
#: the synthetic motions are laid out over at least this many frames, so that a short run (a test)
#: sees the same speeds as the full one
MIN_LAYOUT_FRAMES = 24


@dataclass(frozen=True)
class DemoConfig:
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
    max_misses: int = 8  #: frames a confirmed track may coast through an occlusion
    mot_max_dist: float = 0.1  #: CLEAR-MOT match distance (m)
    plane_threshold: float = 0.006  #: RANSAC inlier distance of the support planes (table, walls), m
    max_planes: int = 2  #: support planes removed before detection (each >= plane_min_share of the cloud)
    plane_min_share: float = 0.08
    min_detection_points: int = 30  #: smaller pieces of a cluster off the planes are not detections
    gate_prob: float = 0.99  #: tracker's chi-square gate probability
    voxel: float = 0.01  #: voxel size for real clouds (open3d), 0 = off
    max_depth: float = 4.0  #: real input: farther points are dropped (m)


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


def _subsample(n: int, max_points: int, rng: np.random.Generator) -> np.ndarray:
    if n <= max_points:
        return np.arange(n)
    return np.sort(rng.choice(n, size=max_points, replace=False))


def estimate_clouds(X, Y, dt: float, cfg: DemoConfig):
    """Every scene-flow method of the demo on one pair of clouds (no index correspondence needed).

    Returns ``(flows, clusters, seconds)``: a dict method → (N, 3) velocities, the motion-cluster
    labels of ``X`` (−1 static) and the seconds each stage took.
    """
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
    labels = cluster_motion(
        X, flows["graph + re-matching"], cfg.cluster_radius, cfg.sigma_v, min_speed=cfg.min_speed,
        method="connected",
    )
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
    return {m: flows[m] for m in METHODS}, clusters, seconds


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

    from flowtrack.realdata import motorcycle_flow_case

    case = motorcycle_flow_case(seed=seed)
    # a sparser cloud (about 1 cm between points) moving faster (about 4 cm per frame)
    cfg = replace(cfg, cluster_radius=0.05, icp_threshold=0.05)
    flows, clusters, seconds = estimate_clouds(case["points_t"], case["points_t1"], case["dt"], cfg)
    gt = case["gt_flow"]
    if figure is not None:
        _plot_motorcycle(case, flows["rigid per cluster"], Path(figure))
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


def _pooled_metrics(pairs: list[FlowPair], dt: float) -> dict[str, dict[str, dict[str, float]]]:
    """FlowNet3D metrics of each method, on all points and on the moving points only.

    Velocities are turned into per-frame displacements (``dt``) so the thresholds are in metres. On
    static points the relative criteria are degenerate (zero ground truth), hence the moving-only set.
    """
    gt = np.concatenate([p.gt_flow for p in pairs])
    moving = np.linalg.norm(gt, axis=1) > 0
    out = {}
    for m in METHODS:
        pred = np.concatenate([p.flows[m] for p in pairs])
        out[m] = {
            "all": scene_flow_metrics(pred, gt, dt=dt),
            "moving": scene_flow_metrics(pred, gt, moving, dt=dt),
        }
    return out


def _flow_table(metrics: dict[str, dict[str, dict[str, float]]], caption: str = "") -> Table:
    rows = []
    for name, m in metrics.items():
        a, mv = m["all"], m["moving"]
        rows.append([name, 1000 * a["epe3d"], 1000 * mv["epe3d"], mv["acc3d_strict"], mv["acc3d_relax"],
                     mv["outliers"]])
    return Table(["method", "EPE3D all (mm)", "EPE3D moving (mm)", "Acc3DS", "Acc3DR", "Outliers"], rows,
                 caption or "Acc3DS, Acc3DR and outliers are over the moving points (FlowNet3D thresholds).",
                 digits=[None, 2, 2, 3, 3, 3])


# ------------------------------------------------------------------------------------------------
# input: synthetic scene or a real RGB-D sequence
# ------------------------------------------------------------------------------------------------
@dataclass
class _Input:
    name: str
    camera: object
    dt: float
    rgb: list
    depth: list
    n: int  # frames the pipeline sees
    scene: object = None  # the synthetic Scene (ground truth), None for real input


def _cloud(inp: _Input, t: int, cfg: DemoConfig, rng: np.random.Generator):
    """Back-projected, subsampled cloud of frame ``t`` and (synthetic) its ground truth."""
    depth = inp.depth[t]
    if inp.scene is not None:
        valid = depth > 0
        P = backproject(depth, inp.camera)[valid]  # row-major valid pixels: the order of frame.points
        idx = _subsample(len(P), cfg.max_points, rng)
        f = inp.scene.frames[t]
        return P[idx], f.gt_flow[idx], f.labels[idx]
    valid = np.isfinite(depth) & (depth > 0) & (depth <= cfg.max_depth)
    P = backproject(np.where(valid, depth, 0.0), inp.camera)[valid]
    if cfg.voxel > 0 and len(P):
        import open3d as o3d

        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
        P = np.asarray(pc.voxel_down_sample(cfg.voxel).points)
    P = P[_subsample(len(P), cfg.max_points, rng)]
    if len(P) < 2 * cfg.k:
        raise ValueError(f"frame {t} of {inp.name} has only {len(P)} valid depth points (within "
                         f"max_depth={cfg.max_depth} m); check depth_scale and the depth images")
    return P, None, None


@contextmanager
def _open3d_threads(n: int):
    """Limit open3d to ``n`` CPU threads inside a ``with`` block; the previous limit is restored after.

    open3d runs its loops on several threads (oneTBB from 0.20 on, OpenMP before), and the result
    of some depends on their timing: ``segment_plane`` (RANSAC) hands out the random samples of one
    seeded generator in whatever order the threads ask for them, so the best plane and its inliers
    change from run to run, and ``registration_icp`` adds up its residuals in a timing-dependent
    order. With one thread both are repeatable bit for bit. The limit holds for the whole process:
    ``open3d.utility.set_max_threads`` (open3d >= 0.20), else (0.19, OpenMP) threadpoolctl's limit of
    the OpenMP runtimes, which also holds for the other libraries that use them.

    Parameters
    ----------
    n : int, >= 1

    Examples
    --------
    >>> import open3d as o3d
    >>> if hasattr(o3d.utility, "get_max_threads"):
    ...     before = o3d.utility.get_max_threads()
    ...     with _open3d_threads(1):
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


def support_planes(points, cfg: DemoConfig) -> np.ndarray:
    """Mask of the points on the largest planes (table, walls): open3d RANSAC, up to ``max_planes``.

    A plane counts when it holds at least ``plane_min_share`` of the points; inliers are within
    ``plane_threshold`` of it. Returns a bool array of shape (N,). The RANSAC samples come from
    open3d's generator seeded with 0 and drawn by one thread (:func:`_open3d_threads`), so the same
    points always give the same mask.
    """
    import open3d as o3d

    P = np.asarray(points, dtype=np.float64)
    on = np.zeros(len(P), dtype=bool)
    rest = np.arange(len(P))
    with _open3d_threads(1):
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


def detect_objects(points, clusters, flow, cfg: DemoConfig, next_points=None,
                   dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    r"""Object detections from motion clusters: centroid and mean velocity of each object piece.

    Graph smoothing spreads an object's motion into the table it stands on (the kNN graph links
    them at the contact), and a translation parallel to a plane leaves that plane unchanged, so the
    table next to an object cannot be told apart from it by geometry. The support planes are
    therefore removed (:func:`support_planes`) and each cluster's remaining points are split into
    spatially connected pieces (radius ``cluster_radius``); every piece with at least
    ``min_detection_points`` points is a detection :math:`(\bar X, \bar v)`.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    clusters : ndarray, shape (N,) int
        Motion-cluster labels, −1 static.
    flow : ndarray, shape (N, 3)
        Velocities whose per-piece mean initialises a track (the rigid flow of each cluster: the
        mean of a rigid motion's flow is the flow of the centroid).
    cfg : DemoConfig
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
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    P = as_array(points, "points", ("N", 3))
    clusters = as_labels(clusters, "clusters", len(P), min_label=-1)
    flow = as_array(flow, "flow", (len(P), 3))
    tree = None
    if next_points is not None:
        if dt is None:
            raise ValueError("dt must be given with next_points")
        dt = positive(dt, "dt")
        tree = cKDTree(as_array(next_points, "next_points", ("M", 3)))
    keep = (clusters >= 0) & ~support_planes(P, cfg)
    Z, V = [], []
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
                if tree is not None:
                    d_static = np.median(tree.query(P[piece])[0])
                    d_moving = np.median(tree.query(P[piece] + dt * flow[piece])[0])
                    if d_static <= d_moving:
                        continue
                Z.append(P[piece].mean(axis=0))
                V.append(flow[piece].mean(axis=0))
    return np.array(Z).reshape(-1, 3), np.array(V).reshape(-1, 3)


def _surface_centroids(frame, min_pixels: int) -> dict[int, np.ndarray]:
    """Ground truth of a detection: the centroid of each object's visible (noiseless) surface."""
    X = frame.gt_points
    out = {}
    for k in sorted(frame.gt_poses):
        m = frame.labels == k
        if m.sum() >= min_pixels:
            out[k] = X[m].mean(axis=0)
    return out


def _assign(tracks: dict[int, np.ndarray], truth: dict[int, np.ndarray], gate: float) -> dict[int, int]:
    """Track id → object id by least total distance among pairs closer than ``gate``."""
    from scipy.optimize import linear_sum_assignment

    if not tracks or not truth:
        return {}
    ti, oi = list(tracks), list(truth)
    C = np.array([[np.linalg.norm(tracks[a] - truth[b]) for b in oi] for a in ti])
    r, c = linear_sum_assignment(np.where(C <= gate, C, 1e6))
    return {ti[i]: oi[j] for i, j in zip(r, c) if C[i, j] <= gate}


# ------------------------------------------------------------------------------------------------
# figures
# ------------------------------------------------------------------------------------------------
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _color(track_id: int):
    import matplotlib

    return matplotlib.colormaps["tab10"](track_id % 10)


def _ellipse(ax, mean, cov, nsig: float = 2.0, **kw) -> None:
    from matplotlib.patches import Ellipse

    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.clip(vals, 0.0, None)
    angle = np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1]))
    ax.add_patch(Ellipse(mean, 2 * nsig * np.sqrt(vals[1]), 2 * nsig * np.sqrt(vals[0]), angle=angle,
                         fill=False, **kw))


def _plot_flow_field(inp: _Input, pair: FlowPair, path: Path) -> None:
    plt = _plt()
    from matplotlib.colors import Normalize

    cam, dt = inp.camera, inp.dt
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    uv = project(pair.points, cam)
    rng = np.random.default_rng(0)
    if pair.gt_flow is not None:
        panels = [("ground-truth scene flow", pair.gt_flow),
                  ("estimate (rigid ICP per motion cluster)", pair.flows["rigid per cluster"])]
        ref = pair.gt_flow
    else:
        panels = [("graph scene flow (re-matched)", pair.flows["graph + re-matching"]),
                  ("rigid ICP per motion cluster", pair.flows["rigid per cluster"])]
        ref = pair.flows["graph + re-matching"]
    pick = np.flatnonzero(np.linalg.norm(ref, axis=1) > max(1e-6, 0.5 * DemoConfig.min_speed))
    if len(pick) == 0:
        pick = np.arange(len(ref))
    pick = pick[rng.permutation(len(pick))[:220]]
    vmax = float(np.linalg.norm(ref[pick], axis=1).max()) if len(pick) else 1.0
    norm = Normalize(0.0, vmax if vmax > 0 else 1.0)
    q = None
    for ax, (title, flow) in zip(axes, panels):
        ax.imshow(inp.rgb[pair.index])
        of = optical_flow_from_scene_flow(pair.points[pick], flow[pick], dt, cam)
        speed = np.linalg.norm(flow[pick], axis=1)
        q = ax.quiver(uv[pick, 0], uv[pick, 1], of[:, 0], of[:, 1], speed, angles="xy", scale_units="xy",
                      scale=0.5, cmap="viridis", width=0.003, norm=norm)
        ax.set_title(f"{title}\n(image-plane arrows ×2)")
        ax.set_axis_off()
    fig.colorbar(q, ax=axes, label="3-D speed (m/s)", shrink=0.8)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _cluster_colours(clusters, truth) -> dict[int, int]:
    """Colour index of each motion cluster: the true object it overlaps most (one cluster per object,
    by the assignment of largest overlap), other clusters the next free colours."""
    from scipy.optimize import linear_sum_assignment

    ids = [int(c) for c in np.unique(clusters) if c >= 0]
    colours: dict[int, int] = {}
    if truth is not None and ids:
        objs = [int(k) for k in np.unique(truth) if k > 0]
        if objs:
            overlap = np.array([[np.count_nonzero((clusters == c) & (truth == k)) for k in objs]
                                for c in ids])
            r, c = linear_sum_assignment(-overlap)
            colours = {ids[i]: objs[j] for i, j in zip(r, c) if overlap[i, j] > 0}
    free = (k for k in range(1, 10_000) if k not in colours.values() and (truth is None or k not in truth))
    for c in ids:
        if c not in colours:
            colours[c] = next(free)
    return colours


def _plot_clusters(inp: _Input, pair: FlowPair, path: Path) -> None:
    """The cloud of one frame pair coloured by motion cluster, beside the true objects.

    Synthetic input is drawn in table coordinates (z up); each cluster gets the colour of the true
    object it overlaps most, so that matching colours mean a correct segmentation.
    """
    plt = _plt()
    import matplotlib
    from matplotlib.ticker import MaxNLocator

    tab = matplotlib.colormaps["tab10"]
    panels = [("motion clusters (estimated)", pair.clusters)]
    if pair.labels_gt is not None:
        panels.append(("ground-truth objects", pair.labels_gt))
    if inp.scene is not None:
        T = np.asarray(inp.scene.camera_pose)
        W = pair.points @ T[:3, :3].T + T[:3, 3]
        axis_names = ("table x (m)", "table y (m)", "height (m)")
    else:
        W = pair.points[:, [0, 2, 1]] * np.array([1.0, 1.0, -1.0])
        axis_names = ("X (m)", "Z, depth (m)", "−Y (m)")
    colours = _cluster_colours(pair.clusters, pair.labels_gt)
    fig = plt.figure(figsize=(5.5 * len(panels), 5), constrained_layout=True)
    # zoom to the moving points (either panel) with a 10 cm margin, at equal scale on every axis
    moving = pair.clusters >= 0
    if pair.labels_gt is not None:
        moving |= pair.labels_gt > 0
    box = W[moving] if moving.any() else W
    lo = np.maximum(box.min(axis=0) - 0.1, W.min(axis=0))
    hi = np.minimum(box.max(axis=0) + 0.1, W.max(axis=0))
    inside = np.all((W >= lo) & (W <= hi), axis=1)
    rng = np.random.default_rng(1)
    sel = np.flatnonzero(inside)
    sel = sel[rng.permutation(len(sel))[:8000]]
    P = W[sel]
    for i, (title, lab_all) in enumerate(panels):
        lab = lab_all[sel]
        ax = fig.add_subplot(1, len(panels), i + 1, projection="3d")
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]))
        ax.set_box_aspect(np.maximum(hi - lo, 1e-3))
        for a in (ax.xaxis, ax.yaxis, ax.zaxis):
            a.set_major_locator(MaxNLocator(4))
        static = lab <= 0 if i == 1 else lab < 0
        ax.scatter(*P[static].T, s=1, c="0.75", alpha=0.25, depthshade=False)
        if i == 0:
            cols = [tab(colours[int(c)] % 10) for c in lab[~static]]
        else:
            cols = [tab(int(c) % 10) for c in lab[~static]]
        ax.scatter(*P[~static].T, s=3, c=cols, depthshade=False)
        ax.set_xlabel(axis_names[0])
        ax.set_ylabel(axis_names[1])
        ax.set_zlabel(axis_names[2])
        ax.set_title(title)
        if inp.scene is not None:
            ax.view_init(elev=35, azim=-60)
        else:
            ax.view_init(elev=25, azim=-70)
    fig.savefig(path, dpi=100, bbox_inches="tight", pad_inches=0.25)  # 3-D labels stick out
    plt.close(fig)


def _plot_motorcycle(case: dict, estimate: np.ndarray, path: Path) -> None:
    from flowtrack.realdata import motorcycle_camera, motorcycle_depth

    plt = _plt()
    cam = motorcycle_camera()
    X, dt = case["points_t"], case["dt"]
    uv = project(X, cam)
    pick = np.random.default_rng(0).permutation(len(X))[:300]
    _, left = motorcycle_depth()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
    for ax, (title, flow) in zip(axes, [("known motion (global + front wheel)", case["gt_flow"]),
                                        ("estimate: rigid ICP per motion cluster", estimate)]):
        ax.imshow(left[::2, ::2], extent=(-0.5, cam.width - 0.5, cam.height - 0.5, -0.5))
        of = optical_flow_from_scene_flow(X[pick], flow[pick], dt, cam)
        ax.quiver(uv[pick, 0], uv[pick, 1], of[:, 0], of[:, 1], angles="xy", scale_units="xy", scale=1 / 3,
                  color="#0040ff", width=0.0025)
        ax.set_title(f"Middlebury Motorcycle: {title}\n(image-plane flow of one frame, arrows ×3)",
                     fontsize=10)
        ax.set_axis_off()
    _save_small_png(fig, path, dpi=80)
    plt.close(fig)


def _save_small_png(fig, path: Path, dpi: int) -> None:
    """Save a figure as a 128-colour palette PNG (a photograph in it: a quarter of the size)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format="png")
    buf.seek(0)
    with Image.open(buf) as im:
        im.convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def _view(inp: _Input):
    """Linear map (A (2,3), b (2,)) from camera coordinates to the top view, and axis labels."""
    if inp.scene is not None:
        T = inp.scene.camera_pose
        return T[:2, :3], T[:2, 3], ("table x (m)", "table y (m)")
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.zeros(2), ("camera X (m)", "camera Z, depth (m)")


def _image_cov(pos, P, cam):
    J = projection_jacobian(pos[None], cam)[0]
    return J @ P @ J.T


def _plot_trajectories(inp, hist, gt_hist, preds, path: Path) -> None:
    """Top and image views; ``hist``: track id → [(position, covariance, status)] per reported
    frame, ``gt_hist``: object id → [true position] per frame."""
    plt = _plt()
    A, b, labels = _view(inp)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5.2), constrained_layout=True)
    for k, pts in gt_hist.items():
        Q = np.array(pts) @ A.T + b
        ax.plot(Q[:, 0], Q[:, 1], "k--", lw=1, alpha=0.7)
        ax.annotate(f"object {k}", Q[0], fontsize=8, color="0.3")
    for tid, rows in hist.items():
        c = _color(tid)
        Q = np.array([p for p, _, _ in rows]) @ A.T + b
        ax.plot(Q[:, 0], Q[:, 1], "-", color=c, lw=1.6, label=f"track {tid}")
        for j, (p, P, status) in enumerate(rows):
            if j % 3 == 0 or j == len(rows) - 1 or status == "coasting":
                _ellipse(ax, p @ A.T + b, A @ P @ A.T, color=c, lw=0.8,
                         ls="--" if status == "coasting" else "-")
        uv = project(np.array([p for p, _, _ in rows]), inp.camera)
        ax2.plot(uv[:, 0], uv[:, 1], "-", color=c, lw=1.6)
        ax2.annotate(str(tid), uv[-1], color=c, fontsize=9, weight="bold")
    for p in preds:
        c = _color(p["track"])
        m = np.asarray(p["predicted"])
        ax.plot(*(m @ A.T + b), "*", color=c, ms=12, mec="k", mew=0.5)
        _ellipse(ax, m @ A.T + b, A @ np.asarray(p["covariance"]) @ A.T, color=c, lw=1.5, ls=":")
        if p.get("truth") is not None:
            ax.plot(*(np.asarray(p["truth"]) @ A.T + b), "x", color="k", ms=9, mew=2)
        uvp = project(m[None], inp.camera)[0]
        ax2.plot(*uvp, "*", color=c, ms=12, mec="k", mew=0.5)
        _ellipse(ax2, uvp, _image_cov(m, np.asarray(p["covariance"]), inp.camera), color=c, lw=1.2, ls=":")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    title = "top view: tracks with 2σ ellipses (dashed = coasting)"
    if gt_hist:
        title += ", ground truth black dashed"
    if preds:
        title += f"\n★ prediction {preds[0]['ahead']} frames ahead with its 2σ ellipse"
        if any(p.get("truth") is not None for p in preds):
            title += ", × where the object really is"
    ax.set_title(title, fontsize=10)
    if hist:
        ax.legend(fontsize=8, loc="best")
    ax2.imshow(inp.rgb[min(inp.n - 1, len(inp.rgb) - 1)], alpha=0.75)
    ax2.set_title("image view (last frame): track paths, ★ predictions with 2σ ellipses (J P Jᵀ)",
                  fontsize=10)
    ax2.set_axis_off()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _write_gif(inp, snapshots, path: Path) -> None:
    plt = _plt()
    from matplotlib.animation import FuncAnimation, PillowWriter

    H, W = inp.rgb[0].shape[:2]
    scale = 480.0 / W  # 480 px wide: track labels and ellipses stay readable
    fig = plt.figure(figsize=(W * scale / 80, H * scale / 80), dpi=80)
    ax = fig.add_axes([0, 0, 1, 1])
    trails: dict[int, list] = {}

    def draw(t):
        ax.clear()
        ax.imshow(inp.rgb[t])
        ax.set_axis_off()
        for tid, pos, P, status in snapshots[t]:
            uv = project(pos[None], inp.camera)[0]
            trails.setdefault(tid, []).append(uv)
            tr = np.array(trails[tid][-15:])
            c = _color(tid)
            ax.plot(tr[:, 0], tr[:, 1], "-", color=c, lw=2.2)
            _ellipse(ax, uv, _image_cov(pos, P, inp.camera), color=c, lw=1.8,
                     ls="--" if status == "coasting" else "-")
            ax.text(uv[0] + 4, uv[1] - 4, str(tid), color=c, fontsize=11, weight="bold")
        ax.text(3, 12 / scale, f"frame {t}", color="w", fontsize=10)
        ax.set_xlim(-0.5, W - 0.5)
        ax.set_ylim(H - 0.5, -0.5)

    anim = FuncAnimation(fig, draw, frames=len(snapshots), interval=200)
    anim.save(str(path), writer=PillowWriter(fps=5))
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# MOT15 TUD-Campus: the frames behind the table, and their figure
# ------------------------------------------------------------------------------------------------
def _runs(frames) -> list[list[int]]:
    """Consecutive stretches of a sorted list of frame numbers."""
    out: list[list[int]] = []
    for t in frames:
        if out and t == out[-1][-1] + 1:
            out[-1].append(t)
        else:
            out.append([t])
    return out


def _plot_tud_campus(centres, hyp, max_dist: float, path: Path) -> None:
    """Space-time view of the TUD-Campus tracking: image x over the frames, and who tracks whom."""
    plt = _plt()
    import matplotlib
    from matplotlib.lines import Line2D

    from flowtrack.metrics import clear_mot

    _, matches, switches = clear_mot(centres, hyp, max_dist, return_matches=True)
    T = len(centres)
    people = sorted({o for f in centres for o in f})
    tracks = sorted({k for f in hyp for k in f})
    tab = matplotlib.colormaps["tab20"]
    # the 10 dark shades first, then the 10 light ones: consecutive track ids get different hues
    colour = {k: tab((2 * i) % 20 + (i // 10) % 2) for i, k in enumerate(tracks)}
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5.4), width_ratios=[1.5, 1], constrained_layout=True)

    # left: image x of every person (grey) and every track (its colour) over the frames; markers
    # batched into one artist each (the layout engine measures every artist)
    for o in people:
        present = [t for t in range(T) if o in centres[t]]
        for run in _runs(present):
            ax.plot(run, [centres[t][o][0] for t in run], "-", color="0.82", lw=7, solid_capstyle="round",
                    zorder=1)
        ax.annotate(f"P{o}", (present[0], centres[present[0]][o][0]), xytext=(-7, 0),
                    textcoords="offset points", ha="right", va="center", fontsize=8, color="0.3")
    for k in tracks:
        present = [t for t in range(T) if k in hyp[t]]
        for run in _runs(present):
            ax.plot(run, [hyp[t][k][0] for t in run], "-", color=colour[k], lw=1.8, zorder=3)
        ax.annotate(str(k), (present[0], hyp[present[0]][k][0]), xytext=(0, 5), textcoords="offset points",
                    ha="center", fontsize=7, color=colour[k], weight="bold", zorder=5)
    fp = [(t, p[0], colour[k]) for t in range(T) for k, p in hyp[t].items() if k not in matches[t].values()]
    miss = [(t, p[0]) for t in range(T) for o, p in centres[t].items() if o not in matches[t]]
    if fp:
        ax.scatter([a for a, _, _ in fp], [b for _, b, _ in fp], s=36, facecolors="none",
                   edgecolors=[c for _, _, c in fp], linewidths=1.2, zorder=4)
    if miss:
        ax.plot(*np.transpose(miss), "x", color="k", ms=6, mew=1.6, zorder=4)
    if switches:
        ax.plot([t for t, _ in switches], [centres[t][o][0] for t, o in switches], "o", mfc="none", mec="red",
                ms=14, mew=2, zorder=6)
    ax.set_xlim(-4, T)
    ax.set_xlabel("frame")
    ax.set_ylabel("image x of the box centre (px)")
    ax.set_title("MOT15 TUD-Campus: people (grey) and tracks (one colour per track id) over the frames",
                 fontsize=10)
    ax.legend(handles=[
        Line2D([], [], color="0.82", lw=7, label="ground truth (person P…)"),
        Line2D([], [], color=colour[tracks[0]] if tracks else "C0", lw=1.8, label="track (id at its start)"),
        Line2D([], [], ls="", marker="x", color="k", mew=1.6, label="miss"),
        Line2D([], [], ls="", marker="o", mfc="none", mec="0.3", label="false positive"),
        Line2D([], [], ls="", marker="o", mfc="none", mec="red", ms=11, mew=2, label="ID switch"),
    ], fontsize=8, loc="best")

    # right: one row per person, each stretch of frames in the colour of the track matched to them
    bars: dict = {"matched": [], "missed": []}  # (row, first frame, length, track id)
    for row, o in enumerate(people):
        k_prev, t_prev = object(), -2
        for t in (t for t in range(T) if o in centres[t]):
            k = matches[t].get(o)
            if k == k_prev and t == t_prev + 1:
                bars["missed" if k is None else "matched"][-1][2] += 1
            else:
                bars["missed" if k is None else "matched"].append([row, t, 1, k])
            k_prev, t_prev = k, t
    for name, style in (("matched", {}), ("missed", {"color": "white", "edgecolor": "0.55", "hatch": "xxx"})):
        if bars[name]:
            rows, first, length, ids = zip(*bars[name])
            if name == "matched":
                style = {"color": [colour[k] for k in ids]}
            ax2.barh(rows, length, left=np.array(first) - 0.5, height=0.72, lw=0.5, **style)
    for row, first, length, k in bars["matched"]:
        if length >= 4:
            ax2.text(first - 0.5 + length / 2, row, str(k), ha="center", va="center", fontsize=7)
    if switches:
        rows = np.array([people.index(o) for _, o in switches])
        ax2.vlines([t - 0.5 for t, _ in switches], rows - 0.5, rows + 0.5, color="red", lw=2.5)
    ax2.set_yticks(range(len(people)), [f"P{o}" for o in people])
    ax2.set_ylim(len(people) - 0.5, -0.5)
    ax2.set_xlim(-0.5, T - 0.5)
    ax2.set_xlabel("frame")
    ax2.set_title("The track matched to each person, frame by frame (CLEAR-MOT):\n"
                  "red bar = ID switch, hatched = miss", fontsize=10)
    _save_small_png(fig, path, dpi=100)  # a third of the size, no visible difference
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# the whole job
# ------------------------------------------------------------------------------------------------
def _load_input(input_dir, n_frames, n_objects, image_size, seed, noise, predict_ahead, scenario,
                input_options) -> _Input:
    if input_dir is None:
        # make_scene checks scenario and n_objects (and names them)
        total = max(n_frames + predict_ahead, MIN_LAYOUT_FRAMES if scenario == "mixed" else 0)
        try:
            scene = make_scene(n_objects=n_objects, n_frames=total, image_size=image_size, dt=0.1,
                               noise=noise, seed=seed, scenario=scenario)
        except RuntimeError as exc:  # no collision-free layout: too many objects for the table
            raise ValueError(f"n_objects={n_objects} does not fit on the table: {exc}") from exc
        return _Input(f"synthetic scene ({scenario})", scene.camera, scene.dt, [f.rgb for f in scene.frames],
                      [f.depth for f in scene.frames], n_frames, scene)
    from flowtrack.rgbd_io import load_rgbd

    opts = dict(input_options or {})
    stereo = bool(opts.pop("stereo", False))
    seq = load_rgbd(input_dir, stereo=stereo, max_frames=n_frames, **opts)
    if len(seq) < 2:
        raise ValueError(f"input {input_dir} has {len(seq)} usable frame(s); scene flow needs at least 2")
    return _Input(f"{'stereo' if stereo else 'RGB-D'} sequence {input_dir}", seq.camera, seq.dt, seq.rgb,
                  seq.depth, len(seq), None)


def _intrinsics_text(spec) -> str:
    """``--intrinsics`` for an ``intrinsics`` value: a string or path as is, else ``fx,fy,cx,cy``."""
    from flowtrack.camera import PinholeCamera

    if isinstance(spec, (str, Path)):
        return str(spec)
    if isinstance(spec, PinholeCamera):
        spec = (spec.fx, spec.fy, spec.cx, spec.cy)
    return ",".join(repr(float(v)) for v in spec)


def _number_text(v) -> str:
    """A number as the command line reads it back exactly (``repr`` of the float, or the integer)."""
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        return repr(float(v))
    return str(v)


def _py(v) -> str:
    """A Python literal of ``v`` with double-quoted strings (so that it sits well in a shell's '...')."""
    if isinstance(v, (str, Path)):
        return json.dumps(str(v))
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_py(k)}: {_py(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        inner = ", ".join(_py(x) for x in v) + ("," if isinstance(v, tuple) and len(v) == 1 else "")
        return f"({inner})" if isinstance(v, tuple) else f"[{inner}]"
    if isinstance(v, (numbers.Number, np.generic)) and not isinstance(v, bool):
        return _number_text(v)
    return repr(v)


def _reproduce_command(out, *, n_objects, n_frames, image_size, seed, noise, config, scenario, predict_ahead,
                       input_dir, input_options, real_data, gif) -> str:
    """The shell command that runs :func:`run_demo` again with these arguments (the report's "Reproduce").

    A ``flowtrack demo`` command line with the options whose value is not the default (arguments that
    the input ignores are left out); when an argument has no command-line option (``noise``, a
    non-default ``config``, an ``input_options`` key the command line does not know), a
    ``python -c`` call of :func:`run_demo` with the non-default arguments instead. Quoted for a POSIX
    shell.

    Examples
    --------
    >>> kw = dict(n_objects=3, n_frames=24, image_size=(240, 320), seed=0, noise=0.002, config=None,
    ...           scenario="mixed", predict_ahead=5, input_dir=None, input_options=None, real_data=True,
    ...           gif=True)
    >>> _reproduce_command("out", **kw)
    'flowtrack demo --out out'
    >>> _reproduce_command("my out", **(kw | {"n_frames": 12, "seed": 3, "gif": False}))
    "flowtrack demo --out 'my out' --frames 12 --seed 3 --no-gif"
    >>> opts = {"intrinsics": "tum-fr1", "step": 2, "dt": None}
    >>> _reproduce_command("out", **(kw | {"input_dir": "seq", "input_options": opts}))
    'flowtrack demo --out out --input seq --intrinsics tum-fr1 --step 2'
    >>> cmd = _reproduce_command("out", **(kw | {"noise": 0.004, "config": DemoConfig(lam=2.0)}))
    >>> shlex.split(cmd)[:2]
    ['python', '-c']
    >>> shlex.split(cmd)[2].split("; ")  # doctest: +NORMALIZE_WHITESPACE
    ['from flowtrack_course.demo import DemoConfig, run_demo',
     'run_demo(out="out", noise=0.004, config=DemoConfig(lam=2.0))']
    """
    import inspect

    default = {k: p.default for k, p in inspect.signature(run_demo).parameters.items()}
    synthetic = input_dir is None
    opts = dict(input_options or {}) if not synthetic else {}
    stereo = bool(opts.pop("stereo", False))
    config = config if config is not None else DemoConfig()
    changed = {f.name: getattr(config, f.name) for f in fields(DemoConfig)
               if getattr(config, f.name) != f.default}
    args = {"n_objects": n_objects, "image_size": tuple(image_size), "scenario": scenario, "noise": noise}
    if not synthetic:  # the synthetic scene's settings do not matter
        args = {}
    args.update(n_frames=n_frames, seed=seed, predict_ahead=predict_ahead, real_data=real_data, gif=gif)
    args = {k: v for k, v in args.items() if v != default[k]}

    from .cli import DEMO_INPUT_OPTIONS, STEREO_DT

    if "noise" in args or changed or set(opts) - set(DEMO_INPUT_OPTIONS):
        text = [f"out={_py(out)}"] + [f"{k}={_py(v)}" for k, v in args.items()]
        if changed:
            text.append("config=DemoConfig(" + ", ".join(f"{k}={_py(v)}" for k, v in changed.items()) + ")")
        if not synthetic:
            opts = dict(opts, stereo=True) if stereo else opts
            text += [f"input_dir={_py(input_dir)}", f"input_options={_py(opts)}"]
        return "python -c " + shlex.quote(
            f"from flowtrack_course.demo import DemoConfig, run_demo; run_demo({', '.join(text)})")

    cmd = ["flowtrack", "demo", "--out", str(out)]  # the options in the order of `flowtrack demo --help`
    for k, flag in (("n_objects", "--objects"), ("n_frames", "--frames"), ("image_size", None),
                    ("seed", "--seed"), ("scenario", "--scenario"), ("predict_ahead", "--predict-ahead")):
        if k == "image_size" and k in args:
            cmd += ["--height", _number_text(image_size[0]), "--width", _number_text(image_size[1])]
        elif k in args:
            cmd += [flag, _number_text(args[k])]
    cmd += ["--no-gif"] * ("gif" in args) + ["--no-real-data"] * ("real_data" in args)
    if not synthetic:
        cmd += ["--input", str(input_dir)] + ["--stereo"] * stereo
        for k, v in opts.items():
            flag, kwargs = DEMO_INPUT_OPTIONS[k]
            if v is not None and v != (STEREO_DT if k == "dt" and stereo else kwargs["default"]):
                cmd += [flag, _intrinsics_text(v) if k == "intrinsics" else _number_text(v)]
    return " ".join(shlex.quote(c) for c in cmd)


# one open3d thread for the whole run: bit-for-bit repeatable results (see the Notes of run_demo)
@_open3d_threads(1)
def run_demo(
    out: Path | str = "out",
    n_objects: int = 3,
    n_frames: int = 24,
    image_size: tuple[int, int] = (240, 320),
    seed: int = 0,
    noise: float = 0.002,
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
    """Run the demo; write figures, ``tracks.gif``, ``metrics.json``, ``metrics.md``, ``report.html``.

    Parameters
    ----------
    out : path
        Output folder (created).
    n_objects, image_size, seed, noise, scenario
        The synthetic scene (:func:`flowtrack.synth.make_scene`); ignored with ``input_dir``.
    n_frames : int, >= 2
        Frames the pipeline processes (at most this many with ``input_dir``).
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
        runs this call again (shown in the report, see :func:`_reproduce_command`).

    Notes
    -----
    Two runs with the same arguments give identical results, bit for bit, on one machine: open3d is
    limited to one thread while the demo runs (:func:`_open3d_threads`; the previous limit is
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
    n_frames = positive_int(n_frames, "n_frames", minimum=2)  # scene flow needs a frame pair
    predict_ahead = positive_int(predict_ahead, "predict_ahead")
    seed = positive_int(seed, "seed", minimum=0)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out must be a folder, got the file {out}")
    started = time.perf_counter()
    inp = _load_input(input_dir, n_frames, n_objects, image_size, seed, noise, predict_ahead, scenario,
                      input_options)
    out.mkdir(parents=True, exist_ok=True)
    scene, cam, dt = inp.scene, inp.camera, inp.dt
    rng = np.random.default_rng(seed)

    from flowtrack.tracking import MultiObjectTracker

    tracker = MultiObjectTracker(dt=dt, q=cfg.track_q, r=cfg.track_r, dim=3, min_hits=cfg.min_hits,
                                 max_misses=cfg.max_misses, gate_prob=cfg.gate_prob)
    # a detection needs min_detection_points subsampled points (off the planes): ground truth ignores
    # objects with fewer visible pixels than that (as MOT benchmarks ignore heavily occluded people)
    n_valid = int(np.count_nonzero(inp.depth[0] > 0))
    min_pixels = int(np.ceil(cfg.min_detection_points * max(1.0, n_valid / cfg.max_points)))
    pairs: list[FlowPair] = []
    snapshots, hyp, gt_frames, n_detections = [], [], [], []
    nxt = _cloud(inp, 0, cfg, rng)
    for t in tqdm(range(inp.n - 1), desc="flowtrack demo", unit="frame", disable=not progress):
        (X, gt_flow, labels_gt), nxt = nxt, _cloud(inp, t + 1, cfg, rng)
        pair = FlowPair(t, X, gt_flow, labels_gt)
        pair.flows, pair.clusters, pair.seconds = estimate_clouds(X, nxt[0], dt, cfg)
        t0 = time.perf_counter()
        Z, V = detect_objects(X, pair.clusters, pair.flows["rigid per cluster"], cfg, next_points=nxt[0],
                              dt=dt)
        pair.seconds["detection"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        reported = tracker.step(Z, V)
        pair.seconds["tracker step"] = time.perf_counter() - t0
        n_detections.append(len(Z))
        snapshots.append([(tr.id, tr.position.copy(), tr.P[:3, :3].copy(), tr.status) for tr in reported])
        hyp.append({tr.id: tr.position.copy() for tr in reported if tr.misses == 0})
        if scene is not None:
            gt_frames.append(_surface_centroids(scene.frames[t], min_pixels))
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
    last = inp.n - 2

    # prediction N frames ahead: the tracker's own filter, predicted without updates
    kf = copy.deepcopy(tracker.kf)
    for _ in range(predict_ahead):
        kf.predict()
    live = {tr.id: i for i, tr in enumerate(tracker.tracks)}
    preds = []
    truth_future, truth_now, centres_future = {}, {}, {}
    if scene is not None:
        fut = scene.frames[last + predict_ahead]
        truth_future = _surface_centroids(fut, min_pixels)
        centres_future = scene.object_centroids(last + predict_ahead)
        truth_now = dict(gt_frames[-1])  # the surface centroids of frame `last`
        for k, c in scene.object_centroids(last).items():
            truth_now.setdefault(k, c)
    final = {tid: pos for tid, pos, _, _ in snapshots[-1]} if snapshots else {}
    owner = _assign(final, truth_now, 2 * cfg.mot_max_dist)
    for tid, pos, _, status in snapshots[-1] if snapshots else []:
        i = live[tid]
        m, P = kf.x[i, :3].copy(), kf.P[i, :3, :3].copy()
        rec = {"track": tid, "status": status, "ahead": predict_ahead, "from_frame": last,
               "to_frame": last + predict_ahead, "last_position": pos.tolist(), "predicted": m.tolist(),
               "covariance": P.tolist(), "velocity": tracker.kf.x[i, 3:].tolist()}
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
        summary["scene_flow"] = _pooled_metrics(pairs, dt)
        summary["clustering_adjusted_rand_index"] = float(np.mean(
            [adjusted_rand_score(np.maximum(p.labels_gt, 0), p.clusters + 1) for p in pairs]))
        mot = clear_mot(gt_frames, hyp, cfg.mot_max_dist)
        summary["tracking"] = {k: _plain(v) for k, v in mot.items()
                               if isinstance(v, (int, float, np.integer, np.floating))}
        summary["tracking"].update(max_dist_m=cfg.mot_max_dist, min_visible_pixels=min_pixels,
                                   ground_truth="centroid of each object's visible noiseless surface")
    else:
        summary["scene_flow"] = None
        summary["tracking"] = None
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
    _plot_flow_field(inp, pairs[0], figures["flow_field"])
    _plot_clusters(inp, pairs[0], figures["clusters_3d"])
    _plot_trajectories(inp, hist, gt_hist, preds, figures["trajectories"])
    if gif:
        figures["tracks"] = out / "tracks.gif"
        _write_gif(inp, snapshots, figures["tracks"])
    real = tud = None
    if real_data:
        figures["motorcycle"] = out / "motorcycle_flow.png"
        real = motorcycle_section(cfg, seed=seed, figure=figures["motorcycle"])
        from flowtrack.realdata import track_tud_campus

        tud, centres, hyp = track_tud_campus(seed=seed, return_frames=True)
        figures["tud_campus"] = out / "tud_campus_tracks.png"
        _plot_tud_campus(centres, hyp, tud["max_dist"], figures["tud_campus"])
        summary["motorcycle"] = real
        summary["tud_campus_tracking"] = {k: _plain(v) for k, v in tud.items()}
    summary["figures"] = {k: str(v) for k, v in figures.items()}
    summary["reproduce"] = _reproduce_command(
        out, n_objects=n_objects, n_frames=n_frames, image_size=image_size, seed=seed, noise=noise,
        config=cfg, scenario=scenario, predict_ahead=predict_ahead, input_dir=input_dir,
        input_options=input_options, real_data=real_data, gif=gif)
    summary["total_seconds"] = time.perf_counter() - started

    sections = _sections(inp, summary, figures, real, tud)
    (out / "metrics.json").write_text(json.dumps(summary, indent=2, default=_json_default))
    (out / "metrics.md").write_text(render_markdown("flowtrack demo: metrics", sections))
    write_report(out / "report.html", "flowtrack demo report", sections,
                 intro="RGB-D frames → point clouds → scene flow → motion clusters → tracks → "
                       "prediction: the "
                 "syllabus' first flowchart, run end to end by flowtrack demo. Every figure is "
                 "embedded; this "
                 "file opens offline.")
    summary["total_seconds"] = time.perf_counter() - started
    _echo_summary(echo, inp, summary, sections, out)
    return summary


def _plain(v):
    """numpy scalars as Python numbers (for JSON and tables)."""
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, np.integer):
        return int(v)
    return v


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _tracking_table(tr: dict) -> Table:
    return Table(["MOTA", "MOTP (mm)", "IDF1", "ID switches", "FP", "FN", "matches"],
                 [[tr["mota"], 1000 * tr["motp"], tr["idf1"], int(tr["id_switches"]), int(tr["fp"]),
                   int(tr["fn"]), int(tr["matches"])]],
                 "CLEAR-MOT (flowtrack.metrics.clear_mot) of the confirmed, detected tracks against the "
                 f"centroid of each object's visible surface; match distance {tr['max_dist_m']} m; "
                 f"objects with fewer than {tr['min_visible_pixels']} visible pixels are not expected.",
                 digits=[3, 1, 3, None, None, None, None])


def _prediction_table(preds: list, has_truth: bool, ahead: int) -> Table:
    def mm(v):
        return None if v is None else 1000.0 * v

    rows = []
    for p in preds:
        sigma = float(np.sqrt(np.max(np.linalg.eigvalsh(np.asarray(p["covariance"])))))
        row = [p["track"], p["status"], *p["predicted"], mm(2 * sigma)]
        if has_truth:
            row += [p.get("object", "—"), mm(p.get("error")), mm(p.get("error_constant_position")),
                    p.get("mahalanobis")]
        rows.append(row)
    header = ["track", "status", "X (m)", "Y (m)", "Z (m)", "2σ largest (mm)"]
    digits = [None, None, 3, 3, 3, 1]
    if has_truth:
        header += ["object", "error (mm)", "constant-position error (mm)", "Mahalanobis"]
        digits += [None, 1, 1, 2]
    cap = (f"Each track predicted {ahead} frames ahead with the tracker's constant-velocity Kalman "
           "filter and no updates (camera coordinates).")
    if has_truth:
        cap += (" Error against the true centroid of the object's visible surface in that frame (its "
                "centre if hidden); the constant-position baseline keeps the last estimate; the "
                "Mahalanobis distance √(eᵀP⁻¹e) should mostly stay below 2.8 (95 % in 3-D).")
    return Table(header, rows, cap, digits=digits)


def _sections(inp, summary, figures, real, tud) -> list[Section]:
    scene = inp.scene
    secs = []
    cam = inp.camera
    if scene is not None:
        sc = summary["scene"]
        intro = (f"{sc['n_objects']} rigid objects move on a table, rendered by exact ray casting at "
                 f"{sc['image_size'][1]}×{sc['image_size'][0]} px with {1000 * sc['noise_m']:.0f} mm "
                 f"depth noise; "
                 f"{inp.n} frames, Δt = {inp.dt} s (scenario '{sc['scenario']}': a tall object crosses "
                 f"in front of "
                 "another and hides it for a few frames, a third slides behind a static grey box).")
    else:
        intro = (f"{inp.name}: {inp.n} frames, Δt = {inp.dt:.4f} s, intrinsics fx={cam.fx}, fy={cam.fy}, "
                 f"cx={cam.cx}, cy={cam.cy}.")
    nog = "No ground truth for this input: the metrics need the synthetic scene (or your own labels)."
    s = Section("Input and pipeline", paragraphs=[
        intro,
        "Per frame pair: back-projection X = Z K⁻¹(u, v, 1)ᵀ; scene flow by nearest neighbour, graph "
        "smoothing (syllabus §4), graph smoothing with re-matching and rigid ICP per motion cluster (§8); "
        "motion clustering of the re-matched graph flow (Problem 5); one MultiObjectTracker step (§7) "
        "with the "
        "cluster centroids as detections and their mean rigid flow as initial velocities.",
        f"{summary['points_per_cloud']} points per cloud, {summary['detections_per_frame']:.1f} detections "
        f"per frame on average; seconds per frame pair: "
        + ", ".join(f"{k} {v:.3f}" for k, v in summary["seconds_per_pair"].items()) + ".",
    ])
    secs.append(s)
    s = Section("Scene flow", figures=[
        Figure(figures["flow_field"], "Scene flow of the first frame pair as image-plane arrows."),
        Figure(figures["clusters_3d"], "The first frame pair's cloud coloured by motion cluster (grey: "
               "static), each cluster in the colour of the true object it overlaps most. Graph "
               "smoothing leaks motion into the table, which can join objects; detection removes "
               "the support planes before tracking."
               if inp.scene is not None else
               "The first frame pair's cloud coloured by motion cluster (grey: static)."),
    ])
    if summary["scene_flow"] is not None:
        s.tables.append(_flow_table(summary["scene_flow"]))
        s.paragraphs.append(
            "EPE3D is the mean end-point error of the per-frame displacement. Nearest-neighbour "
            "correspondences "
            "only see motion normal to a surface; graph smoothing removes noise but not that bias; "
            "re-matching "
            "recovers part of the tangential motion; rigid ICP per motion cluster nearly all of it. Motion "
            f"clustering: adjusted Rand index {summary['clustering_adjusted_rand_index']:.3f} against "
            f"the true "
            "objects.")
    else:
        s.note = nog
    secs.append(s)
    s = Section("Tracking and prediction", figures=[Figure(figures["trajectories"],
                "Tracks with 2σ covariance ellipses and the final prediction.")])
    if "tracks" in figures:
        s.figures.append(Figure(figures["tracks"], "The tracks over the sequence (dashed ellipse: "
                                                   "coasting)."))
    if summary["tracking"] is not None:
        s.tables.append(_tracking_table(summary["tracking"]))
    else:
        s.note = nog + " Tracks and predictions are still drawn."
    s.tables.append(_prediction_table(summary["prediction"], scene is not None, summary["predict_ahead"]))
    if "prediction_mean_error_m" in summary:
        s.paragraphs.append(
            f"Mean prediction error {1000 * summary['prediction_mean_error_m']:.1f} mm "
            "(keeping the last position: "
            f"{1000 * summary['prediction_mean_error_constant_position_m']:.1f} mm).")
    secs.append(s)
    if real is not None:
        s = Section("Real geometry: Middlebury Motorcycle", tables=[_flow_table(real["scene_flow"])],
                    figures=[Figure(figures["motorcycle"], "Known and estimated scene flow on the "
                                    "Motorcycle cloud (300 random points as arrows).")],
                    paragraphs=[
                        f"The Middlebury 2014 Motorcycle stereo pair (shipped inside scikit-image) as a "
                        f"metric "
                        f"cloud of {real['points']} points, moved by a known global rigid motion with "
                        f"the front "
                        f"wheel turning: the same four methods against that exact flow. Motion "
                        f"clustering gives "
                        f"{real['clusters']} clusters (the cloud is spatially fragmented), purity "
                        f"{real['clustering_purity']:.3f} against the two true motions."])
        secs.append(s)
    if tud is not None:
        secs.append(Section("Real trajectories: MOT15 TUD-Campus", tables=[Table(
            ["people", "frames", "MOTA", "IDF1", "MOTP (px)", "ID switches", "FP", "FN"],
            [[int(tud["objects"]), int(tud["frames"]), tud["mota"], tud["idf1"], tud["motp"],
              int(tud["id_switches"]),
              int(tud["fp"]), int(tud["fn"])]],
            "MultiObjectTracker on the ground-truth box centres with 3 px noise and 10 % of detections "
            "dropped.")],
            paragraphs=["Real pedestrian trajectories (the MOT15 TUD-Campus ground truth that ships with "
                        "py-motmetrics), tracked by the same MultiObjectTracker in the image plane."],
            figures=[Figure(figures["tud_campus"],
                            "Left: the image x of every person's box centre (thick grey, P and the "
                            "person's id) and of every track (one colour per track id) over the "
                            f"{tud['frames']} frames; where people cross, identities get swapped. Right: "
                            "the track that the CLEAR-MOT matching assigns to each person in each frame, "
                            "so an ID switch is a change of colour (red bar) and a miss a hatched frame.")]))
    code = summary["reproduce"] + f"\n# this run took {summary['total_seconds']:.1f} s"
    if inp.scene is not None:
        code += "\n# your own TUM RGB-D sequence: flowtrack demo --input DIR --intrinsics fx,fy,cx,cy"
    secs.append(Section("Reproduce", code=code))
    return secs


def _echo_summary(echo, inp, summary, sections, out) -> None:
    echo("")
    echo(f"flowtrack demo: {inp.name}, {inp.n} frames, {inp.camera.width}x{inp.camera.height} px, "
         f"{summary['points_per_cloud']} points per cloud")
    if summary["scene_flow"] is not None:
        echo(_flow_table(summary["scene_flow"]).markdown().split("\n\n")[0])
        echo(f"motion clustering: adjusted Rand index {summary['clustering_adjusted_rand_index']:.3f}")
        tr = summary["tracking"]
        echo(f"tracking: MOTA {tr['mota']:.3f}, MOTP {1000 * tr['motp']:.1f} mm, IDF1 {tr['idf1']:.3f}, "
             f"ID switches {tr['id_switches']}, FP {tr['fp']}, FN {tr['fn']}")
    else:
        echo("no ground truth for this input: scene-flow and tracking metrics are not computed")
    n_ahead = summary["predict_ahead"]
    line = f"prediction {n_ahead} frames ahead: {len(summary['prediction'])} tracks"
    if "prediction_mean_error_m" in summary:
        line += (f", mean error {1000 * summary['prediction_mean_error_m']:.1f} mm (constant position "
                 f"{1000 * summary['prediction_mean_error_constant_position_m']:.1f} mm)")
    echo(line)
    if "motorcycle" in summary:
        rows = summary["motorcycle"]["scene_flow"]
        echo("Motorcycle (real geometry), EPE3D mm: " + ", ".join(
            f"{m} {1000 * v['all']['epe3d']:.1f}" for m, v in rows.items()))
        t = summary["tud_campus_tracking"]
        echo(f"TUD-Campus (real trajectories): MOTA {t['mota']:.3f}, IDF1 {t['idf1']:.3f}, "
             f"ID switches {t['id_switches']}")
    echo(f"wrote {out}/: " + ", ".join(Path(p).name for p in summary["figures"].values())
         + ", metrics.json, metrics.md, report.html")
    echo(f"done in {summary['total_seconds']:.1f} s")
