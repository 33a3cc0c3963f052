"""The demo's input: the synthetic scene (with ground truth) or a real RGB-D / stereo sequence."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from flowtrack.pipeline import (
    PipelineConfig,
    cloud_from_depth,
    moving_first_subsample,
    rgbd_cloud_flow,
    subsample,
)
from flowtrack.synth import make_scene

__all__ = ["MIN_LAYOUT_FRAMES", "DemoInput", "FrameCloud", "frame_cloud", "load_input", "surface_centroids"]

#: the synthetic motions are laid out over at least this many frames, so that a short run (a test)
#: sees the same speeds as the full one
MIN_LAYOUT_FRAMES = 24


@dataclass
class DemoInput:
    """The frames the demo runs on: camera, frame interval, images and (synthetic) the scene."""

    name: str
    camera: object
    dt: float
    rgb: list
    depth: list
    n: int  # frames the pipeline sees
    scene: object = None  # the synthetic Scene (ground truth), None for real input
    #: input frame index of each frame (real input read with ``step``: 0, step, 2 step, ...); None: 0, 1, ...
    frame_index: list | None = None
    #: time of each frame (s; real input: its timestamps, which a sensor does not space evenly, and where
    #: it dropped a frame the gap is two intervals); None: frame t at t * dt
    stamps: np.ndarray | None = None

    def interval(self, t: int, s: int) -> float:
        """Time from frame ``t`` to frame ``s`` (s, > 0 for s > t)."""
        if self.stamps is None:
            return (s - t) * self.dt
        return float(self.stamps[s] - self.stamps[t])


@dataclass(frozen=True)
class FrameCloud:
    """One frame's cloud as the pipeline sees it (:func:`frame_cloud`).

    ``points`` (N, 3): the subsampled cloud. Synthetic input also carries its ground truth,
    ``gt_flow`` (N, 3) and ``labels`` (N,); real input leaves them None. ``flow`` (N, 3) and
    ``flow_seconds``: the RGB-D scene flow at ``points`` and the time it took, when it was estimated
    before the subsample (``PipelineConfig.moving_first_speed``); ``voxels`` (M, 3): then the whole
    voxel cloud, whose density is even where the subsample's is not.
    """

    points: np.ndarray
    gt_flow: np.ndarray | None = None
    labels: np.ndarray | None = None
    flow: np.ndarray | None = None
    flow_seconds: float | None = None
    voxels: np.ndarray | None = None

    @property
    def surface(self) -> np.ndarray:
        """The cloud at an even density, for the detector's geometric static test: the whole voxel
        cloud when the subsample kept the moving points first, else ``points``."""
        return self.points if self.voxels is None else self.voxels


def frame_cloud(inp: DemoInput, t: int, cfg: PipelineConfig, rng: np.random.Generator,
                partner: int | None = None) -> FrameCloud:
    """Back-projected, subsampled cloud of frame ``t`` and (synthetic) its ground truth.

    Synthetic input: a random subsample of the valid pixels with their ground truth. Real input: a
    random subsample of the voxel grid (``cfg.voxel``, ``cfg.max_depth``); with ``partner`` (and
    ``cfg.moving_first_speed`` set) the RGB-D scene flow of the pair (t, partner) is estimated first
    (:func:`flowtrack.pipeline.rgbd_cloud_flow`, velocities toward ``partner`` over their time apart)
    and the subsample keeps every voxel that moves at least ``moving_first_speed``
    (:func:`flowtrack.pipeline.moving_first_subsample`); the result then carries that flow, its time and
    the whole voxel cloud (:class:`FrameCloud`).
    """
    depth = inp.depth[t]
    if inp.scene is not None:
        P = cloud_from_depth(depth, inp.camera)  # row-major valid pixels: the order of frame.points
        idx = subsample(len(P), cfg.max_points, rng)
        f = inp.scene.frames[t]
        return FrameCloud(P[idx], f.gt_flow[idx], f.labels[idx])
    P = cloud_from_depth(depth, inp.camera, max_depth=cfg.max_depth, voxel=cfg.voxel)
    if partner is None or cfg.moving_first_speed is None:
        P = P[subsample(len(P), cfg.max_points, rng)]
        _check_points(inp, t, P, cfg)
        return FrameCloud(P)
    _check_points(inp, t, P, cfg)
    started = time.perf_counter()
    v = rgbd_cloud_flow(inp.rgb[t], depth, inp.rgb[partner], inp.depth[partner], inp.camera,
                        abs(inp.interval(t, partner)), P)
    seconds = time.perf_counter() - started
    idx = moving_first_subsample(np.linalg.norm(v, axis=1), cfg.max_points, cfg.moving_first_speed, rng)
    return FrameCloud(P[idx], flow=v[idx], flow_seconds=seconds, voxels=P)


def _check_points(inp: DemoInput, t: int, P, cfg: PipelineConfig) -> None:
    if len(P) < 2 * cfg.k:
        raise ValueError(f"frame {t} of {inp.name} has only {len(P)} valid depth points (within "
                         f"max_depth={cfg.max_depth} m); check depth_scale and the depth images")


def surface_centroids(frame, min_pixels: int) -> dict[int, np.ndarray]:
    """Ground truth of a detection: the centroid of each object's visible (noiseless) surface."""
    X = frame.gt_points
    out = {}
    for k in sorted(frame.gt_poses):
        m = frame.labels == k
        if m.sum() >= min_pixels:
            out[k] = X[m].mean(axis=0)
    return out


def load_input(input_dir, n_frames, n_objects, image_size, seed, noise, predict_ahead, scenario,
               input_options) -> DemoInput:
    """The synthetic scene (``input_dir`` None; rendered ``predict_ahead`` frames past the last one
    processed, for scoring the prediction) or the sequence in ``input_dir``."""
    if input_dir is None:
        # make_scene checks scenario and n_objects (and names them)
        total = max(n_frames + predict_ahead, MIN_LAYOUT_FRAMES if scenario == "mixed" else 0)
        try:
            scene = make_scene(n_objects=n_objects, n_frames=total, image_size=image_size, dt=0.1,
                               noise=noise, seed=seed, scenario=scenario)
        except RuntimeError as exc:  # no collision-free layout: too many objects for the table
            raise ValueError(f"n_objects={n_objects} does not fit on the table: {exc}") from exc
        return DemoInput(f"synthetic scene ({scenario})", scene.camera, scene.dt,
                         [f.rgb for f in scene.frames], [f.depth for f in scene.frames], n_frames, scene)
    from flowtrack.rgbd_io import load_rgbd

    opts = dict(input_options or {})
    stereo = bool(opts.pop("stereo", False))
    seq = load_rgbd(input_dir, stereo=stereo, max_frames=n_frames, **opts)
    if len(seq) < 2:
        raise ValueError(f"input {input_dir} has {len(seq)} usable frame(s); scene flow needs at least 2")
    return DemoInput(f"{'stereo' if stereo else 'RGB-D'} sequence {input_dir}", seq.camera, seq.dt, seq.rgb,
                     seq.depth, len(seq), None, list(seq.indices) or None, np.asarray(seq.timestamps, float))
