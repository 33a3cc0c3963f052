"""flowtrack: scene flow and object tracking for robot manipulation.

The reference implementation of the flowtrack course. Modules:

- :mod:`flowtrack.camera` – pinhole projection, its Jacobian, back-projection, optical/scene flow.
- :mod:`flowtrack.sceneflow` – variational (grid), graph (point cloud) and rigid (ICP) scene flow, metrics.
- :mod:`flowtrack.variational` – the solvers of variational scene flow on the pixel grid.
- :mod:`flowtrack.clustering` – motion clustering of scene flow into objects (Problem 5).
- :mod:`flowtrack.kalman`, :mod:`flowtrack.bayes`, :mod:`flowtrack.particle` – Bayes filtering;
  :mod:`flowtrack.batch_kalman` – the Kalman filter for many tracks at once (re-exported by ``kalman``).
- :mod:`flowtrack.association`, :mod:`flowtrack.tracking` – data association, multi-object tracker.
- :mod:`flowtrack.pipeline` – frames → clouds → scene flow → clusters → detections (the first flowchart).
- :mod:`flowtrack.motion` – rigid motion from flow, the turn-rate track model (EKF).
- :mod:`flowtrack.tracking_io` – ``tracks.csv``; :mod:`flowtrack.tracking_eval` – scoring a tracker run,
  the position-only vs flow-aided ablation.
- :mod:`flowtrack.metrics` – CLEAR-MOT and identity metrics; scene flow judged by its worst pixels.
- :mod:`flowtrack.synth` – synthetic RGB-D scenes with exact ground truth (a package: shapes, ray
  casting, scenarios, scenes).
- :mod:`flowtrack.datasets` – real data shipped inside installed packages (Middlebury Motorcycle,
  MOT15 TUD-Campus).
- :mod:`flowtrack.symbolic` – the sympy derivations, one module per lesson.
- :mod:`flowtrack.rgbd_io` – RGB-D sequences from disk (TUM layout) and stereo pairs.
- :mod:`flowtrack.validation` – the scalar validators, for code built on the library.

Submodules are imported lazily so that ``import flowtrack`` stays cheap. The course's tooling
(grading, port harnesses, book, widgets, demo app, ``flowtrack`` command) lives in the sibling
package :mod:`flowtrack_course`, which builds on this one; this package never imports it.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_SUBMODULES = {
    "camera",
    "sceneflow",
    "rgbd_flow",
    "variational",
    "clustering",
    "kalman",
    "batch_kalman",
    "bayes",
    "particle",
    "association",
    "tracking",
    "pipeline",
    "motion",
    "tracking_io",
    "tracking_eval",
    "metrics",
    "synth",
    "datasets",
    "rgbd_io",
    "symbolic",
    "validation",
}

__all__ = [*sorted(_SUBMODULES), "__version__"]


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'flowtrack' has no attribute {name!r}")
