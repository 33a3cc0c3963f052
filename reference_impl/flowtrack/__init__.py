"""flowtrack: scene flow and object tracking for robot manipulation.

The reference implementation of the flowtrack course. Modules:

- :mod:`flowtrack.camera` – pinhole projection, its Jacobian, back-projection, optical/scene flow.
- :mod:`flowtrack.sceneflow` – variational (grid), graph (point cloud) and rigid (ICP) scene flow, metrics.
- :mod:`flowtrack.clustering` – motion clustering of scene flow into objects (Problem 5).
- :mod:`flowtrack.kalman`, :mod:`flowtrack.bayes`, :mod:`flowtrack.particle` – Bayes filtering.
- :mod:`flowtrack.association`, :mod:`flowtrack.tracking` – data association, multi-object tracker.
- :mod:`flowtrack.pipeline` – frames → clouds → scene flow → clusters → detections (the first flowchart).
- :mod:`flowtrack.metrics` – CLEAR-MOT and identity metrics.
- :mod:`flowtrack.synth` – synthetic RGB-D scenes with exact ground truth.
- :mod:`flowtrack.realdata` – real data shipped inside installed packages (Middlebury Motorcycle).

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
    "variational",
    "clustering",
    "kalman",
    "bayes",
    "particle",
    "association",
    "tracking",
    "pipeline",
    "metrics",
    "synth",
    "realdata",
    "symbolic",
}

__all__ = [*sorted(_SUBMODULES), "__version__"]


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'flowtrack' has no attribute {name!r}")
