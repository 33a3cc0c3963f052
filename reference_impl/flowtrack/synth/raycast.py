r"""Exact ray casting of the synthetic scenes with a z-buffer, and their shading.

The ray through pixel :math:`(r, c)` (row, column) is :math:`X(s) = s\,d`,
:math:`d = ((c - c_x)/f_x,\ (r - c_y)/f_y,\ 1)^\top`, so the ray parameter :math:`s` *is* the depth
:math:`Z`. Every shape of :mod:`flowtrack.synth.shapes` is intersected analytically for all pixels
of its image rectangle at once and a z-buffer keeps the nearest hit, so occlusion is exact.
:func:`ray_cast` is the public entry; :func:`empty_cast`, :func:`cast_into`, :func:`copy_cast` and
:func:`shade` are the steps :func:`flowtrack.synth.make_scene` runs (the static bodies are cast
once, each frame adds the moving ones to a copy). Part of :mod:`flowtrack.synth`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._graph import apply_transform
from .._validation import as_array
from ..camera import PinholeCamera, backproject, check_camera, project
from .shapes import Body, Box, Cylinder

__all__ = [
    "RayCast",
    "cast_into",
    "copy_cast",
    "empty_cast",
    "look_at",
    "ray_cast",
    "ray_directions",
    "shade",
]


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
    cam = check_camera(camera, "camera", require_size=True)
    return backproject(np.ones((cam.height, cam.width)), cam).reshape(-1, 3)  # depth Z = 1


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


def cast_into(rc: RayCast, cam: PinholeCamera, dirs: np.ndarray, bodies, offset: int) -> None:
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


def empty_cast(H: int, W: int) -> RayCast:
    """A :class:`RayCast` of an ``H × W`` image that hits nothing yet (depth 0, body and label -1)."""
    return RayCast(
        depth=np.zeros((H, W)),
        body=np.full((H, W), -1, dtype=np.int64),
        label=np.full((H, W), -1, dtype=np.int64),
        normal=np.zeros((H, W, 3)),
        local=np.full((H, W, 3), np.nan),
    )


def copy_cast(rc: RayCast) -> RayCast:
    """An independent copy of ``rc`` (every buffer copied), e.g. to add bodies to a cast static scene."""
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
    >>> from flowtrack.synth import Plane
    >>> cam = PinholeCamera(10.0, 10.0, 1.0, 1.0, width=3, height=3)
    >>> T = np.eye(4); T[2, 3] = 2.0                    # a plane z = 2 facing the camera
    >>> ray_cast(cam, [Body(Plane(), T)]).depth
    array([[2., 2., 2.],
           [2., 2., 2.],
           [2., 2., 2.]])
    """
    cam = check_camera(camera, "camera", require_size=True)
    H, W = cam.height, cam.width
    dirs = ray_directions(cam) if dirs is None else as_array(dirs, "dirs", (H * W, 3))
    rc = empty_cast(H, W)
    cast_into(rc, cam, dirs.reshape(H, W, 3), list(bodies), 0)
    return rc


def shade(rc: RayCast, bodies: Sequence[Body], light_c: np.ndarray, mask: np.ndarray | None = None):
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
