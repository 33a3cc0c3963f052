"""Run ``flowtrack demo`` by its command line and record what its tracker was given.

Usage::

    python benchmarks/_record_demo.py RECORD.pkl demo --input SEQ --out DIR ...

runs ``flowtrack_course.cli.main(["demo", "--input", ...])`` (what the ``flowtrack`` command runs)
unchanged, with a passive recorder around :class:`flowtrack.tracking.MultiObjectTracker`: the
arguments each tracker is built with (deep-copied before it uses them) and every call of ``step``
(detections, velocities, their covariances, position covariances; copies). The record is pickled to
``RECORD.pkl`` as ``{"init": [(args, kwargs), ...], "steps": [[(Z, V, C, R, kwargs), ...] per tracker]}``
(``kwargs``: the step's keyword arguments, e.g. ``seen_through``).
``benchmarks/bench_tracking.py`` replays it: the demo's own tracker again (which must reproduce
``tracks.csv`` row for row, the proof that nothing was changed) and a position-only tracker on the
same detections (the ablation, which ``metrics.json`` has only for synthetic input).

With the environment variable ``FLOWTRACK_BENCH_FLOW_CACHE`` set to a folder, the scene flow is
cached there (``benchmarks/_flow_cache.py``): tuning the pipeline or the tracker does not recompute it.
"""

from __future__ import annotations

import copy
import pickle
import sys

import numpy as np


def _copy(x):
    return None if x is None else np.array(x, copy=True)


def main(argv: list[str]) -> int:
    out, cli_args = argv[0], argv[1:]
    import os

    from flowtrack.tracking import MultiObjectTracker

    if os.environ.get("FLOWTRACK_BENCH_FLOW_CACHE"):
        # the scene flow does not depend on the pipeline's or the tracker's settings: tuning them on
        # the training split reuses it (a cached result is the one the call computes, bit for bit)
        import _flow_cache

        _flow_cache.install(os.environ["FLOWTRACK_BENCH_FLOW_CACHE"])

    record: dict = {"init": [], "steps": []}
    index: dict[int, int] = {}
    orig_init, orig_step = MultiObjectTracker.__init__, MultiObjectTracker.step

    def init(self, *args, **kwargs):
        index[id(self)] = len(record["init"])
        record["init"].append((copy.deepcopy(args), copy.deepcopy(kwargs)))
        record["steps"].append([])
        orig_init(self, *args, **kwargs)

    def step(self, detections, velocities=None, velocity_covs=None, position_covs=None, **kwargs):
        # keyword inputs (the free space the sensor saw through, yaw rates) are small, picklable objects
        record["steps"][index[id(self)]].append(
            (_copy(detections), _copy(velocities), _copy(velocity_covs), _copy(position_covs),
             copy.deepcopy(kwargs)))
        return orig_step(self, detections, velocities, velocity_covs, position_covs, **kwargs)

    MultiObjectTracker.__init__ = init
    MultiObjectTracker.step = step
    from flowtrack_course.cli import main as cli

    rc = cli(cli_args)
    with open(out, "wb") as fh:
        pickle.dump(record, fh)
    return rc


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
