r"""The match-based start of :func:`flowtrack.rgbd_flow.rgbd_scene_flow`.

Coarse to fine from zero cannot follow a displacement of more than about two pixels at its coarsest
level, and a linearised data term next to a silhouette pulls a point onto the surface behind it. As in
large-displacement variational flow (Brox and Malik, LDOF, 2011) the variational refinement therefore
starts from, and is tied to, a field of *matches*: displacements found by searching, not by
linearising.

1. **Optical-flow candidates** (both directions, t to t+1 and back). OpenCV's DIS optical flow
   (Kroeger et al., 2016, preset medium) on the grey images; and DIS again, started from an
   exhaustive block search on a coarse level (about 80 px wide) of both the grey and the log-depth
   images: every displacement of up to ``search_radius`` px, mean-normalised grey differences plus
   ``match_depth_weight`` times truncated (``match_depth_trunc``) log-depth differences summed over
   a 5×5 window. The block search finds large motions, of nearly uniform objects too (their depth
   outline moves with them); DIS refines its whole coarse pixels.
2. **Selection.** Per pixel, the candidate with the lowest matching cost (:func:`pixel_cost`: the
   same two differences summed over a ``match_window`` window, the grey one insensitive to a change
   of brightness between the frames); DIS from zero unless another candidate is better by
   ``match_margin`` (in a uniform region the costs differ by noise only).
3. **Confidence.** The thresholds are relative to the image's *typical* cost (its median, at least
   half a grey level). A pixel is *matched* when its cost is under ``match_cost`` typical costs, its
   neighbourhood has texture (the smaller eigenvalue of the structure tensor over the window at least
   ``match_texture`` typical costs squared), it is not next to a depth jump (a silhouette or a flying
   pixel, whose depth belongs to neither surface), its depth change is plausible (``match_max_dz``),
   and the backward flow brings it back to within ``match_fb`` px — or its cost is under
   ``match_sure`` typical costs (the backward flow of a surface cut by the image border is often
   lost). A pixel whose match leaves the image, or lands next to a surface clearly in front of it
   with a poor cost, is *hidden* at t+1.
4. **Lifting.** A pixel's displacement is :math:`X_1 - X_0` with :math:`X_1` back-projected at the
   matched position :math:`x + u` with the depth of frame t+1 read there: of the four pixels around
   :math:`x + u`, the valid depth nearest the point's own (a match next to a silhouette does not read
   the other surface); where even that one is more than ``match_max_dz`` away (or none is valid),
   the point keeps its depth.
5. **Brightness.** :math:`I_1(x + u) \approx a I_0(x) + b`, fitted by least squares with three robust
   refits on the better half of the matched pixels.
6. **Fill** (:func:`geodesic_fill`, used by :func:`flowtrack.rgbd_flow.rgbd_scene_flow` after the
   rigid segments of :mod:`flowtrack._rgbd_segments`). Every pixel that is not matched takes the
   displacement of the geodesically nearest matched pixel, the path length counting depth jumps
   (``fill_depth_scale``) and grey-level jumps (``fill_grey_scale``): a pixel of a uniform face or a
   hidden pixel takes the motion of its own surface, not of the one beside it (EpicFlow's edge-aware
   interpolation, Revaud et al. 2015, with depth edges). A pixel farther than ``fill_reach`` from
   every matched pixel (a surface without any) keeps its own match.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["depth_jumps", "geodesic_fill", "geodesic_nearest_numpy", "geodesic_steps", "match_field",
           "pixel_cost"]


# --------------------------------------------------------------------------------------------------
# geodesic nearest-neighbour fill
# --------------------------------------------------------------------------------------------------
def geodesic_steps(D, I, tau_z, tau_i, hole_step):
    """Lengths of the horizontal (H, W-1) and vertical (H-1, W) pixel steps:
    ``1 + |dZ| / tau_z + |dI| / tau_i`` (``tau_z`` a scalar or per pixel, the mean of the two ends
    used), ``hole_step`` for the depth part where an end has no depth."""
    valid = D > 0
    tz = np.broadcast_to(np.asarray(tau_z, dtype=np.float64), D.shape)
    out = []
    for sa, sb in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                   ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        depth = np.abs(D[sa] - D[sb]) / (0.5 * (tz[sa] + tz[sb]))
        step = 1.0 + np.abs(I[sa] - I[sb]) / tau_i + np.where(valid[sa] & valid[sb], depth, hole_step)
        out.append(np.ascontiguousarray(step))
    return out


def geodesic_nearest_numpy(cost_h, cost_v, known, passes):
    """:func:`flowtrack._rgbd_kernels.geodesic_nearest` by the same sweeps, vectorised across lines."""
    H, W = known.shape
    dist = np.where(known, 0.0, np.inf)
    src = np.where(known, np.arange(H * W).reshape(H, W), -1)
    for _ in range(passes):
        for j, jp in [(j, j - 1) for j in range(1, W)] + [(j, j + 1) for j in range(W - 2, -1, -1)]:
            c = dist[:, jp] + cost_h[:, min(j, jp)]
            better = c < dist[:, j]
            dist[:, j] = np.where(better, c, dist[:, j])
            src[:, j] = np.where(better, src[:, jp], src[:, j])
        for i, ip in [(i, i - 1) for i in range(1, H)] + [(i, i + 1) for i in range(H - 2, -1, -1)]:
            c = dist[ip] + cost_v[min(i, ip)]
            better = c < dist[i]
            dist[i] = np.where(better, c, dist[i])
            src[i] = np.where(better, src[ip], src[i])
    return src, dist


def depth_jumps(D, tau):
    """Pixels with a 4-neighbour more than ``tau`` (m) nearer or farther, or without depth."""
    valid = D > 0
    out = ~valid
    for ax in (0, 1):
        j = np.abs(np.diff(D, axis=ax)) > tau
        j &= np.delete(valid, 0, axis=ax) & np.delete(valid, -1, axis=ax)
        if ax == 0:
            out[1:] |= j
            out[:-1] |= j
        else:
            out[:, 1:] |= j
            out[:, :-1] |= j
    return out


def geodesic_fill(m, known, D, I, *, depth_scale, grey_scale, edge_jump, kernels=None):
    """``m`` (H, W, C) with every pixel not ``known`` set to its geodesically nearest known pixel's.

    The length of a path is the number of its steps plus its depth jumps in units of ``depth_scale``
    (m, scalar or per pixel) and its grey-level jumps in units of ``grey_scale``
    (:func:`geodesic_steps`; a step into a pixel without depth counts 100), so an unmatched or hidden
    pixel takes the value of the nearest known pixel *on its own surface*. Known pixels next to a
    depth jump of more than ``edge_jump`` (silhouettes, flying pixels: their depth is close to both
    sides and their match often belongs to the other one) are not used as sources, unless nothing
    else is known. ``kernels``: the numba module (:mod:`flowtrack._rgbd_kernels`) or None for the
    numpy sweeps (the same result).

    Returns
    -------
    filled : ndarray, shape (H, W, C)
    dist : ndarray, shape (H, W)
        The geodesic distance to the source (0 at the sources, inf where none is reachable).
    """
    source = known & ~ndimage.binary_dilation(depth_jumps(D, edge_jump), iterations=1)
    if source.any():
        known = source
    if not known.any():
        return m.copy(), np.full(known.shape, np.inf)
    if known.all():
        return m.copy(), np.zeros(known.shape)
    ch, cv = geodesic_steps(D, I, depth_scale, grey_scale, 100.0)
    if kernels is not None:
        src, dist = kernels.geodesic_nearest(ch, cv, known, 2)
    else:
        src, dist = geodesic_nearest_numpy(ch, cv, known, 2)
    return m.reshape(-1, m.shape[-1])[src].reshape(m.shape), dist


# --------------------------------------------------------------------------------------------------
# candidates
# --------------------------------------------------------------------------------------------------
def _u8(img):
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def _warp(cv2, img, flow):
    """``img`` (float32) sampled at x + flow (bilinear, border replicated)."""
    H, W = img.shape[:2]
    mx = np.arange(W, dtype=np.float32)[None, :] + flow[..., 0]
    my = np.arange(H, dtype=np.float32)[:, None] + flow[..., 1]
    return cv2.remap(img, mx.astype(np.float32), my.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def _log_depth(D):
    return np.log(np.where(D > 0, D, 1.0)).astype(np.float32), (D > 0).astype(np.float32)


def _coarse_search(cv2, I0, L0, V0, I1, L1, V1, scale, radius, window, depth_weight, depth_trunc):
    """Exhaustive block matching at 1/2**scale: the best integer displacement per coarse pixel."""
    def down(a):
        for _ in range(scale):
            a = cv2.pyrDown(a)
        return a

    g0, g1 = down(I0), down(I1)
    g0 = g0 - cv2.blur(g0, (window, window))
    g1 = g1 - cv2.blur(g1, (window, window))
    # log depth averaged over the valid pixels; NaN where under half of the block has depth
    l0 = down(L0 * V0) / np.maximum(down(V0), 1e-6)
    l0[down(V0) < 0.5] = np.nan
    l1 = down(L1 * V1) / np.maximum(down(V1), 1e-6)
    l1[down(V1) < 0.5] = np.nan
    h, w = g0.shape
    R = radius
    p1 = cv2.copyMakeBorder(g1, R, R, R, R, cv2.BORDER_REPLICATE)
    q1 = np.pad(l1, R, mode="edge")
    best = np.full((h, w), np.inf, np.float32)
    arg = np.zeros((h, w, 2), np.float32)
    for dy in range(-R, R + 1):
        for dx in range(-R, R + 1):
            dd = np.abs(q1[R + dy:R + dy + h, R + dx:R + dx + w] - l0)
            dd = np.where(np.isfinite(dd), np.minimum(dd, depth_trunc), depth_trunc)
            c = np.abs(p1[R + dy:R + dy + h, R + dx:R + dx + w] - g0) + (depth_weight / depth_trunc) * dd
            c = cv2.blur(c, (window, window))
            better = c < best
            best = np.where(better, c, best)
            arg[better] = (dx, dy)
    return arg * np.float32(2**scale)


def _cost(cv2, I0n, I1n, L0, V0, L1, V1, flow, window, depth_weight, depth_trunc):
    """Matching cost of a flow field: windowed mean-normalised grey + truncated log-depth difference."""
    c = np.abs(_warp(cv2, I1n, flow) - I0n)
    d = np.abs(_warp(cv2, L1, flow) - L0)
    ok = (_warp(cv2, V1, flow) > 0.999) & (V0 > 0)
    d = np.where(ok, np.minimum(d, depth_trunc), depth_trunc)
    return cv2.blur(c + (depth_weight / depth_trunc) * d, (window, window))


def pixel_cost(I0, D0, I1, D1, flow, o):
    """The matching cost of an optical flow ``flow`` (H, W, 2) at every pixel (the selection's cost)."""
    import cv2

    win = o["match_window"]
    I0f = np.ascontiguousarray(I0, dtype=np.float32)
    I1f = np.ascontiguousarray(I1, dtype=np.float32)
    L0, V0 = _log_depth(D0)
    L1, V1 = _log_depth(D1)
    I0n = I0f - cv2.blur(I0f, (win, win))
    I1n = I1f - cv2.blur(I1f, (win, win))
    return _cost(cv2, I0n, I1n, L0, V0, L1, V1, flow.astype(np.float32), win, o["match_depth_weight"],
                 o["match_depth_trunc"])


def _structure(cv2, I, window):
    """Smaller eigenvalue of the structure tensor of ``I`` summed over ``window`` (grey² per px²)."""
    gx = cv2.Sobel(I, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(I, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    a = cv2.blur(gx * gx, (window, window))
    b = cv2.blur(gx * gy, (window, window))
    c = cv2.blur(gy * gy, (window, window))
    return 0.5 * (a + c) - np.sqrt(0.25 * (a - c) ** 2 + b * b)


# --------------------------------------------------------------------------------------------------
# the match field
# --------------------------------------------------------------------------------------------------
def _one_way(cv2, I0f, L0, V0, I1f, L1, V1, o):
    """The selected optical flow from frame a to frame b: (flow, its cost, candidates, their costs)."""
    H, W = I0f.shape
    win = o["match_window"]
    dw, dtr = o["match_depth_weight"], o["match_depth_trunc"]
    g0, g1 = _u8(I0f), _u8(I1f)
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    cands = [dis.calc(g0, g1, None)]
    scale = max(0, int(np.round(np.log2(max(H, W) / 80.0))))
    radius = int(np.ceil(o["search_radius"] / 2**scale))
    if radius > 0:
        coarse = _coarse_search(cv2, I0f, L0, V0, I1f, L1, V1, scale, radius, 5, dw, dtr)
        coarse = cv2.resize(coarse, (W, H), interpolation=cv2.INTER_NEAREST)
        # the block search's field is whole coarse pixels: DIS refines it (it is no candidate itself)
        cands.append(dis.calc(g0, g1, coarse.copy()))
    I0n = I0f - cv2.blur(I0f, (win, win))
    I1n = I1f - cv2.blur(I1f, (win, win))
    costs = np.stack([_cost(cv2, I0n, I1n, L0, V0, L1, V1, f, win, dw, dtr) for f in cands])
    # DIS from zero unless another candidate is clearly better (in uniform regions the costs differ
    # only by noise, and DIS's own smoothing is the better guess there)
    margin = np.zeros((len(cands), 1, 1), np.float32)
    margin[1:] = o["match_margin"]
    best = np.argmin(costs + margin, axis=0)
    flow = np.take_along_axis(np.stack(cands), best[None, ..., None], 0)[0]
    cost = np.take_along_axis(costs, best[None], 0)[0]
    return flow, cost, cands, costs


def match_field(I0, D0, I1, D1, intr, o, kernels=None):
    """The match of every pixel of frame t (see the module documentation).

    Parameters
    ----------
    I0, I1 : ndarray, shape (H, W)
        Grey images (float, about [0, 1]).
    D0, D1 : ndarray, shape (H, W)
        Depths (m), 0 where invalid.
    intr : tuple
        ``(fx, fy, cx, cy)``.
    o : dict
        The options of :func:`flowtrack.rgbd_flow.rgbd_scene_flow`.

    Returns
    -------
    dict
        ``m`` (H, W, 3) displacements (m), ``conf`` (H, W) in {0, 1}, ``hidden`` (H, W) bool,
        ``flow`` (H, W, 2) the selected optical flow (px), ``gain`` (a, b) of
        :math:`I_1 \\approx a I_0 + b`.
    """
    import cv2

    cv2.setNumThreads(1)
    H, W = I0.shape
    fx, fy, cx, cy = intr
    I0f = np.ascontiguousarray(I0, dtype=np.float32)
    I1f = np.ascontiguousarray(I1, dtype=np.float32)
    L0, V0 = _log_depth(D0)
    L1, V1 = _log_depth(D1)
    win = o["match_window"]
    flow, cost, cands, costs = _one_way(cv2, I0f, L0, V0, I1f, L1, V1, o)
    back, _, _, _ = _one_way(cv2, I1f, L1, V1, I0f, L0, V0, o)
    # forward-backward consistency: the backward flow at x + u leads back to x
    fb = np.linalg.norm(flow + _warp(cv2, back, flow), axis=-1)
    flow = flow.astype(np.float64)

    # lifting: x + u, and the depth at t+1 read at the valid one of its four pixels nearest Z0
    xx, yy = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    xq, yq = xx + flow[..., 0], yy + flow[..., 1]
    inside = (xq >= 0) & (yq >= 0) & (xq <= W - 1) & (yq <= H - 1)
    x0 = np.clip(np.floor(xq).astype(np.intp), 0, W - 1)
    y0 = np.clip(np.floor(yq).astype(np.intp), 0, H - 1)
    Z1 = np.zeros((H, W))
    near = np.full((H, W), np.inf)
    front = np.full((H, W), np.inf)  # the nearest surface around x + u at t+1
    for dy in (0, 1):
        for dx in (0, 1):
            d = D1[np.minimum(y0 + dy, H - 1), np.minimum(x0 + dx, W - 1)]
            ok = d > 0
            gap = np.where(ok, np.abs(d - D0), np.inf)
            take = gap < near
            Z1 = np.where(take, d, Z1)
            near = np.where(take, gap, near)
            front = np.where(ok, np.minimum(front, d), front)
    valid0 = D0 > 0
    # a depth change beyond match_max_dz per frame reads another surface (or none): the point keeps
    # its depth (a per-pixel sanity bound; such a pixel is never matched, but it may keep this field)
    Z1 = np.where((Z1 > 0) & (near <= o["match_max_dz"]), Z1, D0)
    X0 = np.stack([(xx - cx) / fx * D0, (yy - cy) / fy * D0, D0], axis=-1)
    X1 = np.stack([(xq - cx) / fx * Z1, (yq - cy) / fy * Z1, Z1], axis=-1)
    m = np.where(valid0[..., None], X1 - X0, 0.0)

    # confidence
    # the thresholds are relative to the image's typical cost (its noise level): the median cost
    tex = _structure(cv2, I0f, win)
    # (at least half a grey level: a noiseless rendering matches perfectly where nothing moves)
    typical = max(float(np.median(cost[valid0])) if valid0.any() else 1.0, 0.002)
    good_cost = cost <= o["match_cost"] * typical
    tau = o["occlusion"]
    on_edge = ndimage.binary_dilation(depth_jumps(D0, tau), iterations=1)
    plausible = near <= o["match_max_dz"]
    conf = (valid0 & inside & np.isfinite(near) & plausible & good_cost & ~on_edge
            & (tex >= o["match_texture"] * typical**2)
            # the backward flow confirms the match, or its cost alone is convincing (the backward
            # flow of a surface at the image border, half of it gone at t+1, is often lost)
            & ((fb <= o["match_fb"]) | (cost <= o["match_sure"] * typical)))
    # hidden at t+1: a surface clearly in front of where the point was, and no good match
    hidden = valid0 & ((~inside) | ((front < D0 - tau) & ~good_cost)) & ~conf

    # brightness: I1(x + u) = a I0(x) + b, fitted on the pixels matched with a low cost (a few
    # least-squares refits without the residuals beyond three robust standard deviations)
    gain = (1.0, 0.0)
    fit = valid0 & inside & ~on_edge & (cost <= np.quantile(cost[valid0], 0.5))
    if fit.sum() > 100:
        i1 = _warp(cv2, I1f, flow.astype(np.float32))[fit].astype(np.float64)
        i0 = I0f[fit].astype(np.float64)
        keep = np.ones(i0.size, bool)
        a, b = 1.0, 0.0
        for _ in range(4):
            A = np.column_stack([i0[keep], np.ones(keep.sum())])
            a, b = np.linalg.lstsq(A, i1[keep], rcond=None)[0]
            r = np.abs(i1 - (a * i0 + b))
            keep = r <= 3.0 * 1.4826 * np.median(r) + 1e-6
        if 0.5 < a < 2.0 and np.ptp(i0[keep]) > 0.05:
            gain = (float(a), float(b))
    return {"m": m, "conf": conf.astype(np.float64), "hidden": hidden, "flow": flow, "gain": gain,
            "cost": cost, "typical": typical, "texture": tex, "candidates": cands, "costs": costs, "fb": fb}
