r"""The real data sets of the course, loaded from files that ship inside installed packages.

**Middlebury 2014 Motorcycle** (scene flow on real geometry).
``skimage.data.stereo_motorcycle()`` returns the rectified left/right images (500×741) and the
ground-truth disparity of the left image, down-sampled by 4 from the Middlebury 2014 benchmark
(Scharstein et al., GCPR 2014). Its docstring gives the calibration valid for these images, which is
what this module uses:

=====================  ===============
focal length f         994.978 px
principal point c_x    311.193 px
principal point c_y    254.877 px
doffs (c_x' − c_x)     31.086 px
baseline B             193.001 mm
=====================  ===============

A left pixel :math:`(r, c)` with disparity :math:`d` has depth
:math:`Z = B f / (d + d_\mathrm{offs})` (mm, converted to metres;
:func:`flowtrack.camera.depth_from_disparity`) and back-projects with the pinhole model of
:mod:`flowtrack.camera`, :math:`X = Z ((c - c_x)/f, (r - c_y)/f, 1)`. Invalid disparities (``inf``,
or NaN in older scikit-image versions) get depth 0 and are dropped from the clouds.

**MOTChallenge 2015 TUD-Campus** (multi-object tracking). The py-motmetrics wheel ships the
ground truth and the CEM tracker's output of TUD-Campus and TUD-Stadtmitte;
:func:`load_mot_challenge` reads such files, :func:`tud_campus_tracks` gives them as
:func:`flowtrack.metrics.clear_mot` inputs and :func:`track_tud_campus` runs the course's tracker on
the true box centres.
"""

from __future__ import annotations

import functools
import importlib.util
import numbers
from pathlib import Path

import numpy as np

from ._graph import apply_transform
from ._validation import nonnegative, positive, positive_int, scalar
from .camera import PinholeCamera, backproject_pixels, depth_from_disparity

__all__ = [
    "FRONT_WHEEL_PIXELS",
    "MOTORCYCLE_CALIBRATION",
    "load_mot_challenge",
    "mot_challenge_paths",
    "mot_challenge_tracks",
    "motorcycle_camera",
    "motorcycle_cloud",
    "motorcycle_depth",
    "motorcycle_flow_case",
    "track_tud_campus",
    "tud_campus_paths",
    "tud_campus_tracks",
]


# --------------------------------------------------------------------------------------------------
# Middlebury 2014 Motorcycle
# --------------------------------------------------------------------------------------------------
#: Calibration of the down-sampled pair, from the docstring of ``skimage.data.stereo_motorcycle``.
MOTORCYCLE_CALIBRATION = {
    "f": 994.978,  # px
    "cx": 311.193,  # px
    "cy": 254.877,  # px
    "doffs": 31.086,  # px, x-difference of the principal points of the two cameras
    "baseline_mm": 193.001,
}

#: Pixel box ``(row0, row1, col0, col1)`` (half-open) around the front wheel in the left image.
FRONT_WHEEL_PIXELS = (285, 460, 500, 695)


def motorcycle_camera() -> PinholeCamera:
    """The left camera of the down-sampled Motorcycle pair (741×500 pixels).

    Examples
    --------
    >>> cam = motorcycle_camera()
    >>> cam.fx, cam.width, cam.height
    (994.978, 741, 500)
    """
    c = MOTORCYCLE_CALIBRATION
    return PinholeCamera(c["f"], c["f"], c["cx"], c["cy"], width=741, height=500)


@functools.lru_cache(maxsize=1)
def _load():
    """The left image and its disparity, loaded once; read-only (callers copy what they hand out)."""
    from skimage import data

    left, _right, disp = data.stereo_motorcycle()
    left = np.asarray(left)
    disp = np.asarray(disp, dtype=np.float64)
    left.flags.writeable = False
    disp.flags.writeable = False
    return left, disp


def _depth(disp: np.ndarray) -> np.ndarray:
    """Metres, 0 where the disparity is invalid."""
    c = MOTORCYCLE_CALIBRATION
    # the baseline in mm gives the depth in mm; divided by 1000 afterwards (rather than passing
    # baseline_mm / 1000) so that every depth is rounded exactly as it always was
    return depth_from_disparity(disp, c["f"], c["baseline_mm"], c["doffs"]) / 1000.0


def motorcycle_depth() -> tuple[np.ndarray, np.ndarray]:
    r"""Metric depth of the left image from the ground-truth disparity.

    Returns
    -------
    depth : ndarray, shape (500, 741)
        :math:`Z = B f / (d + d_\mathrm{offs}) / 1000` in metres; 0 where the disparity is invalid.
    rgb : ndarray, shape (500, 741, 3) uint8
        The left image.
    """
    left, disp = _load()
    return _depth(disp), left.copy()


def motorcycle_cloud(step: int = 4, return_pixels: bool = False):
    """Coloured point cloud of the Motorcycle scene (left camera frame, metres).

    Parameters
    ----------
    step : int, >= 1
        Keep every ``step``-th row and column (``step=4`` gives about 20k points).
    return_pixels : bool
        Also return the ``(row, col)`` of each point.

    Returns
    -------
    points : ndarray, shape (N, 3)
        Camera-frame points (x right, y down, z forward), metres.
    colors : ndarray, shape (N, 3)
        RGB in [0, 1].
    pixels : ndarray, shape (N, 2) int
        Only with ``return_pixels``.

    Examples
    --------
    >>> P, C = motorcycle_cloud(step=16)
    >>> P.shape[1], C.shape == P.shape, bool(((C >= 0) & (C <= 1)).all())
    (3, True, True)
    """
    step = positive_int(step, "step")
    left, disp = _load()
    depth = _depth(disp[::step, ::step])  # every step-th row and column, from pixel (0, 0)
    valid = depth > 0
    rows = np.arange(0, disp.shape[0], step, dtype=np.float64)
    cols = np.arange(0, disp.shape[1], step, dtype=np.float64)
    X = backproject_pixels(cols, rows[:, None], depth, motorcycle_camera())[valid]
    colors = left[::step, ::step][valid].astype(np.float64) / 255.0
    if return_pixels:
        return X, colors, np.argwhere(valid) * step
    return X, colors


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula for a unit ``axis``."""
    a = axis / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def motorcycle_flow_case(
    seed: int | None = 0,
    noise: float = 0.002,
    step: int = 4,
    dt: float = 0.1,
    keep: float = 0.9,
    global_angle: float = 0.03,
    global_translation: float = 0.03,
    part_angle: float = 0.15,
) -> dict:
    r"""A scene-flow test case on real geometry with two rigid motions and exact ground truth.

    The Motorcycle cloud :math:`X` (see :func:`motorcycle_cloud`) moves by a global rigid motion
    :math:`T_g` (rotation by ``global_angle`` rad about a random axis through the cloud's centroid,
    then a translation of length ``global_translation`` m in a random direction); the points of the
    front wheel (the pixel box :data:`FRONT_WHEEL_PIXELS`, in front of the wheel's depth cut) first
    turn by ``part_angle`` about the wheel's own axle (the camera x axis through the part's
    centroid), :math:`T_p`:

    .. math::  X' = T_g X \ (\text{rest}), \qquad X' = T_g T_p X \ (\text{wheel}), \qquad
               v = (X' - X)/\Delta t .

    Each time keeps an independent random ``keep`` fraction of the points, shuffled, with
    Gaussian noise of standard deviation ``noise`` on every coordinate, so there is *no* index
    correspondence between ``points_t`` and ``points_t1``.

    Parameters
    ----------
    seed : int or None
    noise : float, >= 0
        Metres.
    step : int, >= 1
        Pixel subsampling of the cloud.
    dt : float, > 0
    keep : float in (0, 1]
        Fraction of the points kept at each time.
    global_angle, global_translation, part_angle : float
        Motion magnitudes (rad, m, rad).

    Returns
    -------
    dict
        ``points_t (N,3)``, ``points_t1 (M,3)``, ``gt_flow (N,3)`` (velocity of the noiseless point
        under ``points_t[i]``), ``clean_t (N,3)`` (those noiseless points), ``colors_t (N,3)``,
        ``labels_t (N,)`` (0 global motion, 1 wheel), ``dt``, ``T_global (4,4)``, ``T_part (4,4)``
        (applied before ``T_global`` to the wheel), ``part_box`` (the pixel box).

    Examples
    --------
    >>> case = motorcycle_flow_case(step=16, noise=0.0)
    >>> X, v, T = case["clean_t"], case["gt_flow"], case["T_global"]
    >>> rest = case["labels_t"] == 0
    >>> bool(np.allclose(X[rest] + v[rest] * case["dt"], X[rest] @ T[:3, :3].T + T[:3, 3]))
    True
    """
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)):
        raise TypeError(f"seed must be an int or None, got {type(seed).__name__}")
    noise = nonnegative(noise, "noise")
    dt = positive(dt, "dt")
    keep = positive(keep, "keep")
    if keep > 1:
        raise ValueError(f"keep must be in (0, 1], got {keep}")
    global_angle = nonnegative(global_angle, "global_angle")
    global_translation = nonnegative(global_translation, "global_translation")
    part_angle = scalar(part_angle, "part_angle")
    rng = np.random.default_rng(seed)

    X, colors, pix = motorcycle_cloud(step=step, return_pixels=True)
    r0, r1, c0, c1 = FRONT_WHEEL_PIXELS
    in_box = (pix[:, 0] >= r0) & (pix[:, 0] < r1) & (pix[:, 1] >= c0) & (pix[:, 1] < c1)
    # the wheel is in front: keep box points nearer than the box's median depth + 0.15 m
    z_cut = np.median(X[in_box, 2]) + 0.15 if in_box.any() else np.inf
    part = in_box & (X[:, 2] < z_cut)

    centre = X.mean(axis=0)
    axis = rng.normal(size=3)
    Rg = _rotation(axis, global_angle)
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    Tg = np.eye(4)
    Tg[:3, :3] = Rg
    Tg[:3, 3] = centre - Rg @ centre + global_translation * direction

    Tp = np.eye(4)
    if part.any():
        pc = X[part].mean(axis=0)
        Rp = _rotation(np.array([1.0, 0.0, 0.0]), part_angle)
        Tp[:3, :3] = Rp
        Tp[:3, 3] = pc - Rp @ pc

    X1 = apply_transform(Tg, X)
    X1[part] = apply_transform(Tg, apply_transform(Tp, X[part]))
    flow = (X1 - X) / dt

    n = X.shape[0]
    m = max(1, round(keep * n))
    i0 = rng.permutation(n)[:m]
    i1 = rng.permutation(n)[:m]
    points_t = X[i0] + rng.normal(0.0, noise, (m, 3)) if noise > 0 else X[i0].copy()
    points_t1 = X1[i1] + rng.normal(0.0, noise, (m, 3)) if noise > 0 else X1[i1].copy()
    return {
        "points_t": points_t,
        "points_t1": points_t1,
        "gt_flow": flow[i0],
        "clean_t": X[i0],
        "colors_t": colors[i0],
        "labels_t": part[i0].astype(np.int64),
        "dt": dt,
        "T_global": Tg,
        "T_part": Tp,
        "part_box": FRONT_WHEEL_PIXELS,
    }


# --------------------------------------------------------------------------------------------------
# MOTChallenge files (TUD-Campus)
# --------------------------------------------------------------------------------------------------
def load_mot_challenge(
    path, num_frames: int | None = None, min_confidence: float | None = None
) -> list[dict]:
    """Read a MOTChallenge 2D text file (``gt.txt`` or a tracker's result).

    Each line is ``frame, id, x, y, w, h, conf, ...`` (comma or whitespace separated; frames are
    1-based). Boxes are returned as stored in the file (MOTChallenge's 1-based pixel coordinates;
    py-motmetrics subtracts 1 from ``x, y``, which does not change any IoU).

    Parameters
    ----------
    path : str or path-like
        The text file.
    num_frames : int, optional
        Length of the returned list (frames beyond the last line are empty); at least the
        largest frame number in the file. Default: the largest frame number.
    min_confidence : float, optional
        Keep only rows whose column 7 (confidence / "consider" flag) is ``>= min_confidence``.
        Default keeps every row, like py-motmetrics' ``loadtxt`` (whose default threshold −1 keeps
        all rows of these files).

    Returns
    -------
    list of dict
        ``frames[k]`` is ``{id: ndarray [x, y, w, h]}`` for frame number ``k + 1``; integral ids
        are returned as ``int``.

    Raises
    ------
    ValueError
        Malformed lines, frame numbers < 1, duplicate ``(frame, id)``, ``num_frames`` too small.

    Examples
    --------
    >>> import os, tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = os.path.join(d, "gt.txt")
    ...     with open(p, "w") as f:
    ...         _ = f.write("1,7,10,20,30,40,1,-1,-1,-1\\n3,7,12,20,30,40,1,-1,-1,-1\\n")
    ...     frames = load_mot_challenge(p)
    >>> len(frames), frames[1], frames[2][7]
    (3, {}, array([12., 20., 30., 40.]))
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"path {str(path)!r} is not a file")
    rows: list[tuple[int, object, np.ndarray, float]] = []
    with path.open() as fh:
        for lineno, line in enumerate(fh, 1):
            fields = line.replace(",", " ").split()
            if not fields:
                continue
            if len(fields) < 6:
                raise ValueError(f"path {path.name}: line {lineno} has {len(fields)} fields, need >= 6")
            try:
                vals = [float(v) for v in fields]
            except ValueError:
                raise ValueError(f"path {path.name}: line {lineno} is not numeric") from None
            frame = vals[0]
            if frame != int(frame) or frame < 1:
                raise ValueError(f"path {path.name}: line {lineno} has invalid frame number {fields[0]}")
            oid = int(vals[1]) if vals[1] == int(vals[1]) else vals[1]
            conf = vals[6] if len(vals) > 6 else 1.0
            rows.append((int(frame), oid, np.array(vals[2:6]), conf))
    last = max((r[0] for r in rows), default=0)
    if num_frames is None:
        n = last
    else:
        if isinstance(num_frames, bool) or not isinstance(num_frames, numbers.Integral):
            raise TypeError(f"num_frames must be an int, got {type(num_frames).__name__}")
        n = int(num_frames)
        if n < last:
            raise ValueError(f"num_frames must be >= the last frame number {last}, got {n}")
    frames: list[dict] = [{} for _ in range(n)]
    for frame, oid, box, conf in rows:
        if min_confidence is not None and conf < min_confidence:
            continue
        if oid in frames[frame - 1]:
            raise ValueError(f"path {path.name}: duplicate id {oid!r} in frame {frame}")
        frames[frame - 1][oid] = box
    return frames


def mot_challenge_paths(sequence: str = "TUD-Campus") -> tuple[Path, Path]:
    """``(gt.txt, test.txt)`` of a MOT15 sequence shipped in the py-motmetrics wheel.

    The motmetrics wheel (a ``dev`` extra) contains TUD-Campus and TUD-Stadtmitte with the CEM
    tracker's output. The package is located without importing it (its code does not run on
    NumPy 2).

    Parameters
    ----------
    sequence : {"TUD-Campus", "TUD-Stadtmitte"}

    Raises
    ------
    FileNotFoundError
        If motmetrics is not installed or lacks the files.
    """
    if sequence not in ("TUD-Campus", "TUD-Stadtmitte"):
        raise ValueError(f"sequence must be 'TUD-Campus' or 'TUD-Stadtmitte', got {sequence!r}")
    spec = importlib.util.find_spec("motmetrics")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError(
            "the MOT15 files come with the py-motmetrics wheel: pip install 'motmetrics==1.4.0' "
            "(only its data files are used)"
        )
    for loc in spec.submodule_search_locations:
        d = Path(loc) / "data" / sequence
        gt, test = d / "gt.txt", d / "test.txt"
        if gt.is_file() and test.is_file():
            return gt, test
    raise FileNotFoundError(f"motmetrics is installed but has no data/{sequence}/gt.txt and test.txt")


def tud_campus_paths() -> tuple[Path, Path]:
    """``(gt_path, test_path)`` of MOT15 TUD-Campus in the installed py-motmetrics wheel.

    Raises
    ------
    FileNotFoundError
        If motmetrics is not installed.
    """
    return mot_challenge_paths("TUD-Campus")


def mot_challenge_tracks(sequence: str = "TUD-Campus") -> tuple[list[dict], list[dict]]:
    """Ground truth and CEM tracker output of a MOT15 sequence as :func:`clear_mot` inputs.

    Parameters
    ----------
    sequence : {"TUD-Campus", "TUD-Stadtmitte"}

    Returns
    -------
    (gt, hyp) : tuple of list of dict
        Frames ``{id: [x, y, w, h]}`` covering the same frame numbers.
    """
    gt_path, test_path = mot_challenge_paths(sequence)
    gt, hyp = load_mot_challenge(gt_path), load_mot_challenge(test_path)
    n = max(len(gt), len(hyp))
    return gt + [{} for _ in range(n - len(gt))], hyp + [{} for _ in range(n - len(hyp))]


def tud_campus_tracks() -> tuple[list[dict], list[dict]]:
    """Ground truth and CEM tracker output of MOT15 TUD-Campus as :func:`clear_mot` inputs.

    ``clear_mot(gt, hyp, 0.5, "iou")`` gives the figures published in the py-motmetrics README:
    MOTA 52.6 %, MOTP 0.277, IDF1 55.8 %, IDP 73.0 %, IDR 45.1 %, recall 58.2 %, precision 94.1 %,
    FP 13, FN 150, 7 ID switches, 8 objects of which 1 mostly tracked, 6 partially, 1 lost.

    Raises
    ------
    FileNotFoundError
        If motmetrics (its data files) is not installed.
    """
    return mot_challenge_tracks("TUD-Campus")


# --------------------------------------------------------------------------------------------------
# the course's tracker on TUD-Campus
# --------------------------------------------------------------------------------------------------
def track_tud_campus(
    noise_px: float = 3.0,
    drop: float = 0.1,
    seed: int | None = 0,
    q: float = 10.0,
    max_misses: int = 5,
    max_dist: float = 30.0,
    *,
    return_frames: bool = False,
):
    """Track real pedestrian trajectories: MOT15 TUD-Campus box centres as noisy detections.

    The ground-truth boxes of TUD-Campus (71 frames, 8 people; the files ship inside the motmetrics
    wheel, see :func:`tud_campus_tracks`) give each person's centre per frame. Each
    centre becomes a detection with Gaussian pixel noise ``noise_px`` and is dropped with probability
    ``drop``; :class:`flowtrack.tracking.MultiObjectTracker` (constant velocity, ``dt`` = 1 frame,
    measurement variance ``noise_px²``) tracks them and :func:`flowtrack.metrics.clear_mot` scores
    the tracks that were updated in the last two frames against the true centres (Euclidean,
    ``max_dist`` pixels).

    Returns
    -------
    dict
        The :func:`~flowtrack.metrics.clear_mot` figures plus ``frames``, ``objects`` and the settings.
    centres, hyp : list of dict, only with ``return_frames=True``
        What was scored, per frame: ``{person id: (x, y)}`` true box centres and ``{track id: (x, y)}``
        the tracks' positions (pixels), e.g. to draw the run (the demo's TUD-Campus figure).
    """
    from .metrics import clear_mot
    from .tracking import MultiObjectTracker

    noise_px = positive(noise_px, "noise_px")
    drop = nonnegative(drop, "drop")
    if drop >= 1:
        raise ValueError(f"drop must be in [0, 1), got {drop}")
    q = positive(q, "q")
    max_misses = positive_int(max_misses, "max_misses")
    gt, _ = tud_campus_tracks()
    centres = [{i: np.array([b[0] + b[2] / 2, b[1] + b[3] / 2]) for i, b in f.items()} for f in gt]
    rng = np.random.default_rng(seed)
    tracker = MultiObjectTracker(dt=1.0, q=q, r=noise_px**2, dim=2, min_hits=2, max_misses=max_misses,
                                 velocity_var=25.0)
    hyp = []
    for frame in centres:
        kept = [i for i in sorted(frame) if rng.random() >= drop]
        Z = np.array([frame[i] + rng.normal(0.0, noise_px, 2) for i in kept]).reshape(-1, 2)
        hyp.append({t.id: t.x[:2].copy() for t in tracker.step(Z) if t.misses <= 1})
    out = clear_mot(centres, hyp, max_dist)
    out.update(frames=len(centres), objects=len({i for f in centres for i in f}), noise_px=noise_px,
               drop=drop, seed=seed, max_dist=max_dist)
    return (out, centres, hyp) if return_frames else out
