r"""Step 1 of the pipeline: depth images → point clouds, and the support planes (part of
:mod:`flowtrack.pipeline`).

- :func:`cloud_from_depth` back-projects every valid pixel :math:`(u, v)` of depth :math:`Z`,
  :math:`X = Z\,K^{-1}(u, v, 1)^\top` (camera frame, metres), in row-major pixel order — the order
  of a synthetic frame's ground truth — or thinned by open3d's voxel grid to one point (the mean) per
  occupied voxel;
- :func:`subsample` draws the random subset of a cloud the later steps work on;
- :func:`support_planes` marks the points of the largest planes (table, walls) by open3d's RANSAC,
  up to ``max_planes`` planes each holding at least ``plane_min_share`` of the cloud: graph
  smoothing spreads an object's motion into the table it stands on, so the detections
  (:mod:`flowtrack.pipeline`'s step 3) leave these points out;
- :func:`open3d_threads` limits open3d's threads, which makes RANSAC and ICP repeatable bit for bit.

Import these names from :mod:`flowtrack.pipeline`, which exports (and documents) them.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from .._validation import nonnegative, positive, positive_int
from ..camera import backproject
from ._config import PipelineConfig

__all__ = ["cloud_from_depth", "moving_first_subsample", "open3d_threads", "subsample", "support_planes"]


def subsample(n: int, max_points: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of a random subset of ``max_points`` of ``range(n)`` (all of them if fewer).

    Examples
    --------
    >>> subsample(5, 10, np.random.default_rng(0))
    array([0, 1, 2, 3, 4])
    >>> idx = subsample(100, 10, np.random.default_rng(0))
    >>> len(idx), bool(np.all(np.diff(idx) > 0))
    (10, True)
    """
    if n <= max_points:
        return np.arange(n)
    return np.sort(rng.choice(n, size=max_points, replace=False))


def moving_first_subsample(speeds, max_points: int, min_speed: float, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of at most ``max_points`` points, every point at least ``min_speed`` fast first.

    A random subsample (:func:`subsample`) keeps each point with the same probability, so a budget
    spent mostly on a room's walls and floor leaves a small or far object with too few points to be
    detected: a 640x480 Kinect-like view holds 110k-170k points on a 1 cm voxel grid, and 30 000 of
    them keep a quarter of an object's points. The points that move are what the motion clustering and
    the detector look at, so they are all kept (a random subset of them when they alone exceed the
    budget), and the rest of the budget is a random subsample of the others (the support planes, the
    static scenery and the geometric static test still see them).

    Parameters
    ----------
    speeds : array_like, shape (N,)
        Each point's speed (m/s), e.g. the norm of its scene flow; NaN counts as slow.
    max_points : int, >= 1
    min_speed : float, >= 0
        Points at least this fast are kept first.
    rng : numpy.random.Generator

    Examples
    --------
    >>> speeds = np.array([0.0, 0.5, 0.0, 0.0, 0.3, 0.0])
    >>> idx = moving_first_subsample(speeds, 3, 0.1, np.random.default_rng(0))
    >>> len(idx), {1, 4} <= set(idx.tolist())  # both moving points, one static one
    (3, True)
    >>> moving_first_subsample(speeds, 10, 0.1, np.random.default_rng(0)).tolist()
    [0, 1, 2, 3, 4, 5]
    """
    v = np.asarray(speeds, dtype=np.float64)
    if v.ndim != 1:
        raise ValueError(f"speeds must have shape (N,), got {v.shape}")
    max_points = positive_int(max_points, "max_points")
    min_speed = nonnegative(min_speed, "min_speed")
    n = len(v)
    if n <= max_points:
        return np.arange(n)
    fast = np.flatnonzero(np.nan_to_num(v, nan=0.0) >= min_speed)
    if len(fast) >= max_points:
        return fast[subsample(len(fast), max_points, rng)]
    slow = np.setdiff1d(np.arange(n), fast, assume_unique=True)
    return np.sort(np.concatenate([fast, slow[subsample(len(slow), max_points - len(fast), rng)]]))


def cloud_from_depth(depth, camera, *, max_depth: float | None = None, voxel: float = 0.0) -> np.ndarray:
    r"""The point cloud of a depth image: :math:`X = Z\,K^{-1}(u, v, 1)^\top` for every valid pixel.

    Parameters
    ----------
    depth : array_like, shape (H, W)
        Depth Z in metres; 0, negative or non-finite values mark pixels without a measurement.
    camera : flowtrack.camera.PinholeCamera
    max_depth : float, optional
        Farther pixels are dropped too (m).
    voxel : float
        With ``voxel > 0`` the cloud is thinned by open3d's voxel grid of that size (m): one point
        (the mean) per occupied voxel, an even density for real sensors. 0 keeps every pixel.

    Returns
    -------
    ndarray, shape (N, 3)
        Camera coordinates; without ``voxel`` the valid pixels in row-major order (the order of a
        synthetic frame's ground truth, :attr:`flowtrack.synth.Frame.points`).
    """
    Z = np.asarray(depth, dtype=np.float64)
    if Z.ndim != 2:
        raise ValueError(f"depth must be an (H, W) image, got shape {Z.shape}")
    voxel = nonnegative(voxel, "voxel")
    valid = np.isfinite(Z) & (Z > 0)
    if max_depth is not None:
        valid &= Z <= positive(max_depth, "max_depth")
    P = backproject(np.where(valid, Z, 0.0), camera)[valid]
    if voxel > 0 and len(P):
        import open3d as o3d

        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
        P = np.asarray(pc.voxel_down_sample(voxel).points)
    return P


@contextmanager
def open3d_threads(n: int) -> Iterator[None]:
    """Limit open3d to ``n`` CPU threads inside a ``with`` block; the previous limit is restored after.

    open3d runs its loops on several threads (oneTBB from 0.20 on, OpenMP before), and the result
    of some depends on their timing: ``segment_plane`` (RANSAC) hands out the random samples of one
    seeded generator in whatever order the threads ask for them, so the best plane and its inliers
    change from run to run, and ``registration_icp`` adds up its residuals in a timing-dependent
    order. With one thread both are repeatable bit for bit. The limit holds for the whole process:
    ``open3d.utility.set_max_threads`` (open3d >= 0.20), else (0.19, OpenMP) threadpoolctl's limit of
    the OpenMP runtimes, which also holds for the other libraries that use them. Also a decorator.

    Parameters
    ----------
    n : int, >= 1

    Examples
    --------
    >>> import open3d as o3d
    >>> if hasattr(o3d.utility, "get_max_threads"):
    ...     before = o3d.utility.get_max_threads()
    ...     with open3d_threads(1):
    ...         assert o3d.utility.get_max_threads() == 1
    ...     assert o3d.utility.get_max_threads() == before
    """
    import open3d as o3d

    n = positive_int(n, "n")
    if not hasattr(o3d.utility, "set_max_threads"):  # open3d 0.19: OpenMP
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=n, user_api="openmp"):
            yield
        return
    previous = o3d.utility.get_max_threads()
    o3d.utility.set_max_threads(n)
    try:
        yield
    finally:
        o3d.utility.set_max_threads(0)  # no limit: the automatic default ...
        if o3d.utility.get_max_threads() != previous:  # ... unless a limit had been set before
            o3d.utility.set_max_threads(previous)


def support_planes(points, config: PipelineConfig | None = None) -> np.ndarray:
    """Mask of the points on the largest planes (table, walls): open3d RANSAC, up to ``max_planes``.

    A plane counts when it holds at least ``plane_min_share`` of the points; inliers are within
    ``plane_threshold`` of it (both from ``config``). Returns a bool array of shape (N,). The RANSAC
    samples come from open3d's generator seeded with 0 and drawn by one thread
    (:func:`open3d_threads`), so the same points always give the same mask.
    """
    import open3d as o3d

    cfg = config if config is not None else PipelineConfig()
    P = np.asarray(points, dtype=np.float64)
    on = np.zeros(len(P), dtype=bool)
    rest = np.arange(len(P))
    with open3d_threads(1):
        o3d.utility.random.seed(0)
        for _ in range(cfg.max_planes):
            if len(rest) < 3:
                break
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P[rest]))
            _, inl = pc.segment_plane(cfg.plane_threshold, 3, 200)
            if len(inl) < cfg.plane_min_share * len(P):
                break
            inl = np.asarray(inl, dtype=np.intp)
            on[rest[inl]] = True
            rest = np.delete(rest, inl)
    return on
