r"""Step 3 of the pipeline: motion clusters → detections, and what each detection measures (part of
:mod:`flowtrack.pipeline`).

A detection is a *piece*: the points of one motion cluster, off the support planes, that are
spatially connected (radius ``cluster_radius``) and number at least ``min_detection_points``
(:func:`detection_pieces`). It reports the centroid :math:`\bar X` of the piece and its mean flow
:math:`\bar v` (:func:`detections_from_clusters`). :func:`detection_pieces` can also skip pieces
that do not move together or that geometry and colour call static, and merge the pieces of one
rigid object — touching ones, or ones an occluder split.

What a detection measures is the *visible* part of an object, so two functions describe its error:

- :func:`occlusion_position_covariances` widens the position covariance of a piece that a nearer
  surface cuts, :math:`R_k = R + (s\,e_k)^2\,\hat u_k \hat u_k^\top` along the image direction
  :math:`\hat u_k` of the occluder (:math:`e_k` the piece's extent along it);
- :func:`visible_centroid_velocities` measures the velocity of the visible-surface centroid,
  :math:`u_k = (\bar B_{t+1}[\ell_{t+1} = k] - \bar B_t[\ell_t = k])/\Delta t` over the depth pixels
  labelled by their nearest (flow-warped) point, and widens the velocity covariance by the gap to
  the mean flow, :math:`C_k + \kappa (u_k - \bar v_k)(u_k - \bar v_k)^\top`.

The derivations are in :mod:`flowtrack.pipeline`'s docstring. Import these names from
:mod:`flowtrack.pipeline`, which exports (and documents) them.
"""

from __future__ import annotations

import numpy as np

from .._graph import as_labels
from .._validation import as_array, nonnegative, positive, positive_int
from ..camera import project
from ..rgbd_flow import grey_image
from ._clouds import cloud_from_depth, support_planes
from ._config import PipelineConfig

__all__ = [
    "detection_pieces",
    "detections_from_clusters",
    "occlusion_position_covariances",
    "visible_centroid_velocities",
]


def detection_pieces(points, clusters, flow, config: PipelineConfig | None = None, next_points=None,
                     dt: float | None = None, *, min_speed: float | None = None,
                     images=None, occluders=None, rigid_merge: bool = False) -> list[np.ndarray]:
    r"""The point sets of :func:`detections_from_clusters`' detections, in the same order.

    Parameters are those of :func:`detections_from_clusters`, and:

    min_speed : float, optional
        A piece whose *mean* flow is slower than this (m/s) is skipped. The motion clustering keeps
        points faster than its threshold one by one; the flow noise of a depth-edge artefact (flying
        pixels, dropouts flickering at a step in depth) is fast point by point but points every way,
        so its mean is near zero, while an object's points move together, :math:`|\bar v| \approx
        \overline{|v|}`. Pass the clustering's own threshold (the demo: ``rgbd_min_speed``).
    images : tuple (rgb_t, rgb_next, camera), optional
        With ``next_points``: the colour images of the two frames (uint8 (H, W, 3) or grey (H, W))
        and the camera. Where geometry cannot tell (the larger of the static and moved points'
        median distances to the next cloud at most 1.5 times the smaller), colour decides: the piece
        is skipped as static when the median grey-level difference between each point's pixel at
        t and its static position :math:`\pi(X_i)` in the next image is no larger than at its moved
        position :math:`\pi(X_i + v_i\,\Delta t)`, and kept as moving otherwise. Geometry alone
        cannot see a textured surface slide along itself (a box pushed along its long face stays on
        that face's plane, and a turning box sweeps its faces over themselves); its texture can.
        A fourth element, the next frame's depth image (metres, 0 = none), does two things. The
        colour test leaves out the points whose static pixel is covered there by a surface more
        than ``occlusion_margin`` nearer: a moving object that passes over a static surface changes
        that surface's colour without moving it. The geometric test leaves out the points whose
        static pixel the next depth image does not see (no depth there, or a surface nearer than
        both the point and its moved position by more than ``occlusion_margin``) and skips a piece
        none of whose points is seen: background next to a moving object, whose flow the object
        dragged along, is hidden where it stood, so its static distance is large although it did
        not move.
    rigid_merge : bool
        Merge touching pieces (closest points within ``cluster_radius``) that one rigid motion
        explains: a turning object's faces move at different velocities, so the motion clustering
        (by velocity similarity) may split it. Pieces a and b are merged when the rigid motion fitted
        to their union's flow (:func:`flowtrack.motion.rigid_motion_from_flow`) adds at most
        ``rigid_merge_tolerance`` (m/s) to the residuals of their own fits,
        :math:`\sqrt{e_{ab}^2 - (n_a e_a^2 + n_b e_b^2)/(n_a + n_b)}` with :math:`e` the residual rms:
        a noisy flow leaves large residuals in every fit, but only two motions add to them (two
        pieces of equal size whose velocities differ by :math:`\Delta` add about
        :math:`|\Delta|/2`).
    occluders : tuple (depth_t, camera), optional
        The depth image of frame t (metres, 0 = none) and the camera: pieces split by something in
        front of them are merged into one detection. An object partly hidden by a nearer one shows
        two pieces with one rigid motion (not one velocity: a turning box's two ends move apart);
        pieces a and b are merged when their closest points are at most ``occlusion_max_gap``
        apart, between the image projections of those points the depth image, once the pieces' own
        surface at either end is passed, is nearer than both points by more than
        ``occlusion_margin`` along at least half of the segment, and one rigid motion explains
        both (as for ``rigid_merge``, ``rigid_merge_tolerance``); merges are transitive.

    Returns
    -------
    list of ndarray of int
        Indices into ``points`` of each detection's piece; detection k is
        ``(points[pieces[k]].mean(0), flow[pieces[k]].mean(0))``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    cfg = config if config is not None else PipelineConfig()
    P = as_array(points, "points", ("N", 3))
    clusters = as_labels(clusters, "clusters", len(P), min_label=-1)
    flow = as_array(flow, "flow", (len(P), 3))
    tree = None
    if next_points is not None:
        if dt is None:
            raise ValueError("dt must be given with next_points")
        dt = positive(dt, "dt")
        tree = cKDTree(as_array(next_points, "next_points", ("M", 3)))
    if min_speed is not None:
        min_speed = nonnegative(min_speed, "min_speed")
    grey = None
    if images is not None:
        if tree is None:
            raise ValueError("images need next_points and dt")
        if len(images) not in (3, 4):
            raise ValueError("images must be (rgb_t, rgb_next, camera[, depth_next])")
        d1 = None
        if len(images) == 4 and images[3] is not None:
            d1 = np.asarray(images[3], dtype=np.float64)
        grey = (grey_image(images[0], "images[0]"), grey_image(images[1], "images[1]"), images[2], d1)
        if grey[0].shape != grey[1].shape:
            raise ValueError(f"images[0] and images[1] must have the same size, got {grey[0].shape} and "
                             f"{grey[1].shape}")
    keep = (clusters >= 0) & ~support_planes(P, cfg)
    pieces = []
    for c in np.unique(clusters[keep]):
        idx = np.flatnonzero(keep & (clusters == c))
        if len(idx) < cfg.min_detection_points:
            continue
        pairs = cKDTree(P[idx]).query_pairs(cfg.cluster_radius, output_type="ndarray")
        A = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(idx), len(idx)))
        _, comp = connected_components(A, directed=False)
        for j in np.unique(comp):
            piece = idx[comp == j]
            if len(piece) >= cfg.min_detection_points:
                if min_speed is not None and np.linalg.norm(flow[piece].mean(axis=0)) < min_speed:
                    continue
                if tree is not None:
                    X, V = P[piece], flow[piece]
                    if grey is not None and grey[3] is not None:
                        # a point whose static pixel is covered at t+1 by a surface nearer than both
                        # of its positions, or by the sensor's shadow, says nothing: background that a
                        # moving object passes over is hidden where it stood, and a flow that drags it
                        # along with the object puts it on visible background, so it looked as if
                        # it moved
                        seen = ~_covered(X, V, dt, grey[3], grey[2], cfg.occlusion_margin)
                        if not seen.any():
                            continue
                        X, V = X[seen], V[seen]
                    d_static = np.median(tree.query(X)[0])
                    d_moving = np.median(tree.query(X + dt * V)[0])
                    # colour decides only where geometry cannot: both hypotheses fit about as well
                    ambiguous = max(d_static, d_moving) <= 1.5 * min(d_static, d_moving)
                    if grey is not None and ambiguous:
                        static = _colour_static(grey, P[piece], flow[piece], dt, cfg.occlusion_margin)
                    else:
                        static = d_static <= d_moving
                    if static:
                        continue
                pieces.append(piece)
    if rigid_merge and len(pieces) > 1:
        pieces = _merge_rigid(P, pieces, flow, dt if dt is not None else 0.1, cfg)
    if occluders is not None and len(pieces) > 1:
        if len(occluders) != 2:
            raise ValueError("occluders must be (depth_t, camera)")
        depth = np.asarray(occluders[0], dtype=np.float64)
        if depth.ndim != 2:
            raise ValueError(f"occluders[0] must be a depth image of shape (H, W), got {depth.shape}")
        pieces = _merge_occluded(P, pieces, flow, depth, occluders[1], cfg, dt if dt is not None else 0.1)
    return pieces


def _groups(n: int, pairs) -> list[list[int]]:
    """The connected components of ``n`` nodes joined by ``pairs``, each sorted, in order of their
    smallest member (scipy's ``connected_components``, as for the pieces themselves)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.array(pairs, dtype=np.intp).reshape(-1, 2)
    _, comp = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)),
                                   directed=False)
    return sorted((np.flatnonzero(comp == c).tolist() for c in np.unique(comp)), key=min)


def _rigid_rms(P, flow, idx, dt) -> float:
    """Residual rms (m/s) of the rigid motion fitted to the flow of the points ``idx``."""
    from ..motion import rigid_motion_from_flow

    return rigid_motion_from_flow(P[idx], flow[idx], dt).residual_rms


def _one_rigid_motion(P, flow, a, b, rms_a, rms_b, dt, tol) -> bool:
    r"""Whether one rigid motion explains pieces ``a`` and ``b``: the residual it adds to their own
    fits, :math:`\sqrt{e_{ab}^2 - (n_a e_a^2 + n_b e_b^2)/(n_a + n_b)}`, is at most ``tol`` (m/s)."""
    union = np.concatenate([a, b])
    pooled = (len(a) * rms_a**2 + len(b) * rms_b**2) / len(union)
    return bool(_rigid_rms(P, flow, union, dt) ** 2 - pooled <= tol**2)


def _merge_rigid_pairs(P, pieces, flow, dt, cfg, near) -> list[np.ndarray]:
    """Merge the pieces a, b for which ``near(tree_a, b)`` holds and one rigid motion explains both
    (``rigid_merge_tolerance``); merges are transitive."""
    from scipy.spatial import cKDTree

    own = [_rigid_rms(P, flow, p, dt) for p in pieces]
    trees = [cKDTree(P[p]) for p in pieces]
    pairs = [(a, b) for a in range(len(pieces)) for b in range(a + 1, len(pieces))
             if near(trees[a], a, b) and _one_rigid_motion(P, flow, pieces[a], pieces[b], own[a], own[b], dt,
                                                           cfg.rigid_merge_tolerance)]
    return [np.sort(np.concatenate([pieces[i] for i in g])) for g in _groups(len(pieces), pairs)]


def _merge_rigid(P, pieces, flow, dt, cfg) -> list[np.ndarray]:
    def touching(tree, a, b):  # closest points within cluster_radius
        gap = tree.query(P[pieces[b]], distance_upper_bound=cfg.cluster_radius)[0].min()
        return gap <= cfg.cluster_radius

    return _merge_rigid_pairs(P, pieces, flow, dt, cfg, touching)


def _occluded_between(xa, xb, depth, cam, margin: float) -> bool:
    """Whether the image segment between the projections of ``xa`` and ``xb`` is covered by a surface
    nearer than both (after the pieces' own surface at either end)."""
    H, W = depth.shape
    ua, ub = project(np.array([xa, xb]), cam)
    n = int(np.ceil(np.hypot(*(ub - ua))))
    if n < 3:
        return False
    uv = ua + np.linspace(0.0, 1.0, n + 1)[1:-1, None] * (ub - ua)
    c = np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)
    r = np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1)
    z = depth[r, c]
    nearer = (z > 0) & (z < min(xa[2], xb[2]) - margin)
    hits = np.flatnonzero(nearer)
    if len(hits) == 0:
        return False
    inner = nearer[hits[0]: hits[-1] + 1]  # the pieces' own surface at the ends is passed
    valid = (z[hits[0]: hits[-1] + 1] > 0)
    return bool(len(inner) >= 0.5 * len(z) and inner[valid].mean() >= 0.8)


def _merge_occluded(P, pieces, flow, depth, cam, cfg, dt) -> list[np.ndarray]:
    def split_by_occluder(tree, a, b):  # closest points near enough, a nearer surface between them
        d, j = tree.query(P[pieces[b]])
        ib = int(np.argmin(d))
        return d[ib] <= cfg.occlusion_max_gap and _occluded_between(
            P[pieces[a]][j[ib]], P[pieces[b]][ib], depth, cam, cfg.occlusion_margin)

    return _merge_rigid_pairs(P, pieces, flow, dt, cfg, split_by_occluder)


def _pixels(Y, cam, shape, offset=(0.0, 0.0)):
    """Column, row (nearest pixel) of the projections of ``Y`` moved by ``offset`` px, and whether
    each lies in front of the camera and inside an image of ``shape`` (outside: column and row -1)."""
    H, W = shape
    ok = Y[:, 2] > 1e-6
    u = np.full(len(Y), -1)
    r = np.full(len(Y), -1)
    u[ok], r[ok] = np.round(project(Y[ok], cam) + offset).astype(int).T
    ok &= (u >= 0) & (u < W) & (r >= 0) & (r < H)
    return np.where(ok, u, -1), np.where(ok, r, -1), ok


def _covered(X, v, dt, depth_next, cam, margin: float) -> np.ndarray:
    """Points whose static pixel the next depth image does not see: no measurement there (a sensor's
    shadow or hole), or a surface nearer by more than ``margin`` than both the point and its moved
    position (another surface in front, not the point's own surface come nearer)."""
    u0, r0, ok0 = _pixels(X, cam, depth_next.shape)
    z1 = np.where(ok0, depth_next[r0, u0], 0.0)
    z_near = np.minimum(X[:, 2], X[:, 2] + dt * v[:, 2]) - margin
    return ok0 & ((z1 <= 0) | (z1 < z_near))


def _colour_static(grey, X, v, dt, margin: float) -> bool:
    """Whether the pixels of ``X`` at t match the next image at least as well at their static
    positions as at their moved ones (median absolute grey difference, nearest pixel); with the next
    depth image, points whose static pixel is covered by a surface nearer by more than ``margin``
    there do not count."""
    g0, g1, cam, d1 = grey
    u0, r0, ok0 = _pixels(X, cam, g0.shape)
    u1, r1, ok1 = _pixels(X + dt * v, cam, g0.shape)
    ok = ok0 & ok1
    if d1 is not None:  # something moved in front of the static pixel: its colour says nothing
        z1 = np.where(ok, d1[r0, u0], 0.0)
        ok &= ~((z1 > 0) & (z1 < X[:, 2] - margin))
    if not ok.any():
        return True
    ref = g0[r0[ok], u0[ok]]
    e_static = np.median(np.abs(g1[r0[ok], u0[ok]] - ref))
    e_moving = np.median(np.abs(g1[r1[ok], u1[ok]] - ref))
    return bool(e_static <= e_moving)


def detections_from_clusters(points, clusters, flow, config: PipelineConfig | None = None, next_points=None,
                             dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    r"""Object detections from motion clusters: centroid and mean velocity of each object piece.

    Graph smoothing spreads an object's motion into the table it stands on (the kNN graph links
    them at the contact), and a translation parallel to a plane leaves that plane unchanged, so the
    table next to an object cannot be told apart from it by geometry. The support planes are
    therefore removed (:func:`support_planes`) and each cluster's remaining points are split into
    spatially connected pieces (radius ``cluster_radius``); every piece with at least
    ``min_detection_points`` points is a detection :math:`(\bar X, \bar v)` (the pieces themselves:
    :func:`detection_pieces`).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    clusters : ndarray, shape (N,) int
        Motion-cluster labels, −1 static.
    flow : ndarray, shape (N, 3)
        Velocities whose per-piece mean initialises a track (the rigid flow of each cluster: the
        mean of a rigid motion's flow is the flow of the centroid).
    config : PipelineConfig, optional
    next_points : ndarray, shape (M, 3), optional
        The cloud of frame t+1; with it (and ``dt``) a piece must be better explained as moving
        than as static: the median distance from :math:`X_i + v_i\,\Delta t` to the nearest point
        of the next cloud must be smaller than that from :math:`X_i` itself. Static surface that a
        cluster reached through noisy points (and whose rigid flow is therefore the cluster's, not
        its own) fails this test and is skipped.
    dt : float, optional

    Returns
    -------
    centroids, velocities : ndarray, shape (K, 3)
    """
    P = as_array(points, "points", ("N", 3))
    flow = as_array(flow, "flow", (len(P), 3))
    pieces = detection_pieces(P, clusters, flow, config, next_points, dt)
    Z = [P[piece].mean(axis=0) for piece in pieces]
    V = [flow[piece].mean(axis=0) for piece in pieces]
    return np.array(Z).reshape(-1, 3), np.array(V).reshape(-1, 3)



def _piece_index(piece, k: int, n: int) -> np.ndarray:
    """``pieces[k]`` as an index array into ``n`` points (ValueError naming it otherwise)."""
    idx = np.asarray(piece)
    if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer) or (idx.size and (
            idx.min() < 0 or idx.max() >= n)):
        raise ValueError(f"pieces[{k}] must be a 1-D int array of indices into points (0 .. {n - 1})")
    return idx


#: the 8 directions (unit image vectors) :func:`occlusion_position_covariances` looks along
_RING = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=float)
_RING /= np.linalg.norm(_RING, axis=1)[:, None]


def occlusion_position_covariances(points, pieces, depth_t, camera, r, *, scale: float = 0.5,
                                   margin: float = 0.02, offset: int = 4, min_fraction: float = 0.03):
    r"""Position covariance of each detection, widened toward a nearer surface that cuts it.

    A detection is the centroid of the *visible* part of an object. When a nearer surface hides part
    of the object, the centroid lies off the object's by up to half the hidden extent, along the
    image direction of the occluder, and a track that follows the whole object sees the detection
    jump by a few cm as the occluder passes (or as the object is cut in two pieces). The detection
    is then a measurement of the object's position with a larger error *along that direction*:

    .. math::
        R_k = R + (s\, e_k)^2\, \hat u_k \hat u_k^\top ,

    with :math:`\hat u_k` the unit 3-D direction (camera frame, at constant depth) of the image
    direction toward the occluder, :math:`e_k` the piece's extent along :math:`\hat u_k` and s
    (``scale``) the fraction of it taken as one standard deviation (0.5: a hidden part as large as
    the visible one). Point :math:`X_i` of a piece touches an occluder when one of the 8 pixels
    ``offset`` px from its projection (along the image axes and diagonals) holds a surface nearer than
    :math:`z_i - \text{margin}`; :math:`\hat u_k` is the sum of those directions over the piece's
    touching points, lifted to 3-D as :math:`(u_x/f_x,\ u_y/f_y,\ 0)` normalised. A piece with fewer
    than ``min_fraction`` of its points (or fewer than 3) touching keeps R.

    The offset is one-sided, of known sign: the visible centroid lies *away* from the occluder. The
    widened :math:`R_k` treats it as zero-mean noise, which keeps the track in the gate and the
    association, but the update still moves the track toward the visible side by the gain times the
    offset (lesson 6 §5e measures it). Shifting the detection toward the occluder would need the
    hidden extent, which is what the camera cannot see, so the mean is left alone.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        The cloud of frame t (camera frame, metres).
    pieces : sequence of array_like of int
        Indices into ``points`` of each detection (:func:`detection_pieces`); K pieces.
    depth_t : array_like, shape (H, W)
        The depth image of frame t (metres; 0 or non-finite: no surface).
    camera : flowtrack.camera.PinholeCamera
    r : float or array_like, shape (3, 3)
        The detections' position variance (m², e.g. ``track_r``) or covariance R.
    scale : float, >= 0
        s.
    margin : float, >= 0
        How much nearer (m) a surface must be to count as an occluder.
    offset : int, >= 1
        Pixels between a point's projection and the pixels looked at.
    min_fraction : float in [0, 1]

    Returns
    -------
    ndarray, shape (K, 3, 3)

    Examples
    --------
    A plate 1 m away, 19 cm wide (columns at x = -0.095 … 0.095 m); a wall 0.5 m away then covers
    the image right of x = 0.1 m. The plate touches it on its right: its variance along x grows by
    (0.5 · 0.19 m)² = 0.009 m²:

    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=29.5, cy=19.5, width=60, height=40)
    >>> x = (np.arange(60) - 29.5) / 100.0                      # x of each column at 1 m
    >>> depth = np.where((x > -0.1) & (x < 0.1), 1.0, 2.0)[None, :].repeat(40, axis=0)
    >>> P = cloud_from_depth(depth, cam)
    >>> plate = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> np.round(occlusion_position_covariances(P, [plate], depth, cam, 1e-4)[0].diagonal(), 4).tolist()
    [0.0001, 0.0001, 0.0001]
    >>> depth[:, x > 0.1] = 0.5
    >>> np.round(occlusion_position_covariances(P, [plate], depth, cam, 1e-4)[0].diagonal(), 4).tolist()
    [0.0091, 0.0001, 0.0001]
    """
    X = as_array(points, "points", ("N", 3))
    D = np.asarray(depth_t, dtype=np.float64)
    if D.ndim != 2:
        raise ValueError(f"depth_t must be a depth image of shape (H, W), got {D.shape}")
    D = np.where(np.isfinite(D), D, 0.0)
    R = np.asarray(r, dtype=np.float64)
    if R.ndim == 0:
        R = positive(float(R), "r") * np.eye(3)
    R = as_array(R, "r", (3, 3))
    scale = nonnegative(scale, "scale")
    margin = nonnegative(margin, "margin")
    offset = positive_int(offset, "offset")
    min_fraction = nonnegative(min_fraction, "min_fraction")
    if min_fraction > 1:
        raise ValueError(f"min_fraction must be in [0, 1], got {min_fraction}")
    out = np.broadcast_to(R, (len(pieces), 3, 3)).copy()
    for k, piece in enumerate(pieces):
        P = X[_piece_index(piece, k, len(X))]
        P = P[P[:, 2] > 1e-6]
        if len(P) < 3:
            continue
        toward = np.zeros((len(P), 2))
        touch = np.zeros(len(P), dtype=bool)
        for o in _RING:
            u, v, inside = _pixels(P, camera, D.shape, offset * o)
            z = np.where(inside, D[v, u], 0.0)
            nearer = (z > 0) & (z < P[:, 2] - margin)
            toward[nearer] += o
            touch |= nearer
        if touch.sum() < 3 or touch.mean() < min_fraction:
            continue
        u = toward[touch].sum(axis=0) / np.array([camera.fx, camera.fy])
        if not np.linalg.norm(u) > 1e-12:
            continue  # surrounded evenly: no direction
        u3 = np.array([u[0], u[1], 0.0]) / np.linalg.norm(u)
        along = P @ u3
        out[k] += (scale * (along.max() - along.min())) ** 2 * np.outer(u3, u3)
    return out


def visible_centroid_velocities(points, pieces, flow, depth_t, depth_t1, camera, dt, *, radius: float = 0.01,
                                velocity_covs=None, inflation: float = 4.0, min_pixels: int = 10):
    r"""Velocity of each detection's visible-surface centroid over a frame pair, and its covariance.

    The method and its maths are in the module docstring (*The velocity of a visible centroid*):
    the pixels of ``depth_t`` take the label of their nearest point of ``points``, those of
    ``depth_t1`` the label of their nearest flow-warped point ``points + dt * flow`` (within
    ``radius``, else none); detection k's velocity is the difference of the centroids of its
    back-projected pixels divided by ``dt``,
    :math:`u_k = (\bar B_{t+1}[\ell_{t+1} = k] - \bar B_t[\ell_t = k])/\Delta t` (:math:`\bar B` the mean
    back-projection of the pixels with that label),
    and with ``velocity_covs`` its covariance is
    :math:`C_k + \kappa (u_k - \bar v_k)(u_k - \bar v_k)^\top`, :math:`\bar v_k` the piece's mean flow.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        The cloud of frame t (camera frame, metres); any subset of ``depth_t``'s back-projection
        or a voxel-thinned version of it.
    pieces : sequence of array_like of int
        Indices into ``points`` of each detection (:func:`detection_pieces`); K pieces.
    flow : array_like, shape (N, 3)
        Velocities of ``points`` (m/s), e.g. :func:`rgbd_cloud_flow`.
    depth_t, depth_t1 : array_like, shape (H, W)
        The depth images of frames t and t+1 (metres; 0 / non-finite = no measurement).
    camera : flowtrack.camera.PinholeCamera
    dt : float, > 0
    radius : float, > 0
        Farthest a pixel may be from its nearest (warped) cloud point and still take its label (m).
    velocity_covs : array_like, shape (K, 3, 3), optional
        Covariance :math:`C_k` of each detection's visible-centroid velocity before the visible-extent
        change (the demo's is described in :mod:`flowtrack.pipeline`); a NaN row stays NaN.
    inflation : float, >= 0
        :math:`\kappa`.
    min_pixels : int, >= 1
        A detection with fewer labelled pixels in either frame keeps its mean flow (and covariance).

    Returns
    -------
    velocities : ndarray, shape (K, 3)
    covariances : ndarray, shape (K, 3, 3) or None
        None without ``velocity_covs``.

    Examples
    --------
    A plate 1 m away slides along x at 0.1 m/s (10 px per frame at fx = 100), its flow exact.
    Unhidden, its visible centroid moves with it; with a nearer wall covering x > 0.12 m the plate's
    leading columns vanish, its visible centroid slows down, and the gap to the flow widens the
    covariance along x:

    >>> import numpy as np
    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(fx=100.0, fy=100.0, cx=29.5, cy=19.5, width=60, height=40)
    >>> def frame(x0, wall):
    ...     X = (np.arange(60) - 29.5) / 100.0                     # x of each column at 1 m
    ...     on = (X > x0) & (X < x0 + 0.2)
    ...     d = np.where(on, 1.0, 2.0)[None, :].repeat(40, axis=0)
    ...     return np.where((X > 0.12)[None, :] & wall, 0.5, d)   # the wall, 0.5 m away
    >>> d0 = frame(-0.2, False)
    >>> P = cloud_from_depth(d0, cam)
    >>> piece = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> flow = np.zeros_like(P)
    >>> flow[piece] = [0.1, 0.0, 0.0]
    >>> u, _ = visible_centroid_velocities(P, [piece], flow, d0, frame(-0.1, False), cam, 1.0)
    >>> np.round(u, 6).tolist()
    [[0.1, 0.0, 0.0]]
    >>> d0 = frame(-0.05, True)
    >>> P = cloud_from_depth(d0, cam)
    >>> piece = np.flatnonzero(np.isclose(P[:, 2], 1.0))
    >>> flow = np.zeros_like(P)
    >>> flow[piece] = [0.1, 0.0, 0.0]
    >>> u, C = visible_centroid_velocities(P, [piece], flow, d0, frame(0.05, True), cam, 1.0,
    ...                                    velocity_covs=np.eye(3)[None] * 1e-4, inflation=4.0)
    >>> (np.round(u, 6) + 0.0).tolist(), np.round(C[0].diagonal(), 6).tolist()
    ([[0.05, 0.0, 0.0]], [0.0101, 0.0001, 0.0001])
    """
    from scipy.spatial import cKDTree

    X = as_array(points, "points", ("N", 3))
    V = as_array(flow, "flow", X.shape)
    dt = positive(dt, "dt")
    radius = positive(radius, "radius")
    inflation = nonnegative(inflation, "inflation")
    min_pixels = positive_int(min_pixels, "min_pixels")
    D0 = np.asarray(depth_t, dtype=np.float64)
    D1 = np.asarray(depth_t1, dtype=np.float64)
    if D0.ndim != 2 or D1.shape != D0.shape:
        raise ValueError(f"depth_t and depth_t1 must be (H, W) images of one shape, got {D0.shape} and "
                         f"{D1.shape}")
    K = len(pieces)
    lab = np.full(len(X), -1, dtype=np.intp)
    for k, piece in enumerate(pieces):
        lab[_piece_index(piece, k, len(X))] = k
    Cin = None
    if velocity_covs is not None:
        from ..motion import check_velocity_covs

        Cin = check_velocity_covs(velocity_covs, K, 3)
    mean_flow = np.array([V[np.asarray(p)].mean(axis=0) if len(p) else np.full(3, np.nan)
                          for p in pieces]).reshape(K, 3)
    U = mean_flow.copy()
    if K and len(X):
        B0, B1 = cloud_from_depth(D0, camera), cloud_from_depth(D1, camera)
        if len(B0) and len(B1):
            d0, n0 = cKDTree(X).query(B0, workers=-1)
            d1, n1 = cKDTree(X + dt * V).query(B1, workers=-1)
            l0 = np.where(d0 <= radius, lab[n0], -1)
            l1 = np.where(d1 <= radius, lab[n1], -1)
            n_0 = np.bincount(l0 + 1, minlength=K + 1)[1:]
            n_1 = np.bincount(l1 + 1, minlength=K + 1)[1:]
            s0 = np.stack([np.bincount(l0 + 1, weights=B0[:, i], minlength=K + 1)[1:] for i in range(3)], 1)
            s1 = np.stack([np.bincount(l1 + 1, weights=B1[:, i], minlength=K + 1)[1:] for i in range(3)], 1)
            ok = (n_0 >= min_pixels) & (n_1 >= min_pixels)
            U[ok] = (s1[ok] / n_1[ok, None] - s0[ok] / n_0[ok, None]) / dt
    if Cin is None:
        return U, None
    gap = U - mean_flow
    C = Cin + inflation * gap[:, :, None] * gap[:, None, :]
    return U, C
