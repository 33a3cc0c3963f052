r"""Synthetic RGB-D sequences of rigid objects moving on a table, with exact ground truth.

A tilted pinhole camera looks down at a table (the world plane :math:`z_w = 0`, world :math:`z` up)
in front of a back wall. Boxes and upright cylinders slide on the table: each object :math:`k`
has a pose :math:`T_{wo}^{(k)}(t) \in SE(3)` made of a planar translation (a slightly curved path)
and a rotation about the vertical axis at constant angular speed. Its object-to-camera pose is
:math:`T_k(t) = T_{cw}\,T_{wo}^{(k)}(t)` (the camera is static).

Rendering is exact ray casting. The ray through pixel :math:`(r, c)` (row, column) is
:math:`X(s) = s\,d`, :math:`d = ((c - c_x)/f_x,\ (r - c_y)/f_y,\ 1)^\top`, so the ray parameter
:math:`s` *is* the depth :math:`Z`. Every surface is intersected analytically for all pixels at once
(slab method for boxes in the box frame, a quadratic plus two caps for cylinders, one division for
planes) and a z-buffer keeps the nearest hit, so occlusion is exact.

Ground truth per frame :math:`t_i = i\,\Delta t`, for each valid pixel with noiseless surface point
:math:`X` owned by object :math:`k`:

.. math::  v(X) = \frac{T_k(t_{i+1})\,T_k(t_i)^{-1} X - X}{\Delta t},

so :math:`X + v\,\Delta t` is *exactly* where that material point is at :math:`t_{i+1}` (the motion
is analytic, so the last frame uses the motion continuing to :math:`t_n`). Static surfaces (table,
wall, static occluders) have :math:`v = 0`. Depth noise :math:`\mathcal N(0, \sigma^2)` is added to
:math:`Z` (and hence to the back-projected points); the ground truth refers to the noiseless point.

Labels: ``0`` = static (table, wall, static occluders), ``1..K`` = the moving objec

The package, by concept:

- :mod:`flowtrack.synth.shapes` – boxes, cylinders, planes and their planar trajectories.
- :mod:`flowtrack.synth.raycast` – the camera pose, exact ray casting with a z-buffer, shading.
- :mod:`flowtrack.synth.scenarios` – options, workspace, placement and the scripted scenarios.
- :mod:`flowtrack.synth.scene` – :class:`Frame`, :class:`Scene` and :func:`make_scene`.
- :mod:`flowtrack.synth.sensor` – Kinect-like depth artefacts for a rendered depth image
  (:func:`kinect_depth`: depth-dependent noise, disparity quantisation, flying pixels, edge holes).

Every name below is importable from ``flowtrack.synth`` itself.
"""

from __future__ import annotations

from .raycast import RayCast, look_at, ray_cast, ray_directions
from .scenarios import SCENARIOS
from .scene import Frame, Scene, make_scene
from .sensor import kinect_depth, kinect_sigma
from .shapes import ArcTrajectory, Body, Box, Cylinder, PlanarTrajectory, Plane

__all__ = [
    "SCENARIOS",
    "ArcTrajectory",
    "Body",
    "Box",
    "Cylinder",
    "Frame",
    "PlanarTrajectory",
    "Plane",
    "RayCast",
    "Scene",
    "look_at",
    "kinect_depth",
    "kinect_sigma",
    "make_scene",
    "ray_cast",
    "ray_directions",
]
