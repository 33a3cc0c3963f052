r"""Evaluation scenes with exact ground truth, and the fixed train / test splits of the held-out protocol.

**Which split is which.** :data:`TRAIN_PAIRS` and :data:`TRAIN_SEQUENCES` form the *training split*:
every default of the scene flow (``rgbd_scene_flow`` options), of the pipeline (``PipelineConfig``)
and of the tracker is chosen on it, and only on it. :data:`TEST_PAIRS` and :data:`TEST_SEQUENCES`
form the *test split*: the benchmarks (``benchmarks/bench_rgbd_flow.py --section heldout``,
``benchmarks/bench_tracking.py --section heldout``) report on it, and it is **never used for tuning**
(no option, threshold or schedule may be picked by looking at a test number; if a test result is
bad, the remedy is found on the training split and the test split is run once more). The two splits
are built the same way from disjoint seeds (:func:`split`).

**What a scene is.** A static Kinect-like RGB-D camera at 30 Hz (320×240 or 640×480, focal length
about 525 px at 640×480, principal point near the centre) looks down 5–30° at a floor 0.8–1.5 m below
it and a back wall 2.2–3.6 m away (yawed up to ±20°, sometimes a side wall): textured static
background. In front of it float 2–6 rigid objects: boxes, cylinders, spheres and thin objects (rods
of 5–15 mm radius, plates 3–8 mm thick), 3–30 cm across, their centres 0.5–3 m from the camera;
each is either textured (two octaves of solid value noise in the object's own frame, so the texture
moves with the body) or nearly uniform in colour (±0.5–3 %), Lambertian with an ambient term, some
with a mild specular highlight. Each moves by a translation and a rotation about its centre (in a
sequence on a slightly curved path) whose fastest pixel moves 0–25 px per frame (a flow pair: the
fastest visible pixel of its fastest object moves exactly as its class says; a sequence: no point of
an object's bounding sphere moves more than its class's upper bound); objects enter, leave the image,
pass in front of each other (occlusions, disocclusions); bounding spheres never interpenetrate, and
no object is inside the floor or the wall while it can be seen. Between frames the global brightness
(exposure gain) may change by ±3–10 %; the colour image is blurred by a 0.5 px Gaussian (optics) and
carries 1.5–3 grey levels of noise.

**The depth sensor** (a Kinect-like model written here):

- axial noise :math:`\sigma(z) = 1.2\,\text{mm} + 1.9\,\text{mm}\,(z - 0.4)^2` (Nguyen et al. 2012), then
  disparity quantised to 1/8 px with the sensor's f = 580 px and 7.5 cm baseline (depth steps of
  :math:`z^2 / (8 f b)`: 2.6 cm at 3 m);
- the projector shadow: a pixel that the projector (7.5 cm to the right) cannot see has no depth (a band
  left of every near object, as wide as the disparity difference);
- depth edges (a 3×3 neighbourhood spanning more than max(3 cm, 3 % z)): 35 % of the edge pixels are
  holes, 30 % *flying pixels* whose depth is a mix of the near and the far surface;
- grazing surfaces (cos of incidence < 0.15, and 30 % of those below 0.3) and random blobs (about 2 %
  of the image) have no depth; nothing nearer than 0.4 m or farther than 4.5 m.

**Ground truth** (exact, from the ray caster): per pixel of frame t the true surface point X (camera
frame, metres) and its displacement ``flow3d`` to frame t+1 (the body's rigid motion applied to that
material point; 0 on the static background); ``labels`` (object id per pixel, 0 = background) of both
frames; ``valid``: the sensor gave a depth within ``4 sigma(z) + one quantisation step + 5 mm`` of the
true surface (holes and flying pixels are not valid: a flying pixel's point lies on no surface, so it
has no true displacement), and ``flow3d`` is NaN where not valid; ``visible1``: the point is seen
again in frame t+1 (inside the image, not hidden); ``moving``: the pixel lies on an object that moves.
Per frame each object's centre (camera frame; the body's centre of symmetry), its visible pixel
count and visible surface area (m²), and the largest speed any of its points can have (m/s). The
camera is static (the tracker assumes one); a moving camera is not modelled.

**Motion that no sensor can see** (the observable ground truth). A nearly uniform body of revolution
(a sphere, a cylinder or a rod whose colour varies by at most ±3 % of its own, a few grey levels at
most, about the camera noise of 1.5–3 grey levels) that turns about its symmetry axis — a sphere
about any axis through its centre — maps its surface onto itself with the same shading and depth at
every pixel: frames t and t+1 differ only by that faint texture, so from two frames the rotation is
practically unmeasurable, by images, depth or both (the aperture problem of the whole body; with no
texture at all it is exactly unmeasurable). The ±3 % threshold is a choice, which is why both scores
are reported. Like KITTI and Sintel, which mark the pixels
whose flow cannot be measured instead of scoring every method against an unknowable answer, the
evaluation then scores the *observable* part of the motion: ``flow3d_observable`` keeps the true
motion everywhere except on these bodies, where the rotation about the symmetry axis is removed — a
sphere's points move with its centre, a cylinder's or rod's points by the *swing* rotation (the
smallest rotation, about the centre, that carries the axis to its new direction; the true rotation is
that swing after a rotation about the axis, its *twist*) plus the centre's translation. Nothing else
is changed: weakly textured boxes and plates, textured bodies of revolution, sliding along an axis
(the ends show it) keep their true motion; ``moving_observable`` drops an object whose whole motion
was unobservable. Each object's record says why (``observability``); the benchmarks report the
scores against ``flow3d`` (raw) beside those against ``flow3d_observable`` (the verdict).

Everything is deterministic in the seed (numpy's PCG64 streams), numpy and PIL only: no code is
shared with ``flowtrack`` (nor with ``benchmarks/_boxes.py``; its ray caster, textures, camera and
depth model are written anew here). A 640×480 frame renders in about 0.2–0.4 s.

Entry points: :func:`make_pair` (a flow pair with its ground truth), :func:`write_sequence` (a sequence
in the TUM layout that ``flowtrack demo --input`` reads, with ``objects.csv``), :func:`split`
(the seed lists). From the shell::

    python benchmarks/_evalscenes.py --split train --out DIR [--limit N]   # writes the sequences
"""

from __future__ import annotations

import argparse
import itertools
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, ImageFilter

FPS = 30.0  #: frame rate of every scene (Hz)
SIZES = ((240, 320), (480, 640))  #: (H, W) of the two image sizes
KINECT_F, KINECT_B = 580.0, 0.075  #: the depth sensor's focal length (px at 640×480) and baseline (m)
DEPTH_SCALE = 5000.0  #: TUM depth PNG units per metre
MIN_RANGE, MAX_RANGE = 0.4, 4.5  #: the depth sensor's range (m)
#: px per frame of the fastest visible pixel of the fastest object in a flow pair
PAIR_MOTIONS = {"small": (0.5, 5.0), "medium": (5.0, 12.0), "large": (12.0, 25.0)}
#: px per frame of an object's translation in a sequence (rotations add up to half the upper bound)
SEQUENCE_SPEEDS = {"slow": (0.0, 5.0), "mixed": (0.0, 12.0), "fast": (4.0, 25.0)}
SHAPES = ("box", "cylinder", "sphere", "rod", "plate")


# ------------------------------------------------------------------------------------------------
# the splits
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PairSpec:
    """One flow pair of a split: its seed, image size (H, W), motion class and brightness change.

    ``brightness`` is the largest relative change of the global gain between the two frames (0: none;
    otherwise the change is ±U(0.03, brightness), sign random).
    """

    seed: int
    size: tuple[int, int]
    motion: str
    brightness: float

    @property
    def name(self) -> str:
        b = f", brightness ±{self.brightness:.0%}" if self.brightness else ""
        return f"pair {self.seed} ({self.size[1]}x{self.size[0]}, {self.motion} motion{b})"


@dataclass(frozen=True)
class SequenceSpec:
    """One sequence of a split: its seed, image size (H, W), frame count, speed class and brightness."""

    seed: int
    size: tuple[int, int]
    n_frames: int
    speed: str
    brightness: float

    @property
    def name(self) -> str:
        b = ", exposure changes" if self.brightness else ""
        return f"seq {self.seed} ({self.size[1]}x{self.size[0]}, {self.n_frames} frames, {self.speed}{b})"


def _pairs(base: int, per_cell: int) -> tuple[PairSpec, ...]:
    out = []
    for size in SIZES:
        for motion in PAIR_MOTIONS:
            for brightness in (0.0, 0.10):
                for _ in range(per_cell):
                    out.append(PairSpec(base + len(out), size, motion, brightness))
    return tuple(out)


def _sequences(base: int, n_frames: int) -> tuple[SequenceSpec, ...]:
    out = []
    for size in SIZES:
        for speed in SEQUENCE_SPEEDS:
            for brightness in (0.0, 0.10):
                out.append(SequenceSpec(base + len(out), size, n_frames, speed, brightness))
    return tuple(out)


#: TRAINING split, flow pairs: 72 = 2 sizes × 3 motion classes × (with, without brightness change) × 6
TRAIN_PAIRS = _pairs(1000, 6)
#: TRAINING split, sequences: 12 = 2 sizes × 3 speed classes × (with, without exposure changes), 60 frames
TRAIN_SEQUENCES = _sequences(2000, 60)
#: TEST split, flow pairs (never used for tuning): the same composition, disjoint seeds
TEST_PAIRS = _pairs(5000, 6)
#: TEST split, sequences (never used for tuning)
TEST_SEQUENCES = _sequences(6000, 60)
SPLITS = {"train": (TRAIN_PAIRS, TRAIN_SEQUENCES), "test": (TEST_PAIRS, TEST_SEQUENCES)}


def split(name: str) -> tuple[tuple[PairSpec, ...], tuple[SequenceSpec, ...]]:
    """``(pairs, sequences)`` of the split ``"train"`` (tune here) or ``"test"`` (report here only)."""
    if name not in SPLITS:
        raise ValueError(f"split must be 'train' or 'test', got {name!r}")
    return SPLITS[name]


# ------------------------------------------------------------------------------------------------
# small geometry helpers
# ------------------------------------------------------------------------------------------------
def _rotation(w) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (axis × angle, Rodrigues)."""
    w = np.asarray(w, dtype=float)
    a = float(np.linalg.norm(w))
    if a < 1e-12:
        return np.eye(3)
    k = w / a
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * (K @ K)


def _random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def sensor_sigma(z):
    """Axial depth noise of the model (m) at depth ``z`` (m)."""
    return 0.0012 + 0.0019 * (np.asarray(z, dtype=float) - 0.4) ** 2


def depth_tolerance(z):
    """Largest |measured - true| depth (m) of a pixel whose depth counts as valid ground truth."""
    z = np.asarray(z, dtype=float)
    return 4.0 * sensor_sigma(z) + z**2 / (8.0 * KINECT_F * KINECT_B) + 0.005


# ------------------------------------------------------------------------------------------------
# textures: solid value noise
# ------------------------------------------------------------------------------------------------
@dataclass
class _Texture:
    base: np.ndarray  # (3,) albedo
    amp: float  # relative amplitude of the noise
    spacing: float  # lattice spacing of the first octave (m)
    lattices: tuple  # two (n, n, n, 3) arrays in [-1, 1]
    offset: np.ndarray  # (3,) shift of the lattice

    def albedo(self, P: np.ndarray) -> np.ndarray:
        if self.amp <= 0:
            return np.broadcast_to(self.base, P.shape).copy()
        noise = 0.65 * _value_noise(self.lattices[0], (P + self.offset) / self.spacing)
        noise += 0.35 * _value_noise(self.lattices[1], (P + self.offset) / (self.spacing / 2.7))
        return np.clip(self.base * (1.0 + self.amp * noise), 0.02, 1.0)


def _value_noise(lat: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Trilinear interpolation of the periodic lattice ``lat`` (n, n, n, 3) at points ``q`` (M, 3)."""
    n = lat.shape[0]
    f = np.floor(q)
    a = q - f
    i = f.astype(np.int64) % n
    j = (i + 1) % n
    out = np.zeros((len(q), 3))
    for cx in (0, 1):
        ix = j[:, 0] if cx else i[:, 0]
        wx = a[:, 0] if cx else 1.0 - a[:, 0]
        for cy in (0, 1):
            iy = j[:, 1] if cy else i[:, 1]
            wy = a[:, 1] if cy else 1.0 - a[:, 1]
            for cz in (0, 1):
                iz = j[:, 2] if cz else i[:, 2]
                wz = a[:, 2] if cz else 1.0 - a[:, 2]
                out += (wx * wy * wz)[:, None] * lat[ix, iy, iz]
    return out


def _texture(rng, textured: bool, spacing: float, base=None) -> _Texture:
    base = rng.uniform(0.15, 0.9, 3) if base is None else base
    amp = rng.uniform(0.35, 0.7) if textured else rng.uniform(0.005, 0.03)
    lats = (rng.uniform(-1, 1, (12, 12, 12, 3)), rng.uniform(-1, 1, (12, 12, 12, 3)))
    # correlated channels: mostly a change of lightness, some of hue
    for lat in lats:
        lat[..., 1] = 0.7 * lat[..., 0] + 0.3 * lat[..., 1]
        lat[..., 2] = 0.7 * lat[..., 0] + 0.3 * lat[..., 2]
    return _Texture(np.asarray(base, float), amp, spacing, lats, rng.uniform(0, 10, 3))


# ------------------------------------------------------------------------------------------------
# the scene
# ------------------------------------------------------------------------------------------------
@dataclass
class _Plane:
    n: np.ndarray  # unit normal pointing away from the camera; the plane is n . X = off (off > 0)
    off: float
    texture: _Texture


@dataclass
class _Object:
    shape: str
    dims: np.ndarray  # box/plate: half sizes; cylinder/rod: (radius, half height, 0); sphere: (r, 0, 0)
    rho: float  # bounding-sphere radius
    R0: np.ndarray  # orientation at time t0
    c0: np.ndarray  # centre at time t0 (camera frame)
    v: np.ndarray  # velocity (m per frame)
    a: np.ndarray  # acceleration (m per frame²)
    w: np.ndarray  # angular velocity (rotation vector per frame, camera frame)
    t0: float
    texture: _Texture
    gloss: float
    target: float = 0.0  # flow pairs: the displacement (px) of the fastest visible pixel

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        s = t - self.t0
        return _rotation(self.w * s) @ self.R0, self.c0 + self.v * s + 0.5 * self.a * s * s

    @property
    def moves(self) -> bool:
        return bool(np.any(self.v != 0) or np.any(self.a != 0) or np.any(self.w != 0))


@dataclass
class _Scene:
    size: tuple[int, int]
    K: tuple[float, float, float, float]
    planes: list
    objects: list
    light: np.ndarray
    ambient: float
    noise: float
    gains: dict = field(default_factory=dict)  # frame -> exposure gain
    rays: np.ndarray | None = None

    def __post_init__(self):
        H, W = self.size
        fx, fy, cx, cy = self.K
        u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        self.rays = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones_like(u)], -1)  # z = 1: t is the depth


def _camera(rng, size):
    H, W = size
    s = W / 640.0
    f = 525.0 * s * rng.uniform(0.95, 1.05)
    return (f, f, (W - 1) / 2 + rng.uniform(-3, 3) * s, (H - 1) / 2 + rng.uniform(-3, 3) * s)


def _background(rng):
    """Floor, back wall and maybe a side wall, in the camera frame of a camera pitched down."""
    pitch = np.radians(rng.uniform(5, 30))
    up = np.array([0.0, -np.cos(pitch), -np.sin(pitch)])  # world up in camera coordinates
    ahead = np.array([0.0, -np.sin(pitch), np.cos(pitch)])  # horizontal forward
    h = rng.uniform(0.8, 1.5)
    yaw = np.radians(rng.uniform(-20, 20))
    wall_n = _unit(np.cos(yaw) * ahead + np.sin(yaw) * np.cross(up, ahead))
    planes = [
        _Plane(-up, h, _texture(rng, True, rng.uniform(0.03, 0.1))),  # floor: -up . X = h
        _Plane(wall_n, rng.uniform(2.2, 3.6), _texture(rng, rng.random() < 0.8, rng.uniform(0.03, 0.12))),
    ]
    for p in planes:
        p.texture.amp = min(p.texture.amp, rng.uniform(0.1, 0.45))
    if rng.random() < 0.4:  # a side wall
        side = np.cross(up, ahead) * rng.choice([-1.0, 1.0])
        planes.append(_Plane(_unit(side), rng.uniform(1.0, 1.8), _texture(rng, True, rng.uniform(0.03, 0.1))))
    return planes, up


def _shape(rng, thin: bool):
    kind = rng.choice(["rod", "plate"]) if thin else rng.choice(["box", "cylinder", "sphere", "box"])
    if kind == "box":
        dims = rng.uniform(0.02, 0.11, 3)
        rho = float(np.linalg.norm(dims))
    elif kind == "plate":
        dims = np.array([rng.uniform(0.05, 0.13), rng.uniform(0.04, 0.11), rng.uniform(0.0015, 0.004)])
        rho = float(np.linalg.norm(dims))
    elif kind == "cylinder":
        dims = np.array([rng.uniform(0.02, 0.08), rng.uniform(0.03, 0.13), 0.0])
        rho = float(np.hypot(dims[0], dims[1]))
    elif kind == "rod":
        dims = np.array([rng.uniform(0.005, 0.015), rng.uniform(0.08, 0.16), 0.0])
        rho = float(np.hypot(dims[0], dims[1]))
    else:
        dims = np.array([rng.uniform(0.025, 0.11), 0.0, 0.0])
        rho = float(dims[0])
    return str(kind), dims, rho


def _fits(c, rho, planes, up) -> bool:
    """The bounding sphere is in front of every plane (a margin), not too near the camera."""
    if c[2] - rho < 0.45 or c[2] > 3.05:
        return False
    return all(p.n @ c <= p.off - rho - 0.01 for p in planes)


def _project(c, K):
    fx, fy, cx, cy = K
    return np.array([fx * c[0] / c[2] + cx, fy * c[1] / c[2] + cy])


def _backproject(uv, z, K):
    fx, fy, cx, cy = K
    return np.array([(uv[0] - cx) / fx * z, (uv[1] - cy) / fy * z, z])


def _make_object(rng, K, size, planes, up, thin, near=None):
    """An object at rest (motion drawn later) at a random place, or near the image point ``near``."""
    H, W = size
    kind, dims, rho = _shape(rng, thin)
    textured = rng.random() < 0.6
    tex = _texture(rng, textured, rng.uniform(0.008, 0.03))
    for _ in range(200):
        if near is not None:
            uv = near + rng.normal(0, 0.12 * W, 2)
        elif rng.random() < 0.8:
            uv = np.array([rng.uniform(0.05, 0.95) * W, rng.uniform(0.05, 0.95) * H])
        else:  # across the border: partly outside the image
            uv = np.array([rng.uniform(-0.15, 1.15) * W, rng.uniform(-0.1, 1.1) * H])
        # depth log-uniform between 0.5 m and the nearest plane along the ray (at most 3 m)
        ray = _backproject(uv, 1.0, K)
        far = min([p.off / (p.n @ ray) for p in planes if p.n @ ray > 1e-9] + [3.0])
        if far - rho - 0.05 <= 0.5:
            continue
        z = float(np.exp(rng.uniform(np.log(0.5), np.log(far - rho - 0.05))))
        c = _backproject(uv, z, K)
        if _fits(c, rho, planes, up):
            return _Object(kind, dims, rho, _random_rotation(rng), c, np.zeros(3), np.zeros(3), np.zeros(3),
                           0.0, tex, float(rng.uniform(0.1, 0.35)) if rng.random() < 0.3 else 0.0)
    return None


def _separated(a: _Object, b: _Object, times) -> bool:
    for t in times:
        if np.linalg.norm(a.pose(t)[1] - b.pose(t)[1]) < a.rho + b.rho + 0.01:
            return False
    return True


def _in_view(ob: _Object, t: float, K, size, margin=0.0) -> bool:
    """The object's bounding box (projected) touches the image (grown by ``margin`` px)."""
    win = _window(ob.pose(t)[1], ob.rho, K, size, margin)
    return win is not None


def _window(c, rho, K, size, margin=0.0):
    """Pixel rectangle (v0, v1, u0, u1) holding the projection of the sphere (c, rho), or None if outside."""
    H, W = size
    fx, fy, cx, cy = K
    if c[2] - rho <= 0.05:
        return 0, H, 0, W
    corners = c + rho * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    u = fx * corners[:, 0] / corners[:, 2] + cx
    v = fy * corners[:, 1] / corners[:, 2] + cy
    u0, u1 = int(np.floor(u.min() - margin)), int(np.ceil(u.max() + margin)) + 1
    v0, v1 = int(np.floor(v.min() - margin)), int(np.ceil(v.max() + margin)) + 1
    u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, W), min(v1, H)
    if u0 >= u1 or v0 >= v1:
        return None
    return v0, v1, u0, u1


def _scene_common(rng, size):
    K = _camera(rng, size)
    planes, up = _background(rng)
    light = _unit(np.array([rng.uniform(-0.6, 0.6), 0.0, 0.0]) + up * rng.uniform(0.5, 1.0)
                  - np.array([0.0, 0.0, rng.uniform(0.3, 0.9)]))
    return K, planes, up, light


def _add_objects(rng, K, size, planes, up, n):
    """Up to ``n`` objects at rest (the callers draw their motions); half of them placed near an earlier
    one in the image, so that they pass in front of each other."""
    objs = []
    for _ in range(n):
        near = None
        if objs and rng.random() < 0.5:  # aim at an earlier object: occlusions
            near = _project(objs[int(rng.integers(len(objs)))].c0, K)
        ob = _make_object(rng, K, size, planes, up, thin=rng.random() < 0.25, near=near)
        if ob is not None:
            objs.append(ob)
    return objs


def _valid_motion(ob, others, planes, up, K, size, times) -> bool:
    for t in times:
        if not _in_view(ob, t, K, size, margin=4.0):
            continue
        if not _fits(ob.pose(t)[1], ob.rho, planes, up):
            return False
    return all(_separated(ob, o, [t for t in times if _in_view(ob, t, K, size, 4.0) or
                                  _in_view(o, t, K, size, 4.0)]) for o in others)


def _draw_motion(rng, ob, K, trans_px, rot_px, horizontal=False, accel=0.0, n_frames=1):
    """Translation of ``trans_px`` px per frame (image-plane direction random, a depth component) and a
    rotation whose fastest point moves ``rot_px`` px per frame, at the object's depth."""
    f = K[0]
    z = ob.c0[2]
    ob.a = np.zeros(3)
    if horizontal:  # mostly sideways (objects on a sequence cross the image rather than fall)
        psi = rng.normal(0, 0.45) + (np.pi if rng.random() < 0.5 else 0.0)
    else:
        psi = rng.uniform(0, 2 * np.pi)
    speed = trans_px * z / f
    ob.v = speed * np.array([np.cos(psi), np.sin(psi), rng.uniform(-0.5, 0.5)])
    ob.w = _unit(rng.normal(size=3)) * min(rot_px * z / (f * ob.rho), 0.35)
    if accel > 0 and speed > 0:
        ob.a = accel * speed / n_frames * _unit(rng.normal(size=3)) * np.array([1.0, 0.5, 0.5])


# ------------------------------------------------------------------------------------------------
# ray casting
# ------------------------------------------------------------------------------------------------
_EPS = 1e-12


def _hit_box(o, D, h):
    Ds = np.where(np.abs(D) < _EPS, _EPS, D)
    t1, t2 = (-h - o) / Ds, (h - o) / Ds
    tmin, tmax = np.minimum(t1, t2), np.maximum(t1, t2)
    tn, tf = tmin.max(1), tmax.min(1)
    face = tmin.argmax(1)
    ok = (tn <= tf) & (tn > 1e-6)
    n = np.zeros_like(D)
    r = np.arange(len(D))
    n[r, face] = -np.sign(Ds[r, face])
    return np.where(ok, tn, np.inf), n


def _hit_sphere(o, D, r):
    a = (D * D).sum(1)
    b = D @ o
    disc = b * b - a * (o @ o - r * r)
    t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
    ok = (disc >= 0) & (t > 1e-6)
    return np.where(ok, t, np.inf), (o + t[:, None] * D) / r


def _hit_cylinder(o, D, r, hh):
    a = D[:, 0] ** 2 + D[:, 1] ** 2
    b = o[0] * D[:, 0] + o[1] * D[:, 1]
    c = o[0] ** 2 + o[1] ** 2 - r * r
    disc = b * b - a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
    zs = o[2] + ts * D[:, 2]
    side_ok = (disc >= 0) & (a > _EPS) & (ts > 1e-6) & (np.abs(zs) <= hh)
    t_side = np.where(side_ok, ts, np.inf)
    Dz = np.where(np.abs(D[:, 2]) < _EPS, _EPS, D[:, 2])
    t_cap = np.full(len(D), np.inf)
    cap_sign = np.zeros(len(D))
    for s in (-1.0, 1.0):
        tc = (s * hh - o[2]) / Dz
        x, y = o[0] + tc * D[:, 0], o[1] + tc * D[:, 1]
        ok = (tc > 1e-6) & (x * x + y * y <= r * r) & (tc < t_cap)
        t_cap = np.where(ok, tc, t_cap)
        cap_sign = np.where(ok, s, cap_sign)
    use_cap = t_cap < t_side
    t = np.where(use_cap, t_cap, t_side)
    P = o + np.where(np.isfinite(t), t, 0.0)[:, None] * D
    n = np.stack([P[:, 0] / r, P[:, 1] / r, np.zeros(len(D))], 1)
    n[use_cap] = np.array([0.0, 0.0, 1.0]) * cap_sign[use_cap, None]
    return t, n


def _intersect(ob, o, D):
    if ob.shape in ("box", "plate"):
        return _hit_box(o, D, ob.dims)
    if ob.shape == "sphere":
        return _hit_sphere(o, D, ob.dims[0])
    return _hit_cylinder(o, D, ob.dims[0], ob.dims[1])


def _render(scene: _Scene, t: float) -> dict:
    """Ray-cast the scene at time ``t`` (frames): true depth, surface ids, hit points, normals, colour."""
    H, W = scene.size
    d = scene.rays.reshape(-1, 3)
    n_pix = H * W
    z = np.full(n_pix, np.inf)
    sid = np.zeros(n_pix, np.int32)  # -(k+1): plane k; k >= 1: object k
    P = np.zeros((n_pix, 3))  # hit point in the surface's own frame (the camera frame for planes)
    N = np.zeros((n_pix, 3))  # normal, camera frame, toward the camera
    for k, pl in enumerate(scene.planes):
        den = d @ pl.n
        with np.errstate(divide="ignore", invalid="ignore"):
            tt = np.where(den > 1e-9, pl.off / den, np.inf)
        hit = tt < z
        z[hit] = tt[hit]
        sid[hit] = -(k + 1)
        P[hit] = tt[hit, None] * d[hit]
        N[hit] = -pl.n
    poses = {}
    for k, ob in enumerate(scene.objects, start=1):
        R, c = ob.pose(t)
        poses[k] = (R, c)
        win = _window(c, ob.rho, scene.K, scene.size)
        if win is None:
            continue
        v0, v1, u0, u1 = win
        gidx = (np.arange(v0, v1)[:, None] * W + np.arange(u0, u1)[None, :]).ravel()
        o = -(c @ R)  # the camera centre in the object's frame, R^T (0 - c)
        D = d[gidx] @ R  # ray directions in the object's frame, R^T d
        tt, nl = _intersect(ob, o, D)
        hit = tt < z[gidx]
        g = gidx[hit]
        z[g] = tt[hit]
        sid[g] = k
        P[g] = o + tt[hit, None] * D[hit]
        N[g] = nl[hit] @ R.T
    # colour: texture albedo, Lambert + ambient, a mild specular highlight on glossy objects
    albedo = np.zeros((n_pix, 3))
    gloss = np.zeros(n_pix)
    for s in np.unique(sid):
        m = sid == s
        if s < 0:
            albedo[m] = scene.planes[-s - 1].texture.albedo(P[m])
        else:
            ob = scene.objects[s - 1]
            albedo[m] = ob.texture.albedo(P[m])
            gloss[m] = ob.gloss
    dn = d / np.linalg.norm(d, axis=1, keepdims=True)
    flip = (N * dn).sum(1) > 0  # a normal facing away (a plane seen from behind, never for solids)
    N[flip] *= -1
    lam = np.clip(N @ scene.light, 0.0, None)
    half = _unit_rows(scene.light[None, :] - dn)
    spec = gloss * np.clip((N * half).sum(1), 0.0, None) ** 30
    rgb = albedo * (scene.ambient + (1.0 - scene.ambient) * lam)[:, None] + spec[:, None]
    cos_inc = np.abs((N * dn).sum(1))
    return {"z": z.reshape(H, W), "sid": sid.reshape(H, W), "P": P.reshape(H, W, 3), "rgb_lin":
            rgb.reshape(H, W, 3), "cos": cos_inc.reshape(H, W), "poses": poses}


def _unit_rows(v):
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)


def _camera_image(rgb_lin, gain, noise, rng) -> np.ndarray:
    """The colour camera: exposure gain, optics blur (0.5 px Gaussian), read noise, 8 bits."""
    img = np.clip(rgb_lin * gain * 255.0, 0, 255).astype(np.uint8)
    img = np.asarray(Image.fromarray(img).filter(ImageFilter.GaussianBlur(0.5)), dtype=float)
    img += rng.normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------------------------
# the depth sensor
# ------------------------------------------------------------------------------------------------
def _shift_max_min(z):
    """3×3 neighbourhood maximum and minimum (edge-replicated)."""
    H, W = z.shape
    zp = np.pad(z, 1, mode="edge")
    hi, lo = z.copy(), z.copy()
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            s = zp[dy:dy + H, dx:dx + W]
            np.maximum(hi, s, out=hi)
            np.minimum(lo, s, out=lo)
    return hi, lo


def _kinect(z, cos_inc, fx, rng) -> np.ndarray:
    """Kinect-like measured depth from the true depth ``z`` (m; inf = nothing): see the module docstring."""
    H, W = z.shape
    zt = np.where(np.isfinite(z), z, 50.0)
    out = zt + rng.normal(0.0, 1.0, z.shape) * sensor_sigma(zt)
    fb = KINECT_F * KINECT_B
    out = fb / (np.round(fb / np.maximum(out, 0.05) * 8.0) / 8.0)
    # projector shadow: a pixel is hidden from the projector (7.5 cm to the right) when a pixel to its
    # right maps to a projector column left of its own (the ordering constraint of a rectified pair)
    up = np.arange(W)[None, :] - fx * KINECT_B / zt
    right_min = np.minimum.accumulate(up[:, ::-1], axis=1)[:, ::-1]
    right_min = np.concatenate([right_min[:, 1:], np.full((H, 1), np.inf)], axis=1)
    shadow = right_min < up - 0.5
    # depth edges: holes and flying pixels (a mix of the near and the far surface)
    hi, lo = _shift_max_min(zt)
    edge = (hi - lo) > np.maximum(0.03, 0.03 * zt)
    r = rng.random(z.shape)
    hole = edge & (r < 0.35)
    fly = edge & (r >= 0.35) & (r < 0.65)
    other = np.where(hi - zt > zt - lo, hi, lo)
    alpha = rng.uniform(0.2, 0.8, z.shape)
    out = np.where(fly, zt + alpha * (other - zt), out)
    # grazing surfaces and random blobs
    graze = (cos_inc < 0.15) | ((cos_inc < 0.3) & (rng.random(z.shape) < 0.3))
    seeds = rng.random(z.shape) < 0.0025
    blob, _ = _shift_max_min(seeds.astype(float))
    drop = shadow | hole | graze | (blob > 0) | ~np.isfinite(z)
    out[drop] = 0.0
    out[(out < MIN_RANGE) | (out > MAX_RANGE)] = 0.0
    return out


# ------------------------------------------------------------------------------------------------
# flow pairs
# ------------------------------------------------------------------------------------------------
def _pair_scene(spec: PairSpec) -> _Scene:
    rng = np.random.default_rng([spec.seed, 0])
    K, planes, up, light = _scene_common(rng, spec.size)
    lo, hi = PAIR_MOTIONS[spec.motion]
    for _attempt in range(20):  # until at least 2 objects and a visible one of the motion class
        objs = _add_objects(rng, K, spec.size, planes, up, int(rng.integers(2, 7)))
        placed: list[_Object] = []
        for ob in objs:
            for _ in range(30):
                if not any(o.target >= lo for o in placed):  # the first moving object sets the class
                    D = rng.uniform(lo, hi)
                else:
                    D = 0.0 if rng.random() < 0.2 else rng.uniform(0.0, hi)
                frac = rng.uniform(0.4, 1.0) if rng.random() < 0.8 else rng.uniform(0.0, 0.4)
                _draw_motion(rng, ob, K, frac * D, (1.0 - frac) * D)
                ob.target = D  # set exactly by _scale_pair_motions
                if _valid_motion(ob, placed, planes, up, K, spec.size, (0.0, 1.0)):
                    placed.append(ob)
                    break
        if len(placed) < 2:
            continue
        scene = _Scene(spec.size, K, planes, placed, light, float(rng.uniform(0.35, 0.6)),
                       float(rng.uniform(1.5, 3.0)))
        seen = _scale_pair_motions(scene)
        if any(ob.target >= lo and seen[k] >= 50 for k, ob in enumerate(placed, start=1)):
            break
    else:
        raise RuntimeError(f"no scene of the motion class found for {spec}")
    g0 = rng.uniform(0.85, 1.1)
    ratio = 1.0
    if spec.brightness:
        ratio = 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.03, spec.brightness)
    scene.gains = {0: g0, 1: g0 * ratio}
    return scene


def _pixel_displacements(scene, ob, R0, c0, P_local):
    """2-D displacement (px) from frame 0 to 1 of the material points ``P_local`` of ``ob``."""
    R1, c1 = ob.pose(1.0)
    X0 = P_local @ R0.T + c0
    X1 = P_local @ R1.T + c1
    fx, fy = scene.K[:2]  # the principal point cancels
    return np.hypot(fx * X1[:, 0] / X1[:, 2] - fx * X0[:, 0] / X0[:, 2],
                    fy * X1[:, 1] / X1[:, 2] - fy * X0[:, 1] / X0[:, 2])


def _scale_pair_motions(scene: _Scene) -> dict[int, int]:
    """Scale each moving object's motion so that its fastest visible pixel (or, when it is hidden, the
    fastest corner of its bounding box) moves exactly its target number of pixels; return each object's
    visible pixel count in frame 0."""
    r0 = _render(scene, 0.0)
    seen = {k: int((r0["sid"] == k).sum()) for k in range(1, len(scene.objects) + 1)}
    for k, ob in enumerate(scene.objects, start=1):
        target = getattr(ob, "target", 0.0)
        if not ob.moves or target <= 0:
            ob.v, ob.w, ob.a = np.zeros(3), np.zeros(3), np.zeros(3)
            continue
        m = r0["sid"] == k
        if m.sum() >= 4:
            Pl = r0["P"][m]
        else:
            Pl = ob.rho / np.sqrt(3) * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                                  for sz in (-1, 1)], float)
        R0, c0 = ob.pose(0.0)
        for _ in range(4):
            cur = float(_pixel_displacements(scene, ob, R0, c0, Pl).max())
            if cur <= 0:
                break
            s = target / cur
            ob.v = ob.v * s
            ob.w = ob.w * s
            if abs(s - 1.0) < 1e-3:
                break
    return seen


def make_pair(spec: PairSpec) -> dict:
    """A flow pair (frames 0 and 1 of a scene) with its exact ground truth.

    Returns
    -------
    dict
        ``rgb0``, ``rgb1`` (H, W, 3) uint8; ``depth0``, ``depth1`` (H, W) float measured depth (m, 0 =
        none); ``K`` (fx, fy, cx, cy); ``dt`` (s); ``flow3d`` (H, W, 3) true displacement (m) from frame 0
        to frame 1, NaN where not ``valid``; ``valid`` (H, W) bool (see the module docstring); ``labels0``,
        ``labels1`` (H, W) int object ids (0 = background); ``moving`` (H, W) bool (on a moving object);
        ``visible1`` (H, W) bool (the point is seen in frame 1); ``flow2d`` (H, W, 2) true optical flow
        (px); ``depth_true0``, ``depth_true1``; ``objects``: per frame {id: (centre (3,), visible
        pixels, visible area m², speed bound m/s)}; ``max_px`` the largest true optical flow on a
        visible object pixel; ``gain_ratio`` the brightness change; ``shapes`` {id: shape}; ``spec``,
        ``name``; ``flow3d_observable`` (H, W, 3) and ``moving_observable`` (H, W) bool: the same with the
        unobservable rotation of nearly uniform bodies of revolution removed (module docstring);
        ``observability`` {id: {"uniform": bool, "symmetry": "point" | "axis" | None, "twist": angle
        (rad) of the removed rotation, 0 when nothing was removed}}.
    """
    scene = _pair_scene(spec)
    rng = np.random.default_rng([spec.seed, 1])
    frames = []
    for t in (0, 1):
        r = _render(scene, float(t))
        r["rgb"] = _camera_image(r["rgb_lin"], scene.gains[t], scene.noise, rng)
        r["depth"] = _kinect(r["z"], r["cos"], scene.K[0], rng)
        frames.append(r)
    f0, f1 = frames
    H, W = spec.size
    X0 = f0["z"][..., None] * scene.rays
    sid0 = f0["sid"]
    X1 = X0.copy()
    X1_obs = X0.copy()
    observability, still = {}, []
    for k, ob in enumerate(scene.objects, start=1):
        (R0, c0), (R1, c1) = ob.pose(0.0), ob.pose(1.0)
        R_obs, observability[k] = observable_rotation(ob, R0, R1)
        if ob.moves and np.allclose(R_obs, np.eye(3), atol=1e-12) and np.allclose(c1, c0, atol=1e-12):
            still.append(k)
        m = sid0 == k
        if m.any():
            X1[m] = f0["P"][m] @ R1.T + c1
            X1_obs[m] = (f0["P"][m] @ R0.T) @ R_obs.T + c1
    flow = X1 - X0
    fx, fy, cx, cy = scene.K
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        u1, v1 = fx * X1[..., 0] / X1[..., 2] + cx, fy * X1[..., 1] / X1[..., 2] + cy
    flow2d = np.stack([u1 - u, v1 - v], -1)
    iu, iv = np.rint(u1), np.rint(v1)
    inside = (iu >= 0) & (iu < W) & (iv >= 0) & (iv < H) & np.isfinite(X1[..., 2])
    iu = np.where(inside, iu, 0).astype(int)
    iv = np.where(inside, iv, 0).astype(int)
    z1 = f1["z"][iv, iu]
    labels0, labels1 = np.maximum(sid0, 0), np.maximum(f1["sid"], 0)
    visible1 = inside & (np.abs(z1 - X1[..., 2]) < 0.01 + 0.01 * X1[..., 2]) & (labels1[iv, iu] == labels0)
    zt = f0["z"]
    valid = (f0["depth"] > 0) & np.isfinite(zt) & (np.abs(f0["depth"] - zt) <= depth_tolerance(zt))
    flow3d = np.where(valid[..., None], flow, np.nan)
    moving_ids = [k for k, ob in enumerate(scene.objects, start=1) if ob.moves]
    moving = np.isin(labels0, moving_ids)
    moving_obs = moving & ~np.isin(labels0, still)
    objects = [_object_truth(scene, f, float(t)) for t, f in enumerate(frames)]
    on_obj = labels0 > 0
    max_px = float(np.linalg.norm(flow2d[on_obj], axis=1).max()) if on_obj.any() else 0.0
    return {
        "name": spec.name, "spec": spec, "rgb0": f0["rgb"], "rgb1": f1["rgb"], "depth0": f0["depth"],
        "depth1": f1["depth"], "K": scene.K, "dt": 1.0 / FPS, "flow3d": flow3d, "valid": valid,
        "labels0": labels0, "labels1": labels1, "moving": moving, "visible1": visible1, "flow2d": flow2d,
        "depth_true0": np.where(np.isfinite(zt), zt, 0.0), "depth_true1": np.where(np.isfinite(f1["z"]),
                                                                                   f1["z"], 0.0),
        "objects": objects, "max_px": max_px, "gain_ratio": scene.gains[1] / scene.gains[0],
        "shapes": {k: ob.shape for k, ob in enumerate(scene.objects, start=1)},
        "flow3d_observable": np.where(valid[..., None], X1_obs - X0, np.nan), "moving_observable": moving_obs,
        "observability": observability,
    }


#: an object's texture amplitude below which its colour counts as uniform (nearly uniform objects are
#: drawn with ±0.5–3 %, textured ones with ±35–70 %)
UNIFORM_AMPLITUDE = 0.05


def observable_rotation(ob, R0, R1):
    """The part of the rotation ``R1 R0^T`` (camera frame, about the centre) that the images can show.

    For a nearly uniform sphere nothing (identity); for a nearly uniform cylinder or rod the swing, the
    smallest rotation taking its axis ``R0 e_z`` to ``R1 e_z`` (``R1 R0^T`` = swing · twist about the
    axis); for every other object the whole rotation. Returns ``(R_obs (3, 3), record)`` with the
    record ``{"uniform", "symmetry", "twist"}`` of :func:`make_pair`.
    """
    R = R1 @ R0.T
    uniform = bool(ob.texture.amp < UNIFORM_AMPLITUDE)
    symmetry = {"sphere": "point", "cylinder": "axis", "rod": "axis"}.get(ob.shape)
    rec = {"uniform": uniform, "symmetry": symmetry, "twist": 0.0}
    if not uniform or symmetry is None:
        return R, rec
    if symmetry == "point":
        R_obs = np.eye(3)
    else:
        a0, a1 = R0[:, 2], R1[:, 2]
        axis = np.cross(a0, a1)
        sin_a = float(np.linalg.norm(axis))
        R_obs = _rotation(axis / sin_a * np.arctan2(sin_a, a0 @ a1)) if sin_a > 1e-12 else np.eye(3)
    rest = R_obs.T @ R  # the removed rotation (about the axis for a cylinder)
    rec["twist"] = float(np.arccos(np.clip((np.trace(rest) - 1.0) / 2.0, -1.0, 1.0)))
    return R_obs, rec


def _object_truth(scene, r, t) -> dict:
    """{id: (centre (3,), visible pixels, visible surface area m², speed bound m/s)} of every object at
    time ``t``; the bound (|centre velocity| + |angular velocity| × bounding radius) is the largest
    speed any point of the body can have."""
    fx, fy = scene.K[0], scene.K[1]
    out = {}
    for k, ob in enumerate(scene.objects, start=1):
        m = r["sid"] == k
        area = float((r["z"][m] ** 2 / (fx * fy * np.maximum(r["cos"][m], 0.2))).sum())
        cdot = ob.v + ob.a * (t - ob.t0)
        speed = (float(np.linalg.norm(cdot)) + float(np.linalg.norm(ob.w)) * ob.rho) * FPS
        out[k] = (ob.pose(t)[1].copy(), int(m.sum()), area, speed)
    return out


# ------------------------------------------------------------------------------------------------
# sequences
# ------------------------------------------------------------------------------------------------
def _sequence_scene(spec: SequenceSpec) -> _Scene:
    rng = np.random.default_rng([spec.seed, 2])
    K, planes, up, light = _scene_common(rng, spec.size)
    lo, hi = SEQUENCE_SPEEDS[spec.speed]
    n = int(rng.integers(2, 7))
    tm = (spec.n_frames - 1) / 2.0
    times = np.arange(spec.n_frames, dtype=float)
    objs = _add_objects(rng, K, spec.size, planes, up, n)
    placed: list[_Object] = []
    for ob in objs:
        ob.t0 = tm  # the drawn position is the one in the middle of the sequence
        for _ in range(30):
            trans = 0.0 if rng.random() < 0.1 else rng.uniform(lo, hi)
            rot = rng.uniform(0.0, 0.5 * hi) if rng.random() < 0.6 else 0.0
            _draw_motion(rng, ob, K, trans, rot, horizontal=True, accel=rng.uniform(0.0, 1.0),
                         n_frames=spec.n_frames)
            _cap_motion(ob, K, spec.size, times, hi)
            if _valid_motion(ob, placed, planes, up, K, spec.size, times):
                placed.append(ob)
                break
    scene = _Scene(spec.size, K, planes, placed, light, float(rng.uniform(0.35, 0.6)),
                   float(rng.uniform(1.5, 3.0)))
    g = rng.uniform(0.85, 1.1)
    for i in range(spec.n_frames):
        if spec.brightness and i and rng.random() < 0.2:  # auto-exposure steps
            g = float(np.clip(g * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.03, spec.brightness)),
                              0.7, 1.3))
        scene.gains[i] = g
    return scene


_SPHERE = np.array([v for v in np.ndindex(3, 3, 3) if v != (1, 1, 1)], float) - 1.0
_SPHERE /= np.linalg.norm(_SPHERE, axis=1, keepdims=True)  # 26 directions


def fastest_pixel(ob: _Object, K, size, times) -> float:
    """Largest image displacement (px) between consecutive frames of 26 points on the object's bounding
    sphere, over the frames in which the object is in view (at least that of any of its pixels)."""
    fx, fy = K[:2]
    best = 0.0
    P = ob.rho * _SPHERE
    for t0, t1 in itertools.pairwise(times):
        if not (_in_view(ob, t0, K, size) or _in_view(ob, t1, K, size)):
            continue
        (R0, c0), (R1, c1) = ob.pose(t0), ob.pose(t1)
        X0, X1 = P @ R0.T + c0, P @ R1.T + c1
        d = np.hypot(fx * (X1[:, 0] / X1[:, 2] - X0[:, 0] / X0[:, 2]),
                     fy * (X1[:, 1] / X1[:, 2] - X0[:, 1] / X0[:, 2]))
        best = max(best, float(d.max()))
    return best


def _cap_motion(ob: _Object, K, size, times, limit: float) -> None:
    """Scale the motion down until no point of the bounding sphere moves more than ``limit`` px per frame."""
    for _ in range(4):
        fast = fastest_pixel(ob, K, size, times)
        if fast <= limit:
            return
        s = 0.98 * limit / fast
        ob.v, ob.a, ob.w = ob.v * s, ob.a * s, ob.w * s


def render_sequence_frames(spec: SequenceSpec):
    """Yield ``(i, rgb, depth, objects)`` for every frame of the sequence (see :func:`write_sequence`)."""
    yield from _frames(_sequence_scene(spec), spec)


def _frames(scene: _Scene, spec: SequenceSpec):
    rng = np.random.default_rng([spec.seed, 3])
    for i in range(spec.n_frames):
        r = _render(scene, float(i))
        rgb = _camera_image(r["rgb_lin"], scene.gains[i], scene.noise, rng)
        depth = _kinect(r["z"], r["cos"], scene.K[0], rng)
        yield i, rgb, depth, _object_truth(scene, r, float(i))


def write_sequence(root, spec: SequenceSpec, progress=None) -> dict:
    """Write the sequence to ``root`` in the TUM RGB-D layout, with its ground truth.

    Files: ``rgb/<stamp>.png``, ``depth/<stamp>.png`` (16 bit, 1/5000 m, 0 = none), ``rgb.txt``,
    ``depth.txt`` (colour 1 ms after depth, both rendered at the depth stamp; frames 1/30 s apart with
    ±1 ms jitter), ``intrinsics.txt`` (fx fy cx cy), ``objects.csv`` (``frame,id,x,y,z,visible_pixels,
    visible_area_m2,max_point_speed``: every object in every frame, its centre in that frame's camera
    frame, metres; 0 visible pixels when it is outside the image or hidden; the largest speed any of
    its points can have, m/s) and ``scene.json`` (the spec and each object's shape). ``progress``: a
    callable given each frame index, or None.

    Returns ``{"intrinsics": "fx,fy,cx,cy", "truth": {frame: {id: (centre, visible pixels, area,
    speed)}}, "stamps": [...], "shapes": {id: shape}}``.
    """
    root = Path(root)
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    (root / "depth").mkdir(exist_ok=True)
    jitter = np.random.default_rng([spec.seed, 4]).uniform(-0.001, 0.001, spec.n_frames)
    t0 = 1500000000.0 + spec.seed
    rgb_lines = ["# color images", "# timestamp filename"]
    depth_lines = ["# depth maps", "# timestamp filename"]
    rows = ["frame,id,x,y,z,visible_pixels,visible_area_m2,max_point_speed"]
    truth, stamps = {}, []
    scene = _sequence_scene(spec)
    for i, rgb, depth, objects in _frames(scene, spec):
        ts = t0 + i / FPS + jitter[i]
        tr = ts + 0.001
        Image.fromarray(rgb).save(root / "rgb" / f"{tr:.6f}.png")
        raw = np.clip(np.rint(depth * DEPTH_SCALE), 0, 65535).astype(np.uint16)
        Image.fromarray(raw).save(root / "depth" / f"{ts:.6f}.png")
        rgb_lines.append(f"{tr:.6f} rgb/{tr:.6f}.png")
        depth_lines.append(f"{ts:.6f} depth/{ts:.6f}.png")
        truth[i] = objects
        stamps.append(ts)
        for k, (c, npx, area, speed) in objects.items():
            rows.append(f"{i},{k},{c[0]:.6f},{c[1]:.6f},{c[2]:.6f},{npx},{area:.6f},{speed:.6f}")
        if progress is not None:
            progress(i)
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (root / "objects.csv").write_text("\n".join(rows) + "\n")
    fx, fy, cx, cy = scene.K
    (root / "intrinsics.txt").write_text(f"# fx fy cx cy\n{fx:.6f} {fy:.6f} {cx:.6f} {cy:.6f}\n")
    shapes = {k: ob.shape for k, ob in enumerate(scene.objects, start=1)}
    meta = {"spec": asdict(spec), "name": spec.name, "shapes": shapes, "fps": FPS}
    (root / "scene.json").write_text(json.dumps(meta, indent=1) + "\n")
    return {"intrinsics": f"{fx:.6f},{fy:.6f},{cx:.6f},{cy:.6f}", "truth": truth, "stamps": stamps,
            "shapes": shapes}


def read_objects_csv(path) -> dict[int, dict[int, tuple[np.ndarray, int, float, float]]]:
    """``objects.csv`` back as ``{frame: {id: (centre (3,), visible pixels, visible area m², speed
    bound m/s)}}`` (NaN for a column the file does not have)."""
    import csv

    def num(r, key):
        return float(r[key]) if r.get(key) not in (None, "") else np.nan

    out: dict[int, dict] = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            c = np.array([float(r[k]) for k in "xyz"])
            out.setdefault(int(r["frame"]), {})[int(r["id"])] = (
                c, int(r["visible_pixels"]), num(r, "visible_area_m2"), num(r, "max_point_speed"))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Write the sequences of a split (TUM layout) to a folder.")
    ap.add_argument("--split", choices=("train", "test"), required=True)
    ap.add_argument("--out", required=True, help="folder; sequence i goes to OUT/<seed>")
    ap.add_argument("--limit", type=int, default=None, help="only the first N sequences")
    args = ap.parse_args(argv)
    _, seqs = split(args.split)
    for spec in seqs[: args.limit]:
        made = write_sequence(Path(args.out) / str(spec.seed), spec)
        print(spec.name, "->", Path(args.out) / str(spec.seed), "intrinsics", made["intrinsics"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
