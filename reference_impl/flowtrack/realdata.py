"""Deprecated: the Motorcycle loader moved to :mod:`flowtrack.datasets`; this module only re-exports it.

Kept while the course tooling (``flowtrack.demo``) still imports ``flowtrack.realdata``; new code
imports :mod:`flowtrack.datasets`.
"""

from .datasets import (
    FRONT_WHEEL_PIXELS,
    MOTORCYCLE_CALIBRATION,
    motorcycle_camera,
    motorcycle_cloud,
    motorcycle_depth,
    motorcycle_flow_case,
    track_tud_campus,
)

__all__ = [
    "FRONT_WHEEL_PIXELS",
    "MOTORCYCLE_CALIBRATION",
    "motorcycle_camera",
    "motorcycle_cloud",
    "motorcycle_depth",
    "motorcycle_flow_case",
    "track_tud_campus",
]
