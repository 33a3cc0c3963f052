"""Benchmark: MultiObjectTracker.step with 50 tracks and 50 detections; scene flow in the tracker.

The peer is a SORT-style tracker written here: one ``filterpy.kalman.KalmanFilter`` per track,
Python loops over (track, detection) pairs to build the Mahalanobis cost matrix, gating by a
prohibitive cost and ``scipy.optimize.linear_sum_assignment``. Both trackers use the same model
(constant velocity, same ``Q``, ``R``, gate) and see the same frames; both are measured in the
same run, interleaved, and the ratio is reported.

Targets: ``MultiObjectTracker.step`` >= 10x faster than the peer and >= 2,000 steps per second.

Second section, scene flow in the tracker, on the demo's pipeline, by the library calls
``flowtrack_course.demo.run_demo`` makes (synthetic RGB-D frames → clouds → dense variational RGB-D flow
at the cloud's points, ``flowtrack.pipeline.rgbd_cloud_flow`` → motion clusters of that flow,
``scene_flow_and_clusters(..., flow=...)`` → detections with their mean RGB-D velocities,
``flowtrack_course.demo.run.detection_measurements``: the pieces' centroids, the velocity of each
piece's visible-surface centroid, ``flowtrack.pipeline.visible_centroid_velocities``, with that estimate's
covariance widened by the visible-extent change): ``flowtrack.tracking_eval.tracking_ablation``
runs position-only and flow-aided tracking (velocity measurements with those covariances in the update) on
the same detections, with the demo's ``max_misses`` (12, covers the occlusion scenario's 9 hidden
frames). Targets: over the crossing, mixed and occlusion
scenarios and several seeds, flow-aided never has more ID switches and never a MOTA lower by more than
0.02 than position-only, and its 5-frames-ahead prediction error is <= 0.8x position-only on average; on
the turning scenario the turn-rate (rigid-motion) model predicts the turning object >= 2x better than
constant velocity (both flow-aided).

Usage::

    .venv/bin/python benchmarks/bench_tracking.py [--quick] [--check]
        [--section {all,speed,flow,confirm,heldout}] [--flow-image H W]
        [--split {train,test,both}] [--limit N] [--workdir DIR]

Third section, track confirmation on Kinect-like depth: the same scenes with and without
``flowtrack.synth.kinect_depth`` artefacts (depth-dependent noise, disparity quantisation, flying pixels,
edge holes), the demo's flow-aided tracker confirming by ``min_hits`` (``HitCountConfirmer``) and by the
sequential track score (``SequentialScoreConfirmer``, ``flowtrack.pipeline.track_confirmer``): spurious
confirmed tracks, MOTA, IDF1, ID switches. Target: the score removes every spurious track without an ID
switch more or a MOTA lower by more than 0.02 in any run.

Fourth section, held-out evaluation (issue 25): the sequences of ``benchmarks/_evalscenes.py`` (a
renderer that shares no code with flowtrack), its training split (where every default is chosen) and
its test split (reported, never tuned on), each run by the command line as a user would
(``flowtrack demo --input SEQ --intrinsics ... --out DIR``, in a child process), ``tracks.csv`` scored
with ``flowtrack.metrics.clear_mot`` at 15 cm against the object centres, counting every row whose
status is not tentative; objects hidden, outside the image or too small to detect in a frame are
ignored there (``flowtrack.metrics.remove_ignored``). Per sequence MOTA, ID switches, FP (and as a
share of the ground-truth objects), FN; the worst sequence beside the mean; the position-only vs
flow-aided ablation by replaying the tracker inputs recorded during the CLI run
(``benchmarks/_record_demo.py``; the replay must reproduce ``tracks.csv``). Targets (test split): MOTA
>= 0.85 on every sequence, <= 1 ID switch per sequence, false positives <= 2 % of the ground-truth
objects. ``--split`` and ``--limit N`` (N sequences spread over the split) run a subset; the worst test
sequence's false positives are drawn to ``benchmarks/results/gallery_tracking_worst_sequence.png``.

Prints its tables and, unless ``--quick``, writes them to ``benchmarks/results/tracking.md``,
``benchmarks/results/tracking_flow.md``, ``benchmarks/results/tracking_confirm.md`` and (full held-out
runs only) ``benchmarks/results/tracking_heldout.md``.
``--check`` exits with status 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import os
import pickle
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy
from filterpy.kalman import KalmanFilter as FilterPyKF
from scipy.optimize import linear_sum_assignment

from _results import RESULTS, publish, save_small_png
from flowtrack.association import chi2_gate
from flowtrack.kalman import constant_velocity_model
from flowtrack.tracking import MultiObjectTracker

N_OBJECTS = 50
DT, Q_ACC, SIGMA = 0.1, 1.0, 0.05
VELOCITY_VAR = 4.0
# A wide gate, so that no detection of the 50 objects falls outside it during the run (with 0.99
# about one in a hundred would, starting a short-lived tentative track): a pure steady state.
GATE_PROB = 0.99999
WARMUP = 10


class SortBaseline:
    """SORT-style tracker: filterpy filter per track, Python-loop costs, scipy assignment."""

    def __init__(self, dt, q, r, dim=2, gate_prob=0.99, min_hits=2, max_misses=3, velocity_var=4.0):
        self.F, self.H, self.Q, self.R = constant_velocity_model(dt, q, r, dim)
        self.dim = dim
        self.gate = chi2_gate(dim, gate_prob)
        self.min_hits, self.max_misses, self.velocity_var = min_hits, max_misses, velocity_var
        self.tracks = []  # dicts: id, kf, hits, misses
        self.next_id = 0

    def _new_track(self, z):
        d = self.dim
        kf = FilterPyKF(dim_x=2 * d, dim_z=d)
        kf.F, kf.H, kf.Q, kf.R = self.F.copy(), self.H.copy(), self.Q.copy(), self.R.copy()
        kf.x = np.concatenate([z, np.zeros(d)])[:, None]
        kf.P = np.diag(np.r_[np.diag(self.R), np.full(d, self.velocity_var)])
        self.tracks.append({"id": self.next_id, "kf": kf, "hits": 1, "misses": 0})
        self.next_id += 1

    def step(self, detections):
        for t in self.tracks:
            t["kf"].predict()
        M, N = len(self.tracks), len(detections)
        cost = np.zeros((M, N))
        for i, t in enumerate(self.tracks):
            kf = t["kf"]
            S = kf.H @ kf.P @ kf.H.T + kf.R
            S_inv = np.linalg.inv(S)
            z_pred = (kf.H @ kf.x)[:, 0]
            for j in range(N):
                y = detections[j] - z_pred
                cost[i, j] = y @ S_inv @ y
        big = 1e6
        gated = np.where(cost <= self.gate, cost, big)
        rows, cols = linear_sum_assignment(gated) if M and N else (np.array([], int), np.array([], int))
        matched_t, matched_d = set(), set()
        for i, j in zip(rows, cols):
            if cost[i, j] <= self.gate:
                self.tracks[i]["kf"].update(detections[j])
                self.tracks[i]["hits"] += 1
                self.tracks[i]["misses"] = 0
                matched_t.add(i)
                matched_d.add(j)
        for i, t in enumerate(self.tracks):
            if i not in matched_t:
                t["misses"] += 1
        self.tracks = [
            t
            for t in self.tracks
            if not (t["misses"] > self.max_misses or (t["misses"] and t["hits"] < self.min_hits))
        ]
        for j in range(N):
            if j not in matched_d:
                self._new_track(detections[j])
        return [t for t in self.tracks if t["hits"] >= self.min_hits]


def make_frames(n_frames, rng):
    """50 objects on a 10 x 5 grid (8 m spacing), slow constant velocities: no births in steady state."""
    gx, gy = np.meshgrid(np.arange(10) * 8.0, np.arange(5) * 8.0)
    p = np.stack([gx.ravel(), gy.ravel()], axis=1)
    v = rng.normal(scale=0.5, size=p.shape)
    frames = []
    for _ in range(n_frames):
        frames.append(p + SIGMA * rng.normal(size=p.shape))
        p = p + v * DT
    return frames


def time_tracker(make, frames):
    """Warm up (births and confirmation), then run one step per remaining frame.

    Returns the CPU time and the wall-clock time per step (seconds), the tracker and its last output.
    CPU time (``time.process_time``, all threads of the process) does not count the time the process
    waits for a core, so it is the figure that survives a loaded machine.
    """
    trk = make()
    for Z in frames[:WARMUP]:
        trk.step(Z)
    timed = frames[WARMUP:]
    c0, w0 = time.process_time(), time.perf_counter()
    for Z in timed:
        out = trk.step(Z)
    cpu = (time.process_time() - c0) / len(timed)
    wall = (time.perf_counter() - w0) / len(timed)
    return cpu, wall, trk, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames and repeats")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    ap.add_argument("--section", choices=("all", "speed", "flow", "confirm", "heldout"), default="all",
                    help="the step-speed section, the scene-flow section, the track "
                         "confirmation section (Kinect-like depth), the held-out train/test sequences "
                         "or all")
    ap.add_argument("--split", choices=("train", "test", "both"), default="both",
                    help="held-out: which split (default both, reported separately)")
    ap.add_argument("--limit", type=int, default=None,
                    help="held-out: N sequences per split, spread evenly over it")
    ap.add_argument("--workdir", default=None,
                    help="held-out: keep the sequences and the demo's outputs here; a later run reuses "
                         "them (delete DIR after changing the code)")
    ap.add_argument("--flow-image", type=int, nargs=2, default=FLOW_IMAGE, metavar=("H", "W"),
                    help="image size of the scene-flow section's scenes (default %(default)s, the demo's; "
                         "the first RGB-D runs used 120 160)")
    args = ap.parse_args(argv)
    ok = True
    if args.section in ("all", "speed"):
        ok &= speed_section(args)
    if args.section in ("all", "flow"):
        ok &= flow_section(args)
    if args.section in ("all", "confirm"):
        ok &= confirm_section(args)
    if args.section in ("all", "heldout"):
        ok &= heldout_section(args)
    return 1 if (args.check and not ok) else 0


def speed_section(args) -> bool:
    """The step-speed benchmark against the SORT-style peer; True when its targets are met."""
    n_timed, repeats = (60, 3) if args.quick else (300, 7)
    rng = np.random.default_rng(0)
    frames = make_frames(WARMUP + n_timed, rng)

    def ours():
        return MultiObjectTracker(DT, Q_ACC, SIGMA**2, gate_prob=GATE_PROB, velocity_var=VELOCITY_VAR)

    def peer():
        return SortBaseline(DT, Q_ACC, SIGMA**2, gate_prob=GATE_PROB, velocity_var=VELOCITY_VAR)

    t_ours, t_peer, w_ours, w_peer = [], [], [], []
    for _ in range(repeats):  # interleaved, so that load changes hit both
        a, wa, trk, out = time_tracker(ours, frames)
        b, wb, base, out_b = time_tracker(peer, frames)
        t_ours.append(a)
        t_peer.append(b)
        w_ours.append(wa)
        w_peer.append(wb)
    # sanity: both trackers hold the same 50 confirmed tracks with the same states
    assert len(out) == N_OBJECTS and len(out_b) == N_OBJECTS, (len(out), len(out_b))
    assert trk._next_id == N_OBJECTS and base.next_id == N_OBJECTS, "unexpected births in steady state"
    x_ours = np.array([t.x for t in out])
    x_peer = np.array([t["kf"].x[:, 0] for t in out_b])
    max_diff = float(np.abs(x_ours - x_peer).max())
    assert max_diff < 1e-8, max_diff

    # Targets are judged on CPU time per step, best run of each (the usual timeit practice: the
    # minimum is the run least disturbed by other processes); wall-clock times are reported too.
    ours_s, peer_s = float(np.min(t_ours)), float(np.min(t_peer))
    ours_w, peer_w = float(np.min(w_ours)), float(np.min(w_peer))
    ours_med, peer_med = float(np.median(t_ours)), float(np.median(t_peer))
    ratio, ratio_w, ratio_med = peer_s / ours_s, peer_w / ours_w, peer_med / ours_med
    rate = 1.0 / ours_s
    ok_ratio, ok_rate = ratio >= 10.0, rate >= 2000.0
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# Tracking benchmark",
        "",
        f"One `step` with {N_OBJECTS} confirmed tracks and {N_OBJECTS} detections (2-D, constant velocity, "
        f"gate probability {GATE_PROB}), {repeats} runs of {n_timed} steady-state frames each, the two "
        "trackers interleaved. Peer: SORT-style (one filterpy `KalmanFilter` per track, Python-loop "
        "Mahalanobis costs, `scipy.optimize.linear_sum_assignment`), same model, same frames; final "
        f"states agree to {max_diff:.1e}. Times per step, best run; CPU time (`time.process_time`) "
        "does not count waiting for a core on a loaded machine, wall-clock time does.",
        "",
        "| tracker | CPU µs / step | steps / CPU-s | wall µs / step | steps / wall-s |",
        "|---|---:|---:|---:|---:|",
        f"| `flowtrack.tracking.MultiObjectTracker` | {ours_s * 1e6:.0f} | {rate:,.0f} | "
        f"{ours_w * 1e6:.0f} | {1.0 / ours_w:,.0f} |",
        f"| SORT-style baseline (filterpy + loops + scipy) | {peer_s * 1e6:.0f} | {1.0 / peer_s:,.0f} | "
        f"{peer_w * 1e6:.0f} | {1.0 / peer_w:,.0f} |",
        "",
        "| target (CPU time, best runs) | measured | met |",
        "|---|---:|:---:|",
        f"| speed-up vs baseline >= 10x | {ratio:.1f}x (wall: {ratio_w:.1f}x; "
        f"median runs: {ratio_med:.1f}x) | {'yes' if ok_ratio else 'NO'} |",
        f"| steps per second >= 2,000 | {rate:,.0f} (wall: {1.0 / ours_w:,.0f}) | "
        f"{'yes' if ok_rate else 'NO'} |",
        "",
        f"Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs, 1-min load average {load:.1f} at the end; "
        f"{'--quick' if args.quick else 'full'} run.",
        "",
    ]
    publish("tracking", "\n".join(lines), args.quick)
    return bool(ok_ratio and ok_rate)


# ----------------------------------------------------------------------------------------------------
# scene flow in the tracker
# ----------------------------------------------------------------------------------------------------
FLOW_SCENARIOS = ("crossing", "mixed", "occlusion")
FLOW_SEEDS = (0, 1, 2)
FLOW_FRAMES = 24
FLOW_IMAGE = (240, 320)  # the demo's image size
AHEAD = 5
TURN_OPTIONS = {"motion_model": "turn_rate", "q_omega": 1.0, "omega_var": 4.0}


def scene_detections(scenario, seed, n_frames=FLOW_FRAMES, image_size=FLOW_IMAGE, cfg=None, kinect=False):
    """The demo's detections (with velocities and covariances) for every frame pair of a synthetic scene.

    Built as :func:`flowtrack_course.demo.run_demo` builds them, by the same calls: the scene and its
    clouds (``flowtrack_course.demo.inputs.load_input`` / ``frame_cloud``, the demo's depth noise,
    rendered ``AHEAD`` frames past the last processed one), the dense RGB-D flow of each pair at the
    cloud's points (:func:`flowtrack.pipeline.rgbd_cloud_flow`), motion clusters of that flow
    (:func:`flowtrack.pipeline.scene_flow_and_clusters` with ``flow=``) and the detections with their
    velocity measurements (``flowtrack_course.demo.run.detection_measurements``: the velocity of each
    piece's visible-surface centroid, covariance of that estimate widened by the
    visible-extent change).

    Returns a dict: ``Z``, ``V``, ``C``, ``R`` (the detections' position covariances, or None; per
    processed frame), ``W`` (each detection's Kabsch yaw rate about the table normal), the references
    ``GV`` (the true mean material flow of the visible object nearest each detection) and ``GU`` (the
    true velocity of that object's visible-surface centroid, ``(truth[t+1] - truth[t]) / dt``; NaN where
    either is missing),
    ``truth`` (per rendered frame ``{object id: centroid of the visible noiseless surface}`` for objects
    with at least as many visible pixels as a detection needs, as the demo scores), ``dt``, ``up`` (the
    table normal in the camera frame) and ``cfg``.
    """
    from flowtrack.pipeline import rgbd_cloud_flow, scene_flow_and_clusters
    from flowtrack_course.demo import DemoConfig
    from flowtrack_course.demo.config import DEFAULT_NOISE
    from flowtrack_course.demo.inputs import frame_cloud, load_input, surface_centroids
    from flowtrack_course.demo.run import detection_measurements

    cfg = cfg or DemoConfig()
    n_objects = 3 if scenario != "turning" else 2
    inp = load_input(None, n_frames, n_objects, image_size, seed, DEFAULT_NOISE, AHEAD, scenario, None)
    if kinect:  # Kinect-like depth artefacts (flowtrack.synth.kinect_depth), their own generator
        from flowtrack.synth import kinect_depth

        art_rng = np.random.default_rng(1000 + seed)
        inp.depth = [kinect_depth(dep, art_rng, noise_floor=DEFAULT_NOISE) for dep in inp.depth]
    scene, cam, dt = inp.scene, inp.camera, inp.dt
    n_valid = int(np.count_nonzero(inp.depth[0] > 0))
    min_pixels = int(np.ceil(cfg.min_detection_points * max(1.0, n_valid / cfg.max_points)))
    truth = [surface_centroids(f, min_pixels) for f in scene.frames]
    rng = np.random.default_rng(seed)  # the demo's subsampling generator
    Zs, Vs, Cs, Rs, GVs, GUs, Ws = [], [], [], [], [], [], []
    up = np.linalg.inv(scene.camera_pose)[:3, :3] @ np.array([0.0, 0.0, 1.0])
    nxt = frame_cloud(inp, 0, cfg, rng)
    for t in range(inp.n - 1):
        X, nxt = nxt.points, frame_cloud(inp, t + 1, cfg, rng)
        rgbd = rgbd_cloud_flow(inp.rgb[t], inp.depth[t], inp.rgb[t + 1], inp.depth[t + 1], cam, dt, X)
        _, clusters, _ = scene_flow_and_clusters(X, nxt.points, dt, cfg, flow=rgbd)
        Z, V, C, Rz, W = detection_measurements(inp, t, X, clusters, rgbd, nxt.points, cfg, yaw_axis=up)
        Ws.append(W)
        Rs.append(Rz)
        Zs.append(Z)
        Vs.append(V)
        Cs.append(C)
        # references only: the true (material) mean flow and the true visible-centroid velocity of the
        # visible object nearest each detection
        f = scene.frames[t]
        seen = {k: f.gt_points[f.labels == k].mean(axis=0) for k in scene.object_ids if (f.labels == k).any()}
        GV = np.full_like(V, np.nan)
        GU = np.full_like(V, np.nan)
        for j, z in enumerate(Z):
            if seen:
                k = min(seen, key=lambda k: np.linalg.norm(seen[k] - z))
                GV[j] = f.gt_flow[f.labels == k].mean(axis=0)
                if k in truth[t] and k in truth[t + 1]:
                    GU[j] = (truth[t + 1][k] - truth[t][k]) / dt
        GVs.append(GV)
        GUs.append(GU)
    return {"Z": Zs, "V": Vs, "C": Cs, "R": Rs, "W": Ws, "GV": GVs, "GU": GUs, "truth": truth, "dt": dt,
            "up": up, "cfg": cfg}


def velocity_nees(d) -> np.ndarray:
    """Normalised squared error e^T C^-1 e of every velocity measurement against the true velocity of
    the visible-surface centroid (3 dof; mean 3 and median 2.37 for a consistent covariance)."""
    out = []
    for V, C, GU in zip(d["V"], d["C"], d["GU"]):
        for v, c, g in zip(V, C, GU):
            if np.isfinite(v - g).all() and np.isfinite(c).all():
                out.append(float((v - g) @ np.linalg.solve(c, v - g)))
    return np.array(out)


def _ablation(d, flow_options=None, truth=None, velocities=None, max_misses=None, cfg=None, yaw_rates=None):
    from flowtrack.pipeline import track_confirmer
    from flowtrack.tracking_eval import tracking_ablation

    cfg = cfg or d["cfg"]
    return tracking_ablation(
        d["Z"], d["V"] if velocities is None else velocities, d["C"], d["truth"] if truth is None else truth,
        d["dt"], q=cfg.track_q, r=cfg.track_r,
        ahead=AHEAD, max_dist=cfg.mot_max_dist, flow_options=flow_options,
        tracker_options={"min_hits": cfg.min_hits, "gate_prob": cfg.gate_prob,
                         "max_misses": cfg.max_misses if max_misses is None else max_misses,
                         "reacquire_radius": cfg.track_reacquire_radius,
                         "birth_exclusion_radius": cfg.track_birth_exclusion_radius,
                         "confirmer": track_confirmer(cfg)},
        position_covs=d.get("R"), yaw_rates=yaw_rates)


def flow_section(args) -> bool:
    """Position-only vs flow-aided tracking, and turn-rate vs constant velocity; True when targets are met."""
    from flowtrack_course.demo import DemoConfig

    seeds = FLOW_SEEDS[:1] if args.quick else FLOW_SEEDS
    n_frames = 14 if args.quick else FLOW_FRAMES
    t0 = time.perf_counter()
    rows, ok_ids, ok_mota, ratios, gt_ratios, gu_ratios, nees_all = [], True, True, [], [], [], []
    for scenario in FLOW_SCENARIOS:
        for seed in seeds:
            d = scene_detections(scenario, seed, n_frames, tuple(args.flow_image))
            res = _ablation(d)
            po, fa = res["position_only"], res["flow_aided"]
            # the same, with the true material flow and with the true visible-centroid velocity
            ideal = _ablation(d, velocities=d["GV"])["flow_aided"]
            gt_ratios.append(ideal["prediction_error_mm"] / po["prediction_error_mm"])
            ideal_u = _ablation(d, velocities=d["GU"])["flow_aided"]
            gu_ratios.append(ideal_u["prediction_error_mm"] / po["prediction_error_mm"])
            err = np.concatenate([v - g for v, g in zip(d["V"], d["GU"])])
            err = err[np.isfinite(err).all(axis=1)]
            v_rms = float(np.sqrt((err**2).sum(axis=1).mean()))
            nees = velocity_nees(d)
            nees_all.append(nees)
            ok_ids &= fa["id_switches"] <= po["id_switches"]
            ok_mota &= fa["mota"] >= po["mota"] - 0.02
            ratios.append(fa["prediction_error_mm"] / po["prediction_error_mm"])
            rows.append(f"| {scenario} | {seed} | {po['mota']:.3f} / {fa['mota']:.3f} | "
                        f"{po['idf1']:.3f} / {fa['idf1']:.3f} | {po['id_switches']} / {fa['id_switches']} | "
                        f"{po['prediction_error_mm']:.1f} / {fa['prediction_error_mm']:.1f} | "
                        f"{ratios[-1]:.2f} | {v_rms:.3f} | {nees.mean():.2f} / {np.median(nees):.2f} | "
                        f"{ideal['prediction_error_mm']:.1f} ({gt_ratios[-1]:.2f}) | "
                        f"{ideal_u['prediction_error_mm']:.1f} ({gu_ratios[-1]:.2f}) |")
    mean_ratio = float(np.mean(ratios))
    ok_pred = mean_ratio <= 0.8
    pooled = np.concatenate(nees_all)
    ok_nees = 1.5 <= pooled.mean() <= 6.0
    turn_rows, turn_ratios = [], []
    for seed in seeds:
        d = scene_detections("turning", seed, n_frames, tuple(args.flow_image))
        obj1 = [{k: v for k, v in f.items() if k == 1} for f in d["truth"]]  # the turning object
        cv = _ablation(d, truth=obj1)
        tr = _ablation(d, {**TURN_OPTIONS, "turn_axis": d["up"]}, truth=obj1)
        tw = _ablation(d, {**TURN_OPTIONS, "turn_axis": d["up"]}, truth=obj1, yaw_rates=d["W"])
        e_po = cv["position_only"]["prediction_error_mm"]
        e_cv = cv["flow_aided"]["prediction_error_mm"]
        e_tr = tr["flow_aided"]["prediction_error_mm"]
        e_tw = tw["flow_aided"]["prediction_error_mm"]
        w1 = [w for W, Z, tr_ in zip(d["W"], d["Z"], d["truth"]) if 1 in tr_
              for w, z in zip(W, Z) if np.linalg.norm(z - tr_[1]) < 0.05]
        turn_ratios.append(e_cv / e_tr)
        turn_rows.append(f"| {seed} | {e_po:.1f} | {e_cv:.1f} | {e_tr:.1f} | {turn_ratios[-1]:.2f}x | "
                         f"{e_tw:.1f} | {np.median(w1):.2f} |")
    mean_turn = float(np.mean(turn_ratios))
    ok_turn = mean_turn >= 2.0
    yes = {True: "yes", False: "NO"}
    lines = [
        "# Scene flow in the tracker (issue 15)",
        "",
        "The demo's pipeline (`flowtrack_course.demo.run_demo`) on synthetic scenes "
        f"({args.flow_image[0]}×{args.flow_image[1]} px, {n_frames} frames, "
        f"`DemoConfig()` defaults (`max_misses={DemoConfig().max_misses}`), the demo's depth noise): the "
        "dense variational RGB-D flow of each frame pair at the cloud's points "
        "(`flowtrack.pipeline.rgbd_cloud_flow`), "
        "motion clusters of that flow (`scene_flow_and_clusters(..., flow=...)`), detections "
        "(`detection_pieces`: the pieces' centroids) with the velocity of each piece's visible-surface "
        "centroid and that estimate's covariance (the flow's residual scatter about its cluster's rigid "
        "motion plus `visible_velocity_std^2 I`, the error the whole piece shares) "
        "widened by the visible-extent change, `C + k (u - v)(u - v)^T` with k = "
        f"{DemoConfig().extent_change_inflation:g} (`flowtrack.pipeline.visible_centroid_velocities`, "
        "via `flowtrack_course.demo.run.detection_measurements`), tracked by `MultiObjectTracker` "
        "position-only (no velocities) and flow-aided "
        "(`velocity_update=True` with those covariances, and each detection's position covariance widened "
        "toward a nearer surface that cuts it, `flowtrack.pipeline.occlusion_position_covariances` with "
        f"s = {DemoConfig().occlusion_position_scale:g}; position-only tracking keeps R) "
        "(`flowtrack.tracking_eval.tracking_ablation`), both with the demo's colour test "
        f"(`colour_check={DemoConfig().colour_check}`) and birth exclusion "
        f"(`track_birth_exclusion_radius={DemoConfig().track_birth_exclusion_radius:g}` m), both confirming "
        "tracks as the demo does "
        f"(`confirmation={DemoConfig().confirmation!r}`: the sequential track score, see the confirmation "
        "section; without velocities a track gathers its score more slowly, so position-only tracks are "
        "confirmed about one frame later than with `min_hits=2`, which lowers their MOTA by about 0.05 and "
        "leaves their worst, earliest predictions unscored: the mean ratio was 0.76 with `min_hits=2`, "
        "the flow-aided rows are the same). MOTA, IDF1, ID switches at 0.1 m against the "
        f"centroid of each object's visible noiseless surface; prediction error {AHEAD} frames ahead, "
        "mean over every frame and every object matched to a track. Cells: position-only / flow-aided.",
        "",
        "| scenario | seed | MOTA | IDF1 | ID switches | prediction error (mm) | ratio | velocity error "
        "(m/s, rms) | velocity NEES (mean / median) | with the true material flow (mm, ratio) | "
        "with the true centroid velocity (mm, ratio) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        "The last four columns are references: *velocity error* is the rms of the detections' velocity "
        "measurements against the true velocity of the visible-surface centroid (the finite difference of "
        "the ground truth, `(truth[t+1] - truth[t]) / dt`); *velocity NEES* the normalised squared error "
        "e^T C^-1 e of those measurements against that truth with their covariances C (3 dof: mean 3 and "
        "median 2.37 for a consistent covariance; pooled over these runs: mean "
        f"{pooled.mean():.2f}, median {np.median(pooled):.2f}, {100 * np.mean(pooled > 7.815):.0f} % "
        "outside the 95 % ellipsoid; the errors are heavy-tailed, so the median stays low where the mean "
        "is right, see `PipelineConfig.visible_velocity_std`, whose constants were chosen on seeds 10-12, "
        "not these); the last two rerun flow-aided tracking with the "
        "true mean (material) flow of the object's visible points, or with that true centroid velocity, "
        "as the velocities (same covariances). "
        f"Mean ratio with the true material flow: {float(np.mean(gt_ratios)):.2f}; with the true centroid "
        f"velocity: {float(np.mean(gu_ratios)):.2f}. The tracks follow the centroid of the visible surface, "
        "which is not a body point: a spinning, partly hidden or entering object's centroid does not move "
        "with its material flow, so even the true material flow predicts it worse than its positions do; "
        "the detections therefore measure the centroid's own velocity. The covariance widening k was "
        "chosen on these scenes (measured when it was written): with k = 1 mixed seed 0 had one ID switch "
        "more than position-only (object 2, hidden by object 1 while its visible centroid slowed, came out "
        "outside its track's gate); k = 3, 4 and 10 met every bar, mean ratios 0.75, 0.76, 0.76.",
        "",
        f"Turning scenario (object 1 on an arc of radius 0.13 m at 1 rad/s; prediction error of that object, "
        f"mm): constant velocity vs the turn-rate model ({TURN_OPTIONS}, axis = table normal), both "
        "flow-aided; position-only constant velocity for reference.",
        "",
        "| seed | CV position-only | CV flow-aided | turn-rate flow-aided | CV / turn-rate | "
        "turn-rate, born with the Kabsch yaw rate | Kabsch yaw rate of object 1 (median, rad/s) |",
        "|---:|---:|---:|---:|---:|---:|---:|",
        *turn_rows,
        "",
        "The next-to-last column starts each turn-rate track with the yaw rate of the rigid motion fitted to "
        "its piece's flow (`step(..., yaw_rates=)`, variance `omega_var`) instead of 0; the last is that "
        "measured rate for the turning object, whose true rate is 1 rad/s: the smoothed RGB-D flow "
        "flattens the velocity differences across a 9 cm object, so its rotation comes out about half as "
        "large, and starting from it changes little (the filter learns the rate from the velocities in a "
        "few frames).",
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| flow-aided never more ID switches | {'none more' if ok_ids else 'more in some run'} | "
        f"{yes[ok_ids]} |",
        f"| flow-aided MOTA never lower by > 0.02 | {'never' if ok_mota else 'lower in some run'} | "
        f"{yes[ok_mota]} |",
        f"| prediction error flow-aided / position-only <= 0.8 (mean) | {mean_ratio:.2f} | {yes[ok_pred]} |",
        f"| velocity NEES within [0.5, 2] x dof (pooled mean) | {pooled.mean():.2f} | {yes[ok_nees]} |",
        f"| turning: CV / turn-rate prediction error >= 2 (mean) | {mean_turn:.2f} | {yes[ok_turn]} |",
        "",
        f"{time.perf_counter() - t0:.0f} s; {'--quick' if args.quick else 'full'} run.",
        "",
    ]
    publish("tracking_flow", "\n".join(lines), args.quick)
    return bool(ok_ids and ok_mota and ok_pred and ok_turn and ok_nees)


# ----------------------------------------------------------------------------------------------------
# track confirmation on Kinect-like depth
# ----------------------------------------------------------------------------------------------------
def confirm_section(args) -> bool:
    """Hit-count vs score confirmation, with and without Kinect-like depth; True when targets are met."""
    from dataclasses import replace

    from flowtrack.pipeline import track_confirmer
    from flowtrack_course.demo import DemoConfig

    seeds = FLOW_SEEDS[:1] if args.quick else FLOW_SEEDS
    n_frames = 14 if args.quick else FLOW_FRAMES
    t0 = time.perf_counter()
    score_cfg = replace(DemoConfig(), confirmation="score")
    hits_cfg = replace(DemoConfig(), confirmation="hits")
    conf = track_confirmer(score_cfg)
    rows, spurious, worse_ids, worse_mota, late = [], {"hits": 0, "score": 0}, 0, 0, 0
    for kinect in (False, True):
        for scenario in FLOW_SCENARIOS:
            for seed in seeds:
                d = scene_detections(scenario, seed, n_frames, tuple(args.flow_image), kinect=kinect)
                h = _ablation(d, cfg=hits_cfg)
                c = _ablation(d, cfg=score_cfg)
                hp, hf, cp, cf = h["position_only"], h["flow_aided"], c["position_only"], c["flow_aided"]
                spurious["hits"] += hf["spurious_tracks"]
                spurious["score"] += cf["spurious_tracks"]
                worse_ids += cf["id_switches"] > hf["id_switches"]
                worse_mota += cf["mota"] < hf["mota"] - 0.02
                late += hf["predictions_scored"] - cf["predictions_scored"]
                rows.append(
                    f"| {'Kinect-like' if kinect else 'rendered'} | {scenario} | {seed} | "
                    f"{hf['spurious_tracks']} / {cf['spurious_tracks']} | "
                    f"{hf['mota']:.3f} / {cf['mota']:.3f} | "
                    f"{hf['idf1']:.3f} / {cf['idf1']:.3f} | {hf['id_switches']} / {cf['id_switches']} | "
                    f"{hf['predictions_scored']} / {cf['predictions_scored']} | "
                    f"{hp['spurious_tracks']} / {cp['spurious_tracks']} |")
    ok = spurious["score"] == 0 and worse_ids == 0 and worse_mota == 0
    yes = {True: "yes", False: "NO"}
    lines = [
        "# Track confirmation on Kinect-like depth (issue 15)",
        "",
        "The scenes of the section 'Scene flow in the tracker' (below), rendered as there and with "
        "Kinect-like depth "
        "(`flowtrack.synth.kinect_depth`: noise σ(Z) = 1.2 mm + 1.9 mm (Z − 0.4)² (Nguyen et al. 2012), "
        "disparity rounded to 1/8 px (f = 580 px, b = 7.5 cm), flying pixels across depth jumps, 30 % of "
        "edge pixels dropped), through the demo's pipeline; the demo's flow-aided tracker confirming a "
        f"track by `min_hits = {DemoConfig().min_hits}` detections (`HitCountConfirmer`) or by its "
        "sequential log-likelihood-ratio score (`SequentialScoreConfirmer` from "
        f"`flowtrack.pipeline.track_confirmer`: P_D = {score_cfg.track_p_detect:g}, clutter "
        f"{score_cfg.track_clutter_density:g} per m³, static clutter's velocity N(0, (rgbd_min_speed/2)² I "
        f"+ R_v), α = {score_cfg.track_false_confirm:g}, β = {score_cfg.track_missed_confirm:g}: "
        f"confirm at L ≥ ln((1 − β)/α) = {conf.confirm_threshold:.2f}, reject at "
        f"L ≤ ln(β/(1 − α)) = {conf.reject_threshold:.2f}). *Spurious tracks*: ids reported as detected but "
        "never within 0.1 m of any object. *Matched*: object-frames matched to a track that has a "
        "prediction (fewer = later confirmation). Cells: hits / score.",
        "",
        "| depth | scenario | seed | spurious tracks | MOTA | IDF1 | ID switches | matched | "
        "position-only spurious |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        "How the parameters were chosen (measured when this was written): with a uniform clutter "
        "velocity density, as the association's (0.1 per m³ × 8 per (m/s)³, α = 1e-4 on mixed 0; 1 per m³ "
        "× 240 per (m/s)³, α = 1e-3 on crossing 0), the spurious tracks stayed: "
        "the spurious tracks sit on the far wall's top edge (about 1.6 m away, flying pixels and "
        "quantisation steps), are detected again at the same place with velocities of 0.02–0.09 m/s, and "
        "their velocity innovations are small, so they score like objects. What tells them apart is that "
        "they do not move: the clutter a motion segmentation lets through is static surface, its velocity"
        " N(0, Σ_c + R_v), which the score now uses as the velocity clutter density. With that density α "
        "= 1e-3 still left one spurious track (Kinect-like crossing 0); α = 1e-4 removes all. The values "
        "were picked on these scenes (crossing 0 and mixed 0 with Kinect-like depth), not held out. "
        "Position-only tracking has no velocity evidence, so its tracks need a third detection. Before "
        "the colour test, the occlusion position covariances and the 5 cm birth exclusion were on in the "
        "demo, the Kinect-like crossing rows had ID switches (2 and 1 on seeds 0 and 1, the same with hits "
        "and score: not clutter tracks) and position-only "
        "tracking kept one clutter track (crossing 1).",
        "",
        "The issue's user's path, `flowtrack demo --input` on a TUM-layout sequence (measured when this "
        "was written, by a script outside this benchmark): mixed and crossing seed 0 rendered with "
        "`kinect_depth`, written as TUM PNGs (depth in 1/5000 m), run through `run_demo(input_dir=...)` "
        "(the real-input branch: 1 cm voxel cloud, about 6 detections per frame instead of 2–3), "
        "`tracks.csv`'s confirmed rows scored by CLEAR-MOT at 15 cm against the objects' centres. "
        "crossing 0: MOTA 0.478 → 0.913, false positives 32 → 2, confirmed tracks 10 → 4 (three objects "
        "and one clutter), 0 ID switches both; mixed 0: MOTA 0.420 → 0.667, false positives 25 → 8, "
        "confirmed tracks 11 → 6, 1 ID switch both (hits → score). Not solved there: static artefacts on "
        "the far wall's top edge that are detected at the same place in three frames in a row still "
        "confirm (their position terms alone pass T_c); the next step would be a static-clutter "
        "hypothesis for the position too (a persistent artefact re-detected where it was), leaving the "
        "velocity (moving-object prior against N(0, Σ_c + R_v)) to decide.",
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| score: no spurious confirmed track (flow-aided, all runs) | {spurious['hits']} → "
        f"{spurious['score']} | {yes[spurious['score'] == 0]} |",
        f"| score: never more ID switches than hits | {worse_ids} runs with more | {yes[worse_ids == 0]} |",
        f"| score: MOTA never lower by > 0.02 | {worse_mota} runs lower | {yes[worse_mota == 0]} |",
        f"| object-frames lost to later confirmation (all runs) | {late} | |",
        "",
        f"{time.perf_counter() - t0:.0f} s; {'--quick' if args.quick else 'full'} run.",
        "",
    ]
    publish("tracking_confirm", "\n".join(lines), args.quick)
    return ok


# ----------------------------------------------------------------------------------------------------
# held-out evaluation (issue 25): `flowtrack demo --input` on the train and test sequences
# ----------------------------------------------------------------------------------------------------
HELDOUT_MAX_DIST = 0.15  #: CLEAR-MOT match distance against the object centres (m)
#: an object counts in a frame when its visible surface would give the demo's detector enough points:
#: min(visible pixels, visible area in cm², i.e. 1 cm voxels) >= this (PipelineConfig.min_detection_points)
HELDOUT_MIN_POINTS = 30
#: ... and when it moves: a point of it at least this fast (m/s; slower is static scenery to a
#: moving-object tracker, whose segmentation calls everything under rgbd_min_speed = 0.04 m/s static)
HELDOUT_MIN_SPEED = 0.05
REPORTED = ("confirmed", "coasting")  #: every row that is not tentative is a claim
HELDOUT_BARS = {"mota": 0.85, "id_switches": 1, "fp_share": 0.02}


def counted(visible_pixels: int, visible_area_m2: float, speed: float) -> bool:
    """Whether an object is ground truth in a frame (else it is ignored: neither missed nor matched)."""
    return min(visible_pixels, visible_area_m2 * 1e4) >= HELDOUT_MIN_POINTS and speed >= HELDOUT_MIN_SPEED


def score_tracks_rows(rows, truth, statuses=REPORTED, max_dist=HELDOUT_MAX_DIST):
    """CLEAR-MOT of ``tracks.csv`` rows against ``objects.csv`` truth (``_evalscenes.read_objects_csv``).

    Every frame of the sequence is scored (a frame without rows misses its objects). Objects that do
    not count in a frame (hidden, outside the image, too small, static: :func:`counted`) are ignored there:
    a row matched to one (``flowtrack.metrics.remove_ignored``) is dropped. Returns the
    ``clear_mot`` dict plus ``fp_share`` (FP / ground-truth objects), ``fp_frames`` ({frame: [(track
    id, position)]}), ``matches`` (per frame {object: track}) and ``frames``.
    """
    from flowtrack.metrics import clear_mot, remove_ignored

    frames = sorted(truth)
    gt, ign = [], []
    for f in frames:
        g, i = {}, {}
        for k, (c, npx, area, speed) in truth[f].items():
            (g if counted(npx, area, speed) else i)[k] = c
        gt.append(g)
        ign.append(i)
    hyp = {f: {} for f in frames}
    for r in rows:
        if r["status"] in statuses and int(r["frame"]) in hyp:
            hyp[int(r["frame"])][int(r["track_id"])] = np.array([float(r[k]) for k in "xyz"])
    kept = remove_ignored(gt, ign, [hyp[f] for f in frames], max_dist)
    m, matches, _ = clear_mot(gt, kept, max_dist, return_matches=True)
    fp_frames = {}
    for f, h, mt in zip(frames, kept, matches):
        fp = [(tid, pos) for tid, pos in h.items() if tid not in set(mt.values())]
        if fp:
            fp_frames[f] = fp
    m.update(fp_share=m["fp"] / m["num_objects"] if m["num_objects"] else float("nan"), fp_frames=fp_frames,
             matches=dict(zip(frames, matches)), frames=len(frames), ignored_rows=sum(
                 len(hyp[f]) - len(k) for f, k in zip(frames, kept)))
    return m


def replay(record, frames, position_only=False):
    """The demo's tracker (or its position-only twin) run again on the recorded inputs: tracks.csv rows."""
    from flowtrack.tracking import MultiObjectTracker
    from flowtrack.tracking_io import tracks_rows

    i = next(j for j, (_, kw) in enumerate(record["init"]) if kw.get("velocity_update"))
    args, kwargs = copy.deepcopy(record["init"][i])
    if position_only:
        kwargs["velocity_update"] = False
    trk = MultiObjectTracker(*args, **kwargs)
    for Z, V, C, R, *more in record["steps"][i]:
        # the sensor's evidence (seen_through: where it looked past a track) goes to both trackers
        seen = dict(seen_through=more[0].get("seen_through")) if more else {}
        if position_only:
            trk.step(Z, **seen)
        else:
            trk.step(Z, V, C, position_covs=R, **seen)
    return tracks_rows(trk, frames)


def _same_rows(a, b) -> bool:
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        key_x = (int(x["frame"]), int(x["track_id"]), x["status"])
        if key_x != (int(y["frame"]), int(y["track_id"]), y["status"]):
            return False
        if not np.allclose([float(x[k]) for k in "xyz"], [float(y[k]) for k in "xyz"], rtol=0, atol=1e-12):
            return False
    return True


def run_recorded_demo(seq: Path, out: Path, intrinsics: str, reuse: bool = False) -> dict:
    """``flowtrack demo --input seq --out out`` (the CLI, in a child process) with its tracker's inputs
    recorded (``benchmarks/_record_demo.py``).

    Returns ``{"secs", "record", "error"}``: the wall time, the record, and the CLI's error message when
    it failed (exit status not 0; then there is no ``tracks.csv`` to score). With ``reuse`` an earlier
    run's outputs in ``out`` are taken as they are (``--workdir``).
    """
    rec_path = out.parent / f"{out.name}.record.pkl"
    meta_path = out.parent / f"{out.name}.run.json"
    if reuse and meta_path.is_file():
        meta = json.loads(meta_path.read_text())
    else:
        t0 = time.perf_counter()
        recorder = str(Path(__file__).with_name("_record_demo.py"))
        cmd = [sys.executable, recorder, str(rec_path), "demo", "--input", str(seq), "--intrinsics",
               intrinsics, "--out", str(out), "--no-real-data", "--no-gif", "--no-progress"]
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        error = None
        if proc.returncode != 0:
            lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
            error = next((ln for ln in lines if "error" in ln.lower()), lines[-1] if lines else "?")
        meta = {"secs": time.perf_counter() - t0, "error": error, "returncode": proc.returncode}
        meta_path.write_text(json.dumps(meta))
    record = None
    if rec_path.is_file():
        with open(rec_path, "rb") as fh:
            record = pickle.load(fh)
    return {**meta, "record": record}


def heldout_sequences(split, limit=None, quick=False):
    from dataclasses import replace

    import _evalscenes

    seqs = list(_evalscenes.split(split)[1])
    if limit is not None and limit < len(seqs):
        idx = np.unique(np.linspace(0, len(seqs) - 1, max(int(limit), 1)).round().astype(int))
        seqs = [seqs[i] for i in idx]
    if quick:
        seqs = [replace(s, n_frames=20) for s in seqs]
    return seqs


def tracking_gallery(seq_dir: Path, score: dict, truth: dict, intrinsics: str, path: Path, name: str,
                     rows, max_frames=4):
    """The frames of a sequence with the most false positives: image, true centres, reported tracks."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from flowtrack.rgbd_io import load_tum_sequence

    fx, fy, cx, cy = (float(v) for v in intrinsics.split(","))
    with_fp = sorted(score["fp_frames"])
    if not with_fp:
        return False
    # the frame with the most false positives in each part of the sequence
    frames = [max(part, key=lambda f: (len(score["fp_frames"][f]), -f))
              for part in np.array_split(np.array(with_fp), min(max_frames, len(with_fp)))]
    seq = load_tum_sequence(seq_dir, intrinsics=intrinsics)

    def uv(p):
        return fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy

    fig, axes = plt.subplots(1, len(frames), figsize=(4.6 * len(frames), 4.0), squeeze=False)
    for ax, f in zip(axes[0], frames):
        ax.imshow(seq.rgb[f])
        H, W = seq.rgb[f].shape[:2]
        for k, (c, npx, area, speed) in truth[f].items():
            u, v = uv(c)
            style = dict(color="lime" if counted(npx, area, speed) else "grey", fontsize=7)
            ax.plot(u, v, "o", mfc="none", mec=style["color"], ms=9)
            ax.text(u + 4, v - 4, f"obj {k}", clip_on=True, **style)
        matched = set(score["matches"].get(f, {}).values())
        fps = {tid for tid, _ in score["fp_frames"].get(f, [])}
        label = len(fps) <= 8  # name the rows only when they can be read
        for r in rows:
            if int(r["frame"]) != f or r["status"] not in REPORTED:
                continue
            tid = int(r["track_id"])
            u, v = uv([float(r[k]) for k in "xyz"])
            colour = "red" if tid in fps else ("cyan" if tid in matched else "orange")
            ax.plot(u, v, "x", color=colour, ms=7, mew=1.5)
            if label or tid not in fps:
                ax.text(u + 4, v + 10, f"{tid} {r['status'][:4]}", color=colour, fontsize=7, clip_on=True)
        ax.set_xlim(-0.5, W - 0.5)
        ax.set_ylim(H - 0.5, -0.5)
        ax.set_title(f"frame {f}: {len(score['fp_frames'][f])} false positive(s)", fontsize=8)
        ax.set_axis_off()
    fig.suptitle(f"{name}: circles = object centres (green counted, grey ignored), x = tracks.csv rows "
                 "(red false positive, cyan matched, orange ignored)", fontsize=8)
    fig.tight_layout()
    save_small_png(fig, path, dpi=60)
    plt.close(fig)
    return True


def heldout_section(args) -> bool:
    """`flowtrack demo --input` on the sequences of the splits; True when the bars hold on the test split
    (on the training split when only that one is run)."""
    import tempfile

    from tqdm.auto import tqdm

    import _evalscenes

    splits = ("train", "test") if args.split == "both" else (args.split,)
    limit = 1 if args.quick and args.limit is None else args.limit
    partial = args.quick or limit is not None or args.split != "both"
    t0 = time.perf_counter()
    results: dict[str, list] = {}
    gallery = None
    with tempfile.TemporaryDirectory(prefix="flowtrack-heldout-") as tmp:
        work = Path(args.workdir) if args.workdir else Path(tmp)
        for split in splits:
            results[split] = []
            specs = heldout_sequences(split, limit, args.quick)
            for spec in tqdm(specs, desc=f"sequences, {split}", unit="seq"):
                seq = work / f"{split}-{spec.seed}-{spec.n_frames}"
                if not (seq / "objects.csv").is_file():
                    _evalscenes.write_sequence(seq, spec)
                intrinsics = ",".join((seq / "intrinsics.txt").read_text().split("\n")[1].split())
                out = work / f"out-{split}-{spec.seed}-{spec.n_frames}"
                run = run_recorded_demo(seq, out, intrinsics, reuse=args.workdir is not None)
                truth = _evalscenes.read_objects_csv(seq / "objects.csv")
                frames = sorted(truth)
                res = {"spec": spec, "secs": run["secs"], "error": run["error"]}
                if run["error"] is None:
                    with open(out / "tracks.csv", newline="") as fh:
                        rows = list(csv.DictReader(fh))
                    res.update(ours=score_tracks_rows(rows, truth),
                               confirmed_only=score_tracks_rows(rows, truth, ("confirmed",)),
                               replayed=_same_rows(rows, replay(run["record"], frames)),
                               position_only=score_tracks_rows(replay(run["record"], frames, True), truth))
                    o = res["ours"]
                    tqdm.write(f"{split} {spec.name}: MOTA {o['mota']:.3f}, IDsw {o['id_switches']}, "
                               f"FP {o['fp']} ({100 * o['fp_share']:.1f} %), FN {o['fn']}; position-only "
                               f"MOTA {res['position_only']['mota']:.3f}; replay identical: "
                               f"{res['replayed']}; {run['secs']:.0f} s")
                else:
                    tqdm.write(f"{split} {spec.name}: the CLI failed: {run['error']}")
                results[split].append(res)
            scored = [r for r in results[split] if r["error"] is None]
            if split == "test" and scored and not partial:
                worst = min(scored, key=lambda r: r["ours"]["mota"])
                spec = worst["spec"]
                seq = work / f"{split}-{spec.seed}-{spec.n_frames}"
                out = work / f"out-{split}-{spec.seed}-{spec.n_frames}"
                intrinsics = ",".join((seq / "intrinsics.txt").read_text().split("\n")[1].split())
                with open(out / "tracks.csv", newline="") as fh:
                    rows = list(csv.DictReader(fh))
                RESULTS.mkdir(exist_ok=True)
                truth = _evalscenes.read_objects_csv(seq / "objects.csv")
                png = RESULTS / "gallery_tracking_worst_sequence.png"
                if tracking_gallery(seq, worst["ours"], truth, intrinsics, png, spec.name, rows):
                    gallery = spec.name

    lines = [
        "# Held-out evaluation: `flowtrack demo --input` on the train and test sequences (issue 25)",
        "",
        "Sequences from `benchmarks/_evalscenes.py` (its own ray caster, no code shared with flowtrack; "
        "TUM layout, 30 Hz, Kinect-like depth, 2–6 boxes, cylinders, spheres, rods and plates crossing, "
        "entering and leaving the image, hiding each other; per split 6 at 320×240 and 6 at 640×480, "
        "slow (0–5 px per frame), mixed (0–12) and fast (4–25) motions, half with exposure steps of "
        "±3–10 %; 60 frames each). **Training split**: every default of the pipeline and the tracker is "
        "chosen on it. **Test split**: disjoint seeds; reported here, never used for tuning.",
        "",
        "Each sequence is run by the command line as a user would (`flowtrack demo --input SEQ "
        "--intrinsics ... --out DIR --no-real-data --no-gif`, in a child process, `DemoConfig()` "
        "defaults) and `tracks.csv` is scored with `flowtrack.metrics.clear_mot` at "
        f"{100 * HELDOUT_MAX_DIST:.0f} cm against the object centres of `objects.csv`, counting **every "
        "row whose status is not tentative** (confirmed and coasting: a coasting row is a claim of where "
        "the object is). An object counts in a frame when min(visible pixels, visible area in cm²) ≥ "
        f"{HELDOUT_MIN_POINTS} (enough 1 cm voxels for the detector's `min_detection_points`) and a point "
        f"of it moves at least {100 * HELDOUT_MIN_SPEED:.0f} cm/s (slower objects are static scenery to a "
        "moving-object tracker); otherwise (hidden, outside the image, too small, static) it is ignored "
        "there: a row matched to it is dropped "
        "(`flowtrack.metrics.remove_ignored`, MOTChallenge's rule), it is neither missed nor matched. "
        "*FP share*: false positives / ground-truth objects. *Confirmed only*: the same, scoring the "
        "confirmed rows alone (the scoring of issue 15). Ablation: `metrics.json[\"tracking_ablation\"]` "
        "is None for `--input` runs (it needs ground truth inside the demo), so the demo's tracker inputs "
        "(detections, flow velocities and covariances, position covariances) are recorded while the CLI "
        "runs (`benchmarks/_record_demo.py`, passive) and replayed: the demo's own flow-aided tracker "
        "(*replay*: it reproduces `tracks.csv` row for row, checked) and the same tracker position-only "
        "(`velocity_update=False`, positions alone), scored the same way.",
        "",
    ]
    ok = True
    yes = {True: "yes", False: "NO"}
    for split in splits:
        res = results[split]
        title = ("TRAINING split (defaults are chosen here)" if split == "train" else
                 "TEST split (reported; never used for tuning)")
        lines += [f"## {title}: {len(res)} sequences", "",
                  "| sequence | frames | GT objects | MOTA | ID switches | FP | FP share | FN "
                  "| confirmed only: MOTA / FP | position-only: MOTA / IDsw / FP | replay identical "
                  "| bars met | time |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|:---:|---:|"]
        for r in res:
            if r["error"] is not None:
                lines.append(f"| {r['spec'].name} | {r['spec'].n_frames} | | **the CLI failed**: "
                             f"`{r['error']}` | | | | | | | | NO | {r['secs']:.0f} s |")
                continue
            o, c, p = r["ours"], r["confirmed_only"], r["position_only"]
            met = (o["mota"] >= HELDOUT_BARS["mota"] and o["id_switches"] <= HELDOUT_BARS["id_switches"]
                   and o["fp_share"] <= HELDOUT_BARS["fp_share"])
            lines.append(f"| {r['spec'].name} | {o['frames']} | {o['num_objects']} | {o['mota']:.3f} "
                         f"| {o['id_switches']} | {o['fp']} | {100 * o['fp_share']:.1f} % | {o['fn']} "
                         f"| {c['mota']:.3f} / {c['fp']} | {p['mota']:.3f} / {p['id_switches']} / {p['fp']} "
                         f"| {yes[r['replayed']]} | {yes[met]} | {r['secs']:.0f} s |")
        failed = [r for r in res if r["error"] is not None]
        res = [r for r in res if r["error"] is None]
        if failed:
            why = "; ".join(f"{r['spec'].name}: `{r['error']}`" for r in failed)
            lines += ["", f"**{len(failed)} of {len(res) + len(failed)} runs failed** (the command exited "
                      f"with an error, no `tracks.csv`): {why}. The figures below are over the runs that "
                      "finished; the bars count a failed run as missed."]
        if not res:
            continue
        mota = np.array([r["ours"]["mota"] for r in res])
        w = int(np.argmin(mota))
        ids = max(r["ours"]["id_switches"] for r in res)
        fps = np.array([r["ours"]["fp_share"] for r in res])
        pm = np.array([r["position_only"]["mota"] for r in res])
        lines += [
            "",
            f"Mean MOTA {mota.mean():.3f}, worst {mota[w]:.3f} ({res[w]['spec'].name}); ID switches: total "
            f"{sum(r['ours']['id_switches'] for r in res)}, most in one sequence {ids}; FP share mean "
            f"{100 * fps.mean():.1f} %, worst {100 * fps.max():.1f} %; FN total "
            f"{sum(r['ours']['fn'] for r in res)}. Ablation: position-only mean MOTA {pm.mean():.3f} "
            f"(worst {pm.min():.3f}) against flow-aided {mota.mean():.3f}; position-only ID switches "
            f"{sum(r['position_only']['id_switches'] for r in res)}, flow-aided "
            f"{sum(r['ours']['id_switches'] for r in res)}.",
            "",
        ]
        bars = [
            (f"MOTA ≥ {HELDOUT_BARS['mota']} on every sequence: worst {mota[w]:.3f}",
             mota.min() >= HELDOUT_BARS["mota"]),
            (f"≤ {HELDOUT_BARS['id_switches']} ID switch per sequence: most {ids}",
             ids <= HELDOUT_BARS["id_switches"]),
            (f"false positives ≤ {100 * HELDOUT_BARS['fp_share']:.0f} % of the ground-truth objects on every "
             f"sequence: worst {100 * fps.max():.1f} %", fps.max() <= HELDOUT_BARS["fp_share"]),
            ("the replayed tracker reproduces every tracks.csv", all(r["replayed"] for r in res)),
            (f"every run finishes: {len(failed)} failed", not failed),
        ]
        judged = split == "test" or splits == ("train",)
        lines += [f"Bars of issue 25 on the {split} split"
                  + (" (the verdict)" if split == "test" else " (information: judged on the test split)"
                     if not judged else " (only this split was run)") + ":", ""]
        lines += [f"- {text}: {'met' if met else 'NOT met'}" for text, met in bars]
        lines.append("")
        if judged:
            ok &= all(met for _, met in bars)
    if gallery:
        lines += [f"Failure gallery: the frames of the worst test sequence ({gallery}) with the most false "
                  "positives, the object centres and the reported rows projected into the image: "
                  "![worst test sequence](results/gallery_tracking_worst_sequence.png) "
                  "(`benchmarks/results/gallery_tracking_worst_sequence.png`).", ""]
    cli = sum(r["secs"] for res in results.values() for r in res)
    lines.append(f"The command-line runs took {cli / 60:.0f} min in all (wall clock on this shared machine; "
                 f"this run {time.perf_counter() - t0:.0f} s); {'partial' if partial else 'full'} run"
                 f"{' (--quick: 20 frames per sequence)' if args.quick else ''}.")
    publish("tracking_heldout", "\n".join(lines) + "\n", partial)
    return ok


if __name__ == "__main__":
    sys.exit(main())
