r"""Rigid motions of the depth-connected surfaces of an RGB-D frame (part of the match field of
:func:`flowtrack.rgbd_flow.rgbd_scene_flow`).

A pixel of a nearly uniform face, or of a face that turns, has no match of its own that can be
trusted; its *surface* has one: all of its pixels together, the outline of its depth and colour
included, fix a rigid motion :math:`T = (R, t)` (six numbers) that a per-pixel search cannot find.
As in piecewise-rigid RGB-D scene flow (Jaimez et al., "Motion cooperation", 3DV 2015) and in direct
RGB-D odometry (Kerl, Sturm and Cremers, 2013):

1. **Segments** (:func:`depth_segments`). The pixels of frame t with depth are split into the
   connected components of the 4-neighbour graph whose edges join pixels less than a depth jump
   apart; components under ``rigid_min_pixels`` pixels are left out.
2. **Direct alignment** (:func:`segment_motions`). For every segment :math:`S` and every starting
   motion offered for it (no motion, the median of its matches, the median of its confident ones,
   the best shift of the whole segment searched as a template, :func:`segment_search`),

   .. math::  E_S(T, a, b) = \sum_{p \in S} \rho\Big(\frac{I_1(\pi(T X_p)) - a I_0(p) - b}{\sigma_I}\Big)
              + \rho\Big(\frac{D_1(\pi(T X_p)) - (T X_p)_z}{\sigma_D}\Big)

   (an affine brightness model :math:`a, b` per segment, as in direct sparse odometry, Engel et al.
   2017: a shaded face changes its brightness when it turns) is minimised by Levenberg–Marquardt on
   the twist of :math:`T` about the segment's centroid (left increments; the rows
   :math:`(a^\top, ((Y - c) \times a)^\top)` with :math:`a` the per-pixel rows of
   :mod:`flowtrack.rgbd_flow` and :math:`Y = T X_p`), robust (Charbonnier) weights, coarse to fine
   from ``rigid_levels`` levels up; a step is kept only if it lowers the cost plus a weak pull back
   to the start (``rigid_prior`` times the diagonal of the normal matrix: the directions the data do
   not see stay where they started). A pixel moved out of the image or behind a nearer surface has
   no term (leaving the image, or being covered, is no evidence against a motion); a depth residual
   beyond the occlusion threshold costs as much as a poor match. At most ``rigid_max_pixels``
   pixels per segment and level (an even subsample); the start with the lowest cost at the first
   level where the segment is large enough goes on.
3. **Still or moving.** A segment keeps *no* motion unless its motion lowers the cost (on a coarse
   level, whose depth averages 4×4 readings) by more than the share ``rigid_still``: a uniform wall
   slides along itself at no cost, and sampling a noisy depth map between pixels averages the noise
   down, which any small motion of a static surface profits from.
4. **Per pixel** (:func:`rigid_field`). A pixel of a segment takes the segment's rigid displacement
   where its matching cost is at most its own match's (plus ``rigid_margin`` times the image's
   typical cost for a pixel without a confident match), where both agree to ``rigid_agree_px``
   pixels in the image, or where the rigid motion takes it out of the image; a segment whose motion
   moves a pixel more than 1.5 ``search_radius`` or changes its depth by more than ``match_max_dz``
   is not believed.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ._rgbd_energy import depth_sigma
from ._rgbd_match import pixel_cost

__all__ = ["depth_segments", "rigid_field", "segment_motions", "segment_search", "so3_exp"]


def depth_segments(D, tau, min_size):
    """Connected components of the pixels with depth (4-neighbours less than ``tau`` (m, scalar or
    per pixel) apart in depth); components under ``min_size`` pixels are -1. Returns (labels, n)."""
    H, W = D.shape
    valid = D > 0
    t = np.broadcast_to(np.asarray(tau, dtype=np.float64), D.shape)
    idx = np.arange(H * W).reshape(H, W)
    rows, cols = [], []
    for sa, sb in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                   ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        ok = valid[sa] & valid[sb] & (np.abs(D[sa] - D[sb]) <= np.minimum(t[sa], t[sb]))
        rows.append(idx[sa][ok])
        cols.append(idx[sb][ok])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    g = coo_matrix((np.ones(r.size, np.int8), (r, c)), shape=(H * W, H * W))
    _, lab = connected_components(g, directed=False)
    lab = lab.reshape(H, W)
    lab[~valid] = -1
    ids, counts = np.unique(lab[valid], return_counts=True)
    keep = ids[counts >= min_size]
    remap = np.full(H * W, -1, np.int64)
    remap[keep] = np.arange(keep.size)
    out = np.where(valid, remap[np.where(valid, lab, 0)], -1)
    return out, int(keep.size)


#: the cost of a pixel term that cannot be evaluated: a residual of about 4 scales
_MISS = 8.0


def so3_exp(w):
    """Rotation matrices (..., 3, 3) of rotation vectors ``w`` (..., 3) (Rodrigues)."""
    w = np.asarray(w, dtype=np.float64)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = np.zeros((*w.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    small = th < 1e-9
    a = np.where(small, 1.0, np.sin(th) / np.where(small, 1.0, th))
    b = np.where(small, 0.5, (1.0 - np.cos(th)) / np.where(small, 1.0, th * th))
    return np.eye(3) + a * K + b * (K @ K)


def _bilinear(stack, x, y):
    """Samples (N, C) of ``stack (H, W, C)`` at float positions; and inside (N,)."""
    H, W = stack.shape[:2]
    inside = (x >= 0) & (y >= 0) & (x <= W - 1) & (y <= H - 1)
    xc = np.clip(x, 0, W - 1)
    yc = np.clip(y, 0, H - 1)
    x0 = np.minimum(np.floor(xc).astype(np.intp), max(W - 2, 0))
    y0 = np.minimum(np.floor(yc).astype(np.intp), max(H - 2, 0))
    ax = (xc - x0)[:, None]
    ay = (yc - y0)[:, None]
    top = stack[y0, x0] * (1 - ax) + stack[y0, x0 + 1] * ax
    bot = stack[y0 + 1, x0] * (1 - ax) + stack[y0 + 1, x0 + 1] * ax
    return top * (1 - ay) + bot * ay, inside


def _grad(a):
    gx = np.zeros_like(a)
    gy = np.zeros_like(a)
    gx[:, 1:-1] = 0.5 * (a[:, 2:] - a[:, :-2])
    gy[1:-1] = 0.5 * (a[2:] - a[:-2])
    return gx, gy


def _level_data(I1, D1, tau_jump):
    """The sampled stack of frame t+1: I, dI/dx, dI/dy, D, dD/dx, dD/dy, ok (depth, no jump near), the
    nearest depth of the 3×3 neighbourhood."""
    Ix, Iy = _grad(I1)
    Dx, Dy = _grad(D1)
    valid = D1 > 0
    ok = ndimage.minimum_filter(valid.astype(np.uint8), size=3, mode="nearest").astype(bool)
    ok &= np.maximum(np.abs(Dx), np.abs(Dy)) <= tau_jump
    ok = ndimage.minimum_filter(ok.astype(np.uint8), size=3, mode="nearest").astype(bool)
    # the nearest surface around each pixel (a point landing next to it may be hidden by it)
    near = ndimage.minimum_filter(np.where(valid, D1, np.inf), size=3, mode="nearest")
    near = np.where(np.isfinite(near), near, 0.0)
    return np.stack([I1, Ix, Iy, D1, Dx, Dy, ok.astype(np.float64), near], axis=-1)


def _evaluate(X, I0p, hyp, Rt, ph, stack, intr, sig_i, sig_d, tau, n_hyp, want_system, centre=None):
    """Robust cost per hypothesis (and its Gauss–Newton system in the 8 unknowns: twist, gain, offset)
    at the motions ``Rt`` (n, 3, 4) and brightness models ``ph`` (n, 2): :math:`I_1 = a I_0 + b`; the
    system's rotation is about ``centre`` (n, 3) (the segment's moved centroid: it decouples turning
    from moving)."""
    fx, fy, cx, cy = intr
    R = Rt[hyp, :, :3]
    Y = np.einsum("nij,nj->ni", R, X) + Rt[hyp, :, 3]
    Z = np.maximum(Y[:, 2], 1e-6)
    u = fx * Y[:, 0] / Z + cx
    v = fy * Y[:, 1] / Z + cy
    smp, inside = _bilinear(stack, u, v)
    inside &= Y[:, 2] > 1e-3
    Iw, Ixw, Iyw, Dw, Dxw, Dyw, okw, nearw = smp.T
    ok_d = inside & (okw > 0.999)
    occluded = inside & (nearw > 0) & (nearw < Y[:, 2] - tau)
    r_i = Iw - (ph[hyp, 0] * I0p + ph[hyp, 1])
    r_d = Dw - Y[:, 2]
    m_i = inside & ~occluded
    m_d = ok_d & ~occluded & (np.abs(r_d) <= tau)
    x_i = (r_i / sig_i) ** 2
    x_d = (r_d / sig_d) ** 2
    # cost per pixel: the Charbonnier penalties; on a surface that is clearly not there (depth far
    # off): a poor depth match; depth unknown at t+1 (holes, edges): no depth term; a pixel moved out
    # of the image has no term (leaving the image is no evidence against a motion, but a motion that
    # keeps under a fifth of a segment in view and unhidden is not believed).
    # A pixel moved behind a nearer surface has no term either: the static background a moving
    # object covers at t+1 would otherwise pull the background's motion towards uncovering it.
    pen_i = 2.0 * (np.sqrt(1.0 + x_i) - 1.0)
    off = ok_d & ~occluded & ~m_d
    pen_d = np.where(m_d, 2.0 * (np.sqrt(1.0 + x_d) - 1.0), _MISS)
    n_d = np.bincount(hyp, m_d | off, n_hyp)
    n_in = np.bincount(hyp, m_i, n_hyp)
    count = np.bincount(hyp, minlength=n_hyp).astype(np.float64)
    cost = (np.bincount(hyp, np.where(m_i, pen_i, 0.0), n_hyp) / np.maximum(n_in, 1.0)
            + np.bincount(hyp, np.where(m_d | off, pen_d, 0.0), n_hyp) / np.maximum(n_d, 1.0))
    cost = np.where(n_in < 0.2 * count, cost + 2.0 * _MISS, cost)
    if not want_system:
        return cost, None, None
    iz = 1.0 / Z
    def rows(gx, gy):
        a = np.empty((X.shape[0], 3))
        a[:, 0] = fx * gx * iz
        a[:, 1] = fy * gy * iz
        a[:, 2] = -(fx * gx * Y[:, 0] + fy * gy * Y[:, 1]) * iz * iz
        return a
    a_i = rows(Ixw, Iyw)
    a_d = rows(np.where(ok_d, Dxw, 0.0), np.where(ok_d, Dyw, 0.0))
    a_d[:, 2] -= 1.0
    arm = Y - centre[hyp]
    n = X.shape[0]
    J_i = np.concatenate([a_i, np.cross(arm, a_i), -I0p[:, None], -np.ones((n, 1))], axis=1)
    J_d = np.concatenate([a_d, np.cross(arm, a_d), np.zeros((n, 2))], axis=1)
    w_i = m_i / np.sqrt(1.0 + x_i) / sig_i**2
    w_d = m_d / np.sqrt(1.0 + x_d) / sig_d**2
    A = np.zeros((n_hyp, 8, 8))
    b = np.zeros((n_hyp, 8))
    for j in range(8):
        b[:, j] = np.bincount(hyp, w_i * r_i * J_i[:, j] + w_d * r_d * J_d[:, j], n_hyp)
        for k in range(j, 8):
            A[:, j, k] = A[:, k, j] = np.bincount(
                hyp, w_i * J_i[:, j] * J_i[:, k] + w_d * J_d[:, j] * J_d[:, k], n_hyp)
    return cost, A, b


def segment_motions(pyr, seg, n_seg, inits, o, iterations=8):
    """The rigid motion of every segment by robust direct alignment, coarse to fine.

    Parameters
    ----------
    pyr : list of (I0, D0, I1, D1, intr)
        The image pyramid, finest first (level 0 = the segments' resolution).
    seg : ndarray of int, shape (H, W)
        Segment of every pixel of level 0 (-1: none).
    n_seg : int
    inits : ndarray, shape (n_seg, K, 3, 4)
        K starting motions [R | t] per segment.
    o : dict
        The estimator's options (``sigma_i``, ``sigma_d``, ``occlusion``, ``rigid_levels``).

    Returns
    -------
    Rt : ndarray, shape (n_seg, 3, 4)
    cost : ndarray, shape (n_seg,)
        Mean robust cost per pixel at the finest level aligned.
    """
    K = inits.shape[1]
    Rt = inits.reshape(n_seg * K, 3, 4).copy()
    twist = np.zeros((n_seg * K, 8))  # the motion since the start (to first order), gain, offset
    ph = np.tile([1.0, 0.0], (n_seg * K, 1))  # the brightness model I1 = a I0 + b of each hypothesis
    alive = np.ones(n_seg * K, bool)
    levels = min(o["rigid_levels"], len(pyr))
    sig_i = 2.0 * o["sigma_i"]
    cost = np.zeros(n_seg * K)
    for lev in range(levels - 1, -1, -1):
        I0, D0, I1, D1, intr = pyr[lev]
        fx, fy, cx, cy = intr
        step = 2**lev
        sl = seg[::step, ::step][: D0.shape[0], : D0.shape[1]]
        use = (sl >= 0) & (D0 > 0)
        ys, xs = np.nonzero(use)
        # at most rigid_max_pixels per segment (an even subsample of a big one: six unknowns)
        s_all = sl[ys, xs]
        counts = np.bincount(s_all, minlength=n_seg)
        stride = np.maximum(1, np.ceil(counts / o["rigid_max_pixels"])).astype(np.int64)
        order = np.argsort(s_all, kind="stable")
        rank = np.empty(order.size, np.int64)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        rank[order] = np.arange(order.size) - np.repeat(starts, counts)
        take = rank % stride[s_all] == 0
        ys, xs = ys[take], xs[take]
        z = D0[ys, xs]
        X = np.stack([(xs - cx) / fx * z, (ys - cy) / fy * z, z], axis=1)
        s_of = sl[ys, xs]
        # every pixel once per live hypothesis of its segment
        hyp_ids = np.arange(n_seg * K).reshape(n_seg, K)
        live = alive.reshape(n_seg, K)
        pix, hyp = [], []
        for k in range(K):
            on = live[s_of, k]
            pix.append(np.nonzero(on)[0])
            hyp.append(hyp_ids[s_of[on], k])
        pix = np.concatenate(pix)
        hyp = np.concatenate(hyp)
        Xp = X[pix]
        I0p = I0[ys, xs][pix]
        # the depth term's scale and trust region at each pixel's depth (noise grows with Z^2)
        sd = depth_sigma(Xp[:, 2], o)
        sig_d = 2.0 * sd
        tau = o["occlusion"] + 2.0 * (sd - o["sigma_d"])
        stack = _level_data(I1, D1, 3.0 * o["occlusion"])
        n_hyp = n_seg * K
        # a hypothesis moves at this level only where its segment has enough pixels here
        n_of = np.bincount(hyp, minlength=n_hyp).astype(np.float64)
        enough = alive & (n_of >= o["rigid_min_pixels"])
        damp = np.full(n_hyp, 1e-4)
        # each segment's centroid at t: its rotations are about it
        c0 = np.stack([np.bincount(hyp, Xp[:, k], n_hyp) for k in range(3)], axis=1)
        c0 /= np.maximum(n_of, 1.0)[:, None]

        def centre(M, c0=c0):
            return np.einsum("nij,nj->ni", M[:, :, :3], c0) + M[:, :, 3]

        cost, A, b = _evaluate(Xp, I0p, hyp, Rt, ph, stack, intr, sig_i, sig_d, tau, n_hyp, True, centre(Rt))
        for _ in range(iterations):
            good = enough & (np.abs(A).sum(axis=(1, 2)) > 0)
            if not good.any():
                break
            Ag = A[good]
            # a weak pull back to the start: the directions the data do not see (a plane sliding in
            # itself, a uniform cylinder turning about its axis) stay where they started
            prior = o["rigid_prior"] * np.einsum("nii->ni", Ag)[:, :, None] * np.eye(8)
            bg = b[good] + np.einsum("nij,nj->ni", prior, twist[good])
            Ag = Ag + prior
            # Levenberg–Marquardt: the diagonal scaled up until a step lowers the cost
            Ag = Ag + (damp[good][:, None, None] * np.eye(8)) * (np.einsum("nii->ni", Ag)[:, :, None] + 1e-9)
            delta = -np.linalg.solve(Ag, bg[..., None])[..., 0]
            trial = Rt.copy()
            ph_trial = ph.copy()
            dR = so3_exp(delta[:, 3:6])
            c = centre(Rt)[good]
            trial[good, :, :3] = dR @ Rt[good, :, :3]
            trial[good, :, 3] = np.einsum("nij,nj->ni", dR, Rt[good, :, 3] - c) + c + delta[:, :3]
            ph_trial[good] += delta[:, 6:]
            c_new, A_new, b_new = _evaluate(Xp, I0p, hyp, trial, ph_trial, stack, intr, sig_i, sig_d, tau,
                                            n_hyp, True, centre(trial))
            # the step must lower the cost with the prior's share (E = data + tw'P tw / 2, the mean
            # Charbonnier cost being 2 E / n per pixel)
            tw = twist[good] + delta
            n_px = np.maximum(n_of[good], 1.0)
            gain = (cost[good] + np.einsum("ni,nij,nj->n", twist[good], prior, twist[good]) / n_px) - (
                c_new[good] + np.einsum("ni,nij,nj->n", tw, prior, tw) / n_px)
            better = np.zeros(n_hyp, bool)
            better[np.nonzero(good)[0][gain >= 0]] = True
            Rt[better] = trial[better]
            ph[better] = ph_trial[better]
            twist[better] = tw[better[good]]
            cost = np.where(better, c_new, cost)
            A[better], b[better] = A_new[better], b_new[better]
            damp = np.where(better, np.maximum(damp * 0.3, 1e-6), np.where(good, damp * 10.0, damp))
            enough &= damp < 1e4
        if K > 1:
            # a segment aligned at this level keeps only its best start from now on (a segment too
            # small for this level keeps them all for the next one)
            moved = (enough | ~alive).reshape(n_seg, K).all(axis=1) & enough.reshape(n_seg, K).any(axis=1)
            if lev == 0:
                moved[:] = True
            c = np.where(alive, cost, np.inf).reshape(n_seg, K)
            best = np.argmin(c, axis=1)
            keep = np.zeros((n_seg, K), bool)
            keep[np.arange(n_seg), best] = True
            alive = np.where(moved[:, None], keep, alive.reshape(n_seg, K)).ravel()
    c = np.where(alive, cost, np.inf).reshape(n_seg, K)
    best = np.argmin(c, axis=1)
    out = Rt.reshape(n_seg, K, 3, 4)[np.arange(n_seg), best]
    ph_out = ph.reshape(n_seg, K, 2)[np.arange(n_seg), best]
    # a segment stays put unless its motion explains the frames clearly better than no motion: a
    # uniform wall "slides" along itself at no cost, and noise favours some small motion (sampling a
    # noisy depth map between pixels averages its noise down). The test is made on a coarse level,
    # whose depth is already an average of 4×4 readings.
    lev = min(2, len(pyr) - 1)
    I0, D0, I1, D1, intr = pyr[lev]
    fx, fy, cx, cy = intr
    step = 2**lev
    sl = seg[::step, ::step][: D0.shape[0], : D0.shape[1]]
    ys, xs = np.nonzero((sl >= 0) & (D0 > 0))
    z = D0[ys, xs]
    X = np.stack([(xs - cx) / fx * z, (ys - cy) / fy * z, z], axis=1)
    sd = depth_sigma(z, o)
    stack = _level_data(I1, D1, 3.0 * o["occlusion"])
    still = np.zeros((n_seg, 3, 4))
    still[:, :, :3] = np.eye(3)
    sid = sl[ys, xs]
    args = (X, I0[ys, xs], sid)
    rest = (stack, intr, sig_i, 2.0 * sd, o["occlusion"] + 2.0 * (sd - o["sigma_d"]), n_seg, False,
            np.zeros((n_seg, 3)))
    # no motion with its own brightness model (least squares on the pixels in view)
    i1 = _bilinear(stack[..., :1], X[:, 0] * fx / z + cx, X[:, 1] * fy / z + cy)[0][:, 0]  # I1(x)
    i0 = I0[ys, xs]
    sw = np.bincount(sid, minlength=n_seg).astype(np.float64)
    s0, s00 = np.bincount(sid, i0, n_seg), np.bincount(sid, i0 * i0, n_seg)
    s1, s01 = np.bincount(sid, i1, n_seg), np.bincount(sid, i0 * i1, n_seg)
    det = sw * s00 - s0 * s0
    ok = det > 1e-9 * np.maximum(sw * s00, 1e-30)
    ph_still = np.tile([1.0, 0.0], (n_seg, 1))
    ph_still[ok, 0] = (sw * s01 - s0 * s1)[ok] / det[ok]
    ph_still[ok, 1] = (s00 * s1 - s0 * s01)[ok] / det[ok]
    ph_still[~ok, 1] = np.where(sw > 0, (s1 - s0) / np.maximum(sw, 1.0), 0.0)[~ok]
    c_still, _, _ = _evaluate(*args, still, ph_still, *rest)
    c_best, _, _ = _evaluate(*args, out, ph_out, *rest)
    # (a segment too small at that level to compare keeps its motion)
    stay = (c_best >= (1.0 - o["rigid_still"]) * c_still) & (
        np.bincount(sid, minlength=n_seg) >= o["rigid_min_pixels"])
    out[stay] = still[stay]
    return out, np.where(stay, c_still, c_best)


def _correlate(image, templ):
    """Σ_q templ(q) image(q + d) for every shift d of ``templ`` inside ``image`` (float32)."""
    # imported here, as in _rgbd_match: the grader imports flowtrack without OpenCV installed
    import cv2

    return cv2.matchTemplate(image, templ, cv2.TM_CCORR)


def segment_search(pyr, seg, n_seg, o, level=1, max_share=0.3):
    r"""A start for every segment's alignment found by search: its best image shift.

    The matches of a segment may all be wrong (a nearly uniform face, a small object moving far, a
    brightness change), and the alignment only refines the start it is given. So the segment itself
    is searched for, as a template (its pixels only, not what lies around them), over every integer
    shift :math:`d` within ``search_radius``, on pyramid ``level`` (the radius halved per level; the
    alignment refines the shift below that level's pixel). Level 1 was chosen on the training split
    of the held-out pairs: against level 2 at 640×480 it left 24 pairs instead of 26 above the
    gross-outlier bar, for 10 % more time. A shift costs the per-pixel sum of squares, each after its
    own mean is removed, of

    .. math:: I_1(p + d) - I_0(p) \quad\text{and}\quad D_1(p + d) - D_0(p)

    over the segment's pixels :math:`p` that land inside the image (and, for depth, on a valid
    depth), scaled by ``sigma_i`` and the depth noise at the segment's depth: a brightness offset and
    a motion along the optical axis cost nothing, the outline of a uniform object is matched by its
    pixels falling off it. Every sum is a correlation of the frame t+1 with a masked template
    (``cv2.matchTemplate``, ``TM_CCORR``). Returns the 3-D translation of the best shift (the
    segment's points moved to :math:`p + d` and to the mean depth change), shape ``(n_seg, 3)``, and
    which segments were searched (those with ``rigid_min_pixels`` pixels at that level and at most
    ``max_share`` of the image: the background is static or moves as a whole, which its matches see).
    """
    level = min(level, len(pyr) - 1)
    I0, D0, I1, D1, intr = pyr[level]
    fx, fy, cx, cy = intr
    h, w = D0.shape
    step = 2**level
    sl = seg[::step, ::step][:h, :w]
    R = max(1, int(np.ceil(o["search_radius"] / step)))
    out = np.zeros((n_seg, 3))
    searched = np.zeros(n_seg, bool)
    on = (sl >= 0) & (D0 > 0)
    counts = np.bincount(sl[on], minlength=n_seg)
    # frame t+1 padded by the radius: outside the image nothing is compared
    pad = lambda a: np.pad(a, R).astype(np.float32)  # noqa: E731
    inside = pad(np.ones((h, w)))
    vd = pad(D1 > 0)
    Ip, I2p = pad(I1), pad(I1 * I1)
    Dp, D2p = pad(np.where(D1 > 0, D1, 0.0)), pad(np.where(D1 > 0, D1 * D1, 0.0))
    objs = ndimage.find_objects(np.where(on, sl + 1, 0))
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    dyy, dxx = np.mgrid[-R:R + 1, -R:R + 1]
    for k in np.nonzero((counts >= o["rigid_min_pixels"] / step**2) & (counts <= max_share * h * w))[0]:
        if k >= len(objs) or objs[k] is None:
            continue
        sy, sx = objs[k]
        m = (sl[sy, sx] == k) & on[sy, sx]
        mt = m.astype(np.float32)
        i0 = np.where(m, I0[sy, sx], 0.0).astype(np.float32)
        z0 = np.where(m, D0[sy, sx], 0.0).astype(np.float32)
        # the region of frame t+1 the template can reach (padded coordinates)
        ry, rx = slice(sy.start, sy.stop + 2 * R), slice(sx.start, sx.stop + 2 * R)
        n_i = _correlate(inside[ry, rx], mt)
        s1, s11 = _correlate(Ip[ry, rx], mt), _correlate(I2p[ry, rx], mt)
        s10 = _correlate(Ip[ry, rx], i0)
        s0, s00 = _correlate(inside[ry, rx], i0), _correlate(inside[ry, rx], i0 * i0)
        n_d = _correlate(vd[ry, rx], mt)
        t1, t11 = _correlate(Dp[ry, rx], mt), _correlate(D2p[ry, rx], mt)
        t10 = _correlate(Dp[ry, rx], z0)
        t0, t00 = _correlate(vd[ry, rx], z0), _correlate(vd[ry, rx], z0 * z0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ssd_i = (s11 - 2 * s10 + s00) - (s1 - s0) ** 2 / n_i
            ssd_d = (t11 - 2 * t10 + t00) - (t1 - t0) ** 2 / n_d
            sd = float(depth_sigma(np.median(D0[sy, sx][m]), o))
            cost = ssd_i / n_i / o["sigma_i"] ** 2 + ssd_d / n_d / (2.0 * sd) ** 2
        n = float(m.sum())
        # most of the segment must stay comparable (in the image, on valid depth)
        cost = np.where((n_i >= 0.5 * n) & (n_d >= 0.3 * n), cost, np.inf)
        if not np.isfinite(cost).any():
            continue
        # of (nearly) equal costs the shortest shift: a uniform face slides along itself for free
        cost = cost + 1e-3 * (dxx**2 + dyy**2)
        iy, ix = np.unravel_index(np.argmin(cost), cost.shape)
        dy, dx = iy - R, ix - R
        dz = float((t1[iy, ix] - t0[iy, ix]) / n_d[iy, ix])
        z = D0[sy, sx][m]
        x, y = xx[sy, sx][m], yy[sy, sx][m]
        X0 = np.stack([(x - cx) / fx * z, (y - cy) / fy * z, z], axis=1)
        z1 = z + dz
        X1 = np.stack([(x + dx - cx) / fx * z1, (y + dy - cy) / fy * z1, z1], axis=1)
        out[k] = np.median(X1 - X0, axis=0)
        searched[k] = True
    return out, searched


def rigid_field(match, I0, D0, I1, D1, pyr, intr, o):
    """The match field with every pixel of a well-aligned segment moved rigidly with its segment.

    ``match``: :func:`flowtrack._rgbd_match.match_field`'s dict (updated copy returned), ``I0, D0,
    I1, D1``: the frames (grey, depth) at full resolution, ``pyr``: the pyramid of the frames (I1
    with the brightness change removed), ``intr`` (fx, fy, cx, cy). A pixel takes its segment's
    rigid displacement where that matches its neighbourhood at least about as well as its own match
    (the matching cost of :func:`flowtrack._rgbd_match.pixel_cost`, with a margin
    ``rigid_margin`` times the image's typical cost in favour of the rigid one); such a pixel is
    matched when that cost is low, hidden when its rigidly moved point leaves the image or lands
    behind a nearer surface.
    """
    H, W = D0.shape
    fx, fy, cx, cy = intr
    sig = depth_sigma(D0, o)
    tau = o["occlusion"] + 2.0 * (sig - o["sigma_d"])
    seg, n = depth_segments(D0, tau, o["rigid_min_pixels"])
    out = dict(match)
    out["segments"] = seg
    if n == 0:
        return out
    m, conf = match["m"], match["conf"] > 0
    on = seg >= 0
    # starts: no motion; the median match of the segment; the median of its matched pixels;
    inits = np.zeros((n, 4, 3, 4))
    inits[:, :, :, :3] = np.eye(3)
    s_on = seg[on]
    order = np.argsort(s_on, kind="stable")
    bounds = np.searchsorted(s_on[order], np.arange(n + 1))
    m_on, c_on = m[on][order], conf[on][order]
    for k in range(n):
        mk, ck = m_on[bounds[k]:bounds[k + 1]], c_on[bounds[k]:bounds[k + 1]]
        inits[k, 1, :, 3] = np.median(mk, axis=0)
        inits[k, 2, :, 3] = np.median(mk[ck], axis=0) if ck.sum() >= 5 else inits[k, 1, :, 3]
    # and the segment's own best shift, found by search (its matches may all be wrong)
    t_search, searched = segment_search(pyr, seg, n, o)
    inits[:, 3, :, 3] = np.where(searched[:, None], t_search, inits[:, 1, :, 3])
    Rt, _ = segment_motions(pyr, seg, n, inits, o)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    X = np.stack([(xx - cx) / fx * D0, (yy - cy) / fy * D0, D0], axis=-1)
    Rk = Rt[s_on]
    Y = np.einsum("nij,nj->ni", Rk[:, :, :3], X[on]) + Rk[:, :, 3]
    s_r = np.zeros((H, W, 3))
    s_r[on] = Y - X[on]
    Yz = np.where(on, 0.0, 1.0)
    Yz[on] = Y[:, 2]
    Yz = np.maximum(Yz, 1e-6)
    Yfull = X + s_r
    u = fx * Yfull[..., 0] / Yz + cx
    v = fy * Yfull[..., 1] / Yz + cy
    flow_r = np.stack([u - xx, v - yy], axis=-1)
    # a segment motion beyond what the search covers (image motion, depth change) is not believed
    speed = np.where(on, np.linalg.norm(flow_r, axis=-1), 0.0)
    dz = np.where(on, np.abs(s_r[..., 2]), 0.0)
    wild = np.zeros(n + 1, bool)
    np.logical_or.at(wild, np.where(on, seg, n),
                     (speed > 1.5 * o["search_radius"]) | (dz > o["match_max_dz"]))
    on &= ~wild[np.where(on, seg, n)]
    cost_r = pixel_cost(I0, D0, I1, D1, np.where(on[..., None], flow_r, 0.0), o)
    typical = match["typical"]
    # a matched pixel keeps its match unless the rigid motion fits it better; an unmatched one takes
    # the rigid motion unless it fits clearly worse
    margin = np.where(conf, 0.0, o["rigid_margin"] * typical)
    inside = (u >= 0) & (v >= 0) & (u <= W - 1) & (v <= H - 1)
    # a pixel the rigid motion takes out of the image has no cost to compare: it moves with its segment
    # (and where both agree in the image, the rigid motion: its depth change is that of the whole
    # segment, not the difference of two noisy depth readings)
    agree = np.linalg.norm(flow_r - match["flow"], axis=-1) <= o["rigid_agree_px"]
    take = on & ((cost_r <= match["cost"] + margin) | ~inside | agree)
    # behind a nearer surface: every valid depth around the target clearly in front of the point
    ui = np.clip(np.floor(u).astype(np.intp), 0, W - 2)
    vi = np.clip(np.floor(v).astype(np.intp), 0, H - 2)
    far = np.zeros((H, W))
    for dy in (0, 1):
        for dx in (0, 1):
            far = np.maximum(far, D1[vi + dy, ui + dx])
    behind = (far > 0) & (far < Yz - tau)
    good = cost_r <= o["match_cost"] * typical
    out["m"] = np.where(take[..., None], s_r, m)
    out["conf"] = np.where(take, (good & inside & ~behind).astype(np.float64), match["conf"])
    out["hidden"] = np.where(take, ~inside | (behind & ~good), match["hidden"]) & (D0 > 0)
    out["flow"] = np.where(take[..., None], flow_r, match["flow"])
    out["rigid"] = take
    return out
