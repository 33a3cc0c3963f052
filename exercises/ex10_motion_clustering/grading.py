"""Ex10: motion clustering into track initialisations: the trusted tests of the notebook next to this file."""

from __future__ import annotations

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Outcome,
    Report,
    as_float_array,
    graded_test,
)


def _ex10_expected(P, V, radius, sigma_v, min_speed):
    from flowtrack.clustering import cluster_motion, tracks_from_clusters

    n = P.shape[0]
    # every moving point within `radius` is a candidate neighbour (k = N) and every component is a
    # cluster (min_size = 1): the plain connected components the exercise asks for
    labels = cluster_motion(
        P, V, radius, sigma_v, min_speed=min_speed, method="connected", k=max(n, 1), min_size=1
    )
    tracks = tracks_from_clusters(P, V, labels)
    D = P.shape[1]
    cents = np.array([c for c, _ in tracks]).reshape(-1, D)
    vels = np.array([v for _, v in tracks]).reshape(-1, D)
    sizes = np.array([np.sum(labels == k) for k in range(len(tracks))])
    return cents, vels, sizes


def _same_clusters(gc, gv, cents, vels, rtol=1e-6, atol=1e-9) -> bool:
    from scipy.optimize import linear_sum_assignment

    if gc.shape != cents.shape or gv.shape != vels.shape:
        return False
    if cents.shape[0] == 0:
        return True
    cost = np.linalg.norm(gc[:, None, :] - cents[None], axis=2)
    cost = cost + np.linalg.norm(gv[:, None, :] - vels[None], axis=2)
    r, c = linear_sum_assignment(cost)
    return bool(
        np.allclose(gc[r], cents[c], rtol=rtol, atol=atol)
        and np.allclose(gv[r], vels[c], rtol=rtol, atol=atol)
    )


def _ex10_check(P, V, radius, sigma_v, min_speed) -> Check:
    c, v, _ = _ex10_expected(P, V, radius, sigma_v, min_speed)
    variants = {
        "clusters-by-position-only": _ex10_expected(P, V, radius, 1e12, min_speed)[:2],
        "static-points-kept": _ex10_expected(P, V, radius, sigma_v, 0.0)[:2],
    }
    variants = {k: w for k, w in variants.items() if not _same_clusters(w[0], w[1], c, v)}
    return _clusters_check(c, v, variants=variants)


def _clusters_check(
    cents: np.ndarray, vels: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9, variants: dict | None = None
) -> Check:
    """Same set of (centroid, velocity) pairs as the reference, in any order."""
    from scipy.optimize import linear_sum_assignment

    K, D = cents.shape
    variants = variants or {}

    def named(gc, gv) -> list[str]:
        return [k for k, (wc, wv) in variants.items() if _same_clusters(gc, gv, wc, wv, rtol, atol)]

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        value = outcome.value
        if type(value) not in (list, tuple) or len(value) != 2:
            return 0.0, "expected a tuple (centroids, velocities)"
        gc = as_float_array(value[0])
        gv = as_float_array(value[1])
        if gc is None or gv is None:
            return 0.0, "centroids and velocities must be arrays of numbers"
        if K == 0:
            return (1.0, "ok") if gc.size == 0 and gv.size == 0 else (0.0, "expected no clusters")
        if gc.shape != (K, D) or gv.shape != (K, D):
            msg = f"expected {K} clusters: arrays of shape ({K}, {D}), got {gc.shape} and {gv.shape}"
            safe = f"wrong shape (expected {K} clusters: arrays of shape ({K}, {D}))"
            return 0.0, Report(msg, safe, named(gc, gv) if gc.ndim == 2 and gv.ndim == 2 else (), variants)
        if not (np.isfinite(gc).all() and np.isfinite(gv).all()):
            return 0.0, "NaN or inf in the result"
        cost = np.linalg.norm(gc[:, None, :] - cents[None], axis=2) + np.linalg.norm(
            gv[:, None, :] - vels[None], axis=2
        )
        r, c = linear_sum_assignment(cost)
        ok_c = np.allclose(gc[r], cents[c], rtol=rtol, atol=atol)
        ok_v = np.allclose(gv[r], vels[c], rtol=rtol, atol=atol)
        if ok_c and ok_v:
            return 1.0, Report("ok", checked=variants)
        msg = "the right number of clusters, but " + ("centroids" if not ok_c else "velocities") + " differ"
        return 0.0, Report(msg, msg, named(gc, gv), variants)

    return check


def _ex10_public_data():
    g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0)), -1).reshape(-1, 2) * 0.1
    a = np.column_stack([g, np.zeros(len(g))])
    P = np.vstack([a, a + np.array([0.35, 0.0, 0.0]), a + np.array([2.0, 2.0, 0.0])])
    V = np.vstack([np.tile([1.0, 0.0, 0.0], (12, 1)), np.tile([0.0, -1.0, 0.0], (12, 1)), np.zeros((12, 3))])
    return P, V


@graded_test("two touching boxes moving apart and a static one", "test_public_clusters", 4.0, hidden=False)
def _ex10_public(rng):
    P, V = _ex10_public_data()
    out = []
    for radius, sigma_v, min_speed in ((0.15, 0.5, 0.1), (0.15, 2.0, 0.1), (0.15, 0.5, 0.0)):
        check = _ex10_check(P, V, radius, sigma_v, min_speed)
        out.append(("cluster_tracks", (P, V, radius, sigma_v, min_speed), {}, check))
    return out


def _ex10_random_scene(rng, n_objects: int, with_static: bool, radius: float):
    """Boxes of jittered grid points in a row, each with its velocity (+ small noise), and static
    clutter. Neighbouring boxes either touch (gap < radius: only their motion separates them) or
    stand apart (gap > 2 radius)."""
    P, V = [], []
    x = 0.0
    for _ in range(n_objects):
        nx, ny = (int(v) for v in rng.integers(2, 6, size=2))
        g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny)), -1).reshape(-1, 2) * 0.1
        pts = np.column_stack([g, np.zeros(len(g))]) + rng.uniform(-0.01, 0.01, size=(len(g), 3))
        P.append(pts + np.array([x, 0.0, 0.0]))
        # touching and separate neighbours alternate (the same for every student: a position-only
        # clustering fails the same cases for everyone)
        x += 0.1 * (nx - 1) + (0.4 * radius if len(P) % 2 == 1 else 3.0 * radius)
        while True:  # a box touching the previous one moves clearly differently (|dv| > 2.5 > sigma_v)
            vel = rng.normal(size=3)
            vel *= rng.uniform(1.0, 2.0) / np.linalg.norm(vel)
            if not V or len(P) % 2 == 1 or np.linalg.norm(vel - V[-1].mean(axis=0)) > 2.5:
                break
        V.append(vel + rng.normal(scale=0.01, size=(len(g), 3)))
    if with_static:
        m = int(rng.integers(5, 15))
        P.append(rng.uniform(-1.0, 4.0, size=(m, 3)))
        V.append(rng.normal(scale=0.01, size=(m, 3)))
    return np.vstack(P), np.vstack(V)


@graded_test("random scenes of moving boxes and static clutter", "test_random_clusters", 6.0, hidden=True)
def _ex10_hidden(rng):
    out = []
    for n_obj, static, radius, sigma_v, min_speed in (
        (2, False, 0.15, 0.5, 0.1),
        (3, True, 0.15, 0.5, 0.2),
        (4, True, 0.25, 0.3, 0.2),
        (5, True, 0.15, 1.5, 0.2),
    ):
        P, V = _ex10_random_scene(rng, n_obj, static, radius)
        check = _ex10_check(P, V, radius, sigma_v, min_speed)
        out.append(("cluster_tracks", (P, V, radius, sigma_v, min_speed), {}, check))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L6 = "lesson 06_flow_to_tracks"

MISTAKES = (
    Mistake(
        "clusters-by-position-only",
        "points are joined by position only: two touching objects moving differently must be "
        "separated by their velocities (|v_i - v_j| <= sigma_v); "
        f"see {_L6} §1-2 (the motion affinity, motion clustering)",
    ),
    Mistake(
        "static-points-kept",
        "the static background is kept: points slower than min_speed are not moving objects and "
        f"are dropped before clustering; see {_L6} §2-3 (motion clustering, starting a track)",
    ),
)


EXERCISE = Exercise(
    id="ex10_motion_clustering",
    title="Motion clustering into track initialisations",
    notebook="ex10_motion_clustering.ipynb",
    answer_cells=("cluster_tracks",),
    blocked=("flowtrack.clustering",),
    allowed=('numpy', 'scipy'),
    tests=(_ex10_public, _ex10_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
