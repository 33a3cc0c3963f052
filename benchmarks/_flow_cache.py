"""A disk cache of ``flowtrack.rgbd_flow.rgbd_scene_flow`` for the held-out tracking benchmark.

The RGB-D scene flow is most of the time of a ``flowtrack demo --input`` run, and it does not depend on
anything the tracking experiments change (the pipeline's clustering and detection settings, the
tracker). :func:`install` replaces ``flowtrack.rgbd_flow.rgbd_scene_flow`` (which
``rgbd_point_flow``, and so the demo, calls through the module) with a wrapper that stores each result
under a key made of

- the exact bytes, shapes and dtypes of the four images, the camera's intrinsics and size, ``dt`` and
  the options, and
- the source of every module the flow runs (``flowtrack/rgbd_flow.py`` and ``flowtrack/_rgbd_*.py``),

so a cached flow is returned only for the same inputs and the same flow code: it is the result the
call would compute, bit for bit (the flow is deterministic; ``benchmarks/bench_tracking.py`` checks a
cached run against a fresh one on the first sequence when asked, ``--check-cache``). Results are
stored as ``.npy`` (float64) under the cache folder.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

__all__ = ["code_hash", "install"]


def code_hash() -> str:
    """SHA-1 of the source of the scene-flow modules (``rgbd_flow.py`` and ``_rgbd_*.py``)."""
    import flowtrack

    root = Path(flowtrack.__file__).parent
    h = hashlib.sha1()
    for p in sorted([root / "rgbd_flow.py", *root.glob("_rgbd_*.py")]):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _key(code: str, args, options) -> str:
    rgb_t, depth_t, rgb_t1, depth_t1, cam, dt = args
    h = hashlib.sha1(code.encode())
    for a in (rgb_t, depth_t, rgb_t1, depth_t1):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    h.update(repr((float(cam.fx), float(cam.fy), float(cam.cx), float(cam.cy), int(cam.width),
                   int(cam.height), float(dt))).encode())
    h.update(repr(sorted((k, repr(v)) for k, v in options.items())).encode())
    return h.hexdigest()


def install(folder) -> None:
    """Cache ``flowtrack.rgbd_flow.rgbd_scene_flow`` in ``folder`` for this process (plain calls only:
    a call with ``return_info`` or an array ``init`` is passed through)."""
    import flowtrack.rgbd_flow as rf

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    code = code_hash()
    original = rf.rgbd_scene_flow

    def cached(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options):
        if options.get("return_info") or isinstance(options.get("init"), np.ndarray):
            return original(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options)
        path = folder / f"{_key(code, (rgb_t, depth_t, rgb_t1, depth_t1, cam, dt), options)}.npy"
        if path.is_file():
            return np.load(path)
        v = original(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options)
        tmp = path.with_suffix(".tmp.npy")
        np.save(tmp, np.asarray(v))
        tmp.replace(path)
        return v

    cached.__wrapped__ = original
    rf.rgbd_scene_flow = cached
