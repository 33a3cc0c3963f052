r"""Shapes of the synthetic scenes and their motion: analytic ray intersection, planar trajectories.

:class:`Box`, :class:`Cylinder` and :class:`Plane` intersect a bundle of rays in their own frame
(slab method, a quadratic plus two caps, one division); a :class:`Body` places a shape in the camera
frame with a label, colour and texture; a :class:`PlanarTrajectory` moves an object on the table,
analytic in time. Part of :mod:`flowtrack.synth`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import as_array, positive

__all__ = ["ArcTrajectory", "Body", "Box", "Cylinder", "PlanarTrajectory", "Plane"]


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


