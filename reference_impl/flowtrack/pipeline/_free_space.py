"""Where a depth camera saw through: the evidence that a coasting track's object is gone.

A tracked object that is not detected in a frame is either hidden (something nearer stands in front
of where it should be) or not there (it left, stopped, or the track never was an object). The depth
image tells the two apart: at the pixel where the track's predicted position projects, a surface
nearer than the position hides it; a surface well *behind* it means the sensor looked through the
place where the object should be and saw none. Coasting the track on through free space reports an
object where the sensor sees none, and a user's robot would act on that row.

:class:`FreeSpace` holds one depth image reduced to a coarse grid, each cell its readings' low
quantile (robust to the sensor's holes and flying pixels, and small enough to record with the
tracker's inputs), and answers :meth:`flowtrack.tracking.MultiObjectTracker.step`'s
``seen_through`` question: for positions ``X`` (K, 3) in the camera frame, ``True`` where that
quantile is more than ``margin`` beyond ``X``'s depth, i.e. nearly all of the cell looks past the
position. A low quantile rather than the median: a small object (a far sphere of a hundred pixels)
covers only part of the cell its centroid falls in, and while it is there, that part must be
enough to say "not seen through" (with the median, training sequence 2000 of
``benchmarks/_evalscenes.py`` lost such a sphere's track at a single missed detection and
switched its identity twice). Positions outside the image, behind the camera, or over cells with
too few depth readings are not seen through (nothing is known there).
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validation import as_array, positive, positive_int

__all__ = ["FreeSpace"]


class FreeSpace:
    """A depth image's free space, for :meth:`MultiObjectTracker.step`'s ``seen_through``.

    Parameters
    ----------
    depth : array_like, shape (H, W)
        Depth (m) along the optical axis; 0 or NaN where the sensor has no reading.
    camera : PinholeCamera
        Its intrinsics (``fx, fy, cx, cy``).
    margin : float, default 0.1
        How far (m) behind a position the surface must be for the position to count as seen
        through: more than a tabletop object's depth, so that the object's own far side or the
        table right under it does not count.
    cell : int, optional
        Cell size (px) of the median grid; default ``max(1, round(min(H, W) / 30))`` (8 px at
        320x240), about a small object's image size at a metre.
    min_valid : float, default 0.25
        Share of a cell's pixels that must have a depth reading for the cell to count.
    quantile : float, default 0.2
        The cell's depth is this quantile of its readings: a position counts as seen through only
        if more than this share of the cell looks past it.

    Examples
    --------
    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(100.0, 100.0, 31.5, 23.5)
    >>> depth = np.full((48, 64), 2.0)          # a wall 2 m away
    >>> depth[:, :20] = 0.8                     # a box in front of its left part
    >>> fs = FreeSpace(depth, cam)
    >>> fs(np.array([[0.0, 0.0, 1.0],           # centre, 1 m: the wall is seen behind it
    ...              [-0.2, 0.0, 1.0],          # left, 1 m: the box (0.8 m) would hide it
    ...              [0.0, 0.0, 1.95]])).tolist()  # on the wall: not 10 cm behind
    [True, False, False]
    """

    def __init__(self, depth, camera, margin: float = 0.1, cell: int | None = None, min_valid: float = 0.25,
                 quantile: float = 0.2):
        D = as_array(depth, "depth", ("H", "W"), finite=False)
        if np.isinf(D).any():
            raise ValueError("depth must not contain inf (0 or NaN mark a missing reading)")
        self.margin = positive(margin, "margin")
        H, W = D.shape
        self.cell = positive_int(cell if cell is not None else max(1, round(min(H, W) / 30)), "cell")
        if not 0.0 < float(min_valid) <= 1.0:
            raise ValueError(f"min_valid must be in (0, 1], got {min_valid!r}")
        if not 0.0 <= float(quantile) <= 1.0:
            raise ValueError(f"quantile must be in [0, 1], got {quantile!r}")
        self.fx, self.fy, self.cx, self.cy = (float(camera.fx), float(camera.fy), float(camera.cx),
                                              float(camera.cy))
        self.shape = (H, W)
        c = self.cell
        gh, gw = -(-H // c), -(-W // c)
        pad = np.full((gh * c, gw * c), np.nan)
        pad[:H, :W] = np.where(D > 0, D, np.nan)
        blocks = pad.reshape(gh, c, gw, c).transpose(0, 2, 1, 3).reshape(gh, gw, c * c)
        valid = np.isfinite(blocks).sum(axis=2)
        # a cell's low quantile over its readings; too few readings: unknown (NaN)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN cells
            med = np.nanquantile(blocks, float(quantile), axis=2)
        med[valid < float(min_valid) * c * c] = np.nan
        self.grid = med.astype(np.float32)

    def __call__(self, positions) -> np.ndarray:
        """Bool (K,): the sensor saw more than ``margin`` past each position (camera frame, m)."""
        X = as_array(positions, "positions", (None, 3))
        H, W = self.shape
        out = np.zeros(len(X), dtype=bool)
        front = X[:, 2] > 1e-6
        if not front.any():
            return out
        Xf = X[front]
        u = np.floor(self.fx * Xf[:, 0] / Xf[:, 2] + self.cx + 0.5).astype(np.int64)
        v = np.floor(self.fy * Xf[:, 1] / Xf[:, 2] + self.cy + 0.5).astype(np.int64)
        inside = (u >= 0) & (u < W) & (v >= 0) & (v < H)
        behind = np.zeros(len(Xf), dtype=bool)
        z = self.grid[v[inside] // self.cell, u[inside] // self.cell]
        with np.errstate(invalid="ignore"):
            behind[inside] = z > Xf[inside, 2] + self.margin  # NaN (unknown) compares False
        out[front] = behind
        return out
