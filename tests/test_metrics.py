"""Tests of flowtrack.metrics: CLEAR-MOT / IDF1 against published figures and independent oracles."""

from __future__ import annotations

import importlib.util
import itertools
import math

import numpy as np
import pytest

from flowtrack.datasets import mot_challenge_tracks, tud_campus_tracks
from flowtrack.metrics import (
    clear_mot,
    flow_end_point_errors,
    interior_mask,
    iou_distance,
    remove_ignored,
    worst_case_flow_metrics,
)

HAVE_MOTMETRICS_DATA = importlib.util.find_spec("motmetrics") is not None
needs_data = pytest.mark.skipif(not HAVE_MOTMETRICS_DATA, reason="motmetrics wheel (data files) missing")


# --------------------------------------------------------------------------------------------------
# published figures
# --------------------------------------------------------------------------------------------------
@needs_data
def test_tud_campus_matches_the_published_readme_table():
    # py-motmetrics README (TUD-Campus, IoU matching at 0.5), printed precision:
    # IDF1 55.8% IDP 73.0% IDR 45.1% Rcll 58.2% Prcn 94.1% GT 8 MT 1 PT 6 ML 1 FP 13 FN 150 IDs 7 FM 7
    # MOTA 52.6% MOTP 0.277
    gt, hyp = tud_campus_tracks()
    m = clear_mot(gt, hyp, max_dist=0.5, distance="iou")
    assert f"{100 * m['idf1']:.1f}" == "55.8"
    assert f"{100 * m['idp']:.1f}" == "73.0"
    assert f"{100 * m['idr']:.1f}" == "45.1"
    assert f"{100 * m['recall']:.1f}" == "58.2"
    assert f"{100 * m['precision']:.1f}" == "94.1"
    assert f"{100 * m['mota']:.1f}" == "52.6"
    assert f"{m['motp']:.3f}" == "0.277"
    assert (m["num_unique_objects"], m["mostly_tracked"], m["partially_tracked"], m["mostly_lost"]) == (
        8,
        1,
        6,
        1,
    )
    assert (m["fp"], m["fn"], m["id_switches"], m["num_fragmentations"]) == (13, 150, 7, 7)
    # FN 150 at recall 58.2 % pins 359 objects; 359 - 150 - 7 = 202 matches.
    assert m["num_objects"] == 359
    assert m["matches"] == 202


@needs_data
@pytest.mark.parametrize(
    ("sequence", "expected"),
    [
        # py-motmetrics' own test_motchallenge_files (6 digits): idf1 idp idr recall precision
        # GT MT PT ML FP FN IDs FM mota motp
        (
            "TUD-Campus",
            [0.557659, 0.729730, 0.451253, 0.582173, 0.941441, 8, 1, 6, 1, 13, 150, 7, 7, 0.526462, 0.277201],
        ),
        (
            "TUD-Stadtmitte",
            [
                0.644619,
                0.819760,
                0.531142,
                0.608997,
                0.939920,
                10,
                5,
                4,
                1,
                45,
                452,
                7,
                6,
                0.564014,
                0.345904,
            ],
        ),
    ],
)
def test_mot15_sequences_match_py_motmetrics_test_values(sequence, expected):
    gt, hyp = mot_challenge_tracks(sequence)
    m = clear_mot(gt, hyp, 0.5, distance="iou")
    keys = [
        "idf1",
        "idp",
        "idr",
        "recall",
        "precision",
        "num_unique_objects",
        "mostly_tracked",
        "partially_tracked",
        "mostly_lost",
        "fp",
        "fn",
        "id_switches",
        "num_fragmentations",
        "mota",
        "motp",
    ]
    np.testing.assert_allclose([m[k] for k in keys], expected, atol=1e-6)


# --------------------------------------------------------------------------------------------------
# hand-computed cases
# --------------------------------------------------------------------------------------------------
def _straight_tracks(n_frames, n_objects, labels=None):
    labels = labels or list(range(n_objects))
    return [{labels[k]: [10.0 * k + t, 0.0] for k in range(n_objects)} for t in range(n_frames)]


def test_perfect_tracking():
    gt = _straight_tracks(5, 3)
    hyp = _straight_tracks(5, 3, labels=["a", "b", "c"])
    m = clear_mot(gt, hyp, max_dist=1.0)
    assert m["mota"] == 1.0 and m["idf1"] == 1.0 and m["motp"] == 0.0
    assert (m["matches"], m["id_switches"], m["fp"], m["fn"]) == (15, 0, 0, 0)
    assert m["mostly_tracked"] == 3 and m["num_fragmentations"] == 0


def test_one_identity_change_is_one_switch():
    gt = [{1: [float(t), 0.0]} for t in range(4)]
    hyp = [{("a" if t < 2 else "b"): [float(t), 0.0]} for t in range(4)]
    m = clear_mot(gt, hyp, 0.5)
    assert (m["matches"], m["id_switches"], m["fp"], m["fn"]) == (3, 1, 0, 0)
    assert m["mota"] == pytest.approx(1 - 1 / 4)
    # best identity map 1 -> "a" (or "b") covers 2 of 4 frames: IDF1 = 2*2 / (4 + 4)
    assert m["idf1"] == pytest.approx(0.5)
    assert (m["idtp"], m["idfp"], m["idfn"]) == (2, 2, 2)


def test_exchanging_two_labels_is_two_switches():
    gt = [{1: [0.0, 0.0], 2: [10.0, 0.0]} for _ in range(4)]
    hyp = [
        {"a": [0.0, 0.0], "b": [10.0, 0.0]} if t < 3 else {"b": [0.0, 0.0], "a": [10.0, 0.0]}
        for t in range(4)
    ]
    m = clear_mot(gt, hyp, 1.0)
    assert m["id_switches"] == 2 and m["matches"] == 6
    assert m["mota"] == pytest.approx(1 - 2 / 8)
    assert m["idf1"] == pytest.approx(2 * 6 / 16)


def test_switch_is_counted_after_a_gap():
    gt = [{1: [0.0]}, {1: [0.0]}, {1: [0.0]}]
    hyp = [{"a": [0.0]}, {}, {"b": [0.0]}]
    m = clear_mot(gt, hyp, 0.5)
    assert (m["matches"], m["id_switches"], m["fn"]) == (1, 1, 1)
    assert m["num_fragmentations"] == 1


def test_all_missed():
    gt = _straight_tracks(3, 2)
    hyp = [{} for _ in range(3)]
    m = clear_mot(gt, hyp, 1.0)
    assert (m["fn"], m["fp"], m["matches"], m["id_switches"]) == (6, 0, 0, 0)
    assert m["mota"] == 0.0  # 1 - 6/6
    assert m["idf1"] == 0.0
    assert math.isnan(m["motp"])
    assert m["mostly_lost"] == 2


def test_false_positives_only():
    gt = [{1: [0.0, 0.0]}, {1: [1.0, 0.0]}]
    hyp = [{"a": [0.0, 0.0], "x": [50.0, 50.0]}, {"a": [1.0, 0.0], "y": [60.0, 0.0], "z": [70.0, 0.0]}]
    m = clear_mot(gt, hyp, 1.0)
    assert (m["fp"], m["fn"], m["matches"]) == (3, 0, 2)
    assert m["mota"] == pytest.approx(1 - 3 / 2)  # MOTA can be negative
    assert m["precision"] == pytest.approx(2 / 5)
    assert m["idf1"] == pytest.approx(2 * 2 / (2 + 5))
    empty = clear_mot([{}], [{"a": [0.0]}], 1.0)
    assert empty["fp"] == 1 and math.isnan(empty["mota"])


def test_threshold_is_inclusive_and_gates():
    gt = [{1: [0.0, 0.0]}]
    hyp = [{"a": [0.5, 0.0]}]
    assert clear_mot(gt, hyp, 0.5)["matches"] == 1
    m = clear_mot(gt, hyp, 0.49)
    assert (m["matches"], m["fp"], m["fn"]) == (0, 1, 1)
    assert m["idtp"] == 0  # identity true positives use the same threshold


def test_previous_correspondence_is_kept_over_a_closer_hypothesis():
    gt = [{1: [0.0]}, {1: [0.0]}]
    hyp = [{"a": [0.1]}, {"a": [0.4], "b": [0.05]}]
    m = clear_mot(gt, hyp, 0.5)
    assert (m["matches"], m["id_switches"], m["fp"]) == (2, 0, 1)
    assert m["motp"] == pytest.approx((0.1 + 0.4) / 2)


def test_assignment_maximises_matches_before_cost():
    # Greedy nearest-first would pair (g1, h1) at 0.39 and leave g2 unmatched;
    # the assignment pairs g1-h2 (0.45) and g2-h1 (0.41).
    gt = [{"g1": [0.0], "g2": [0.8]}]
    hyp = [{"h1": [0.39], "h2": [-0.45]}]
    m = clear_mot(gt, hyp, 0.5)
    assert (m["matches"], m["fn"], m["fp"]) == (2, 0, 0)
    assert m["motp"] == pytest.approx((0.45 + 0.41) / 2)


def test_iou_threshold_in_clear_mot():
    # IoU of [0,0,2,1] and [0,0,1,1] is exactly 1/2: distance 0.5 matches at max_dist 0.5
    gt = [{1: [0, 0, 2, 1]}]
    hyp = [{"a": [0, 0, 1, 1]}]
    assert clear_mot(gt, hyp, 0.5, distance="iou")["matches"] == 1
    assert clear_mot(gt, hyp, 0.4, distance="iou")["matches"] == 0


# --------------------------------------------------------------------------------------------------
# IoU
# --------------------------------------------------------------------------------------------------
def test_iou_distance_hand_computed():
    d = iou_distance([[0, 0, 2, 2], [0, 0, 4, 4]], [[1, 1, 2, 2], [1, 1, 2, 2], [10, 10, 1, 1], [0, 0, 0, 0]])
    # overlap 1, union 7 | contained 4 in 16 | disjoint | zero-area box
    np.testing.assert_allclose(d[:, 0], [1 - 1 / 7, 1 - 4 / 16])
    np.testing.assert_array_equal(d[:, 2:], 1.0)


def test_iou_distance_against_pixel_counting(rng):
    a = rng.integers(0, 8, size=(6, 4))
    b = rng.integers(0, 8, size=(5, 4))
    a[:, 2:] += 1
    b[:, 2:] += 1
    d = iou_distance(a, b)

    def mask(box):
        m = np.zeros((20, 20), dtype=bool)
        x, y, w, h = box
        m[y : y + h, x : x + w] = True
        return m

    for i, j in itertools.product(range(len(a)), range(len(b))):
        ma, mb = mask(a[i]), mask(b[j])
        expected = 1 - (ma & mb).sum() / (ma | mb).sum()
        assert d[i, j] == pytest.approx(expected)


# --------------------------------------------------------------------------------------------------
# independent brute-force oracle on random sequences
# --------------------------------------------------------------------------------------------------
def _oracle(gt, hyp, tau):
    """Plain re-implementation: brute-force matchings, max cardinality then min cost."""
    last = {}
    tp = fp = fn = sw = 0
    dsum = 0.0
    pairs = {}
    frames, switches = [], []  # per frame {object: hypothesis}; (frame, object) of each switch
    for t, (g, h) in enumerate(zip(gt, hyp)):
        dist = {(o, k): float(np.linalg.norm(np.subtract(g[o], h[k]))) for o in g for k in h}
        ok = {p: d for p, d in dist.items() if d <= tau}
        for p in ok:
            pairs[p] = pairs.get(p, 0) + 1
        fixed = {}
        for o in g:
            if o in last and last[o] in h and last[o] not in fixed.values() and (o, last[o]) in ok:
                fixed[o] = last[o]
        ro = [o for o in g if o not in fixed]
        rh = [k for k in h if k not in fixed.values()]
        best = (0, 0.0, ())
        for r in range(min(len(ro), len(rh)) + 1):
            for os_ in itertools.combinations(ro, r):
                for hs in itertools.permutations(rh, r):
                    if all((o, k) in ok for o, k in zip(os_, hs)):
                        cost = sum(ok[(o, k)] for o, k in zip(os_, hs))
                        if r > best[0] or (r == best[0] and cost < best[1]):
                            best = (r, cost, tuple(zip(os_, hs)))
        for o, k in fixed.items():
            tp += 1
            dsum += ok[(o, k)]
        for o, k in best[2]:
            if o in last and last[o] != k:
                sw += 1
                switches.append((t, o))
            else:
                tp += 1
            dsum += ok[(o, k)]
            last[o] = k
        frames.append({**fixed, **dict(best[2])})
        n_matched = len(fixed) + len(best[2])
        fn += len(g) - n_matched
        fp += len(h) - n_matched
    n_obj = sum(len(g) for g in gt)
    n_pred = sum(len(h) for h in hyp)
    oids = sorted({o for g in gt for o in g})
    hids = sorted({k for h in hyp for k in h})
    idtp = 0
    padded = hids + [None] * len(oids)
    for perm in itertools.permutations(padded, len(oids)):
        idtp = max(idtp, sum(pairs.get((o, k), 0) for o, k in zip(oids, perm) if k is not None))
    return dict(
        matches=tp,
        id_switches=sw,
        fp=fp,
        fn=fn,
        num_objects=n_obj,
        idtp=idtp,
        motp=dsum / (tp + sw) if tp + sw else math.nan,
        mota=1 - (fn + fp + sw) / n_obj,
        idf1=2 * idtp / (n_obj + n_pred),
        frames=frames,
        switches=switches,
    )


def _random_sequence(rng, n_frames=8, n_obj=3, n_hyp=4):
    pos = rng.uniform(0, 3, size=(n_obj, 2))
    vel = rng.normal(0, 0.3, size=(n_obj, 2))
    gt, hyp = [], []
    for _ in range(n_frames):
        pos = pos + vel
        g = {o: pos[o].copy() for o in range(n_obj) if rng.random() < 0.85}
        h = {}
        labels = rng.permutation(n_hyp)  # noisy detections, labels sometimes shuffled
        for o in range(n_obj):
            if rng.random() < 0.8:
                lab = int(labels[o]) if rng.random() < 0.3 else o
                if lab not in h:
                    h[lab] = pos[o] + rng.normal(0, 0.3, 2)
        if rng.random() < 0.3:
            h[100 + int(rng.integers(3))] = rng.uniform(0, 3, 2)
        gt.append(g)
        hyp.append(h)
    return gt, hyp


def test_random_sequences_agree_with_brute_force_oracle(rng):
    for _ in range(40):
        gt, hyp = _random_sequence(rng)
        tau = float(rng.uniform(0.3, 1.5))
        m = clear_mot(gt, hyp, tau)
        o = _oracle(gt, hyp, tau)
        for k in ("matches", "id_switches", "fp", "fn", "num_objects", "idtp"):
            assert m[k] == o[k], k
        for k in ("mota", "idf1", "motp"):
            assert m[k] == pytest.approx(o[k], nan_ok=True), k
        # the correspondences themselves (return_matches) are the oracle's, frame by frame
        m2, frames, switches = clear_mot(gt, hyp, tau, return_matches=True)
        assert m2 == pytest.approx(m, nan_ok=True)
        assert frames == o["frames"] and switches == o["switches"]
        # bookkeeping against counts made here: every gt entry is associated (match or switch) or
        # missed, every hypothesis entry associated or false; the associations are the oracle's
        n_obj = sum(len(g) for g in gt)
        n_pred = sum(len(h) for h in hyp)
        assoc = o["matches"] + o["id_switches"]
        assert (m["num_objects"], m["num_predictions"], m["num_detections"]) == (n_obj, n_pred, assoc)
        assert (m["fn"], m["fp"]) == (n_obj - assoc, n_pred - assoc)
        assert m["num_frames"] == len(gt)
        assert m["num_unique_objects"] == len({k for g in gt for k in g})
        # MOTA from those counts: 1 - (misses + false positives + switches) / gt entries
        misses, false_pos = n_obj - assoc, n_pred - assoc
        assert m["mota"] == pytest.approx(1 - (misses + false_pos + o["id_switches"]) / n_obj)
        assert m["precision"] == pytest.approx(assoc / n_pred)
        assert m["recall"] == pytest.approx(assoc / n_obj)
        assert m["idp"] == pytest.approx(o["idtp"] / n_pred)
        assert m["idr"] == pytest.approx(o["idtp"] / n_obj)
        assert (m["idfn"], m["idfp"]) == (n_obj - o["idtp"], n_pred - o["idtp"])


def test_renaming_hypotheses_changes_nothing(rng):
    gt, hyp = _random_sequence(rng)
    renamed = [{f"t{k}": v for k, v in h.items()} for h in hyp]
    a, b = clear_mot(gt, hyp, 1.0), clear_mot(gt, renamed, 1.0)
    assert a == pytest.approx(b, nan_ok=True)


# --------------------------------------------------------------------------------------------------
# bad inputs
# --------------------------------------------------------------------------------------------------
GOOD = [{1: [0.0, 0.0]}]


@pytest.mark.parametrize(
    ("gt", "hyp", "kwargs", "exc", "match"),
    [
        ({1: [0.0]}, GOOD, {}, TypeError, "gt"),
        (GOOD, "frames", {}, TypeError, "hyp"),
        ([{1: [0.0, 0.0]}, [0.0, 1.0]], [{}, {}], {}, TypeError, r"gt\[1\]"),
        (GOOD, [{}, {}], {}, ValueError, "same number of frames"),
        (GOOD, [{"a": [np.nan, 0.0]}], {}, ValueError, r"hyp\[0\]\['a'\]"),
        (GOOD, [{"a": [0.0, 0.0, 0.0]}], {}, ValueError, r"hyp\[0\]\['a'\]"),
        (GOOD, [{"a": "xy"}], {}, TypeError, r"hyp\[0\]\['a'\]"),
        (GOOD, GOOD, {"max_dist": 0.0}, ValueError, "max_dist"),
        (GOOD, GOOD, {"max_dist": -1.0}, ValueError, "max_dist"),
        (GOOD, GOOD, {"max_dist": float("nan")}, ValueError, "max_dist"),
        (GOOD, GOOD, {"distance": "manhattan"}, ValueError, "distance"),
        (GOOD, GOOD, {"distance": 3}, TypeError, "distance"),
        (GOOD, GOOD, {"distance": "iou"}, ValueError, r"gt\[0\]\[1\]"),
        ([{1: [0, 0, -1, 2]}], [{}], {"distance": "iou"}, ValueError, r"gt\[0\]\[1\]"),
    ],
)
def test_bad_inputs_name_the_argument(gt, hyp, kwargs, exc, match):
    kwargs = {"max_dist": 1.0, **kwargs}
    with pytest.raises(exc, match=match):
        clear_mot(gt, hyp, **kwargs)


def test_iou_distance_bad_inputs():
    with pytest.raises(ValueError, match="boxes_a"):
        iou_distance([[0, 0, 1]], [[0, 0, 1, 1]])
    with pytest.raises(ValueError, match="boxes_b"):
        iou_distance([[0, 0, 1, 1]], [[0, 0, -1, 1]])
    with pytest.raises(ValueError, match="boxes_b"):
        iou_distance([[0, 0, 1, 1]], [[0, np.inf, 1, 1]])


# --------------------------------------------------------------------------------------------------
# objects to ignore: against enumerating every assignment
# --------------------------------------------------------------------------------------------------
def _best_assignment_brute(D, max_dist):
    """All partial one-to-one assignments within max_dist: the most pairs, then the least total."""
    n, m = D.shape
    best, best_key = [], (0, 0.0)
    rows = list(range(n))
    for k in range(1, min(n, m) + 1):
        for rs in itertools.combinations(rows, k):
            for cs in itertools.permutations(range(m), k):
                if all(D[r, c] <= max_dist for r, c in zip(rs, cs)):
                    key = (k, -sum(D[r, c] for r, c in zip(rs, cs)))
                    if key > best_key:
                        best, best_key = list(zip(rs, cs)), key
    return best


def test_remove_ignored_agrees_with_brute_force_joint_assignment(rng):
    for _ in range(60):
        n_g, n_i, n_h = rng.integers(0, 3), rng.integers(0, 3), rng.integers(0, 4)
        G = rng.uniform(0, 1, (n_g, 2))
        I_ = rng.uniform(0, 1, (n_i, 2))
        Hy = rng.uniform(0, 1, (n_h, 2))
        gt = [{f"g{k}": G[k] for k in range(n_g)}]
        ign = [{f"i{k}": I_[k] for k in range(n_i)}]
        hyp = [{f"h{k}": Hy[k] for k in range(n_h)}]
        kept = remove_ignored(gt, ign, hyp, 0.4)
        objs = np.vstack([G, I_]) if n_g + n_i else np.zeros((0, 2))
        D = np.linalg.norm(objs[:, None] - Hy[None], axis=-1).reshape(len(objs), n_h)
        drop = {f"h{c}" for r, c in _best_assignment_brute(D, 0.4) if r >= n_g}
        assert set(kept[0]) == set(hyp[0]) - drop


def test_remove_ignored_prefers_the_counted_object_when_it_keeps_more_pairs():
    # hypothesis "a" is near both the counted object 1 and the ignored object 2, "b" only near 2: the
    # joint assignment pairs a-1 and b-2 (two pairs), so "a" is kept as a match and "b" is dropped
    gt, ign = [{1: [0.0, 0.0]}], [{2: [0.15, 0.0]}]
    hyp = [{"a": [0.1, 0.0], "b": [0.2, 0.0]}]
    assert remove_ignored(gt, ign, hyp, 0.12) == [{"a": [0.1, 0.0]}]
    # with no ignored objects the hypotheses are returned as they are
    assert remove_ignored([{}], [{}], [{"x": [1.0, 2.0]}], 0.1) == [{"x": [1.0, 2.0]}]


def test_remove_ignored_bad_inputs():
    with pytest.raises(ValueError, match="same number of frames"):
        remove_ignored([{}], [{}, {}], [{}], 0.1)
    with pytest.raises(ValueError, match="both in gt and in ignore"):
        remove_ignored([{1: [0.0, 0.0]}], [{1: [0.0, 0.0]}], [{}], 0.1)
    with pytest.raises(ValueError, match="max_dist"):
        remove_ignored([{}], [{}], [{}], 0.0)
    with pytest.raises(TypeError, match="ignore"):
        remove_ignored([{}], "frames", [{}], 0.1)


# --------------------------------------------------------------------------------------------------
# scene flow, worst case: against pixel-by-pixel loops and hand-computed cases
# --------------------------------------------------------------------------------------------------
def _interior_brute(lab, w):
    H, W = lab.shape
    out = np.zeros((H, W), bool)
    for r in range(H):
        for c in range(W):
            if lab[r, c] <= 0:
                continue
            out[r, c] = all(lab[rr, cc] == lab[r, c] for rr in range(max(0, r - w), min(H, r + w + 1))
                            for cc in range(max(0, c - w), min(W, c + w + 1)))
    return out


def _blobs(rng, shape, n=4):
    lab = np.zeros(shape, int)
    for k in range(1, n + 1):
        r0, c0 = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        lab[r0:r0 + rng.integers(2, 9), c0:c0 + rng.integers(2, 9)] = k
    return lab


@pytest.mark.parametrize("width", [0, 1, 2, 3])
def test_interior_mask_against_pixel_loops(rng, width):
    for _ in range(5):
        lab = _blobs(rng, (13, 17))
        assert np.array_equal(interior_mask(lab, width), _interior_brute(lab, width))


def test_interior_mask_bad_inputs():
    with pytest.raises(ValueError, match="labels"):
        interior_mask(np.zeros((3, 3)), 1)
    with pytest.raises(ValueError, match="labels"):
        interior_mask(np.zeros((3, 3, 1), int), 1)
    with pytest.raises(ValueError, match="width"):
        interior_mask(np.zeros((3, 3), int), -1)


def _worst_case_brute(pred, gt, lab, moving, tau_a, tau_r, w):
    H, W, _ = gt.shape
    inner = _interior_brute(lab, w)
    mv, st, gross, inter = [], [], 0, []
    for r in range(H):
        for c in range(W):
            g = gt[r, c]
            if any(math.isnan(x) for x in g):
                continue
            p = pred[r, c] if all(math.isfinite(x) for x in pred[r, c]) else np.zeros(3)
            e = math.sqrt(sum((a - b) ** 2 for a, b in zip(p, g)))
            if moving[r, c]:
                mv.append(e)
                gross += e > tau_a and e > tau_r * math.sqrt(sum(x * x for x in g))
            else:
                st.append(e)
            if inner[r, c]:
                inter.append((e, (r, c)))
    mv_sorted = sorted(mv)
    n = len(mv_sorted)
    median = (mv_sorted[(n - 1) // 2] + mv_sorted[n // 2]) / 2
    return {"epe_moving_mean": sum(mv) / n, "epe_moving_median": median,
            "epe_static_mean": sum(st) / len(st), "outlier_share": gross / n,
            "max_interior_error": max(inter)[0], "max_interior_pixel": max(inter)[1],
            "n_moving": n, "n_static": len(st), "n_outliers": gross, "n_interior": len(inter)}


def test_worst_case_flow_metrics_against_pixel_loops(rng):
    for _ in range(4):
        H, W = 14, 18
        lab = _blobs(rng, (H, W), n=3)
        gt = np.zeros((H, W, 3))
        for k in range(1, 4):
            gt[lab == k] = rng.normal(0, 0.02, 3)
        gt[rng.random((H, W)) < 0.1] = np.nan  # no ground truth
        pred = gt + rng.normal(0, 0.004, gt.shape) * (1 + 20 * (rng.random((H, W, 1)) < 0.1))
        pred[rng.random((H, W)) < 0.05] = np.nan  # not answered: zero displacement
        moving = lab > 0
        got = worst_case_flow_metrics(pred, gt, lab, moving, abs_threshold=0.01, rel_threshold=0.5,
                                      interior_width=1)
        want = _worst_case_brute(pred, gt, lab, moving, 0.01, 0.5, 1)
        assert got["max_interior_pixel"] == want.pop("max_interior_pixel")
        for k, v in want.items():
            assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k


def test_gross_outliers_need_both_thresholds():
    # moving 4 cm: an error is gross above max(1 cm, 2 cm); moving 1 cm: above max(1 cm, 0.5 cm)
    gt = np.zeros((1, 6, 3))
    gt[0, :3, 0] = 0.04
    gt[0, 3:, 0] = 0.01
    pred = gt.copy()
    pred[0, :3, 1] = [0.015, 0.019, 0.021]  # only the last error is above 2 cm
    pred[0, 3:, 1] = [0.009, 0.0105, 0.02]  # the last two are above 1 cm
    m = worst_case_flow_metrics(pred, gt, np.ones((1, 6), int), interior_width=0)
    assert m["n_moving"] == 6 and m["n_outliers"] == 3
    assert m["outlier_share"] == pytest.approx(0.5)
    assert m["max_interior_error"] == pytest.approx(0.021) and m["max_interior_pixel"] == (0, 2)
    assert math.isnan(m["epe_static_mean"]) and m["n_static"] == 0


def test_the_default_moving_set_is_the_nonzero_ground_truth_and_nan_is_unscored():
    gt = np.zeros((2, 2, 3))
    gt[0, 0] = [0.0, 0.0, 0.05]
    gt[1, 1] = np.nan
    pred = np.full((2, 2, 3), 0.001)
    m = worst_case_flow_metrics(pred, gt, np.zeros((2, 2), int))
    assert (m["n_moving"], m["n_static"], m["n_interior"]) == (1, 2, 0)
    assert m["epe_static_mean"] == pytest.approx(0.001 * math.sqrt(3))
    assert math.isnan(m["max_interior_error"]) and m["max_interior_pixel"] is None


def test_end_point_errors_count_an_unanswered_pixel_as_zero_motion():
    e = flow_end_point_errors([[np.inf, 0.0, 0.0], [1.0, 2.0, 2.0]], [[0.0, 0.3, 0.4], [1.0, 0.0, 0.0]])
    assert e.tolist() == pytest.approx([0.5, math.sqrt(8.0)])
    with pytest.raises(ValueError, match="pred"):
        flow_end_point_errors(np.zeros((2, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="gt"):
        flow_end_point_errors(np.zeros(3), [0.0, np.inf, 0.0])
    with pytest.raises(ValueError, match="moving"):
        worst_case_flow_metrics(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 2), int),
                                moving=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="labels"):
        worst_case_flow_metrics(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), np.zeros((3, 2), int))
