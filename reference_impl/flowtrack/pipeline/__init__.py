r"""The syllabus' first flowchart as library steps: frames → clouds → scene flow → clusters → detections.

What the demo app (``flowtrack demo``) and lesson 6 share. Per frame pair :math:`(t, t+1)`:

1. :func:`cloud_from_depth` back-projects a depth image, :math:`X = Z\,K^{-1}(u, v, 1)^\top`
   (optionally thinned by open3d's voxel grid to an even density);
2. :func:`scene_flow_and_clusters` estimates scene flow by four point-cloud methods (:data:`METHODS`:
   nearest neighbour, graph, graph with re-matching, rigid ICP per motion cluster) and the motion
   clusters of the re-matched graph flow — or, given the dense RGB-D flow of the pair
   (:func:`rgbd_cloud_flow`: :func:`flowtrack.rgbd_flow.rgbd_point_flow` at the cloud's points, the
   row :data:`RGBD_METHOD`), the motion clusters of that flow, which sees the tangential motion
   that nearest neighbours miss;
3. :func:`detections_from_clusters` removes the support planes (:func:`support_planes`, open3d
   RANSAC) and turns each remaining connected piece of a cluster into a detection: its centroid
   :math:`\bar X` and mean rigid velocity :math:`\bar v` (the mean of a rigid motion's flow over a
   piece is the flow of its centroid, exactly). :func:`detection_pieces`, which finds the pieces,
   can also skip pieces whose points do not move together (``min_speed``: depth-edge artefacts),
   pieces that geometry *and* colour call static (``images``), and merge the pieces of an object
   split by a nearer occluder (``occluders``);
4. :func:`visible_centroid_velocities` gives each detection the velocity of what it measures, the
   centroid of the object's *visible* surface, and a velocity covariance inflated where the visible
   extent changes (below);
5. :meth:`flowtrack.tracking.MultiObjectTracker.step` takes the detections (and velocities), and
   :meth:`~flowtrack.tracking.MultiObjectTracker.predict_ahead` predicts every track N frames.

**The velocity of a visible centroid.** A detection is the centroid :math:`c_t` of the visible
surface :math:`S_t` of an object, so a track follows :math:`c_t`, not a point of the body. The mean
flow :math:`\bar v` of the piece is the velocity of the *material* at :math:`c_t`; the centroid moves
differently whenever :math:`S_t` changes: with :math:`P \subset S_t` the points that stay visible,
:math:`P'` the same points moved by the flow, :math:`H = S_t \setminus P` the surface hidden and
:math:`A` the surface revealed, :math:`S_{t+1} = P' \cup A` and

.. math::
    \frac{c_{t+1} - c_t}{\Delta t} = \bar v_P + \frac{\bar X_P - c_t}{\Delta t}
    + \frac{|A|}{|P| + |A|}\,\frac{\bar Y_A - \bar Y_{P'}}{\Delta t},

(:math:`\bar v_P` the mean flow of the persisting points, :math:`\bar X_P` their centroid at t,
:math:`\bar Y` centroids at t+1). Only when nothing is hidden or revealed (:math:`H = A = \emptyset`)
is this the mean flow. While an object slides behind an occluder, leaves or enters the image, or
turns a face away, the last two terms are a few cm/s, as large as the flow's own error, and a filter
fed :math:`\bar v` extrapolates the visible centroid wrongly even with the true flow.
:func:`visible_centroid_velocities` measures the left side directly, at full resolution: every
valid pixel of depth image t is labelled with the detection of its nearest cloud point
:math:`X_i` and every pixel of depth image t+1 with the detection of its nearest *flow-warped*
point :math:`X_i + v_i\,\Delta t` (static points included, so a pixel belongs to an object only
when the object is its nearest neighbour; farther than ``radius`` from every point: no label).
The flow thus supplies the correspondence; a pixel that becomes hidden has no counterpart at t+1,
a revealed one next to the object's warped surface joins it. Then

.. math::
    u = \frac{\operatorname{mean}\{B_{t+1}(p) : \ell_{t+1}(p) = k\}
            - \operatorname{mean}\{B_t(p) : \ell_t(p) = k\}}{\Delta t},
    \qquad
    C_u = C_e + \Big(\sigma_u^2 + f^2\lVert\bar v\rVert^2\,\frac{n_0}{n}\Big) I
          + \kappa\,(u - \bar v)(u - \bar v)^\top ,

with :math:`B_t(p)` the back-projection of pixel p. The covariance describes :math:`u` itself:
:math:`C_e` is the flow's scatter about its cluster's rigid motion
(:func:`flowtrack.motion.detection_velocity_covariances`), the noise the labels carried by the flow
inherit; the second term (the demo's ``visible_velocity_std`` :math:`\sigma_u` and
``visible_velocity_speed_fraction`` f, :math:`n_0` = 100 points, n the piece's) is the error the
whole piece shares, which no residual can see: surface revealed or lost at the outline as it sweeps
:math:`\lVert\bar v\rVert\Delta t` per frame that no warped point marks, larger for a small or
ragged piece (much outline for its area); the gap
:math:`u - \bar v` between the visible centroid's and the material's velocity is the *measured*
visible-extent change, and :math:`\kappa` (``extent_change_inflation``, 4: the gap as a
two-standard-deviation error) widens the covariance along it. Without a change the gap is the
pixel-sampling noise (a few mm/s) and :math:`u \approx \bar v`; with one, the filter learns the
centroid's motion yet gates and coasts with the object's (an object hidden while it slowed would
otherwise reappear outside its gate).

**The position of an occluded centroid.** The same surface change moves the detection itself:
while a nearer surface hides part of an object, the visible centroid sits toward the visible side,
off the object's centroid by up to half the hidden extent, and a cut object is two pieces whose
centroids are both off. :func:`occlusion_position_covariances` widens such a detection's position
covariance along the occluder's direction, :math:`R_k = R + (s\,e_k)^2\hat u_k\hat u_k^\top`
(:math:`e_k` the piece's extent along it), and the tracker gates, associates and updates each
detection with its own :math:`R_k` (``MultiObjectTracker.step(..., position_covs=)``), so the track
of the whole object keeps the piece instead of the piece starting a new identity.

**Any frame rate.** The thresholds (speeds in m/s, coasting in frames) were set at 10 Hz. A faster
sensor moves an object less per frame while the flow's noise per frame pair stays the same, so
:func:`flow_partners` pairs every frame with the one ``flow_interval`` (0.1 s) later — a 30 Hz
sequence pairs frame t with t + 3, and its last three frames with t − 3 (velocity negated) — and the
demo coasts ``max_misses`` flow intervals.

**Where the code lives.** This module is the pipeline's face: it exports every name above,
and the API reference documents them here. The steps live in private modules beside it, one per
box of the flowchart: ``_config`` (:class:`PipelineConfig`, :func:`track_confirmer`,
:func:`flow_step`, :func:`flow_partners`), ``_clouds`` (clouds and support planes), ``_flow_clusters``
(scene flow and motion clusters) and ``_detections`` (pieces, their merges and colour test, the
occlusion position covariances and the visible-centroid velocities).

Examples
--------
>>> import numpy as np
>>> from flowtrack.camera import PinholeCamera
>>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=1.5, cy=1.0, width=4, height=3)
>>> depth = np.full((3, 4), 2.0)
>>> depth[0, 0] = 0.0                                   # no measurement
>>> cloud_from_depth(depth, cam).shape
(11, 3)
>>> cloud_from_depth(depth, cam, max_depth=1.5).shape   # everything farther than 1.5 m dropped
(0, 3)
"""

from __future__ import annotations

from ._clouds import cloud_from_depth, moving_first_subsample, open3d_threads, subsample, support_planes
from ._config import PipelineConfig, flow_partners, flow_step, track_confirmer
from ._detections import (
    detection_pieces,
    detections_from_clusters,
    occlusion_position_covariances,
    visible_centroid_velocities,
)
from ._flow_clusters import METHODS, RGBD_METHOD, rgbd_cloud_flow, scene_flow_and_clusters
from ._free_space import FreeSpace

__all__ = [
    "FreeSpace",
    "METHODS",
    "PipelineConfig",
    "RGBD_METHOD",
    "cloud_from_depth",
    "detection_pieces",
    "detections_from_clusters",
    "flow_partners",
    "flow_step",
    "moving_first_subsample",
    "occlusion_position_covariances",
    "open3d_threads",
    "rgbd_cloud_flow",
    "scene_flow_and_clusters",
    "track_confirmer",
    "subsample",
    "support_planes",
    "visible_centroid_velocities",
]
