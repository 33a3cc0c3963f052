"""RGB-D variational scene flow (`flowtrack.sceneflow.rgbd_scene_flow`) against its peers, in one run.

Methods, each given the same two RGB-D frames:

- ``flowtrack rgbd``: :func:`flowtrack.sceneflow.rgbd_scene_flow` with its default options; and two
  ablations, the geometric (range-flow) term only (``use_color=False``) and the photometric term only
  (``use_depth=False``);
- ``OpenCV DIS medium + lifting`` and ``OpenCV Farnebäck + lifting``: OpenCV's dense optical flow on
  the grey images, lifted to 3-D with the two depth maps by
  :func:`flowtrack.camera.scene_flow_from_optical_flow`;
- ``skimage TV-L1 + lifting``: :func:`skimage.registration.optical_flow_tvl1`, lifted the same way;
- ``nearest neighbour``: the nearest point of the t+1 cloud
  (:func:`flowtrack.sceneflow.nearest_neighbor_targets`), the demo's correspondences.

A method without an answer at a pixel (a lifted flow leaving the image or landing on invalid depth)
is scored as predicting zero motion there; ``cover`` is the share of scored pixels it answered.

Data:

- synthetic: :func:`flowtrack.synth.make_scene` scenarios ``crossing``, ``mixed``, ``occlusion``
  (320×240, 2 mm depth noise, exact ground truth per valid pixel) over several seeds and frame pairs;
  ``kinect``: the same ``mixed`` frames with Kinect-like depth: quantised in disparity (step
  0.00285 Z² m), holes along depth edges (the IR shadow, 2 px) and 1 % random 3×3 dropouts;
- real: the Middlebury 2014 *Motorcycle* pair shipped with scikit-image, at half resolution: the left
  image with depth Z = fB/(d + doffs) is frame t, the right image (shifted by doffs so both frames share
  the left camera's intrinsics) with its depth (the left depth forward-warped with a z-buffer) is
  frame t + Δt. The true motion is the baseline, X' = X − (B, 0, 0) at every pixel; only pixels
  visible in both views (z-buffer test) are scored.

Scores (per-frame displacements, mm): EPE3D mean and median on moving, static, all pixels and on
the interior (pixels at least 3 px from a depth edge or an object boundary); the FlowNet3D accuracies
(:func:`flowtrack.sceneflow.scene_flow_metrics`, moving pixels); the 2-D end-point error of the induced
optical flow (px); CPU time (``time.process_time``, the fair measure on this shared machine) and wall
time per pair, single-threaded.

Bars: synthetic moving-pixel mean EPE3D ≤ 0.5× the better OpenCV-lifted peer and ≤ 0.5× nearest
neighbour; static ≤ 2 mm; interior no worse than that peer; Motorcycle: better than TV-L1 + lifting and
at least as good as DIS medium + lifting; 320×240 ≤ 0.5 s, 640×480 ≤ 2.0 s per pair, never slower than
TV-L1 at the same size.

Usage: ``python benchmarks/bench_rgbd_flow.py [--quick]``; writes ``results/rgbd_flow.md``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402
from skimage.registration import optical_flow_tvl1  # noqa: E402

from _results import publish  # noqa: E402
from flowtrack.camera import PinholeCamera, backproject, scene_flow_from_optical_flow  # noqa: E402
from flowtrack.datasets import MOTORCYCLE_CALIBRATION  # noqa: E402
from flowtrack.sceneflow import nearest_neighbor_targets, rgbd_scene_flow, scene_flow_metrics  # noqa: E402
from flowtrack.synth import make_scene  # noqa: E402

cv2.setNumThreads(1)

OURS = "flowtrack rgbd"
DIS = "OpenCV DIS medium + lifting"
FARNEBACK = "OpenCV Farnebäck + lifting"
TVL1 = "skimage TV-L1 + lifting"
NN = "nearest neighbour"
GEOM_ONLY = "flowtrack rgbd, geometric term only"
PHOTO_ONLY = "flowtrack rgbd, photometric term only"
METHODS = (OURS, GEOM_ONLY, PHOTO_ONLY, DIS, FARNEBACK, TVL1, NN)


# --------------------------------------------------------------------------------------------------
# methods: every one maps (rgb_t, depth_t, rgb_t1, depth_t1, cam, dt) -> (velocity (H, W, 3), flow (H, W, 2))
# --------------------------------------------------------------------------------------------------
def _grey_u8(img):
    if img.dtype == np.uint8:
        return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def _project(X, cam):
    return np.stack([cam.fx * X[..., 0] / X[..., 2] + cam.cx, cam.fy * X[..., 1] / X[..., 2] + cam.cy], -1)


def _induced_flow(depth_t, v, cam, dt):
    X = backproject(depth_t, cam)
    return _project(X + v * dt, cam) - _project(X, cam)


def ours(rgb0, d0, rgb1, d1, cam, dt):
    v = rgbd_scene_flow(rgb0, d0, rgb1, d1, cam, dt)
    return v, _induced_flow(d0, v, cam, dt)


def _ablation(**kw):
    def run(rgb0, d0, rgb1, d1, cam, dt):
        v = rgbd_scene_flow(rgb0, d0, rgb1, d1, cam, dt, **kw)
        return v, _induced_flow(d0, v, cam, dt)

    return run


def _lift(flow, d0, d1, cam, dt):
    return scene_flow_from_optical_flow(d0, d1, flow, dt, cam), flow


def dis(rgb0, d0, rgb1, d1, cam, dt):
    of = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    flow = of.calc(_grey_u8(rgb0), _grey_u8(rgb1), None).astype(np.float64)
    return _lift(flow, d0, d1, cam, dt)


def farneback(rgb0, d0, rgb1, d1, cam, dt):
    flow = cv2.calcOpticalFlowFarneback(_grey_u8(rgb0), _grey_u8(rgb1), None, 0.5, 5, 15, 3, 5, 1.2, 0)
    return _lift(flow.astype(np.float64), d0, d1, cam, dt)


def tvl1(rgb0, d0, rgb1, d1, cam, dt):
    g0 = _grey_u8(rgb0).astype(np.float64) / 255.0
    g1 = _grey_u8(rgb1).astype(np.float64) / 255.0
    rc = optical_flow_tvl1(g0, g1)  # (row, col) displacements
    return _lift(np.stack([rc[1], rc[0]], axis=-1), d0, d1, cam, dt)


def nearest(rgb0, d0, rgb1, d1, cam, dt):
    X0 = backproject(d0, cam)
    X1 = backproject(d1, cam)
    ok0 = np.isfinite(X0[..., 2])
    Y = nearest_neighbor_targets(X0[ok0], X1[np.isfinite(X1[..., 2])])
    v = np.full(X0.shape, np.nan)
    v[ok0] = (Y - X0[ok0]) / dt
    flow = np.full((*d0.shape, 2), np.nan)
    flow[ok0] = _project(Y, cam) - _project(X0[ok0], cam)
    return v, flow


RUNNERS = {OURS: ours, GEOM_ONLY: _ablation(use_color=False), PHOTO_ONLY: _ablation(use_depth=False),
           DIS: dis, FARNEBACK: farneback, TVL1: tvl1, NN: nearest}


# --------------------------------------------------------------------------------------------------
# data
# --------------------------------------------------------------------------------------------------
def kinect_depth(depth, rng):
    """Kinect-like depth: disparity quantisation, holes along depth edges and random dropouts."""
    q = 0.00285 * depth**2
    out = np.where(depth > 0, np.rint(depth / q) * q, 0.0)
    gx = np.abs(np.diff(depth, axis=1, prepend=depth[:, :1]))
    gy = np.abs(np.diff(depth, axis=0, prepend=depth[:1]))
    edge = np.maximum(gx, gy) > 0.02
    out[ndimage.binary_dilation(edge, iterations=2)] = 0.0
    drop = ndimage.binary_dilation(rng.random(depth.shape) < 0.01 / 9, np.ones((3, 3), bool))
    out[drop] = 0.0
    return out


def _interior(depth_gt, labels, width=3):
    """Pixels at least ``width`` px away from a depth edge (> 1 cm between neighbours) or a label change."""
    jump = np.zeros(depth_gt.shape, bool)
    for ax in (0, 1):
        d = np.abs(np.diff(depth_gt, axis=ax)) > 0.01
        d |= np.diff(labels, axis=ax) != 0
        if ax == 0:
            jump[1:] |= d
            jump[:-1] |= d
        else:
            jump[:, 1:] |= d
            jump[:, :-1] |= d
    return ~ndimage.binary_dilation(jump, iterations=width)


def synthetic_cases(seeds, pairs, size=(240, 320), kinect=False):
    """Frame pairs of the demo's scenarios with per-pixel ground truth."""
    scen = {"crossing": 2, "mixed": 3, "occlusion": 1}
    for name, n_obj in scen.items():
        if kinect and name != "mixed":
            continue
        for seed in seeds:
            sc = make_scene(n_objects=n_obj, n_frames=24, image_size=size, seed=seed, scenario=name)
            rng = np.random.default_rng(1000 + seed)
            for t in pairs:
                f0, f1 = sc.frames[t], sc.frames[t + 1]
                d0, d1 = f0.depth, f1.depth
                if kinect:
                    d0, d1 = kinect_depth(d0, rng), kinect_depth(d1, rng)
                gt = np.full((*size, 3), np.nan)
                gt[f0.valid] = f0.gt_flow
                Xgt = backproject(f0.depth_gt, sc.camera)
                gt_flow2d = _project(Xgt + gt * sc.dt, sc.camera) - _project(Xgt, sc.camera)
                yield {
                    "name": f"{'kinect' if kinect else name} seed {seed} t {t}",
                    "rgb0": f0.rgb, "d0": d0, "rgb1": f1.rgb, "d1": d1, "cam": sc.camera, "dt": sc.dt,
                    "gt": gt, "gt_flow": gt_flow2d,
                    "score": f0.valid & (d0 > 0),
                    "moving": f0.label_image > 0,
                    "interior": _interior(f0.depth_gt, f0.label_image),
                }


def motorcycle_case():
    """The Motorcycle stereo pair as two RGB-D frames at half resolution (see the module docstring)."""
    from skimage import data

    left, right, disp = data.stereo_motorcycle()
    c = MOTORCYCLE_CALIBRATION
    f, B, doffs = c["f"] / 2, c["baseline_mm"] / 1000.0, c["doffs"] / 2
    cam = PinholeCamera(f, f, (c["cx"] + 0.5) / 2 - 0.5, (c["cy"] + 0.5) / 2 - 0.5)
    H, W = left.shape[0] // 2, left.shape[1] // 2

    def half(img):
        img = img[: 2 * H, : 2 * W].astype(np.float64)
        return 0.25 * (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2])

    d = np.asarray(disp, dtype=np.float64)[: 2 * H, : 2 * W]
    ok = np.isfinite(d)
    dsum = half(np.where(ok, d, 0.0)) * 4
    n = half(ok.astype(np.float64)) * 4
    d_half = np.where(n == 4, dsum / np.maximum(n, 1) / 2.0, np.nan)  # all 4 valid; half-res disparity
    Z0 = np.where(np.isfinite(d_half), f * B / (d_half + doffs), 0.0)
    rgb0 = np.clip(np.rint(half(left)), 0, 255).astype(np.uint8)
    # the right image resampled so that it has the left camera's principal point: R'(x) = R(x + doffs)
    R = half(right)
    rgb1 = np.stack(
        [ndimage.shift(R[..., k], (0.0, -doffs), order=1, mode="nearest") for k in range(3)], axis=-1
    )
    rgb1 = np.clip(np.rint(rgb1), 0, 255).astype(np.uint8)
    # right depth: forward warp with a z-buffer (x' = x - fB/Z), splatted to the two nearest columns
    rows, cols = np.nonzero(Z0 > 0)
    z = Z0[rows, cols]
    xt = cols - f * B / z
    Z1 = np.full((H, W), np.inf)
    for xc in (np.floor(xt), np.ceil(xt)):
        xi = xc.astype(np.int64)
        inside = (xi >= 0) & (xi < W)
        np.minimum.at(Z1, (rows[inside], xi[inside]), z[inside])
    Z1[~np.isfinite(Z1)] = 0.0
    # a left pixel is visible in the right view when the z-buffer at its target holds its own depth
    xi = np.rint(xt).astype(np.int64)
    visible = np.zeros((H, W), bool)
    inside = (xi >= 0) & (xi < W)
    visible[rows[inside], cols[inside]] = np.abs(Z1[rows[inside], xi[inside]] - z[inside]) < 0.01 * z[inside]
    dt = 0.1
    gt = np.zeros((H, W, 3))
    gt[..., 0] = -B / dt
    gt[Z0 == 0] = np.nan
    X = backproject(Z0, cam)
    gt_flow = _project(X + gt * dt, cam) - _project(X, cam)
    return {
        "name": "motorcycle half-res", "rgb0": rgb0, "d0": Z0, "rgb1": rgb1, "d1": Z1, "cam": cam, "dt": dt,
        "gt": gt, "gt_flow": gt_flow, "score": visible & (Z0 > 0), "moving": np.ones((H, W), bool),
        "interior": visible & _interior(Z0, np.zeros((H, W), np.int64)),
    }


# --------------------------------------------------------------------------------------------------
# scoring
# --------------------------------------------------------------------------------------------------
def run_case(case, methods=METHODS):
    out = {}
    for m in methods:
        args = (case["rgb0"], case["d0"], case["rgb1"], case["d1"], case["cam"], case["dt"])
        c0, w0 = time.process_time(), time.perf_counter()
        v, flow = RUNNERS[m](*args)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        out[m] = (v, flow, cpu, wall)
    return out


def accumulate(acc, case, results):
    dt = case["dt"]
    score = case["score"]
    for m, (v, flow, cpu, wall) in results.items():
        a = acc.setdefault(m, {"err": {k: [] for k in ("moving", "static", "all", "interior")},
                               "pred": [], "gt": [], "epe2d": [], "cover": [], "cpu": [], "wall": []})
        answered = np.isfinite(v).all(axis=-1)
        vv = np.where(answered[..., None], v, 0.0)
        e = np.linalg.norm(vv - case["gt"], axis=-1) * dt * 1000.0
        for key, sel in (("moving", score & case["moving"]), ("static", score & ~case["moving"]),
                         ("all", score), ("interior", score & case["interior"])):
            a["err"][key].append(e[sel])
        mv = score & case["moving"]
        a["pred"].append(vv[mv])
        a["gt"].append(case["gt"][mv])
        ff = np.where(np.isfinite(flow), flow, 0.0)
        a["epe2d"].append(np.linalg.norm(ff - case["gt_flow"], axis=-1)[mv])
        a["cover"].append(answered[score])
        a["cpu"].append(cpu)
        a["wall"].append(wall)


def summarise(acc, dt):
    rows = {}
    for m, a in acc.items():
        r = {}
        for key, lst in a["err"].items():
            e = np.concatenate(lst)
            r[key] = (float(e.mean()), float(np.median(e))) if e.size else (np.nan, np.nan)
        pred, gt = np.concatenate(a["pred"]), np.concatenate(a["gt"])
        r["metrics"] = scene_flow_metrics(pred, gt, dt=dt)
        r["epe2d"] = float(np.concatenate(a["epe2d"]).mean())
        r["cover"] = float(np.concatenate(a["cover"]).mean())
        r["cpu"] = float(np.median(a["cpu"]))
        r["wall"] = float(np.median(a["wall"]))
        rows[m] = r
    return rows


def table(title, rows):
    lines = [
        f"### {title}",
        "",
        "| method | moving mean / median | static mean / median | all mean / median | interior mean / median "
        "| Acc3DS | Acc3DR | outliers | EPE2D (px) | cover | CPU s / pair | wall s / pair |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for m, r in rows.items():
        mm = " | ".join(f"{r[k][0]:.2f} / {r[k][1]:.2f}" for k in ("moving", "static", "all", "interior"))
        x = r["metrics"]
        lines.append(f"| {m} | {mm} | {x['acc3d_strict']:.3f} | {x['acc3d_relax']:.3f} | {x['outliers']:.3f} "
                     f"| {r['epe2d']:.2f} | {r['cover']:.3f} | {r['cpu']:.3f} | {r['wall']:.3f} |")
    return lines


def _verdict(ok):
    return "met" if ok else "NOT met"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed, one pair per scenario (smoke run)")
    args = parser.parse_args()
    seeds, pairs = ((0,), (10,)) if args.quick else ((0, 1, 2), (4, 11, 18))
    # warm-up (numba compilation, FFT plans) outside the clock
    warm = next(synthetic_cases((0,), (10,), size=(48, 64)))
    run_case(warm)

    lines = ["## RGB-D variational scene flow (`flowtrack.sceneflow.rgbd_scene_flow`)", ""]
    summaries = {}
    for label, kinect in (("synthetic", False), ("kinect", True)):
        acc = {}
        n = 0
        for case in synthetic_cases(seeds, pairs, kinect=kinect):
            accumulate(acc, case, run_case(case))
            n += 1
        summaries[label] = summarise(acc, 0.1)
        what = ("crossing, mixed, occlusion" if not kinect else
                "mixed with Kinect-like depth (quantised, edge holes, dropouts)")
        lines += table(f"Synthetic 320×240: {what}; {n} frame pairs (seeds {list(seeds)}, t {list(pairs)})",
                       summaries[label])
        lines.append("")

    mc = motorcycle_case()
    acc = {}
    accumulate(acc, mc, run_case(mc))
    summaries["motorcycle"] = summarise(acc, mc["dt"])
    H, W = mc["d0"].shape
    lines += table(f"Middlebury Motorcycle, half resolution ({W}×{H}), true motion = baseline "
                   f"{MOTORCYCLE_CALIBRATION['baseline_mm']:.0f} mm sideways; {int(mc['score'].sum())} "
                   "pixels visible in both views", summaries["motorcycle"])
    lines.append("")

    # speed at 320x240 and 640x480 against TV-L1 (the same scene rendered at both sizes)
    speed = {}
    for size in ((240, 320), (480, 640)):
        case = next(synthetic_cases((0,), (10,), size=size))
        cpu = {m: [] for m in (OURS, TVL1)}
        wall = {m: [] for m in (OURS, TVL1)}
        for _ in range(1 if args.quick else 3):
            for m, (_, _, c, w) in run_case(case, (OURS, TVL1)).items():
                cpu[m].append(c)
                wall[m].append(w)
        speed[size] = {m: (min(cpu[m]), min(wall[m])) for m in cpu}
    lines += ["### Speed (one mixed-scene pair, best of 3, single thread)", "",
              "| size | flowtrack rgbd CPU s | wall s | skimage TV-L1 + lifting CPU s | wall s "
              "| ratio (CPU) |",
              "|---|---:|---:|---:|---:|---:|"]
    for (h, w), s in speed.items():
        lines.append(f"| {w}×{h} | {s[OURS][0]:.3f} | {s[OURS][1]:.3f} | {s[TVL1][0]:.3f} | {s[TVL1][1]:.3f} "
                     f"| {s[TVL1][0] / s[OURS][0]:.1f}x faster |")
    lines.append("")

    # verdicts
    syn = summaries["synthetic"]
    peer = min((DIS, FARNEBACK), key=lambda m: syn[m]["moving"][0])
    ours_mv = syn[OURS]["moving"][0]
    mcs = summaries["motorcycle"]
    s1, s2 = speed[(240, 320)], speed[(480, 640)]
    lines += [
        "Bars (issue 14; EPE3D in mm per frame, time = CPU time, the fair measure on this shared machine):",
        f"- synthetic moving mean EPE3D {ours_mv:.2f} ≤ 0.5 × better OpenCV peer ({peer}, "
        f"{syn[peer]['moving'][0]:.2f}): {_verdict(ours_mv <= 0.5 * syn[peer]['moving'][0])}",
        f"- synthetic moving mean EPE3D {ours_mv:.2f} ≤ 0.5 × nearest neighbour "
        f"({syn[NN]['moving'][0]:.2f}): "
        f"{_verdict(ours_mv <= 0.5 * syn[NN]['moving'][0])}",
        f"- static mean EPE3D {syn[OURS]['static'][0]:.2f} ≤ 2 mm: {_verdict(syn[OURS]['static'][0] <= 2.0)}",
        f"- interior mean EPE3D {syn[OURS]['interior'][0]:.2f} no worse than {peer} "
        f"({syn[peer]['interior'][0]:.2f}): {_verdict(syn[OURS]['interior'][0] <= syn[peer]['interior'][0])}",
        f"- Motorcycle mean EPE3D {mcs[OURS]['all'][0]:.2f} < TV-L1 + lifting ({mcs[TVL1]['all'][0]:.2f}): "
        f"{_verdict(mcs[OURS]['all'][0] < mcs[TVL1]['all'][0])}",
        f"- Motorcycle mean EPE3D {mcs[OURS]['all'][0]:.2f} ≤ DIS medium + lifting "
        f"({mcs[DIS]['all'][0]:.2f}): "
        f"{_verdict(mcs[OURS]['all'][0] <= mcs[DIS]['all'][0])}",
        f"- 320×240: {s1[OURS][0]:.3f} s ≤ 0.5 s: {_verdict(s1[OURS][0] <= 0.5)}; "
        f"640×480: {s2[OURS][0]:.3f} s ≤ 2.0 s: {_verdict(s2[OURS][0] <= 2.0)}; "
        f"never slower than TV-L1: {_verdict(s1[OURS][0] <= s1[TVL1][0] and s2[OURS][0] <= s2[TVL1][0])}",
        "",
        "Wall-clock times are shown beside the CPU times: on this machine (2 cores shared by many jobs)",
        "the wall clock of a single-threaded job is several times its CPU time, the same for every method.",
    ]
    publish("rgbd_flow", "\n".join(lines) + "\n", args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
