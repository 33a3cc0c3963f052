r"""Step 2 of the pipeline: scene flow of a pair of clouds and its motion clusters (part of
:mod:`flowtrack.pipeline`).

:func:`scene_flow_and_clusters` runs the four point-cloud methods of :data:`METHODS` on the clouds
:math:`X` (time t) and :math:`Y` (t + Δt), which need no index correspondence: nearest neighbour
:math:`v_i = (\operatorname{NN}_Y(X_i) - X_i)/\Delta t`, graph flow
(:math:`(\Delta t^2 I + \lambda L)\,V = \Delta t\,(Y_{NN} - X)`) and graph flow with re-matched
correspondences (:func:`flowtrack.sceneflow.iterative_graph_scene_flow`, whose first pass is the
plain graph flow), and rigid ICP per motion cluster; the motion clusters
(:func:`flowtrack.clustering.cluster_motion`, connected components of the points closer than
``cluster_radius`` whose velocities agree within ``sigma_v``, slower than ``min_speed``: static)
come from the re-matched graph flow. Given a flow estimated from more than the clouds — the dense
RGB-D flow of the pair at the cloud's points, :func:`rgbd_cloud_flow` — the clusters come from that
flow instead (thresholds ``rgbd_min_speed``, ``rgbd_sigma_v``) and it is reported as the row
:data:`RGBD_METHOD`.

Import these names from :mod:`flowtrack.pipeline`, which exports (and documents) them.
"""

from __future__ import annotations

import time

import numpy as np

from .._validation import as_array
from ..clustering import cluster_motion, drop_small_clusters
from ..rgbd_flow import rgbd_point_flow
from ..sceneflow import iterative_graph_scene_flow, nearest_neighbor_targets, rigid_flow_per_cluster
from ._config import PipelineConfig

__all__ = ["METHODS", "RGBD_METHOD", "rgbd_cloud_flow", "scene_flow_and_clusters"]

#: The scene-flow methods of :func:`scene_flow_and_clusters`, in the order of the demo's tables.
METHODS = ("nearest-neighbour", "graph", "graph + re-matching", "rigid per cluster")
#: The row of :func:`scene_flow_and_clusters` given the RGB-D flow (:func:`rgbd_cloud_flow`).
RGBD_METHOD = "variational RGB-D"



def rgbd_cloud_flow(rgb_t, depth_t, rgb_t1, depth_t1, camera, dt, points, **options) -> np.ndarray:
    r"""Velocities of a cloud of frame t from the dense RGB-D scene flow of the pair (t, t+1).

    :func:`flowtrack.rgbd_flow.rgbd_point_flow` gives the velocity of the back-projection
    :math:`X_p` of every valid pixel of ``depth_t``; each of ``points`` gets the velocity of the
    nearest :math:`X_p` (a k-d tree). For a cloud of back-projected pixels (:func:`cloud_from_depth`
    without ``voxel``, or any subset of it) that nearest point is the pixel itself, so the velocity
    is exactly the estimator's; for a voxel-thinned cloud it is the velocity of the pixel closest to
    the voxel's mean.

    Parameters
    ----------
    rgb_t, depth_t, rgb_t1, depth_t1, camera, dt
        As for :func:`flowtrack.sceneflow.rgbd_scene_flow` (images uint8 (H, W, 3) or grey (H, W),
        depth in metres with 0 = invalid).
    points : array_like, shape (N, 3)
        A cloud of frame t in the camera frame (metres).
    **options
        Options of :func:`~flowtrack.sceneflow.rgbd_scene_flow`.

    Returns
    -------
    ndarray, shape (N, 3)
        Velocities (m/s) in the camera frame of frame t.
    """
    from scipy.spatial import cKDTree

    P = as_array(points, "points", ("N", 3))
    X, v = rgbd_point_flow(rgb_t, depth_t, rgb_t1, depth_t1, camera, dt, **options)
    if len(P) == 0:
        return np.empty((0, 3))
    _, nn = cKDTree(X).query(P, workers=-1)
    return v[nn]


def scene_flow_and_clusters(X, Y, dt: float, config: PipelineConfig | None = None, flow=None):
    """Every scene-flow method of :data:`METHODS` on one pair of clouds, and the motion clusters.

    No index correspondence between the clouds is needed.

    Parameters
    ----------
    X, Y : ndarray, shape (N, 3) and (M, 3)
        The clouds at t and t + dt.
    dt : float
    config : PipelineConfig, optional
    flow : ndarray, shape (N, 3), optional
        A scene flow of ``X`` estimated from more than the clouds — the dense RGB-D flow
        (:func:`rgbd_cloud_flow`). With it the motion clusters (and hence the rigid ICP per cluster)
        come from this flow instead of the re-matched graph flow (thresholds ``rgbd_min_speed`` and
        ``rgbd_sigma_v``), and it is returned as the row :data:`RGBD_METHOD`.

    Returns
    -------
    flows : dict
        Method → (N, 3) velocities of ``X``'s points: the :data:`METHODS` in their order, then
        :data:`RGBD_METHOD` when ``flow`` is given.
    clusters : ndarray, shape (N,) int
        Motion-cluster labels of ``X`` (−1 static; clusters smaller than ``min_cluster_points``
        sent to −1).
    seconds : dict
        The seconds each stage took.
    """
    cfg = config if config is not None else PipelineConfig()
    if flow is not None:
        flow = as_array(flow, "flow", (len(X), 3))
    flows = {}
    t0 = time.perf_counter()
    flows["nearest-neighbour"] = (nearest_neighbor_targets(X, Y) - X) / dt
    t1 = time.perf_counter()
    # the first re-matching pass is the plain graph flow on nearest-neighbour targets
    flows["graph + re-matching"], passes = iterative_graph_scene_flow(
        X, Y, dt, cfg.lam, k=cfg.k, iterations=cfg.rematch_iterations, return_passes=True
    )
    flows["graph"] = passes[0]
    t3 = time.perf_counter()
    if flow is None:
        labels = cluster_motion(X, flows["graph + re-matching"], cfg.cluster_radius, cfg.sigma_v,
                                min_speed=cfg.min_speed, method="connected")
    else:
        labels = cluster_motion(X, flow, cfg.cluster_radius, cfg.rgbd_sigma_v, min_speed=cfg.rgbd_min_speed,
                                method="connected")
    clusters = drop_small_clusters(labels, cfg.min_cluster_points)
    t4 = time.perf_counter()
    flows["rigid per cluster"] = rigid_flow_per_cluster(X, Y, clusters, dt, cfg.icp_threshold)
    t5 = time.perf_counter()
    seconds = {
        "nearest-neighbour": t1 - t0,
        "graph, all passes": t3 - t1,
        "clustering": t4 - t3,
        "rigid per cluster": t5 - t4,
    }
    out = {m: flows[m] for m in METHODS}
    if flow is not None:
        out[RGBD_METHOD] = flow
    return out, clusters, seconds
