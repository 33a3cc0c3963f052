r"""Tracks you can export: ``tracks.csv`` from a tracker's per-frame output.

One row per live track per frame, tentative and coasting tracks included, columns exactly

``frame,track_id,status,x,y,z,vx,vy,vz``

with ``frame`` the 0-based index of the input frame the position refers to, positions in metres and
velocities in m/s in the frame the detections were given in (the camera frame of that frame for the
demo). Two-dimensional tracks leave ``z`` and ``vz`` empty. Rows are in frame order, then track id.

Examples
--------
>>> import io
>>> import numpy as np
>>> from flowtrack.tracking import MultiObjectTracker
>>> trk = MultiObjectTracker(dt=0.1, q=1.0, r=1e-4, dim=3)
>>> for t in range(2):
...     _ = trk.step(np.array([[0.01 * t, 0.0, 1.0]]))
>>> buf = io.StringIO()
>>> write_tracks_csv(buf, trk)
2
>>> print(buf.getvalue().splitlines()[0])
frame,track_id,status,x,y,z,vx,vy,vz
>>> [r["status"] for r in read_tracks_csv(io.StringIO(buf.getvalue()))]
['tentative', 'confirmed']
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Sequence

import numpy as np

__all__ = ["TRACKS_CSV_COLUMNS", "read_tracks_csv", "tracks_rows", "write_tracks_csv"]

TRACKS_CSV_COLUMNS = ("frame", "track_id", "status", "x", "y", "z", "vx", "vy", "vz")
_STATUSES = ("tentative", "confirmed", "coasting")


def tracks_rows(source, frames: Sequence[int] | None = None) -> list[dict]:
    """The rows of ``tracks.csv`` as dicts (numbers as int / float; 2-D: ``z``, ``vz`` None).

    Parameters
    ----------
    source : MultiObjectTracker or sequence of sequences of Track
        A tracker (its :meth:`~flowtrack.tracking.MultiObjectTracker.history`, every recorded frame,
        tentative tracks included), or one list of tracks per processed frame (e.g. the tracker's
        :attr:`~flowtrack.tracking.MultiObjectTracker.tracks` after each step).
    frames : sequence of int, optional
        Input frame index of each processed frame (default: the tracker's frame counter, or
        0, 1, ... for lists); must have one entry per processed frame.

    Returns
    -------
    list of dict
    """
    if hasattr(source, "history"):
        hist = source.history()
        steps = [tracks for _, tracks in hist]
        default = [f for f, _ in hist]
    else:
        steps = [list(s) for s in source]
        default = list(range(len(steps)))
    if frames is None:
        frames = default
    frames = [int(f) for f in frames]
    if len(frames) != len(steps):
        raise ValueError(f"frames must have one entry per processed frame ({len(steps)}), got {len(frames)}")
    if any(f < 0 for f in frames):
        raise ValueError("frames must be >= 0")
    rows = []
    for f, tracks in zip(frames, steps):
        for tr in sorted(tracks, key=lambda t: t.id):
            if tr.status not in _STATUSES:
                raise ValueError(f"track {tr.id} has status {tr.status!r}, expected one of {_STATUSES}")
            p, v = np.asarray(tr.position, dtype=float), np.asarray(tr.velocity, dtype=float)
            if p.shape not in ((2,), (3,)):
                raise ValueError(f"track {tr.id}: position must have 2 or 3 components, got {p.shape}")
            z, vz = (float(p[2]), float(v[2])) if p.shape == (3,) else (None, None)
            rows.append({"frame": f, "track_id": int(tr.id), "status": tr.status, "x": float(p[0]),
                         "y": float(p[1]), "z": z, "vx": float(v[0]), "vy": float(v[1]), "vz": vz})
    return rows


def write_tracks_csv(path, source, frames: Sequence[int] | None = None) -> int:
    """Write ``tracks.csv`` (see the module docstring); return the number of rows written.

    Parameters
    ----------
    path : str, os.PathLike or text file object
    source, frames
        As for :func:`tracks_rows`.
    """
    rows = tracks_rows(source, frames)

    def fmt(v):
        if v is None:
            return ""
        return repr(v) if isinstance(v, float) else str(v)

    def write(fh):
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(TRACKS_CSV_COLUMNS)
        for r in rows:
            w.writerow([fmt(r[c]) for c in TRACKS_CSV_COLUMNS])

    if isinstance(path, io.TextIOBase) or hasattr(path, "write"):
        write(path)
    else:
        with open(os.fspath(path), "w", newline="") as fh:
            write(fh)
    return len(rows)


def read_tracks_csv(path) -> list[dict]:
    """Read a ``tracks.csv`` back into the dicts of :func:`tracks_rows` (checks the header)."""

    def read(fh) -> Iterable[dict]:
        r = csv.reader(fh)
        header = next(r, None)
        if header is None or tuple(header) != TRACKS_CSV_COLUMNS:
            raise ValueError(f"not a tracks.csv: header {header!r}, expected {','.join(TRACKS_CSV_COLUMNS)}")
        out = []
        for line in r:
            rec = dict(zip(TRACKS_CSV_COLUMNS, line))
            row = {"frame": int(rec["frame"]), "track_id": int(rec["track_id"]), "status": rec["status"]}
            for c in ("x", "y", "z", "vx", "vy", "vz"):
                row[c] = float(rec[c]) if rec[c] != "" else None
            out.append(row)
        return out

    if hasattr(path, "read"):
        return read(path)
    with open(os.fspath(path), newline="") as fh:
        return read(fh)
