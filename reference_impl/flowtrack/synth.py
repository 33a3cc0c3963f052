r"""Synthetic RGB-D sequences of rigid objects moving on a table, with exact ground truth.

A tilted pinhole camera looks down at a table (the world plane :math:`z_w = 0`, world :math:`z` up)
in front of a back wall. Boxes and upright cylinders slide on the table: each object :math:`k`
has a pose :math:`T_{wo}^{(k)}(t) \in SE(3)` made of a planar translation (a slightly curved path)
and a rotation about the vertical axis at constant angular speed. Its object-to-camera pose is
:math:`T_k(t) = T_{cw}\,T_{wo}^{(k)}(t)` (the camera is static).

Rendering is exact ray casting. The ray through pixel :math:`(r, c)` (row, column) is
:math:`X(s) = s\,d`, :math:`d = ((c - c_x)/f_x,\ (r - c_y)/f_y,\ 1)^\top`, so the ray parameter
:math:`s` *is* the depth :math:`Z`. Every surface is intersected analytically for all pixels at once
(slab method for boxes in the box frame, a quadratic plus two caps for cylinders, one division for
planes) and a z-buffer keeps the nearest hit, so occlusion is exact.

Ground truth per frame :math:`t_i = i\,\Delta t`, for each valid pixel with noiseless surface point
:math:`X` owned by object :math:`k`:

.. math::  v(X) = \frac{T_k(t_{i+1})\,T_k(t_i)^{-1} X - X}{\Delta t},

so :math:`X + v\,\Delta t` is *exactly* where that material point is at :math:`t_{i+1}` (the motion
is analytic, so the last frame uses the motion continuing to :math:`t_n`). Static surfaces (table,
wall, static occluders) have :math:`v = 0`. Depth noise :math:`\mathcal N(0, \sigma^2)` is added to
:math:`Z` (and hence to the back-projected points); the ground truth refers to the noiseless point.

Labels: ``0`` = static (table, wall, static occluders), ``1..K`` = the moving objects.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from ._graph import apply_transform
from ._validation import as_array, nonnegative, positive, positive_int
from .camera import PinholeCamera, _check_cam, backproject, project

__all__ = [
    "SCENARIOS",
    "Body",
    "Box",
    "ArcTrajectory",
    "Cylinder",
    "Frame",
    "PlanarTrajectory",
    "Plane",
    "RayCast",
    "Scene",
    "look_at",
    "make_scene",
    "ray_cast",
    "ray_directions",
]

SCENARIOS = ("default", "crossing", "occlusion", "mixed", "turning")

_PALETTE = np.array(
    [
        [220, 50, 40],  # red
        [40, 170, 70],  # green
        [40, 90, 220],  # blue
        [235, 190, 30],  # yellow
        [190, 60, 200],  # magenta
        [30, 190, 200],  # cyan
        [240, 130, 30],  # orange
        [120, 80, 40],  # brown
    ],
    dtype=np.float64,
)
_LIGHT_W = np.array([0.3, -0.5, 1.0]) / np.linalg.norm([0.3, -0.5, 1.0])  # towards the light, world


# ----------------------------------------------------------------------------------------------
# shapes: analytic ray intersection in the shape's own frame
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Box:
    """Axis-aligned box centred at the origin of its frame.

    Parameters
    ----------
    half_extents : array_like, shape (3,)
        Half side lengths :math:`(a, b, c)` in metres; the box is :math:`|x|\\le a, |y|\\le b, |z|\\le c`.

    Examples
    --------
    >>> t, n = Box((1.0, 1.0, 1.0)).intersect(np.array([0.0, 0.0, -5.0]), np.array([[0.0, 0.0, 1.0]]))
    >>> float(t[0]), n[0].tolist()
    (4.0, [0.0, 0.0, -1.0])
    """

    half_extents: tuple

    def __post_init__(self):
        h = as_array(self.half_extents, "half_extents", (3,))
        if (h <= 0).any():
            raise ValueError(f"half_extents must be > 0, got {h.tolist()}")
        object.__setattr__(self, "half_extents", tuple(float(x) for x in h))

    @property
    def radius(self) -> float:
        """Radius of the footprint's bounding circle (x-y plane)."""
        return float(np.hypot(self.half_extents[0], self.half_extents[1]))

    @property
    def half_height(self) -> float:
        return self.half_extents[2]

    def intersect(self, origin: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""First hit of rays :math:`o + s\,d_m`, :math:`s > 0` (slab method).

        Parameters
        ----------
        origin : ndarray, shape (3,)
            Ray origin in the box frame.
        dirs : ndarray, shape (M, 3)
            Ray directions in the box frame (not necessarily unit).

        Returns
        -------
        s : ndarray, shape (M,)
            Ray parameter of the entry point, ``inf`` for a miss (or a ray starting inside).
        normal : ndarray, shape (M, 3)
            Outward unit normal of the face hit (box frame), 0 for a miss.
        """
        h = np.asarray(self.half_extents)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / dirs
            t1 = (-h - origin) * inv
            t2 = (h - origin) * inv
        # a direction component of exactly 0: inside the slab -> (-inf, inf), outside -> empty
        zero = dirs == 0
        inside = np.abs(origin) <= h
        lo = np.where(zero, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        hi = np.where(zero, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        axis = np.argmax(lo, axis=1)
        tnear = np.take_along_axis(lo, axis[:, None], axis=1)[:, 0]
        tfar = hi.min(axis=1)
        hit = (tnear <= tfar) & (tnear > 0)
        s = np.where(hit, tnear, np.inf)
        normal = np.zeros_like(dirs)
        rows = np.nonzero(hit)[0]
        normal[rows, axis[rows]] = -np.sign(dirs[rows, axis[rows]])
        return s, normal


@dataclass(frozen=True)
class Cylinder:
    """Upright (axis = frame z) solid cylinder centred at the origin of its frame.

    Parameters
    ----------
    radius : float, > 0
    half_height : float, > 0
        The cylinder is :math:`x^2 + y^2 \\le r^2,\\ |z| \\le h`.

    Examples
    --------
    >>> t, n = Cylinder(1.0, 2.0).intersect(np.array([-5.0, 0.0, 0.0]), np.array([[1.0, 0.0, 0.0]]))
    >>> float(t[0]), n[0].tolist()
    (4.0, [-1.0, 0.0, 0.0])
    """

    radius: float
    half_height: float

    def __post_init__(self):
        object.__setattr__(self, "radius", positive(self.radius, "radius"))
        object.__setattr__(self, "half_height", positive(self.half_height, "half_height"))

    def intersect(self, origin: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""First hit of rays :math:`o + s\,d_m`, :math:`s > 0`: side :math:`\|p_{xy}\| = r` or caps.

        Parameters and returns as :meth:`Box.intersect`.
        """
        r, h = self.radius, self.half_height
        ox, oy, oz = origin
        dx, dy, dz = dirs[:, 0], dirs[:, 1], dirs[:, 2]
        a = dx * dx + dy * dy
        b = 2.0 * (ox * dx + oy * dy)
        c = ox * ox + oy * oy - r * r
        disc = b * b - 4.0 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            s_side = (-b - np.sqrt(np.where(disc >= 0, disc, 0.0))) / (2.0 * a)
            s_side = np.where((disc >= 0) & (a > 0), s_side, np.inf)
            z_side = oz + s_side * dz
            s_side = np.where((s_side > 0) & (np.abs(z_side) <= h), s_side, np.inf)
            caps = []
            for zc in (h, -h):
                s = (zc - oz) / dz
                px = ox + s * dx
                py = oy + s * dy
                ok = (dz != 0) & (s > 0) & (px * px + py * py <= r * r)
                caps.append(np.where(ok, s, np.inf))
        s_all = np.stack([s_side, caps[0], caps[1]])
        which = np.argmin(s_all, axis=0)
        s = s_all[which, np.arange(dirs.shape[0])]
        normal = np.zeros_like(dirs)
        side = (which == 0) & np.isfinite(s)
        p = origin + s[side, None] * dirs[side]
        normal[side, 0] = p[:, 0] / r
        normal[side, 1] = p[:, 1] / r
        normal[(which == 1) & np.isfinite(s), 2] = 1.0
        normal[(which == 2) & np.isfinite(s), 2] = -1.0
        return s, normal


@dataclass(frozen=True)
class Plane:
    """The infinite plane :math:`z = 0` of its frame (a table top or a wall).

    Examples
    --------
    >>> t, n = Plane().intersect(np.array([0.0, 0.0, 2.0]), np.array([[0.0, 1.0, -1.0]]))
    >>> float(t[0]), n[0].tolist()
    (2.0, [0.0, 0.0, 1.0])
    """

    def intersect(self, origin: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First hit of rays with the plane; parameters and returns as :meth:`Box.intersect`."""
        dz = dirs[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -origin[2] / dz
        s = np.where((dz != 0) & (s > 0), s, np.inf)
        normal = np.zeros_like(dirs)
        normal[np.isfinite(s), 2] = 1.0 if origin[2] >= 0 else -1.0
        return s, normal


@dataclass
class Body:
    """A shape placed in the camera frame.

    Parameters
    ----------
    shape : Box, Cylinder or Plane
    pose : ndarray, shape (4, 4)
        Shape-to-camera transform :math:`T_{cb}`.
    label : int
        Label written into the label image (0 = static).
    color : array_like, shape (3,)
        Base RGB colour in [0, 255].
    texture : float
        Side of the checker texture cells in metres, in the shape's frame (0 = plain).
    """

    shape: Box | Cylinder | Plane
    pose: np.ndarray
    label: int = 0
    color: tuple = (200.0, 200.0, 200.0)
    texture: float = 0.0


# ----------------------------------------------------------------------------------------------
# motion
# ----------------------------------------------------------------------------------------------
def _rot_z(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class PlanarTrajectory:
    r"""Planar rigid motion on the table, analytic in time.

    With :math:`s = t / T` the centre follows
    :math:`p(t) = p_0 + (p_1 - p_0)\,s + \beta\, s(1 - s)\, n_\perp` (a parabola: constant velocity
    plus a slight constant lateral acceleration; :math:`n_\perp` is the unit normal of
    :math:`p_1 - p_0`) at height :math:`z`, and the heading is :math:`\theta(t) = \theta_0 + \omega t`.

    Parameters
    ----------
    p0, p1 : array_like, shape (2,)
        Start (t = 0) and end (t = T) of the chord, world x-y, metres.
    duration : float, > 0
        :math:`T` in seconds.
    z : float
        Height of the object's centre above the table.
    theta0, omega : float
        Initial heading (rad) and angular speed (rad/s) about the vertical axis.
    bend : float
        Lateral bulge :math:`\beta` (m); the path leaves the chord by at most :math:`\beta/4`.

    Examples
    --------
    >>> tr = PlanarTrajectory((0.0, 0.0), (1.0, 0.0), duration=2.0, z=0.1)
    >>> tr.pose(1.0)[:3, 3].tolist()
    [0.5, 0.0, 0.1]
    """

    p0: tuple
    p1: tuple
    duration: float
    z: float
    theta0: float = 0.0
    omega: float = 0.0
    bend: float = 0.0

    def position(self, t) -> np.ndarray:
        """World position of the centre at time(s) ``t``: shape (3,) for a scalar, (len(t), 3) else."""
        p0 = np.asarray(self.p0, dtype=float)
        p1 = np.asarray(self.p1, dtype=float)
        chord = p1 - p0
        n = np.array([-chord[1], chord[0]])
        nn = np.linalg.norm(n)
        n = n / nn if nn > 0 else n
        s = np.asarray(t, dtype=float)[..., None] / self.duration
        xy = p0 + chord * s + self.bend * s * (1.0 - s) * n
        return np.concatenate([xy, np.full((*xy.shape[:-1], 1), float(self.z))], axis=-1)

    def pose(self, t: float) -> np.ndarray:
        """Object-to-world transform :math:`T_{wo}(t)`, shape (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = _rot_z(self.theta0 + self.omega * t)
        T[:3, 3] = self.position(t)
        return T


# ----------------------------------------------------------------------------------------------
# camera and ray casting
# ----------------------------------------------------------------------------------------------
def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera-to-world transform of a camera at ``eye`` looking at ``target``.

    The camera frame is the computer-vision one: x right, y down, z forward (optical axis).

    Parameters
    ----------
    eye, target, up : array_like, shape (3,)
        World positions and the world "up" direction.

    Returns
    -------
    ndarray, shape (4, 4)
        :math:`T_{wc}`; its columns 0..2 are the camera axes in world coordinates.

    Examples
    --------
    >>> T = look_at([0, 0, 1], [0, 1, 1])
    >>> np.round(T[:3, :3], 12).tolist()
    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
    """
    eye = as_array(eye, "eye", (3,))
    target = as_array(target, "target", (3,))
    up = as_array(up, "up", (3,))
    z = target - eye
    if np.linalg.norm(z) == 0:
        raise ValueError("target must differ from eye")
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-12:
        raise ValueError("up must not be parallel to the viewing direction (target - eye)")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def ray_directions(camera: PinholeCamera) -> np.ndarray:
    """Un-normalised ray directions :math:`((c - c_x)/f_x, (r - c_y)/f_y, 1)` of every pixel.

    Parameters
    ----------
    camera : PinholeCamera
        Must have ``width`` and ``height``.

    Returns
    -------
    ndarray, shape (H*W, 3)
        Row-major over pixels (row ``r``, column ``c`` at index ``r*W + c``); the ray parameter along
        these directions equals the depth Z.

    Examples
    --------
    >>> ray_directions(PinholeCamera(1.0, 1.0, 0.0, 0.0, width=2, height=1)).tolist()
    [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]
    """
    cam = _check_camera(camera)
    return backproject(np.ones((cam.height, cam.width)), cam).reshape(-1, 3)  # depth Z = 1


def _check_camera(camera) -> PinholeCamera:
    _check_cam(camera, "camera")
    if camera.width is None or camera.height is None:
        raise ValueError("camera must have width and height")
    return camera


@dataclass
class RayCast:
    """Result of :func:`ray_cast` (all images of shape (H, W)).

    Attributes
    ----------
    depth : ndarray, shape (H, W)
        Z of the nearest hit, 0 where no surface is hit.
    body : ndarray, shape (H, W) int
        Index into the ``bodies`` list of the nearest body, -1 for none.
    label : ndarray, shape (H, W) int
        That body's ``label``, -1 for none.
    normal : ndarray, shape (H, W, 3)
        Unit surface normal in the camera frame (0 for none).
    local : ndarray, shape (H, W, 3)
        Hit point in the body's own frame (NaN for none).
    """

    depth: np.ndarray
    body: np.ndarray
    label: np.ndarray
    normal: np.ndarray
    local: np.ndarray


def _roi(shape, pose: np.ndarray, cam: PinholeCamera) -> tuple[slice, slice] | None:
    """Pixel rectangle that contains the image of a bounded shape (None = whole image).

    The shape lies inside its bounding box, whose image (all corners in front of the camera) is
    inside the convex hull of the 8 projected corners; pixel centres are integers, so
    ``floor(min)..ceil(max)`` is conservative.
    """
    if isinstance(shape, Box):
        h = np.asarray(shape.half_extents)
    elif isinstance(shape, Cylinder):
        h = np.array([shape.radius, shape.radius, shape.half_height])
    else:
        return None
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    C = apply_transform(pose, corners)
    if (C[:, 2] <= 1e-9).any():
        return None
    x, y = project(C, cam).T
    c0, c1 = int(np.floor(x.min())) - 1, int(np.ceil(x.max())) + 2
    r0, r1 = int(np.floor(y.min())) - 1, int(np.ceil(y.max())) + 2
    c0, r0 = max(c0, 0), max(r0, 0)
    c1, r1 = min(c1, cam.width), min(r1, cam.height)
    if c0 >= c1 or r0 >= r1:
        return (slice(0, 0), slice(0, 0))
    return (slice(r0, r1), slice(c0, c1))


def _cast_into(rc: RayCast, cam: PinholeCamera, dirs: np.ndarray, bodies, offset: int) -> None:
    """Z-buffer ``bodies`` into the buffers of ``rc`` in place (body indices start at ``offset``)."""
    for i, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise TypeError(f"bodies[{i}] must be a Body, got {type(b).__name__}")
        T = as_array(b.pose, f"bodies[{i}].pose", (4, 4))
        roi = _roi(b.shape, T, cam)
        if roi is None:
            roi = (slice(None), slice(None))
        d = dirs[roi]
        shp = d.shape[:2]
        if d.size == 0:
            continue
        d = d.reshape(-1, 3)
        R, p = T[:3, :3], T[:3, 3]
        o_b = -R.T @ p
        d_b = d @ R  # rows: R^T d
        s, n_b = b.shape.intersect(o_b, d_b)
        best = rc.depth[roi].reshape(-1)
        closer = s < np.where(best > 0, best, np.inf)
        if not closer.any():
            continue
        idx = np.nonzero(closer)[0]
        sub = [a[roi].reshape(-1, *a.shape[2:]) for a in (rc.depth, rc.body, rc.label, rc.normal, rc.local)]
        sub[0][idx] = s[idx]
        sub[1][idx] = offset + i
        sub[2][idx] = b.label
        sub[3][idx] = n_b[idx] @ R.T
        sub[4][idx] = o_b + s[idx, None] * d_b[idx]
        for a, v in zip((rc.depth, rc.body, rc.label, rc.normal, rc.local), sub):
            a[roi] = v.reshape(*shp, *a.shape[2:])


def _empty_cast(H: int, W: int) -> RayCast:
    return RayCast(
        depth=np.zeros((H, W)),
        body=np.full((H, W), -1, dtype=np.int64),
        label=np.full((H, W), -1, dtype=np.int64),
        normal=np.zeros((H, W, 3)),
        local=np.full((H, W, 3), np.nan),
    )


def _copy_cast(rc: RayCast) -> RayCast:
    return RayCast(rc.depth.copy(), rc.body.copy(), rc.label.copy(), rc.normal.copy(), rc.local.copy())


def ray_cast(camera: PinholeCamera, bodies: Sequence[Body], dirs: np.ndarray | None = None) -> RayCast:
    r"""Z-buffered analytic ray casting of ``bodies`` through every pixel.

    For body :math:`b` with pose :math:`T_{cb} = [R\,|\,p]` the camera rays become
    :math:`o_b = -R^\top p`, :math:`d_b = R^\top d` in the body frame (same parameter :math:`s`), the
    shape is intersected there, and :math:`Z = \min_b s_b` per pixel. Bounded shapes are only
    intersected with the rays of a conservative pixel rectangle around their projected bounding
    box (the result is the same as casting every ray; it is just faster).

    Parameters
    ----------
    camera : PinholeCamera
        With ``width`` and ``height``.
    bodies : sequence of Body
    dirs : ndarray, shape (H*W, 3), optional
        Precomputed :func:`ray_directions` (speed only).

    Returns
    -------
    RayCast

    Examples
    --------
    >>> cam = PinholeCamera(10.0, 10.0, 1.0, 1.0, width=3, height=3)
    >>> T = np.eye(4); T[2, 3] = 2.0                    # a plane z = 2 facing the camera
    >>> ray_cast(cam, [Body(Plane(), T)]).depth
    array([[2., 2., 2.],
           [2., 2., 2.],
           [2., 2., 2.]])
    """
    cam = _check_camera(camera)
    H, W = cam.height, cam.width
    dirs = ray_directions(cam) if dirs is None else as_array(dirs, "dirs", (H * W, 3))
    rc = _empty_cast(H, W)
    _cast_into(rc, cam, dirs.reshape(H, W, 3), list(bodies), 0)
    return rc


def _shade(rc: RayCast, bodies: Sequence[Body], light_c: np.ndarray, mask: np.ndarray | None = None):
    """Lambertian shading with checker textures of the pixels in ``mask``; returns (n, 3) uint8."""
    idx = rc.body if mask is None else rc.body[mask]
    loc = rc.local if mask is None else rc.local[mask]
    nrm = rc.normal if mask is None else rc.normal[mask]
    idx, loc, nrm = idx.reshape(-1), loc.reshape(-1, 3), nrm.reshape(-1, 3)
    colors = np.array([b.color for b in bodies] + [(0.0, 0.0, 0.0)], dtype=np.float64)
    cells = np.array([b.texture for b in bodies] + [0.0])
    base = colors[idx]
    cell = cells[idx]
    tex = np.ones(idx.shape[0])
    has = (cell > 0) & (idx >= 0)
    if has.any():
        q = np.floor(loc[has] / cell[has, None] + 1e-9).astype(np.int64).sum(axis=1)
        tex[has] = np.where(q % 2 == 0, 1.0, 0.72)
    lam = np.clip(nrm @ light_c, 0.0, 1.0)
    rgb = base * (tex * (0.35 + 0.65 * lam))[:, None]
    rgb[idx < 0] = 0.0
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# scene containers
# ----------------------------------------------------------------------------------------------
@dataclass
class Frame:
    """One RGB-D frame with exact ground truth.

    Attributes
    ----------
    index : int
        Frame number ``i``; its time is ``i * dt``.
    time : float
    depth : ndarray, shape (H, W)
        Metric depth Z with noise, 0 where no surface is hit (never, with the table and wall).
    depth_gt : ndarray, shape (H, W)
        Noiseless depth.
    rgb : ndarray, shape (H, W, 3) uint8
    label_image : ndarray, shape (H, W) int
        0 static, 1..K objects, -1 no surface.
    points : ndarray, shape (N, 3)
        Back-projection of ``depth`` at the valid pixels (row-major order), camera frame.
    labels : ndarray, shape (N,) int
        Label of each point (0 static, 1..K object id).
    gt_flow : ndarray, shape (N, 3)
        Exact velocity (m/s) of each point's *noiseless* surface point over ``[t, t + dt]``.
    gt_poses : dict[int, ndarray (4, 4)]
        Object-to-camera pose of each moving object at this frame.
    visible : dict[int, int]
        Number of pixels of each moving object in this frame (0 = fully occluded).
    """

    index: int
    time: float
    depth: np.ndarray
    depth_gt: np.ndarray
    rgb: np.ndarray
    label_image: np.ndarray
    points: np.ndarray
    labels: np.ndarray
    gt_flow: np.ndarray
    gt_poses: dict
    visible: dict
    _camera: PinholeCamera = field(repr=False, default=None)
    _gt_points: np.ndarray | None = field(repr=False, default=None)

    @property
    def valid(self) -> np.ndarray:
        """Boolean (H, W) mask of the pixels that have a point."""
        return self.depth_gt > 0

    @property
    def pixels(self) -> np.ndarray:
        """``(N, 2)`` int ``(row, col)`` of each point (same order as ``points``)."""
        return np.argwhere(self.valid)

    @property
    def gt_points(self) -> np.ndarray:
        """``(N, 3)`` noiseless surface points (back-projection of ``depth_gt``; a fresh array)."""
        if self._gt_points is not None:  # computed by make_scene
            return self._gt_points.copy()
        return backproject(self.depth_gt, self._camera)[self.valid]


@dataclass
class Scene:
    """A synthetic sequence; see :func:`make_scene`.

    Attributes
    ----------
    camera : PinholeCamera
        Intrinsics with ``width`` and ``height``.
    dt : float
        Time between frames (s).
    frames : list of Frame
    camera_pose : ndarray, shape (4, 4)
        Camera-to-world transform :math:`T_{wc}` (world: table plane z = 0, z up).
    objects : dict[int, Box | Cylinder]
        Shape of each moving object (id 1..K), in its own frame (origin = geometric centre).
    trajectories : dict[int, PlanarTrajectory]
        World motion of each moving object.
    static_bodies : list of Body
        Table, wall and static occluders (label 0), posed in the camera frame.
    colors : dict[int, ndarray (3,)]
        Base colour of each object.
    scenario : str
    """

    camera: PinholeCamera
    dt: float
    frames: list
    camera_pose: np.ndarray
    objects: dict
    trajectories: dict
    static_bodies: list
    colors: dict
    scenario: str = "default"

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[Frame]:
        return iter(self.frames)

    @property
    def object_ids(self) -> list[int]:
        """Ids of the moving objects, ``[1, ..., K]``."""
        return sorted(self.objects)

    def pose(self, object_id: int, t: float) -> np.ndarray:
        """Object-to-camera pose :math:`T_{cw} T_{wo}(t)` at any time ``t`` (4, 4)."""
        if object_id not in self.trajectories:
            raise ValueError(f"object_id must be one of {self.object_ids}, got {object_id}")
        return np.linalg.inv(self.camera_pose) @ self.trajectories[object_id].pose(float(t))

    def _frame_index(self, frame_index) -> int:
        if isinstance(frame_index, bool) or not isinstance(frame_index, numbers.Integral):
            raise TypeError(f"frame_index must be an int, got {type(frame_index).__name__}")
        n = len(self.frames)
        if not -n <= frame_index < n:
            raise ValueError(f"frame_index must be in [-{n}, {n}), got {frame_index}")
        return int(frame_index) % n

    def object_centroids(self, frame_index: int) -> dict[int, np.ndarray]:
        """Centre (origin of the object frame) of every moving object in the camera frame.

        Returns
        -------
        dict[int, ndarray (3,)]
            All objects, visible or not (see ``frames[i].visible``).
        """
        i = self._frame_index(frame_index)
        return {k: T[:3, 3].copy() for k, T in self.frames[i].gt_poses.items()}

    def ground_truth_tracks(self, coords: str = "camera", min_visible: int = 1) -> list[dict]:
        """Per-frame ground-truth object positions for tracking metrics.

        Parameters
        ----------
        coords : {"camera", "world", "table", "image"}
            ``camera``: centre in the camera frame (3,); ``world``: in the world frame (3,);
            ``table``: world x-y on the table (2,); ``image``: projected centre in pixels (x, y).
        min_visible : int, >= 0
            Leave out objects with fewer visible pixels in that frame (0 keeps all), so that
            trackers are not charged for fully occluded objects.

        Returns
        -------
        list of dict[int, ndarray]
            One ``{object_id: position}`` per frame, the format of :func:`flowtrack.metrics.clear_mot`.
        """
        if coords not in ("camera", "world", "table", "image"):
            raise ValueError(f"coords must be 'camera', 'world', 'table' or 'image', got {coords!r}")
        min_visible = positive_int(min_visible, "min_visible", minimum=0)
        out = []
        for f in self.frames:
            d = {}
            for k, T in f.gt_poses.items():
                if f.visible[k] < min_visible:
                    continue
                c = T[:3, 3]
                if coords == "camera":
                    d[k] = c.copy()
                elif coords == "image":
                    d[k] = project(c[None], self.camera)[0]
                else:
                    w = self.camera_pose[:3, :3] @ c + self.camera_pose[:3, 3]
                    d[k] = w if coords == "world" else w[:2]
            out.append(d)
        return out


# ----------------------------------------------------------------------------------------------
# scene generation
# ----------------------------------------------------------------------------------------------
_OPTIONS = {
    "scenario": "default",
    "shapes": None,
    "speed": (0.06, 0.15),
    "max_angular_speed": 0.8,
    "bend": 0.08,
    "wall": True,
    "texture": True,
}

# workspace on the table (world x-y, metres) that the default camera sees with margin
_X_RANGE = (-0.32, 0.32)
_Y_RANGE = (-0.05, 0.45)


def _default_camera(image_size) -> tuple[PinholeCamera, np.ndarray]:
    H, W = image_size
    f = 0.9 * W
    cam = PinholeCamera(f, f, (W - 1) / 2.0, (H - 1) / 2.0, width=W, height=H)
    T_wc = look_at([0.0, -0.6, 0.65], [0.0, 0.2, 0.0])
    return cam, T_wc


def _random_shape(rng: np.random.Generator, kind: str):
    if kind == "box":
        return Box((rng.uniform(0.035, 0.06), rng.uniform(0.035, 0.06), rng.uniform(0.035, 0.07)))
    return Cylinder(rng.uniform(0.035, 0.055), rng.uniform(0.04, 0.08))


def _collides(tr: PlanarTrajectory, r: float, others, times) -> bool:
    P = tr.position(times)[:, :2]
    for tr2, r2 in others:
        Q = tr2.position(times)[:, :2]
        if (np.linalg.norm(P - Q, axis=1) < r + r2 + 0.02).any():
            return True
    return False


def _in_workspace(tr: PlanarTrajectory, r: float, times) -> bool:
    P = tr.position(times)[:, :2]
    return bool(
        (P[:, 0] - r >= _X_RANGE[0]).all()
        and (P[:, 0] + r <= _X_RANGE[1]).all()
        and (P[:, 1] - r >= _Y_RANGE[0]).all()
        and (P[:, 1] + r <= _Y_RANGE[1]).all()
    )


# Random objects are placed one after the other; when one finds no free path (crowded scenes), all of
# them are placed again, up to this many times, continuing the same random stream (deterministic by
# seed; a scene placed at the first try is exactly what it always was).
_PLACEMENT_ROUNDS = 100


def _random_trajectories(rng, objects, scripted, duration, opts, placed, times, static_discs):
    """Random non-colliding paths for the objects not in ``scripted`` (dict id -> trajectory)."""
    for round_ in range(_PLACEMENT_ROUNDS):
        taken, chosen = list(placed), {}
        try:
            for k in objects:
                if k in scripted:
                    continue
                chosen[k] = _random_trajectory(rng, objects[k], duration, opts, taken, times, static_discs)
                taken.append((chosen[k], objects[k].radius))
            return chosen
        except RuntimeError:
            if round_ == _PLACEMENT_ROUNDS - 1:
                raise
    raise AssertionError("unreachable")  # pragma: no cover


def _random_trajectory(rng, shape, duration, opts, others, times, static_discs) -> PlanarTrajectory:
    r = shape.radius
    lo_s, hi_s = opts["speed"]
    for _ in range(500):
        p0 = np.array([rng.uniform(*_X_RANGE), rng.uniform(*_Y_RANGE)])
        ang = rng.uniform(0, 2 * np.pi)
        speed = rng.uniform(lo_s, hi_s)
        p1 = p0 + speed * duration * np.array([np.cos(ang), np.sin(ang)])
        tr = PlanarTrajectory(
            tuple(p0),
            tuple(p1),
            duration=duration,
            z=shape.half_height,
            theta0=rng.uniform(-np.pi, np.pi),
            omega=rng.uniform(-1, 1) * opts["max_angular_speed"],
            bend=rng.uniform(-1, 1) * opts["bend"],
        )
        if _in_workspace(tr, r, times) and not _collides(tr, r, others + static_discs, times):
            return tr
    raise RuntimeError(
        f"could not place a non-colliding trajectory in the workspace ({_PLACEMENT_ROUNDS} rounds of 500 "
        "tries per object); use fewer objects (n_objects) or a lower speed"
    )


def _straight_trajectory(rng, p0, p1, duration, shape, opts) -> PlanarTrajectory:
    """Straight path ``p0 -> p1`` resting on the table, random start angle and spin (scenarios)."""
    theta0 = rng.uniform(-np.pi, np.pi)
    omega = rng.uniform(-1, 1) * opts["max_angular_speed"]
    return PlanarTrajectory(p0, p1, duration, shape.half_height, theta0, omega, 0.0)


#: Fewest moving objects each scripted scenario needs (its scripted objects are ids 1..n).
_SCENARIO_MIN_OBJECTS = {"crossing": 2, "occlusion": 1, "mixed": 3, "turning": 1}
_LOW = (0.04, 0.04, 0.035)  # half extents of the low object that gets crossed
_SMALL = (0.03, 0.03, 0.035)  # half extents of the small object that hides behind an occluder


def _upright(kind: str, half_extents: tuple) -> Box | Cylinder:
    """``Box(half_extents)``; for ``kind="cylinder"`` the cylinder of radius ``a``, half height ``c``."""
    a, b, c = half_extents
    return Box((a, b, c)) if kind == "box" else Cylinder(a, c)


def _scenario_script(scenario: str, kinds: Sequence[str]) -> tuple[dict, tuple | None]:
    """What a scripted scenario places, as data: no randomness here.

    Returns
    -------
    paths : dict[int, (Box | Cylinder, (float, float), (float, float))]
        Object id -> (shape, start, end) of a straight path on the table (world x-y at t = 0 and at
        the end of the sequence); empty for ``"default"``.
    occluder : ((float, float, float), (float, float)) or None
        Half extents and world x-y of the static box standing on the table.
    """
    if scenario == "crossing":
        # a tall object 1 near the camera crosses in front of a low object 2 further away
        s1, s2 = _upright(kinds[0], (0.05, 0.045, 0.09)), _upright(kinds[1], _LOW)
        y1, y2 = 0.02 + s1.radius, 0.40 - s2.radius
        x = _X_RANGE[1] - max(s1.radius, s2.radius) - 0.01
        return {1: (s1, (-x, y1), (x, y1)), 2: (s2, (x, y2), (-x, y2))}, None
    if scenario == "occlusion":
        # object 1 (small, low) slides behind a static tall box standing between it and the camera
        s1 = _upright(kinds[0], _SMALL)
        return {1: (s1, (-0.26, 0.36), (0.26, 0.36))}, ((0.075, 0.03, 0.13), (0.0, 0.10))
    if scenario == "mixed":
        # the crossing pair on shorter paths: 1 (taller, near) passes in front of 2 (low, middle of the
        # table) around the middle of the sequence; and 3 (small, far) slides behind a static box
        s1, s2 = _upright(kinds[0], (0.045, 0.04, 0.11)), _upright(kinds[1], _LOW)
        s3 = _upright(kinds[2], _SMALL)
        y1, y3 = 0.01 + s1.radius, 0.44 - s3.radius
        paths = {1: (s1, (-0.2, y1), (0.16, y1)), 2: (s2, (0.2, 0.22), (-0.2, 0.22)),
                 3: (s3, (-0.05, y3), (0.3, y3))}
        return paths, ((0.05, 0.02, 0.07), (0.15, 0.31))
    if scenario == "turning":
        return _turning_script(), None
    return {}, None


# ----------------------------------------------------------------------------------------------
# the turning scenario (issue 15): an object on a circular arc, turning with it
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ArcTrajectory:
    r"""Rigid motion on a circle of the table: a constant rotation about a vertical axis.

    The centre follows :math:`p(t) = c + \rho\,(\cos\phi(t), \sin\phi(t))` at height :math:`z`
    with :math:`\phi(t) = \phi_0 + \omega t`, and the object turns with its path: heading
    :math:`\phi(t) + \pi/2` (the tangent), so the whole body rotates at :math:`\omega` about the
    vertical axis through :math:`c` (speed :math:`|\omega|\rho`, yaw rate :math:`\omega`). The
    interface of :class:`PlanarTrajectory` (``position``, ``pose``).

    Parameters
    ----------
    center : (float, float)
        :math:`c`, world x-y (m).
    radius : float
        :math:`\rho` (m).
    omega : float
        Angular speed (rad/s), positive = counter-clockwise seen from above.
    phase : float
        :math:`\phi_0` (rad).
    z : float
        Height of the object's centre above the table.

    Examples
    --------
    >>> tr = ArcTrajectory((0.0, 0.0), 1.0, omega=np.pi / 2, phase=0.0, z=0.1)
    >>> np.round(tr.pose(1.0)[:3, 3], 12).tolist(), np.round(tr.pose(1.0)[:2, 0], 12).tolist()
    ([0.0, 1.0, 0.1], [-1.0, 0.0])
    """

    center: tuple
    radius: float
    omega: float
    phase: float
    z: float

    def position(self, t) -> np.ndarray:
        """World position of the centre at time(s) ``t``: shape (3,) for a scalar, (len(t), 3) else."""
        phi = self.phase + self.omega * np.asarray(t, dtype=float)
        cx, cy = self.center
        xy = np.stack([cx + self.radius * np.cos(phi), cy + self.radius * np.sin(phi)], axis=-1)
        return np.concatenate([xy, np.full((*xy.shape[:-1], 1), float(self.z))], axis=-1)

    def pose(self, t: float) -> np.ndarray:
        """Object-to-world transform :math:`T_{wo}(t)`, shape (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = _rot_z(self.phase + self.omega * t + np.pi / 2)
        T[:3, 3] = self.position(t)
        return T


#: the turning object: an upright cylinder (its visible-surface centroid turns with its centre)
_TURNING_SHAPE = (0.045, 0.045, 0.05)
_TURNING_ARC = {"center": (0.0, 0.2), "radius": 0.13, "omega": 1.0, "phase": -np.pi / 2}


def _turning_script() -> dict:
    """Object 1 of the ``"turning"`` scenario: a cylinder going around an arc at 1 rad/s (0.13 m/s)."""
    shape = _upright("cylinder", _TURNING_SHAPE)
    return {1: (shape, ArcTrajectory(**_TURNING_ARC, z=shape.half_height))}


def _static_occluder(half_extents: tuple, xy: tuple, T_cw: np.ndarray, duration: float, tex: float):
    """The grey box standing on the table at world ``xy`` (a label-0 Body) and its footprint disc."""
    occ = Box(half_extents)
    T_wocc = np.eye(4)
    T_wocc[:3, 3] = [xy[0], xy[1], occ.half_extents[2]]
    body = Body(occ, T_cw @ T_wocc, 0, (110.0, 110.0, 110.0), 0.03 * tex)
    return body, (PlanarTrajectory(xy, xy, duration, 0.0), occ.radius)


def _parse_options(options: dict) -> dict:
    unknown = set(options) - set(_OPTIONS)
    if unknown:
        raise TypeError(f"make_scene got unknown option(s) {sorted(unknown)}; known: {sorted(_OPTIONS)}")
    opts = {**_OPTIONS, **options}
    if opts["scenario"] not in SCENARIOS:
        raise ValueError(f"scenario must be one of {SCENARIOS}, got {opts['scenario']!r}")
    sp = as_array(opts["speed"], "speed", (2,))
    if sp[0] <= 0 or sp[1] < sp[0]:
        raise ValueError(f"speed must be (low, high) with 0 < low <= high, got {sp.tolist()}")
    opts["speed"] = (float(sp[0]), float(sp[1]))
    opts["max_angular_speed"] = nonnegative(opts["max_angular_speed"], "max_angular_speed")
    opts["bend"] = nonnegative(opts["bend"], "bend")
    return opts


def make_scene(
    n_objects: int = 3,
    n_frames: int = 30,
    image_size: tuple[int, int] = (240, 320),
    dt: float = 0.1,
    noise: float = 0.002,
    seed: int | None = 0,
    **options,
) -> Scene:
    r"""Render a synthetic RGB-D sequence of rigid objects moving on a table.

    The camera (focal length :math:`0.9\,W` px, principal point at the image centre) sits 0.65 m
    above the table and looks down at about 40°; a back wall closes the view, so every pixel has a
    valid depth. Objects (boxes and upright cylinders, 6–16 cm) translate on slightly curved paths
    at ``speed`` m/s and spin about the vertical axis; they never collide and stay in view.

    Parameters
    ----------
    n_objects : int, >= 0
        Number K of moving objects (ids 1..K).
    n_frames : int, >= 1
    image_size : (int, int)
        ``(H, W)`` in pixels, each >= 8.
    dt : float, > 0
        Frame interval in seconds.
    noise : float, >= 0
        Standard deviation (m) of the Gaussian noise added to the depth Z (and the points).
    seed : int or None
        Everything (shapes, colours, motions, noise) is a deterministic function of the seed.
    **options
        ``scenario`` : ``"default"`` (random motions), ``"crossing"`` (objects 1 and 2 move in
        opposite directions at different distances from the camera, so their images cross and 1
        passes in front of 2 around the middle of the sequence; needs ``n_objects >= 2``) or
        ``"occlusion"`` (a static tall box, label 0, hides object 1 completely for a few frames
        in the middle; needs ``n_objects >= 1``) or ``"mixed"`` (both at once, the demo's scene:
        objects 1 and 2 cross as in ``"crossing"`` on shorter paths, object 3 slides behind a
        static box on the right and is hidden for a few frames just after the middle; needs
        ``n_objects >= 3``) or ``"turning"`` (object 1, a cylinder, goes around a circular arc of
        radius 0.13 m at 1 rad/s, turning with it: :class:`ArcTrajectory`; needs
        ``n_objects >= 1``). Remaining objects move randomly.
        ``shapes`` : sequence of ``"box"``/``"cylinder"`` per object (default: alternate, random
        start). ``speed`` : ``(low, high)`` translation speed range in m/s (default (0.06, 0.15)).
        ``max_angular_speed`` : rad/s (default 0.8). ``bend`` : maximal lateral bulge of a path
        in m (default 0.08). ``wall`` : add the back wall (default True). ``texture`` : checker
        textures on table and objects (default True), so optical flow has something to track.

    Returns
    -------
    Scene
        ``scene.frames[i]`` holds ``depth``, ``rgb``, ``points``, ``labels``, ``gt_flow``,
        ``gt_poses``, ``visible``, ``pixels`` ... (see :class:`Frame`).

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    RuntimeError
        The objects do not fit: no non-colliding paths in the workspace after repeated placement
        rounds (about 6 objects at the default speeds and 24 frames is where this starts).

    Examples
    --------
    >>> scene = make_scene(n_objects=2, n_frames=2, image_size=(48, 64), noise=0.0, seed=1)
    >>> f = scene.frames[0]
    >>> f.depth.shape, f.rgb.dtype, f.points.shape == (48 * 64, 3)
    ((48, 64), dtype('uint8'), True)
    >>> sorted(set(f.labels.tolist())) == [0, 1, 2] and sorted(f.gt_poses) == [1, 2]
    True
    >>> X, v, k = f.points, f.gt_flow, f.labels
    >>> T0, T1 = f.gt_poses[1], scene.frames[1].gt_poses[1]
    >>> Y = (X[k == 1] + v[k == 1] * scene.dt) @ T1[:3, :3] - T1[:3, 3] @ T1[:3, :3]
    >>> Z = X[k == 1] @ T0[:3, :3] - T0[:3, 3] @ T0[:3, :3]   # same material point, object frame
    >>> bool(np.allclose(Y, Z, atol=1e-12))
    True
    """
    n_objects = positive_int(n_objects, "n_objects", minimum=0)
    n_frames = positive_int(n_frames, "n_frames", minimum=1)
    if isinstance(image_size, (str, bytes)) or not isinstance(image_size, Sequence) or len(image_size) != 2:
        raise ValueError(f"image_size must be a pair (H, W), got {image_size!r}")
    H = positive_int(image_size[0], "image_size[0]", minimum=8)
    W = positive_int(image_size[1], "image_size[1]", minimum=8)
    dt = positive(dt, "dt")
    noise = nonnegative(noise, "noise")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)):
        raise TypeError(f"seed must be an int or None, got {type(seed).__name__}")
    opts = _parse_options(options)
    scenario = opts["scenario"]
    needed = _SCENARIO_MIN_OBJECTS.get(scenario, 0)
    if n_objects < needed:
        raise ValueError(f"n_objects must be >= {needed} for scenario={scenario!r}, got {n_objects}")

    rng = np.random.default_rng(seed)
    noise_rng = np.random.default_rng(rng.integers(2**63))
    cam, T_wc = _default_camera((H, W))
    T_cw = np.linalg.inv(T_wc)
    duration = n_frames * dt  # the motion is defined up to t_n (flow of the last frame)
    times = np.linspace(0.0, duration, 4 * n_frames + 1)

    # shapes
    shapes_opt = opts["shapes"]
    if shapes_opt is None:
        start = int(rng.integers(2))
        kinds = [("box", "cylinder")[(start + i) % 2] for i in range(n_objects)]
    else:
        if isinstance(shapes_opt, str) or len(shapes_opt) != n_objects:
            raise ValueError(f"shapes must be a sequence of {n_objects} 'box'/'cylinder', got {shapes_opt!r}")
        kinds = list(shapes_opt)
        for s in kinds:
            if s not in ("box", "cylinder"):
                raise ValueError(f"shapes entries must be 'box' or 'cylinder', got {s!r}")
    objects = {k + 1: _random_shape(rng, kinds[k]) for k in range(n_objects)}
    palette_order = rng.permutation(len(_PALETTE))
    colors = {k: _PALETTE[palette_order[(k - 1) % len(_PALETTE)]].copy() for k in objects}

    # static bodies: table, wall, occluder
    tex = 1.0 if opts["texture"] else 0.0  # texture cell sizes are multiplied by this
    static_bodies = [Body(Plane(), T_cw.copy(), 0, (185.0, 160.0, 120.0), 0.05 * tex)]
    if opts["wall"]:
        T_ww = np.eye(4)  # wall frame: z towards the camera (-y world), origin at y = 1.0
        T_ww[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
        T_ww[:3, 3] = [0.0, 1.0, 0.0]
        static_bodies.append(Body(Plane(), T_cw @ T_ww, 0, (150.0, 170.0, 190.0), 0.1 * tex))
    # scripted objects (straight paths, random spin) replace the first random shapes; the rest move randomly
    paths, occluder = _scenario_script(scenario, kinds)
    static_discs = []
    if occluder is not None:
        body, disc = _static_occluder(*occluder, T_cw, duration, tex)
        static_bodies.append(body)
        static_discs = [disc]
    trajectories: dict[int, PlanarTrajectory] = {}
    placed = []
    for k, (shape, *path) in paths.items():
        objects[k] = shape
        # a scripted path is (start, end) of a straight path, or a trajectory of its own (an arc)
        if len(path) == 1:
            trajectories[k] = path[0]
        else:
            trajectories[k] = _straight_trajectory(rng, *path, duration, shape, opts)
        placed.append((trajectories[k], shape.radius))
    trajectories.update(_random_trajectories(rng, objects, trajectories, duration, opts, placed, times,
                                             static_discs))

    light_c = T_cw[:3, :3] @ _LIGHT_W
    dirs = ray_directions(cam).reshape(H, W, 3)
    static_rc = _empty_cast(H, W)
    _cast_into(static_rc, cam, dirs, static_bodies, 0)
    static_rgb = _shade(static_rc, static_bodies, light_c).reshape(H, W, 3)
    n_static = len(static_bodies)
    frames = []
    # object-to-camera poses at t_0 .. t_n (frame i moves from pose i to pose i + 1)
    all_poses = [{k: T_cw @ trajectories[k].pose(i * dt) for k in objects} for i in range(n_frames + 1)]
    for i in range(n_frames):
        t0 = i * dt
        poses, poses_next = all_poses[i], all_poses[i + 1]
        moving = [
            Body(objects[k], poses[k], k, tuple(colors[k]), 0.02 if opts["texture"] else 0.0) for k in objects
        ]
        rc = _copy_cast(static_rc)
        _cast_into(rc, cam, dirs, moving, n_static)
        bodies = list(static_bodies) + moving
        on_obj = rc.body >= n_static
        rgb = static_rgb.copy()
        rgb[on_obj] = _shade(rc, bodies, light_c, on_obj)
        valid = rc.depth > 0
        depth_gt = rc.depth
        depth = depth_gt.copy()
        if noise > 0:
            depth[valid] += noise_rng.normal(0.0, noise, int(valid.sum()))
            depth[valid] = np.maximum(depth[valid], 1e-6)
        points = backproject(depth, cam)[valid]
        X = backproject(depth_gt, cam)[valid]
        labels = rc.label[valid].astype(np.int64)
        flow = np.zeros_like(X)
        for k in objects:
            m = labels == k
            if m.any():
                M = poses_next[k] @ np.linalg.inv(poses[k])
                flow[m] = (apply_transform(M, X[m]) - X[m]) / dt
        visible = {k: int(np.count_nonzero(rc.label == k)) for k in objects}
        frames.append(
            Frame(
                index=i,
                time=t0,
                depth=depth,
                depth_gt=depth_gt,
                rgb=rgb,
                label_image=rc.label,
                points=points,
                labels=labels,
                gt_flow=flow,
                gt_poses=poses,
                visible=visible,
                _camera=cam,
                _gt_points=X,
            )
        )
    return Scene(
        camera=cam,
        dt=dt,
        frames=frames,
        camera_pose=T_wc,
        objects=objects,
        trajectories=trajectories,
        static_bodies=static_bodies,
        colors=colors,
        scenario=scenario,
    )
