r"""CLEAR-MOT and identity (IDF1) metrics for multi-object tracking.

The evaluation follows py-motmetrics (Heindl et al.) event by event, so that its published figures
for the MOTChallenge 2015 sequence TUD-Campus are reproduced exactly (see
:func:`flowtrack.datasets.tud_campus_tracks`, which loads it).

**Per-frame matching** (Bernardin & Stiefelhagen 2008). Let :math:`d_{ij}` be the distance between
ground-truth object :math:`i` and hypothesis :math:`j` in frame :math:`t`; pairs with
:math:`d_{ij} > \tau` (``max_dist``) are never matched.

1. *Carry forward*: a ground-truth object whose last matched hypothesis is present in frame
   :math:`t` with :math:`d_{ij} \le \tau` keeps it (a ``MATCH``).
2. *Assign the rest*: the remaining objects and hypotheses are matched by a minimum-cost
   assignment (the Hungarian problem, :func:`scipy.optimize.linear_sum_assignment`) over the pairs
   within the threshold. A pair :math:`(i, j)` is an *identity switch* when object :math:`i` was
   matched before and its last matched hypothesis is not :math:`j`; otherwise it is a ``MATCH``.
3. Unmatched objects are misses (FN), unmatched hypotheses false positives (FP).

With :math:`G = \sum_t |\mathrm{gt}_t|` ground-truth appearances and :math:`c_t` the matched pairs
(matches and switches),

.. math::

   \mathrm{MOTA} = 1 - \frac{\mathrm{FN} + \mathrm{FP} + \mathrm{IDSW}}{G}, \qquad
   \mathrm{MOTP} = \frac{\sum_t \sum_{(i,j) \in c_t} d_{ij}}{\sum_t |c_t|}.

MOTP is the mean *distance* of the matched pairs (the py-motmetrics convention; the MOTChallenge
devkit reports :math:`100\,(1 - \mathrm{MOTP})` for IoU).

**Identity metrics** (Ristani et al. 2016). Let :math:`n_{oh}` be the number of frames in which
ground-truth trajectory :math:`o` and hypothesis trajectory :math:`h` are both present within the
threshold. A one-to-one map between trajectory ids maximising :math:`\sum n_{oh}` over the mapped
pairs (a bipartite matching, solved globally over the whole sequence) gives the identity true
positives :math:`\mathrm{IDTP}`; then :math:`\mathrm{IDFN} = G - \mathrm{IDTP}`,
:math:`\mathrm{IDFP} = H - \mathrm{IDTP}` (:math:`H` hypothesis appearances) and

.. math::  \mathrm{IDF1} = \frac{2\,\mathrm{IDTP}}{G + H}.

(py-motmetrics phrases this as a min-cost assignment of cost :math:`c_o + c_h - 2 n_{oh}` with
dummy nodes; the minimisers coincide.)

**Objects nobody can see** (:func:`remove_ignored`). As MOTChallenge does with its distractors and
heavily occluded people, ground truth may name objects that are to be *ignored* in a frame (hidden,
outside the image, too small to be detected): a hypothesis matched to one of them in that frame (one
per object, by the same gated min-cost assignment, jointly with the objects that count) is removed
before scoring, so that it is neither a false positive nor a match.

**Scene flow judged by the worst case** (:func:`worst_case_flow_metrics`). With :math:`s_p` the true
and :math:`\hat s_p` the estimated displacement of pixel :math:`p` (one frame, metres), the end-point
error is :math:`e_p = \lVert \hat s_p - s_p \rVert` (a method without an answer at :math:`p`
predicts :math:`\hat s_p = 0`). Pixel :math:`p` is a *gross outlier* when

.. math::  e_p > \tau_\text{abs} \quad\text{and}\quad e_p > \tau_\text{rel} \lVert s_p \rVert

(the KITTI convention, an error large in absolute terms *and* relative to the motion; defaults 1 cm
and 50 %), counted over the moving pixels. The *interior* of an object (:func:`interior_mask`) are its
pixels whose whole :math:`(2w+1) \times (2w+1)` neighbourhood lies on it (:math:`w = 2`): at least
:math:`w` px from its silhouette; the largest error there is what a robot acting on the worst pixel
of a body meets.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from ._validation import as_array, positive

__all__ = [
    "clear_mot",
    "flow_end_point_errors",
    "interior_mask",
    "iou_distance",
    "remove_ignored",
    "worst_case_flow_metrics",
]

_DISTANCES = ("euclidean", "iou")


# --------------------------------------------------------------------------------------------------
# distances
# --------------------------------------------------------------------------------------------------
def _check_boxes(boxes: np.ndarray, name: str) -> np.ndarray:
    if (boxes[..., 2:] < 0).any():
        raise ValueError(f"{name} must have non-negative widths and heights")
    return boxes


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of broadcastable ``[x, y, w, h]`` boxes (same operations as py-motmetrics' ``boxiou``)."""
    a_min, a_max = a[..., :2], a[..., :2] + a[..., 2:]
    b_min, b_max = b[..., :2], b[..., :2] + b[..., 2:]
    i_size = np.maximum(np.minimum(a_max, b_max) - np.maximum(a_min, b_min), 0.0)
    i_vol = np.prod(i_size, axis=-1)
    a_vol = np.prod(np.maximum(a_max - a_min, 0.0), axis=-1)
    b_vol = np.prod(np.maximum(b_max - b_min, 0.0), axis=-1)
    u_vol = a_vol + b_vol - i_vol
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(i_vol == 0, 0.0, i_vol / np.where(u_vol == 0, 1.0, u_vol))


def iou_distance(boxes_a, boxes_b) -> np.ndarray:
    r"""Pairwise IoU distance :math:`1 - \mathrm{IoU}` between two sets of boxes.

    .. math::  d(a, b) = 1 - \frac{|a \cap b|}{|a| + |b| - |a \cap b|},

    with :math:`d = 1` when the boxes do not overlap (including degenerate, zero-area boxes).

    Parameters
    ----------
    boxes_a : array_like, shape (N, 4)
        Boxes ``[x, y, w, h]`` (top-left corner, width, height; ``w, h >= 0``).
    boxes_b : array_like, shape (M, 4)
        Boxes in the same format.

    Returns
    -------
    ndarray, shape (N, M)
        Distances in :math:`[0, 1]`.

    Examples
    --------
    >>> iou_distance([[0, 0, 2, 2]], [[1, 0, 2, 2], [0, 0, 2, 2], [5, 5, 1, 1]])
    array([[0.66666667, 0.        , 1.        ]])
    """
    a = _check_boxes(as_array(boxes_a, "boxes_a", ("N", 4)), "boxes_a")
    b = _check_boxes(as_array(boxes_b, "boxes_b", ("M", 4)), "boxes_b")
    return 1.0 - _iou(a[:, None, :], b[None, :, :])


def _euclidean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=-1))


# --------------------------------------------------------------------------------------------------
# assignment helpers
# --------------------------------------------------------------------------------------------------
def _gated_assignment(costs: np.ndarray) -> list[tuple[int, int]]:
    """Min-cost assignment over the finite entries of ``costs`` (NaN = do not pair).

    Non-edges get a cost so large that no optimal solution of the completed problem uses one
    unless it must (py-motmetrics' ``add_expensive_edges``); pairs on non-edges are then dropped.
    The result has the most pairs possible and, among those, the least total cost.
    """
    if costs.size == 0:
        return []
    valid = np.isfinite(costs)
    if not valid.any():
        return []
    c = np.abs(costs[valid]).max() + 1.0
    large = 2 * min(costs.shape) * c + 1.0
    rows, cols = linear_sum_assignment(np.where(valid, costs, large))
    return [(int(i), int(j)) for i, j in zip(rows, cols) if valid[i, j]]


# --------------------------------------------------------------------------------------------------
# input validation
# --------------------------------------------------------------------------------------------------
def _check_sequence(frames, name: str) -> Sequence:
    if isinstance(frames, (str, bytes, Mapping)) or not isinstance(frames, Sequence):
        if isinstance(frames, np.ndarray) and frames.dtype == object and frames.ndim == 1:
            return list(frames)
        raise TypeError(f"{name} must be a sequence (list) of frames, got {type(frames).__name__}")
    return frames


def _frame_arrays(frame, name: str, t: int, distance: str, dim: list[int | None]):
    if not isinstance(frame, Mapping):
        raise TypeError(f"{name}[{t}] must be a dict {{object_id: position}}, got {type(frame).__name__}")
    ids = list(frame.keys())
    if not ids:
        return ids, None
    rows = []
    for oid in ids:
        label = f"{name}[{t}][{oid!r}]"
        if distance == "iou":
            p = _check_boxes(as_array(frame[oid], label, (4,)), label)
        else:
            p = as_array(frame[oid], label, ("D",))
            if p.size == 0:
                raise ValueError(f"{label} must be a non-empty position vector")
            if dim[0] is None:
                dim[0] = p.size
            elif p.size != dim[0]:
                raise ValueError(
                    f"{label} must have shape ({dim[0]},) like the other positions, got {p.shape}"
                )
        rows.append(p)
    return ids, np.stack(rows)


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den else math.nan


# --------------------------------------------------------------------------------------------------
# the metrics
# --------------------------------------------------------------------------------------------------
def clear_mot(gt, hyp, max_dist, distance: str = "euclidean", *, return_matches: bool = False):
    r"""CLEAR-MOT (MOTA, MOTP, ID switches) and identity (IDF1) metrics of a tracking result.

    See the module docstring for the matching rules and formulas; they follow py-motmetrics
    event by event.

    Parameters
    ----------
    gt : sequence of dict
        Ground truth, one dict ``{object_id: position}`` per frame (``T`` frames). Ids are any
        hashable values; an id names the same object in every frame.
    hyp : sequence of dict
        Tracker output, ``T`` frames in the same format.
    max_dist : float
        Matching threshold :math:`\tau > 0`: pairs at distance :math:`> \tau` are never matched.
        For ``distance="iou"``, ``max_dist=0.5`` means IoU :math:`\ge 0.5`.
    distance : {"euclidean", "iou"}
        ``"euclidean"``: positions are vectors of one common length ``D`` and
        :math:`d = \lVert g - h \rVert_2`. ``"iou"``: positions are boxes ``[x, y, w, h]`` and
        :math:`d = 1 - \mathrm{IoU}` (:func:`iou_distance`).
    return_matches : bool, keyword-only
        Also return the correspondences, e.g. to draw them.

    Returns
    -------
    dict
        ``mota``, ``motp``, ``idf1`` (floats; NaN when the denominator is 0), ``id_switches``,
        ``fp``, ``fn``, ``matches`` (ints; ``matches`` excludes the switches, as in
        py-motmetrics' ``num_matches``), plus ``num_frames``, ``num_objects`` (G),
        ``num_predictions`` (H), ``num_detections`` (matches + switches), ``num_unique_objects``,
        ``precision``, ``recall``, ``idp``, ``idr``, ``idtp``, ``idfp``, ``idfn``,
        ``mostly_tracked`` (tracked :math:`\ge 80\%` of its frames), ``partially_tracked``,
        ``mostly_lost`` (:math:`< 20\%`), ``num_fragmentations``.
    matches : list of dict, only with ``return_matches=True``
        Per frame ``{object id: hypothesis id}`` of the matched pairs (switches included); an object
        missing from it is a miss, a hypothesis missing from its values a false positive.
    switches : list of (int, object id), only with ``return_matches=True``
        ``(frame, object id)`` of every identity switch.

    Raises
    ------
    TypeError
        ``gt``/``hyp`` not a sequence of dicts, non-numeric positions, ``distance`` not a string.
    ValueError
        Different numbers of frames, NaN/inf or wrongly shaped positions, negative box sizes,
        ``max_dist <= 0``, unknown ``distance``.

    Examples
    --------
    Object 1 is tracked by hypothesis ``"a"`` and then by ``"b"`` (one identity switch); object 2
    is missed once and there is one false positive:

    >>> gt = [{1: [0.0, 0.0], 2: [5.0, 5.0]}, {1: [1.0, 0.0], 2: [5.0, 6.0]}]
    >>> hyp = [{"a": [0.1, 0.0], "c": [5.0, 5.0]}, {"b": [1.0, 0.0], "x": [9.0, 9.0]}]
    >>> m = clear_mot(gt, hyp, max_dist=0.5)
    >>> m["matches"], m["id_switches"], m["fp"], m["fn"]
    (2, 1, 1, 1)
    >>> round(m["mota"], 3)  # 1 - (1 + 1 + 1) / 4
    0.25
    >>> clear_mot(gt, hyp, max_dist=0.5, return_matches=True)[1:]
    ([{1: 'a', 2: 'c'}, {1: 'b'}], [(1, 1)])
    """
    gt = _check_sequence(gt, "gt")
    hyp = _check_sequence(hyp, "hyp")
    if len(gt) != len(hyp):
        raise ValueError(f"gt and hyp must have the same number of frames, got {len(gt)} and {len(hyp)}")
    tau = positive(max_dist, "max_dist")
    if not isinstance(distance, str):
        raise TypeError(f"distance must be a string, got {type(distance).__name__}")
    if distance not in _DISTANCES:
        raise ValueError(f"distance must be one of {_DISTANCES}, got {distance!r}")

    dim: list[int | None] = [None]
    last_hyp: dict = {}  # gt id -> hypothesis it was last matched to
    n_match = n_switch = n_fp = n_fn = 0
    dist_sum = 0.0
    obj_count: dict = {}  # gt id -> frames present
    obj_tracked: dict = {}  # gt id -> frames matched
    obj_states: dict = {}  # gt id -> [tracked?] per frame present (for fragmentations)
    hyp_count: dict = {}
    pair_count: dict = {}  # (gt id, hyp id) -> frames both present within the threshold
    matches: list[dict] = []  # per frame {gt id: hyp id}
    switches: list[tuple] = []  # (frame, gt id)

    for t, (gframe, hframe) in enumerate(zip(gt, hyp)):
        oids, G = _frame_arrays(gframe, "gt", t, distance, dim)
        hids, H = _frame_arrays(hframe, "hyp", t, distance, dim)
        for o in oids:
            obj_count[o] = obj_count.get(o, 0) + 1
        for h in hids:
            hyp_count[h] = hyp_count.get(h, 0) + 1
        no, nh = len(oids), len(hids)
        matched_o = np.zeros(no, dtype=bool)
        pairs: dict = {}
        matches.append(pairs)
        if no and nh:
            if distance == "iou":
                D = 1.0 - _iou(G[:, None, :], H[None, :, :])
            else:
                D = _euclidean(G, H)
            D = np.where(D > tau, np.nan, D)
            for i, j in zip(*np.nonzero(np.isfinite(D))):
                key = (oids[i], hids[j])
                pair_count[key] = pair_count.get(key, 0) + 1
            matched_h = np.zeros(nh, dtype=bool)
            col = {h: j for j, h in enumerate(hids)}
            # 1. carry forward previous correspondences that are still valid
            for i, o in enumerate(oids):
                j = col.get(last_hyp[o]) if o in last_hyp else None
                if j is not None and not matched_h[j] and np.isfinite(D[i, j]):
                    matched_o[i] = matched_h[j] = True
                    pairs[o] = hids[j]
                    n_match += 1
                    dist_sum += D[i, j]
            # 2. min-cost assignment of the rest
            D2 = D.copy()
            D2[matched_o, :] = np.nan
            D2[:, matched_h] = np.nan
            for i, j in _gated_assignment(D2):
                o, h = oids[i], hids[j]
                if o in last_hyp and last_hyp[o] != h:
                    n_switch += 1
                    switches.append((t, o))
                else:
                    n_match += 1
                dist_sum += D2[i, j]
                last_hyp[o] = pairs[o] = h
                matched_o[i] = matched_h[j] = True
            n_fp += int(nh - matched_h.sum())
        else:
            n_fp += nh
        n_fn += int(no - matched_o.sum())
        for i, o in enumerate(oids):
            obj_tracked[o] = obj_tracked.get(o, 0) + int(matched_o[i])
            obj_states.setdefault(o, []).append(bool(matched_o[i]))

    num_objects = sum(obj_count.values())
    num_predictions = sum(hyp_count.values())
    num_detections = n_match + n_switch

    # identity metrics: max-weight bipartite matching of trajectories
    idtp = 0
    if pair_count:
        o_index = {o: k for k, o in enumerate(obj_count)}
        h_index = {h: k for k, h in enumerate(hyp_count)}
        W = np.zeros((len(o_index), len(h_index)))
        for (o, h), n in pair_count.items():
            W[o_index[o], h_index[h]] = n
        rows, cols = linear_sum_assignment(W, maximize=True)
        idtp = int(W[rows, cols].sum())
    idfn = num_objects - idtp
    idfp = num_predictions - idtp

    ratios = [obj_tracked[o] / obj_count[o] for o in obj_count]
    fragmentations = sum(_fragmentations(states) for states in obj_states.values())

    out = {
        "mota": 1.0 - _ratio(n_fn + n_fp + n_switch, num_objects),
        "motp": _ratio(dist_sum, num_detections),
        "idf1": _ratio(2 * idtp, num_objects + num_predictions),
        "id_switches": n_switch,
        "fp": n_fp,
        "fn": n_fn,
        "matches": n_match,
        "num_frames": len(gt),
        "num_objects": num_objects,
        "num_predictions": num_predictions,
        "num_detections": num_detections,
        "num_unique_objects": len(obj_count),
        "precision": _ratio(num_detections, num_detections + n_fp),
        "recall": _ratio(num_detections, num_objects),
        "idp": _ratio(idtp, num_predictions),
        "idr": _ratio(idtp, num_objects),
        "idtp": idtp,
        "idfp": idfp,
        "idfn": idfn,
        "mostly_tracked": sum(r >= 0.8 for r in ratios),
        "partially_tracked": sum(0.2 <= r < 0.8 for r in ratios),
        "mostly_lost": sum(r < 0.2 for r in ratios),
        "num_fragmentations": fragmentations,
    }
    return (out, matches, switches) if return_matches else out


def _fragmentations(states: list[bool]) -> int:
    """Tracked → missed transitions between the first and the last tracked frame of an object."""
    if not any(states):
        return 0
    first = states.index(True)
    last = len(states) - 1 - states[::-1].index(True)
    span = states[first : last + 1]
    return sum(1 for prev, cur in itertools.pairwise(span) if prev and not cur)


# --------------------------------------------------------------------------------------------------
# objects to ignore (MOTChallenge's distractors)
# --------------------------------------------------------------------------------------------------
def remove_ignored(gt, ignore, hyp, max_dist):
    r"""Remove the hypotheses that match an object to be ignored, frame by frame.

    In each frame the hypotheses are matched to the objects that count (``gt``) and to those to be
    ignored (``ignore``) together, by the gated min-cost assignment :func:`clear_mot` uses (pairs
    farther than ``max_dist`` never match; the most pairs, then the least total distance); a
    hypothesis matched to an ignored object is dropped. Score the result with :func:`clear_mot`
    against ``gt``.

    Parameters
    ----------
    gt, ignore, hyp : sequence of dict
        ``T`` frames each, ``{id: position}`` (Euclidean positions of one common length). An id may be
        in ``gt`` in some frames and in ``ignore`` in others, not in both in one frame.
    max_dist : float, > 0

    Returns
    -------
    list of dict
        ``hyp`` without the hypotheses matched to ignored objects.

    Examples
    --------
    Object 2 is hidden in frame 0: the track on it there is neither a match nor a false positive;
    the clutter track ``"x"`` is a false positive.

    >>> gt = [{1: [0.0, 0.0]}]
    >>> ignore = [{2: [1.0, 0.0]}]
    >>> hyp = [{"a": [0.05, 0.0], "b": [1.02, 0.0], "x": [3.0, 0.0]}]
    >>> kept = remove_ignored(gt, ignore, hyp, max_dist=0.1)
    >>> sorted(kept[0])
    ['a', 'x']
    >>> clear_mot(gt, kept, 0.1)["fp"]
    1
    """
    gt = _check_sequence(gt, "gt")
    ignore = _check_sequence(ignore, "ignore")
    hyp = _check_sequence(hyp, "hyp")
    if not len(gt) == len(ignore) == len(hyp):
        raise ValueError(f"gt, ignore and hyp must have the same number of frames, got {len(gt)}, "
                         f"{len(ignore)} and {len(hyp)}")
    max_dist = positive(max_dist, "max_dist")
    dim: list[int | None] = [None]
    out = []
    for t, (g, ig, h) in enumerate(zip(gt, ignore, hyp)):
        both = set(g) & set(ig) if isinstance(g, Mapping) and isinstance(ig, Mapping) else set()
        if both:
            raise ValueError(f"frame {t}: ids {sorted(both, key=repr)} are both in gt and in ignore")
        gids, G = _frame_arrays(g, "gt", t, "euclidean", dim)
        iids, I = _frame_arrays(ig, "ignore", t, "euclidean", dim)
        hids, Hy = _frame_arrays(h, "hyp", t, "euclidean", dim)
        if not iids or not hids:
            out.append(dict(h))
            continue
        objs = I if G is None else np.vstack([G, I])
        D = _euclidean(objs, Hy)
        drop = {hids[j] for i, j in _gated_assignment(np.where(D > max_dist, np.nan, D)) if i >= len(gids)}
        out.append({k: v for k, v in h.items() if k not in drop})
    return out


# --------------------------------------------------------------------------------------------------
# scene flow, worst case
# --------------------------------------------------------------------------------------------------
def flow_end_point_errors(pred, gt) -> np.ndarray:
    r"""Per-pixel end-point error :math:`\lVert \hat s - s \rVert` of a scene (or optical) flow.

    Parameters
    ----------
    pred : array_like, shape (..., D)
        Estimated flow. A non-finite entry is a pixel the method did not answer: it counts as
        predicting zero flow there (so it is not rewarded for abstaining).
    gt : array_like, shape (..., D)
        True flow, same shape; NaN where there is no ground truth (inf is rejected).

    Returns
    -------
    ndarray, shape (...)
        The errors, NaN where ``gt`` has a NaN.

    Examples
    --------
    >>> pred = [[3.0, 4.0], [np.nan, 0.0], [1.0, 1.0]]
    >>> flow_end_point_errors(pred, [[0.0, 0.0], [0.0, 2.0], [np.nan, 0.0]])
    array([ 5.,  2., nan])
    """
    p = as_array(pred, "pred", finite=False)
    g = as_array(gt, "gt", allow_nan=True)
    if p.shape != g.shape or p.ndim < 1:
        raise ValueError(f"pred must have the shape of gt {g.shape} (..., D), got {p.shape}")
    answered = np.isfinite(p).all(axis=-1, keepdims=True)
    return np.linalg.norm(np.where(answered, p, 0.0) - g, axis=-1)


def interior_mask(labels, width: int = 2) -> np.ndarray:
    r"""Object pixels at least ``width`` px inside their object's silhouette.

    A pixel with label :math:`k > 0` is interior when every pixel of its
    :math:`(2w+1) \times (2w+1)` neighbourhood inside the image also has label :math:`k` (the image
    border is not a silhouette: an object cut by it keeps an interior up to the border). Label 0 is
    the background, never interior.

    Parameters
    ----------
    labels : array_like of int, shape (H, W)
    width : int, >= 0
        :math:`w`; 0 marks every object pixel.

    Returns
    -------
    ndarray of bool, shape (H, W)

    Examples
    --------
    >>> lab = np.zeros((7, 7), int)
    >>> lab[1:7, 1:6] = 3
    >>> interior_mask(lab, width=1).astype(int)
    array([[0, 0, 0, 0, 0, 0, 0],
           [0, 0, 0, 0, 0, 0, 0],
           [0, 0, 1, 1, 1, 0, 0],
           [0, 0, 1, 1, 1, 0, 0],
           [0, 0, 1, 1, 1, 0, 0],
           [0, 0, 1, 1, 1, 0, 0],
           [0, 0, 1, 1, 1, 0, 0]])
    """
    lab = np.asarray(labels)
    if lab.ndim != 2 or not (np.issubdtype(lab.dtype, np.integer) or np.issubdtype(lab.dtype, np.bool_)):
        raise ValueError(f"labels must be an integer array of shape (H, W), got {lab.dtype} {lab.shape}")
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) or width < 0:
        raise ValueError(f"width must be an integer >= 0, got {width!r}")
    w = int(width)
    H, W = lab.shape
    padded = np.pad(lab, w, mode="edge")
    inside = lab > 0
    for dy in range(2 * w + 1):
        for dx in range(2 * w + 1):
            inside &= padded[dy:dy + H, dx:dx + W] == lab
    return inside


def worst_case_flow_metrics(pred, gt, labels, moving=None, *, abs_threshold: float = 0.01,
                            rel_threshold: float = 0.5, interior_width: int = 2) -> dict:
    r"""A flow estimate judged by its worst pixels: tails, gross outliers and interior maxima.

    See the module docstring for the definitions. Pixels without ground truth (NaN in ``gt``) are not
    scored; a pixel the method did not answer (non-finite ``pred``) counts as predicting zero.

    Parameters
    ----------
    pred, gt : array_like, shape (H, W, D)
        Estimated and true displacements (one frame; metres for scene flow).
    labels : array_like of int, shape (H, W)
        Object id per pixel, 0 = background (for the interior).
    moving : array_like of bool, shape (H, W), optional
        The moving pixels (default: :math:`\lVert s_p \rVert > 0`); the others are static.
    abs_threshold, rel_threshold : float, > 0
        :math:`\tau_\text{abs}` (same unit as the flow) and :math:`\tau_\text{rel}` of a gross outlier.
    interior_width : int, >= 0
        :math:`w` of :func:`interior_mask`.

    Returns
    -------
    dict
        ``epe_moving_mean``, ``epe_moving_median``, ``epe_static_mean``, ``outlier_share`` (gross outliers
        / moving pixels), ``max_interior_error`` (over every object's interior pixels; NaN when there are
        none) and ``max_interior_pixel`` (its (row, col) or None), ``n_moving``, ``n_static``,
        ``n_outliers``, ``n_interior``. Means and shares are NaN over an empty set.

    Examples
    --------
    An object moving 2 cm per frame, one interior pixel of it off by 3 cm:

    >>> gt = np.zeros((6, 6, 3)); lab = np.zeros((6, 6), int)
    >>> gt[:, :5, 0] = 0.02; lab[:, :5] = 1
    >>> pred = gt.copy(); pred[2, 2, 0] = -0.01
    >>> m = worst_case_flow_metrics(pred, gt, lab, interior_width=1)
    >>> m["n_moving"], m["n_outliers"], round(m["max_interior_error"], 3), m["max_interior_pixel"]
    (30, 1, 0.03, (2, 2))
    """
    e = flow_end_point_errors(pred, gt)
    g = as_array(gt, "gt", allow_nan=True)
    if e.ndim != 2:
        raise ValueError(f"pred and gt must have shape (H, W, D), got {g.shape}")
    lab = np.asarray(labels)
    if lab.shape != e.shape:
        raise ValueError(f"labels must have shape {e.shape}, got {lab.shape}")
    abs_threshold = positive(abs_threshold, "abs_threshold")
    rel_threshold = positive(rel_threshold, "rel_threshold")
    scored = np.isfinite(e)
    speed = np.linalg.norm(np.where(np.isfinite(g), g, 0.0), axis=-1)
    if moving is None:
        mov = speed > 0
    else:
        mov = np.asarray(moving)
        if mov.shape != e.shape or mov.dtype != bool:
            raise ValueError(f"moving must be a bool array of shape {e.shape}, got {mov.dtype} {mov.shape}")
    mv, st = scored & mov, scored & ~mov
    gross = mv & (e > abs_threshold) & (e > rel_threshold * speed)
    inner = scored & interior_mask(lab, interior_width)

    def mean(x):
        return float(x.mean()) if x.size else math.nan

    out = {
        "epe_moving_mean": mean(e[mv]),
        "epe_moving_median": float(np.median(e[mv])) if mv.any() else math.nan,
        "epe_static_mean": mean(e[st]),
        "outlier_share": _ratio(gross.sum(), mv.sum()),
        "max_interior_error": math.nan,
        "max_interior_pixel": None,
        "n_moving": int(mv.sum()),
        "n_static": int(st.sum()),
        "n_outliers": int(gross.sum()),
        "n_interior": int(inner.sum()),
    }
    if inner.any():
        ei = np.where(inner, e, -np.inf)
        r, c = np.unravel_index(int(np.argmax(ei)), ei.shape)
        out["max_interior_error"] = float(e[r, c])
        out["max_interior_pixel"] = (int(r), int(c))
    return out
