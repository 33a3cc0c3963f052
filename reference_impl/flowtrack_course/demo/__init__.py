r"""The main job: an RGB-D sequence through the syllabus' whole first flowchart.

RGB-D frames → point clouds (back-projection) → scene flow → motion clusters → multi-object
tracking (detections = cluster centroids, velocities from the flow) → a prediction of every track
some frames ahead. On the default synthetic sequence (:func:`flowtrack.synth.make_scene`,
scenario ``"mixed"``: a tall object crossing in front of another, a third one hidden behind a static
box for a while) everything is scored against the exact ground truth; ``--input DIR`` runs the same
pipeline on a real sequence in the TUM RGB-D layout (or a stereo pair with disparity, see
:mod:`flowtrack.rgbd_io`), without ground truth. ``flowtrack demo`` calls :func:`run_demo`, which
writes figures, an animated GIF, ``tracks.csv`` (every track of every frame:
``frame,track_id,status,x,y,z,vx,vy,vz``), ``metrics.json``, ``metrics.md`` and a self-contained
``report.html``.

Per frame pair :math:`(t, t+1)`:

1. back-project both depth images, :math:`X = Z\,K^{-1}(u, v, 1)^\top` (open3d's voxel grid thins
   real clouds to an even density);
2. dense variational RGB-D scene flow from both colour and depth images
   (:func:`flowtrack.pipeline.rgbd_cloud_flow`), and for comparison four point-cloud methods
   (nearest neighbour, graph, graph with re-matching, rigid ICP per motion cluster); the metrics
   table compares them;
3. motion clusters of the RGB-D flow (connected components of the motion graph), the support
   planes removed, one detection per connected piece (:mod:`flowtrack.pipeline`);
4. one :meth:`~flowtrack.tracking.MultiObjectTracker.step` with the pieces' centroids
   :math:`\bar X_c` as detections and, as velocity measurements, the velocity of each piece's
   visible-surface centroid (what a detection measures: its pixels carried into the next depth image
   by the flow, :func:`flowtrack.pipeline.visible_centroid_velocities`), each with the covariance of
   that estimate (the flow's residual scatter and the error the piece shares,
   ``visible_velocity_std``, :class:`flowtrack.pipeline.PipelineConfig`) widened by
   the gap between that velocity and the mean flow, the visible-extent change
   (``velocity_update=True``; :func:`flowtrack_course.demo.run.detection_measurements`), and a
   position covariance widened toward a nearer surface that cuts the piece
   (:func:`flowtrack.pipeline.occlusion_position_covariances`: an occluded object's visible
   centroid is off its own).

With ground truth the same detections are also tracked with positions only, and
``metrics.json["tracking_ablation"]`` compares the two (MOTA, IDF1, ID switches, prediction error).

Finally each reported track is predicted ``predict_ahead`` frames with the tracker's own Kalman
filter and no updates (:meth:`~flowtrack.tracking.MultiObjectTracker.predict_ahead`),
:math:`x \leftarrow F^N x`, :math:`P \leftarrow F P F^\top + Q` (N times),
and compared with where the object really is then (frames rendered for this but never shown to the
pipeline).

The package, by concept: :mod:`.options` (the command's options, read back by :mod:`.reproduce`),
:mod:`.config`, :mod:`.inputs` (synthetic scene or real sequence), :mod:`.run` (:func:`run_demo`:
orchestration of the library's pipeline, tracker and metrics), :mod:`.figures`, :mod:`.sections`
(report sections and tables) and :mod:`.reproduce` (the report's command line). The pipeline's steps
themselves are library code in :mod:`flowtrack.pipeline`.

Names are loaded lazily: ``flowtrack --help`` imports :mod:`.options` only.
"""

from __future__ import annotations

import importlib

__all__ = [
    "DemoConfig", "FlowPair", "METHODS", "detect_objects", "estimate_clouds", "run_demo", "support_planes",
]

# name -> module that defines it (the pipeline's steps keep their old demo names here)
_WHERE = {
    "DemoConfig": (".config", "DemoConfig"),
    "FlowPair": (".run", "FlowPair"),
    "run_demo": (".run", "run_demo"),
    "METHODS": ("flowtrack.pipeline", "METHODS"),
    "detect_objects": ("flowtrack.pipeline", "detections_from_clusters"),
    "estimate_clouds": ("flowtrack.pipeline", "scene_flow_and_clusters"),
    "support_planes": ("flowtrack.pipeline", "support_planes"),
}


def __getattr__(name: str):
    if name in _WHERE:
        module, attr = _WHERE[name]
        return getattr(importlib.import_module(module, __name__), attr)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
