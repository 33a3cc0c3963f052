"""The demo's figures: flow field, 3-D clusters, trajectories, tracks.gif, Motorcycle, TUD-Campus."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flowtrack.camera import optical_flow_from_scene_flow, project, projection_jacobian
from flowtrack.pipeline import RGBD_METHOD, PipelineConfig

from .inputs import DemoInput

if TYPE_CHECKING:
    from .run import FlowPair

__all__ = [
    "cluster_colours", "covariance_ellipse", "plot_clusters", "plot_flow_field", "plot_motorcycle",
    "plot_trajectories", "plot_tud_campus", "save_small_png", "write_gif",
]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _color(track_id: int):
    import matplotlib

    return matplotlib.colormaps["tab10"](track_id % 10)


def covariance_ellipse(ax, mean, cov, nsig: float = 2.0, **kw) -> None:
    r"""Draw the ``nsig``-sigma ellipse of a 2-D Gaussian ``N(mean, cov)`` (shapes (2,), (2, 2)) on ``ax``.

    The ellipse :math:`(x - m)^\top C^{-1} (x - m) = n_\sigma^2`: semi-axes :math:`n_\sigma\sqrt{\lambda_k}`
    along the eigenvectors of ``cov``; ``kw`` go to :class:`matplotlib.patches.Ellipse` (unfilled).

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import matplotlib.pyplot as plt
    >>> fig, ax = plt.subplots()
    >>> covariance_ellipse(ax, [0.0, 0.0], [[4.0, 0.0], [0.0, 1.0]])
    >>> e = ax.patches[0]
    >>> float(e.width), float(e.height)
    (8.0, 4.0)
    >>> plt.close(fig)
    """
    from matplotlib.patches import Ellipse

    mean = np.asarray(mean, dtype=float)
    cov = np.asarray(cov, dtype=float)

    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.clip(vals, 0.0, None)
    angle = np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1]))
    ax.add_patch(Ellipse(mean, 2 * nsig * np.sqrt(vals[1]), 2 * nsig * np.sqrt(vals[0]), angle=angle,
                         fill=False, **kw))


_ellipse = covariance_ellipse


def plot_flow_field(inp: DemoInput, pair: FlowPair, path: Path) -> None:
    """True and estimated scene flow of one frame pair as image-plane arrows over the RGB image."""
    plt = _plt()
    from matplotlib.colors import Normalize

    cam, dt = inp.camera, inp.dt
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    uv = project(pair.points, cam)
    rng = np.random.default_rng(0)
    est = ("variational RGB-D", pair.flows[RGBD_METHOD]) if RGBD_METHOD in pair.flows else (
        "graph scene flow (re-matched)", pair.flows["graph + re-matching"])
    if pair.gt_flow is not None:
        panels = [("ground-truth scene flow", pair.gt_flow), (f"estimate ({est[0]})", est[1])]
        ref = pair.gt_flow
    else:
        panels = [est, ("rigid ICP per motion cluster", pair.flows["rigid per cluster"])]
        ref = est[1]
    pick = np.flatnonzero(np.linalg.norm(ref, axis=1) > max(1e-6, 0.5 * PipelineConfig.min_speed))
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


def cluster_colours(clusters, truth) -> dict[int, int]:
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


def plot_clusters(inp: DemoInput, pair: FlowPair, path: Path) -> None:
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
    colours = cluster_colours(pair.clusters, pair.labels_gt)
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


def plot_motorcycle(case: dict, estimate: np.ndarray, path: Path) -> None:
    """Known and estimated scene flow on the Motorcycle cloud (300 random points as arrows)."""
    from flowtrack.datasets import motorcycle_camera, motorcycle_depth

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
    save_small_png(fig, path, dpi=80)
    plt.close(fig)


def save_small_png(fig, path: Path, dpi: int) -> None:
    """Save a figure as a 128-colour palette PNG (a photograph in it: a quarter of the size)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format="png")
    buf.seek(0)
    with Image.open(buf) as im:
        im.convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def _view(inp: DemoInput):
    """Linear map (A (2,3), b (2,)) from camera coordinates to the top view, and axis labels."""
    if inp.scene is not None:
        T = inp.scene.camera_pose
        return T[:2, :3], T[:2, 3], ("table x (m)", "table y (m)")
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.zeros(2), ("camera X (m)", "camera Z, depth (m)")


def _image_cov(pos, P, cam):
    J = projection_jacobian(pos[None], cam)[0]
    return J @ P @ J.T


def plot_trajectories(inp, hist, gt_hist, preds, path: Path) -> None:
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


def write_gif(inp, snapshots, path: Path) -> None:
    """The tracks over the sequence, one frame per processed frame pair (``tracks.gif``)."""
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


def _runs(frames) -> list[list[int]]:
    """Consecutive stretches of a sorted list of frame numbers."""
    out: list[list[int]] = []
    for t in frames:
        if out and t == out[-1][-1] + 1:
            out[-1].append(t)
        else:
            out.append([t])
    return out


def plot_tud_campus(centres, hyp, max_dist: float, path: Path) -> None:
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
    save_small_png(fig, path, dpi=100)  # a third of the size, no visible difference
    plt.close(fig)
