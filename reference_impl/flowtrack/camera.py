r"""Pinhole camera geometry and the link between scene flow and optical flow.

A point :math:`X = (X, Y, Z)^\top` in camera coordinates projects to

.. math::  \pi(X) = \begin{bmatrix} f_x X / Z + c_x \\ f_y Y / Z + c_y \end{bmatrix},

with Jacobian

.. math::  \frac{\partial \pi}{\partial X} =
   \begin{bmatrix} f_x/Z & 0 & -f_x X/Z^2 \\ 0 & f_y/Z & -f_y Y / Z^2 \end{bmatrix}.

A scene flow :math:`v` moves the point by :math:`v\,\Delta t` and, to first order, its image by the
optical flow :math:`u = (\partial\pi/\partial X)\, v\, \Delta t` (syllabus section 2, Problem 1).
Every function is vectorised over points or pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validation import as_array, positive, scalar

__all__ = [
    "PinholeCamera",
    "project",
    "projection_jacobian",
    "backproject",
    "backproject_pixels",
    "check_camera",
    "depth_from_disparity",
    "optical_flow_from_scene_flow",
    "scene_flow_from_optical_flow",
]


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics of a pinhole camera (pixels).

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels (> 0).
    cx, cy : float
        Principal point in pixels.
    width, height : int, optional
        Image size in pixels, when known.

    Examples
    --------
    >>> cam = PinholeCamera(500.0, 500.0, 320.0, 240.0)
    >>> cam.K
    array([[500.,   0., 320.],
           [  0., 500., 240.],
           [  0.,   0.,   1.]])
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int | None = None
    height: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "fx", positive(self.fx, "fx"))
        object.__setattr__(self, "fy", positive(self.fy, "fy"))
        for name in ("cx", "cy"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise TypeError(f"{name} must be a real number, got {type(v).__name__}")
            if not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v}")
            object.__setattr__(self, name, float(v))
        for name in ("width", "height"):
            v = getattr(self, name)
            if v is not None:
                if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                    raise TypeError(f"{name} must be an int or None, got {type(v).__name__}")
                if v <= 0:
                    raise ValueError(f"{name} must be > 0, got {v}")
                object.__setattr__(self, name, int(v))

    @property
    def K(self) -> np.ndarray:
        """The 3×3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def from_K(cls, K, width: int | None = None, height: int | None = None) -> PinholeCamera:
        """Build a camera from a 3×3 intrinsic matrix (zero skew)."""
        K = as_array(K, "K", (3, 3))
        if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
            raise ValueError("K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")
        return cls(K[0, 0], K[1, 1], K[0, 2], K[1, 2], width, height)


def check_camera(cam, name: str = "cam", *, require_size: bool = False) -> PinholeCamera:
    """Check that ``cam`` is a :class:`PinholeCamera` (with ``width`` and ``height`` if required).

    Parameters
    ----------
    cam : PinholeCamera
    name : str
        The argument's name, used in error messages.
    require_size : bool
        Also require the image size (``width`` and ``height`` not None).

    Returns
    -------
    PinholeCamera
        ``cam`` itself.

    Raises
    ------
    TypeError
        ``cam`` is not a :class:`PinholeCamera`.
    ValueError
        ``require_size`` and the camera has no width or height.

    Examples
    --------
    >>> check_camera(PinholeCamera(1.0, 1.0, 0.0, 0.0), require_size=True)
    Traceback (most recent call last):
    ...
    ValueError: cam must have width and height
    """
    if not isinstance(cam, PinholeCamera):
        raise TypeError(f"{name} must be a PinholeCamera, got {type(cam).__name__}")
    if require_size and (cam.width is None or cam.height is None):
        raise ValueError(f"{name} must have width and height")
    return cam


def _backproject_pixels(u, v, Z, cam: PinholeCamera) -> np.ndarray:
    """``Z · ((u - cx)/fx, (v - cy)/fy, 1)``; no validation (see :func:`backproject_pixels`)."""
    out = np.empty((*np.broadcast_shapes(np.shape(u), np.shape(v), np.shape(Z)), 3))
    out[..., 0] = (u - cam.cx) / cam.fx * Z
    out[..., 1] = (v - cam.cy) / cam.fy * Z
    out[..., 2] = Z
    return out


def backproject_pixels(u, v, Z, cam: PinholeCamera) -> np.ndarray:
    r"""Back-project pixels with known depth: :math:`X = Z\,((u - c_x)/f_x,\ (v - c_y)/f_y,\ 1)`.

    The pixel-wise form of :func:`backproject` for any set of pixels (e.g. every ``step``-th row
    and column of an image).

    Parameters
    ----------
    u, v : array_like
        Column and row coordinates (pixels), finite.
    Z : array_like
        Depths; NaN gives a NaN point (an invalid pixel), inf is rejected.
    cam : PinholeCamera

    ``u``, ``v`` and ``Z`` broadcast against each other.

    Returns
    -------
    ndarray, shape ``broadcast(u, v, Z).shape + (3,)``

    Raises
    ------
    TypeError
        ``cam`` is not a :class:`PinholeCamera`, or non-numeric input.
    ValueError
        Shapes that do not broadcast, NaN or inf in ``u``/``v``, inf in ``Z``.

    Examples
    --------
    >>> cam = PinholeCamera(2.0, 2.0, 1.0, 1.0)
    >>> backproject_pixels([1.0, 3.0], 1.0, [1.0, 2.0], cam)
    array([[0., 0., 1.],
           [2., 0., 2.]])
    """
    cam = check_camera(cam)
    u = as_array(u, "u")
    v = as_array(v, "v")
    Z = as_array(Z, "Z", allow_nan=True)
    try:
        np.broadcast_shapes(u.shape, v.shape, Z.shape)
    except ValueError:
        raise ValueError(f"u, v and Z must broadcast, got shapes {u.shape}, {v.shape}, {Z.shape}") from None
    return _backproject_pixels(u, v, Z, cam)


def _points(X, name: str = "X") -> np.ndarray:
    X = as_array(X, name, ("N", 3))
    if (X[:, 2] <= 0).any():
        raise ValueError(f"{name} must have Z > 0 (points in front of the camera)")
    return X


def project(X, cam: PinholeCamera) -> np.ndarray:
    """Project camera-frame points to pixel coordinates.

    Parameters
    ----------
    X : array_like, shape (N, 3)
        Points in the camera frame, Z > 0.
    cam : PinholeCamera

    Returns
    -------
    ndarray, shape (N, 2)
        Pixel coordinates ``(x, y)``.

    Examples
    --------
    >>> cam = PinholeCamera(100.0, 100.0, 50.0, 40.0)
    >>> project([[0.1, -0.2, 2.0]], cam)
    array([[55., 30.]])
    """
    cam = check_camera(cam)
    X = _points(X)
    x = cam.fx * X[:, 0] / X[:, 2] + cam.cx
    y = cam.fy * X[:, 1] / X[:, 2] + cam.cy
    return np.stack([x, y], axis=1)


def projection_jacobian(X, cam: PinholeCamera) -> np.ndarray:
    r"""Jacobian :math:`\partial\pi/\partial X` of the projection at each point.

    Parameters
    ----------
    X : array_like, shape (N, 3)
        Points in the camera frame, Z > 0.
    cam : PinholeCamera

    Returns
    -------
    ndarray, shape (N, 2, 3)
        ``[[fx/Z, 0, -fx X/Z²], [0, fy/Z, -fy Y/Z²]]`` per point.

    Examples
    --------
    >>> cam = PinholeCamera(100.0, 100.0, 0.0, 0.0)
    >>> projection_jacobian([[1.0, 2.0, 4.0]], cam)[0]
    array([[ 25.  ,   0.  ,  -6.25],
           [  0.  ,  25.  , -12.5 ]])
    """
    cam = check_camera(cam)
    X = _points(X)
    inv_z = 1.0 / X[:, 2]
    J = np.zeros((X.shape[0], 2, 3))
    J[:, 0, 0] = cam.fx * inv_z
    J[:, 0, 2] = -cam.fx * X[:, 0] * inv_z**2
    J[:, 1, 1] = cam.fy * inv_z
    J[:, 1, 2] = -cam.fy * X[:, 1] * inv_z**2
    return J


def backproject(depth, cam: PinholeCamera, depth_scale: float = 1.0) -> np.ndarray:
    """Back-project a depth image to camera-frame points.

    Parameters
    ----------
    depth : array_like, shape (H, W)
        Depth along the optical axis (Z), in units such that ``depth / depth_scale`` is metres
        (e.g. ``depth_scale=5000`` for TUM RGB-D 16-bit PNGs). 0, NaN and inf mark invalid pixels.
    cam : PinholeCamera
    depth_scale : float, > 0

    Returns
    -------
    ndarray, shape (H, W, 3)
        ``X[v, u] = Z · ((u - cx)/fx, (v - cy)/fy, 1)``; NaN at invalid pixels.

    Examples
    --------
    >>> cam = PinholeCamera(1.0, 1.0, 0.0, 0.0)
    >>> backproject([[2.0, 0.0]], cam)[0]
    array([[ 0.,  0.,  2.],
           [nan, nan, nan]])
    """
    cam = check_camera(cam)
    scale = positive(depth_scale, "depth_scale")
    arr = np.asarray(depth)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number):
        raise TypeError(f"depth must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise ValueError(f"depth must have shape (H, W), got {arr.shape}")
    Z = arr.astype(np.float64) / scale
    Z = np.where(np.isfinite(Z) & (Z > 0), Z, np.nan)
    if (np.asarray(depth, dtype=np.float64) < 0).any():
        raise ValueError("depth must be >= 0 (0 or NaN marks an invalid pixel)")
    H, W = Z.shape
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    return _backproject_pixels(u, v, Z, cam)


def depth_from_disparity(disparity, focal_px: float, baseline: float, doffs: float = 0.0) -> np.ndarray:
    r"""Depth :math:`Z = f B / (d + d_\mathrm{offs})` of a rectified stereo pair, 0 where there is none.

    A left-image pixel with disparity :math:`d` (pixels; its match in the right image is :math:`d`
    columns to the left) lies at depth :math:`Z = f B / (d + d_\mathrm{offs})`, with :math:`f` the
    focal length (pixels), :math:`B` the baseline and :math:`d_\mathrm{offs}` the column difference
    of the two principal points (Middlebury's ``doffs``, 0 for most rigs, e.g. KITTI).

    A disparity is invalid where it is NaN or :math:`\pm\infty` (Middlebury's "unknown" is ``inf``)
    or where :math:`d + d_\mathrm{offs} \le 0` (no point in front of the cameras); its depth is 0,
    the package's "no depth" value (as in TUM depth images; :func:`backproject` turns 0 into NaN
    points). A format whose files mark "no measurement" with ``d = 0`` (KITTI and older Middlebury
    PNGs) must be masked first when ``doffs > 0``, since :math:`0 + d_\mathrm{offs} > 0` is a valid
    disparity here.

    Parameters
    ----------
    disparity : array_like
        Disparities in pixels, any shape; NaN and inf mark invalid pixels.
    focal_px : float, > 0
        Focal length :math:`f` in pixels (``fx`` of the rectified left camera).
    baseline : float, > 0
        Distance :math:`B` between the camera centres. The depth has the same unit: give metres
        for the metric depth the rest of the package expects.
    doffs : float
        :math:`d_\mathrm{offs}`, added to the disparity before the division (finite).

    Returns
    -------
    ndarray, float64, same shape as ``disparity``
        :math:`Z`, finite and > 0 at the valid pixels and 0 at the invalid ones (also where
        :math:`f B / (d + d_\mathrm{offs})` overflows).

    Raises
    ------
    TypeError
        A non-numeric ``disparity`` or a non-real scalar argument.
    ValueError
        ``focal_px`` or ``baseline`` not finite and > 0, ``doffs`` not finite (each named).

    Examples
    --------
    >>> depth_from_disparity([[40.0, 20.0, 0.0, np.inf, np.nan]], focal_px=500.0, baseline=0.1)
    array([[1.25, 2.5 , 0.  , 0.  , 0.  ]])
    >>> depth_from_disparity([0.0, -10.0, -20.0], 500.0, 0.1, doffs=10.0)  # -10 + 10 is not > 0
    array([5., 0., 0.])
    """
    d = as_array(disparity, "disparity", finite=False, copy=False)
    f = positive(focal_px, "focal_px")
    B = positive(baseline, "baseline")
    doffs = scalar(doffs, "doffs")
    dd = d + doffs
    valid = np.isfinite(dd) & (dd > 0)
    Z = np.zeros(dd.shape)
    with np.errstate(over="ignore"):
        Z[valid] = f * B / dd[valid]
    Z[~np.isfinite(Z)] = 0.0
    return Z


def optical_flow_from_scene_flow(X, v, dt: float, cam: PinholeCamera) -> np.ndarray:
    """First-order optical flow ``u = J(X) v dt`` induced by scene flow.

    Parameters
    ----------
    X : array_like, shape (N, 3)
        Points at time t (camera frame, Z > 0).
    v : array_like, shape (N, 3)
        Their 3-D velocities.
    dt : float, > 0
    cam : PinholeCamera

    Returns
    -------
    ndarray, shape (N, 2)
        Pixel displacement per point.
    """
    X = _points(X)
    v = as_array(v, "v", (X.shape[0], 3))
    dt = positive(dt, "dt")
    return np.einsum("nij,nj->ni", projection_jacobian(X, cam), v) * dt


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear sampling of ``img (H, W)`` at float pixel coordinates; NaN outside or at NaN taps."""
    H, W = img.shape
    x0 = np.floor(x)
    y0 = np.floor(y)
    ax = x - x0
    ay = y - y0
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    inside = (x0 >= 0) & (y0 >= 0) & (x0 + 1 <= W - 1) & (y0 + 1 <= H - 1)
    # exact hits on the last row/column
    edge = (x >= 0) & (y >= 0) & (x <= W - 1) & (y <= H - 1) & ~inside
    x0c = np.clip(x0, 0, W - 2) if W > 1 else np.zeros_like(x0)
    y0c = np.clip(y0, 0, H - 2) if H > 1 else np.zeros_like(y0)
    x1c = np.minimum(x0c + 1, W - 1)
    y1c = np.minimum(y0c + 1, H - 1)
    axc = np.where(edge, x - x0c, ax)
    ayc = np.where(edge, y - y0c, ay)
    val = (
        img[y0c, x0c] * (1 - axc) * (1 - ayc)
        + img[y0c, x1c] * axc * (1 - ayc)
        + img[y1c, x0c] * (1 - axc) * ayc
        + img[y1c, x1c] * axc * ayc
    )
    return np.where(inside | edge, val, np.nan)


def scene_flow_from_optical_flow(depth_t, depth_t1, flow_uv, dt: float, cam: PinholeCamera) -> np.ndarray:
    """Scene flow from optical flow and two depth maps.

    Pixel ``p`` at time t back-projects to ``X_t(p)``; it moves to ``p + u(p)`` at t+dt, where the
    second depth map (sampled bilinearly) gives ``X_{t+dt}(p + u(p))``. The velocity is
    ``(X_{t+dt}(p + u) - X_t(p)) / dt`` (the depth-constancy link of syllabus section 2).

    Parameters
    ----------
    depth_t, depth_t1 : array_like, shape (H, W)
        Metric depth maps (0 or NaN invalid).
    flow_uv : array_like, shape (H, W, 2)
        Optical flow ``(u_x, u_y)`` in pixels from t to t+dt.
    dt : float, > 0
    cam : PinholeCamera

    Returns
    -------
    ndarray, shape (H, W, 3)
        Velocity per pixel; NaN where either depth is invalid or the flow leaves the image.
    """
    cam = check_camera(cam)
    dt = positive(dt, "dt")
    d0 = as_array(depth_t, "depth_t", ("H", "W"), allow_nan=True)
    d1 = as_array(depth_t1, "depth_t1", d0.shape, allow_nan=True)
    flow = as_array(flow_uv, "flow_uv", (d0.shape[0], d0.shape[1], 2), allow_nan=True)
    for name, d in (("depth_t", d0), ("depth_t1", d1)):
        if (d < 0).any():
            raise ValueError(f"{name} must be >= 0 (0 or NaN marks an invalid pixel)")
    X0 = backproject(d0, cam)
    H, W = d0.shape
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    x1 = u + flow[..., 0]
    y1 = v + flow[..., 1]
    d1n = np.where(d1 > 0, d1, np.nan)
    Z1 = _bilinear(d1n, x1.ravel(), y1.ravel()).reshape(H, W)
    X1 = _backproject_pixels(x1, y1, Z1, cam)
    return (X1 - X0) / dt
