r"""Shared test vectors for the cross-language ports, made by the Python reference.

Every problem is one file ``cpp_java_matlab_ports/vectors/<problem>.json``::

    {"problem": "<name>",
     "cases": [{"id": "<case id>", "input": {...}, "expected": {...}, "rtol": r, "atol": a}, ...]}

A port passes a case iff every expected number ``e`` and the port's ``g`` satisfy
``|g - e| <= atol + rtol * |e|`` (and integer outputs such as matches are equal). The files are
generated, never edited by hand: :func:`write_vectors` (``flowtrack ports --regenerate``) is
deterministic (fixed seeds, JSON with sorted keys, ``repr``-exact floats). Regenerating on the machine
that wrote the files gives the same bytes; on another CPU, BLAS, CHOLMOD, open3d or OpenCV build the
floats may differ in their last bits, so a test compares a regeneration with the committed files by
:func:`vector_differences` within :data:`REGENERATION_RTOL` (far below the ports' tolerances, far
above rounding noise). Matrices are nested lists, row-major (``M[i][j]`` is row ``i``).

Problems (inputs -> expected; the conventions the ports must follow):

``kalman_cv2d``
    ``{"dt", "process_var", "meas_var", "x0" (4,), "P0" (4, 4), "measurements" (T, 2)}`` ->
    ``{"positions" (T, 2), "P_final" (4, 4)}``. State :math:`[p_x, p_y, v_x, v_y]`,
    :math:`F = [[I, \Delta t I], [0, I]]`, :math:`H = [I\ 0]`, :math:`R = r I`,
    :math:`Q = q\,Q_{1D} \otimes I_2` (not the syllabus' ``blkdiag(Q1d, Q1d)``); for every measurement
    predict then update; ``positions[t]`` is :math:`(x_0, x_1)` after update ``t``, ``P_final`` the
    covariance after the last update. The syllabus' own run (``x0 = 0``, ``P0 = 1e3 I``) is the
    case ``syllabus``.
``white_noise_q``
    ``{"dt", "q", "dim"}`` -> ``{"Q" (2 dim, 2 dim)}``, :math:`Q = q\,Q_{1D}(\Delta t) \otimes I_{dim}`.
``projection_jacobian``
    ``{"X" (3,), "fx", "fy", "cx", "cy"}`` -> ``{"J" (2, 3)}``, :math:`\partial\pi/\partial X`.
``mahalanobis_assignment``
    ``{"z_pred" (M, m), "S" (M, m, m), "detections" (N, m), "gate"}`` ->
    ``{"cost" (M, N), "matches" (K, 2)}``: ``cost[i][j]`` is the squared Mahalanobis distance
    :math:`(z_j - \hat z_i)^\top S_i^{-1} (z_j - \hat z_i)` of *every* pair (no entry is gated or
    replaced by a sentinel); ``matches`` are the ``[track, detection]`` pairs, sorted by track, of
    the matching that uses only pairs with ``cost <= gate``, has the most pairs and among those the
    least total cost (unique in every case: the generator checks it by brute force).
``graph_scene_flow``
    ``{"points" (N, 3), "targets" (N, 3), "dt", "lam"}`` plus either ``{"k", "sigma"}`` (ports build
    the graph: every point is joined to its ``k`` nearest other points, Euclidean, the edge set is
    symmetrised by union and weighted :math:`w_{ij} = \exp(-\lVert X_i - X_j\rVert^2/\sigma^2)`) or
    ``{"edges": [[i, j, w_ij], ...]}`` (each undirected edge once, ``i < j``, 0-based) ->
    ``{"flow" (N, 3)}`` solving :math:`(\Delta t^2 I + \lambda L) V = \Delta t (Y - X)`,
    :math:`L = D - W`.
``variational_scene_flow``
    ``{"a" (C, H, W), "b" (C, H, W), "dt", "lam"}`` with ``C`` = 1 or 3 components ->
    ``{"v" (C, H, W)}`` solving :math:`(\Delta t^2 I + \lambda L_{grid}) v_c = \Delta t (b_c - a_c)`
    per component, :math:`L_{grid}` the Laplacian of the 4-neighbour grid graph (5-point stencil,
    Neumann boundary: a pixel's diagonal entry is its number of neighbours).
``rigid_icp``
    ``{"source" (N, 3), "target" (N, 3), "threshold", "max_iter"}`` -> ``{"T" (4, 4), "T_true"
    (4, 4)}``: ``T`` is the reference's open3d point-to-point ICP from the identity (pairs farther
    than ``threshold`` ignored); the case tolerance is for ``T``. ``T_true`` is the motion that made
    ``target`` (before 1 mm noise), for information; the vector tests check ``T`` against it.
``lucas_kanade``, ``steady_state_scalar``
    From :mod:`flowtrack_course.ports.vectors_extra` (documented there).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from ..course import vectors_dir as _course_vectors
from .vectors_extra import lucas_kanade, steady_state_scalar

__all__ = [
    "PROBLEMS",
    "REGENERATION_RTOL",
    "dumps",
    "generate",
    "problem_names",
    "load_vectors",
    "vector_differences",
    "write_vectors",
]


# ----------------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------------
def _plain(obj):
    """Convert numpy arrays/scalars inside ``obj`` to Python lists, floats and ints."""
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        if not np.isfinite(value):
            raise ValueError(f"vector values must be finite, got {value}")
        return value + 0.0  # no negative zero in the files
    return obj


def _case(case_id: str, inp: dict, expected: dict, rtol: float, atol: float) -> dict:
    return {"id": case_id, "input": _plain(inp), "expected": _plain(expected), "rtol": rtol, "atol": atol}


def dumps(doc: dict) -> str:
    """Serialise a problem document: sorted keys, ``repr``-exact floats, one case per line.

    Parameters
    ----------
    doc : dict
        ``{"problem": str, "cases": [dict, ...]}``.

    Returns
    -------
    str
        JSON text ending in a newline; ``json.loads`` gives ``doc`` back exactly.

    Examples
    --------
    >>> print(dumps({"problem": "p", "cases": [{"id": "a", "input": {"x": 0.1}}]}), end="")
    {"cases": [
    {"id": "a", "input": {"x": 0.1}}
    ], "problem": "p"}
    """
    if not isinstance(doc, dict) or "problem" not in doc or "cases" not in doc:
        raise ValueError("doc must be a dict with keys 'problem' and 'cases'")
    cases = [json.dumps(_plain(c), sort_keys=True, allow_nan=False) for c in doc["cases"]]
    rest = {k: v for k, v in doc.items() if k != "cases"}
    head = json.dumps(_plain(rest), sort_keys=True, allow_nan=False)
    # keys sort as "cases" < "problem": put the case list first, one per line for readable diffs
    return '{"cases": [\n' + ",\n".join(cases) + "\n], " + head[1:] + "\n"


# ----------------------------------------------------------------------------------------------------
# kalman_cv2d
# ----------------------------------------------------------------------------------------------------
def _kalman_case(case_id, dt, q, r, x0, P0, Z, rtol=1e-9, atol=1e-9) -> dict:
    from flowtrack.kalman import KalmanFilter, constant_velocity_model

    F, H, Q, R = constant_velocity_model(dt, q, r, dim=2)
    kf = KalmanFilter(F, H, Q, R, np.asarray(x0, float), np.asarray(P0, float))
    positions = []
    for z in Z:
        kf.predict()
        kf.update(z)
        positions.append(kf.x[:2].copy())
    inp = {"dt": dt, "process_var": q, "meas_var": r, "x0": x0, "P0": P0, "measurements": Z}
    return _case(case_id, inp, {"positions": np.array(positions), "P_final": kf.P}, rtol, atol)


def _cv_track(rng: np.random.Generator, steps: int, dt: float, q: float, r: float) -> np.ndarray:
    """Noisy position measurements of a simulated constant-velocity target, shape (steps, 2)."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    G = np.vstack([0.5 * dt * dt * np.eye(2), dt * np.eye(2)])  # piecewise-constant acceleration
    x = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-2, 2), rng.uniform(-2, 2)])
    Z = np.empty((steps, 2))
    for t in range(steps):
        x = F @ x + G @ (np.sqrt(q) * rng.standard_normal(2))
        Z[t] = x[:2] + np.sqrt(r) * rng.standard_normal(2)
    return np.round(Z, 6)  # short decimal measurements keep the files small


def kalman_cv2d() -> dict:
    """Problem document ``kalman_cv2d`` (see the module docstring for the conventions)."""
    x0 = np.zeros(4)
    P0 = 1e3 * np.eye(4)
    syllabus = [[0.0, 0.0], [0.9, 0.1], [2.1, 0.2], [3.0, 0.1]]
    cases = [_kalman_case("syllabus", 0.1, 1.0, 4.0, x0, P0, np.array(syllabus))]
    for seed, steps, dt, q, r in [(1, 25, 0.1, 1.0, 4.0), (2, 40, 0.05, 3.0, 0.25), (3, 1000, 0.1, 0.5, 1.0)]:
        rng = np.random.default_rng(seed)
        Z = _cv_track(rng, steps, dt, q, r)
        cases.append(_kalman_case(f"random_seed{seed}_steps{steps}", dt, q, r, x0, P0, Z))
    # a filter started at the first measurement with a tighter prior (x0/P0 are inputs, not fixed)
    rng = np.random.default_rng(4)
    Z = _cv_track(rng, 30, 0.2, 2.0, 0.5)
    x0 = np.array([Z[0, 0], Z[0, 1], 0.0, 0.0])
    P0 = np.diag([0.5, 0.5, 10.0, 10.0])
    P0[0, 2] = P0[2, 0] = 0.1
    cases.append(_kalman_case("informative_prior_seed4", 0.2, 2.0, 0.5, x0, P0, Z[1:]))
    return {"problem": "kalman_cv2d", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# white_noise_q, projection_jacobian
# ----------------------------------------------------------------------------------------------------
def white_noise_q() -> dict:
    """Problem document ``white_noise_q``."""
    from flowtrack.kalman import white_noise_acceleration_Q

    cases = []
    for dt, q, dim in [(0.1, 1.0, 2), (1.0, 4.0, 2), (0.5, 2.0, 1), (0.033, 9.81, 3), (2.0, 0.1, 3)]:
        Q = white_noise_acceleration_Q(dt, q, dim)
        cases.append(
            _case(f"dim{dim}_dt{dt:g}_q{q:g}", {"dt": dt, "q": q, "dim": dim}, {"Q": Q}, 1e-12, 1e-15)
        )
    return {"problem": "white_noise_q", "cases": cases}


def projection_jacobian() -> dict:
    """Problem document ``projection_jacobian``."""
    from flowtrack.camera import PinholeCamera
    from flowtrack.camera import projection_jacobian as jac

    rng = np.random.default_rng(6)
    cases = []
    setups = [([0.1, -0.2, 1.5], 525.0, 525.0, 319.5, 239.5), ([0.0, 0.0, 1.0], 500.0, 480.0, 320.0, 240.0)]
    for _ in range(4):
        X = [
            float(np.round(rng.uniform(-1, 1), 6)),
            float(np.round(rng.uniform(-1, 1), 6)),
            float(np.round(rng.uniform(0.3, 4.0), 6)),
        ]
        setups.append(
            (
                X,
                float(np.round(rng.uniform(300, 900), 3)),
                float(np.round(rng.uniform(300, 900), 3)),
                float(np.round(rng.uniform(100, 400), 3)),
                float(np.round(rng.uniform(100, 300), 3)),
            )
        )
    for i, (X, fx, fy, cx, cy) in enumerate(setups):
        J = jac(np.array([X]), PinholeCamera(fx, fy, cx, cy))[0]
        inp = {"X": X, "fx": fx, "fy": fy, "cx": cx, "cy": cy}
        cases.append(_case(f"point{i}", inp, {"J": J}, 1e-12, 1e-12))
    return {"problem": "projection_jacobian", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# mahalanobis_assignment
# ----------------------------------------------------------------------------------------------------
def _brute_force_assignment(cost: np.ndarray, gate: float) -> tuple[list[list[int]], bool]:
    """Best gated matching by enumerating every matching of admissible pairs (small M, N only).

    Returns the pairs sorted by track and whether the optimum is unique (by a 1e-6 cost margin).
    """
    M, N = cost.shape
    found: list[tuple[int, float, list[list[int]]]] = []

    def extend(i: int, used: frozenset, pairs: list, total: float) -> None:
        if i == M:
            found.append((-len(pairs), total, list(pairs)))
            return
        extend(i + 1, used, pairs, total)  # track i unmatched
        for j in range(N):
            if j not in used and cost[i, j] <= gate:
                extend(i + 1, used | {j}, [*pairs, [i, j]], total + float(cost[i, j]))

    extend(0, frozenset(), [], 0.0)
    found.sort(key=lambda f: (f[0], f[1]))
    best = found[0]
    unique = len(found) == 1 or found[1][0] != best[0] or found[1][1] - best[1] > 1e-6
    return best[2], unique


def _assignment_case(case_id: str, z_pred, S, Z, gate) -> dict:
    from flowtrack.association import assign, mahalanobis_cost

    cost = mahalanobis_cost(z_pred, S, Z)
    matches = assign(cost, gate)[0]
    brute, unique = _brute_force_assignment(cost, gate)
    if not unique or brute != matches.tolist():
        raise RuntimeError(f"assignment case {case_id} is ambiguous or disagrees with brute force")
    inp = {"z_pred": z_pred, "S": S, "detections": Z, "gate": gate}
    return _case(case_id, inp, {"cost": cost, "matches": matches}, 1e-10, 1e-10)


def mahalanobis_assignment() -> dict:
    """Problem document ``mahalanobis_assignment``."""
    from flowtrack.association import chi2_gate

    cases = []
    # The gate trap of the API's most-pairs rule: with costs [[0, 6], [6, 11]] and gate 10, solving
    # ungated and dropping the (1,1) pair afterwards loses a pair; the rule's answer keeps two, crossed.
    s6 = np.sqrt(6.0)
    x = 1.0 / (2.0 * s6)
    t1 = [x, float(np.sqrt(6.0 - x * x))]
    cases.append(
        _assignment_case(
            "gate_trap",
            np.array([[0.0, 0.0], t1]),
            np.stack([np.eye(2)] * 2),
            np.array([[0.0, 0.0], [s6, 0.0]]),
            10.0,
        )
    )
    seed = 10
    for M, N, m in [(3, 4, 2), (4, 3, 2), (4, 4, 2), (5, 5, 2), (3, 5, 3), (2, 6, 2)]:
        while True:
            rng = np.random.default_rng(seed)
            seed += 1
            z_pred = np.round(rng.uniform(0, 10, size=(M, m)), 4)
            A = rng.normal(size=(M, m, m))
            S = np.round(np.einsum("kij,klj->kil", A, A) * 0.3 + 0.5 * np.eye(m), 6)
            near = z_pred[rng.integers(0, M, size=N)] + rng.normal(scale=1.2, size=(N, m))
            Z = np.round(near, 4)
            gate = chi2_gate(m, 0.99)
            try:
                cases.append(_assignment_case(f"random_M{M}_N{N}_m{m}", z_pred, S, Z, gate))
                break
            except RuntimeError:
                continue
    return {"problem": "mahalanobis_assignment", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# graph_scene_flow
# ----------------------------------------------------------------------------------------------------
def _cloud_and_targets(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A cloud of two blobs moving differently, with noisy targets, rounded to 1e-6 m."""
    X = rng.uniform(-0.1, 0.1, size=(n, 3))
    X[: n // 2, 0] += 0.15
    motion = np.where(np.arange(n)[:, None] < n // 2, [0.01, 0.0, 0.002], [-0.005, 0.008, 0.0])
    Y = X + motion + rng.normal(scale=0.002, size=(n, 3))
    return np.round(X, 6), np.round(Y, 6)


def graph_scene_flow() -> dict:
    """Problem document ``graph_scene_flow`` (kNN-graph and explicit-edge variants)."""
    import scipy.sparse as sp

    from flowtrack.sceneflow import graph_scene_flow as gsf
    from flowtrack.sceneflow import knn_graph

    cases = []
    for seed, n, k, sigma, dt, lam in [(20, 60, 6, 0.04, 0.1, 0.02), (21, 150, 8, 0.03, 0.1, 0.05)]:
        X, Y = _cloud_and_targets(np.random.default_rng(seed), n)
        V = gsf(X, Y, dt, lam, k=k, sigma=sigma, solver="splu")
        inp = {"points": X, "targets": Y, "dt": dt, "lam": lam, "k": k, "sigma": sigma}
        cases.append(_case(f"knn_n{n}_k{k}", inp, {"flow": V}, 1e-8, 1e-9))
    for seed, n, dt, lam in [(22, 100, 0.1, 0.03), (23, 50, 0.05, 0.01)]:
        X, Y = _cloud_and_targets(np.random.default_rng(seed), n)
        W = knn_graph(X, k=5, sigma=0.05).tocoo()
        keep = W.row < W.col
        w = np.round(W.data[keep], 12)
        edges = [[int(i), int(j), float(v)] for i, j, v in zip(W.row[keep], W.col[keep], w)]
        edges.sort()
        ii, jj, ww = (np.array([e[c] for e in edges]) for c in range(3))
        Wm = sp.coo_matrix((ww, (ii.astype(int), jj.astype(int))), shape=(n, n))
        V = gsf(X, Y, dt, lam, W=(Wm + Wm.T).tocsr(), solver="splu")
        inp = {"points": X, "targets": Y, "dt": dt, "lam": lam, "edges": edges}
        cases.append(_case(f"edges_n{n}", inp, {"flow": V}, 1e-8, 1e-9))
    return {"problem": "graph_scene_flow", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# variational_scene_flow
# ----------------------------------------------------------------------------------------------------
def variational_scene_flow() -> dict:
    """Problem document ``variational_scene_flow`` (grids of 1 or 3 components)."""
    from flowtrack.variational import solve_component

    cases = []
    for seed, C, H, W, dt, lam in [
        (30, 1, 6, 8, 0.1, 0.5),
        (31, 1, 9, 5, 0.05, 0.02),
        (32, 3, 10, 12, 0.1, 2.0),
    ]:
        rng = np.random.default_rng(seed)
        yy, xx = np.mgrid[0:H, 0:W] / max(H, W)
        a = np.round(rng.uniform(0.5, 1.5, size=(C, H, W)), 6)
        smooth = np.stack([0.02 * np.sin(3 * xx + c) + 0.01 * yy for c in range(C)])
        b = np.round(a + smooth + rng.normal(scale=0.003, size=(C, H, W)), 6)
        v = np.stack([solve_component(a[c], b[c], dt, lam, method="dct") for c in range(C)])
        inp = {"a": a, "b": b, "dt": dt, "lam": lam}
        cases.append(_case(f"grid{H}x{W}_c{C}", inp, {"v": v}, 1e-8, 1e-10))
    return {"problem": "variational_scene_flow", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# rigid_icp
# ----------------------------------------------------------------------------------------------------
def _box_surface(rng: np.random.Generator, n: int, size) -> np.ndarray:
    """``n`` points uniformly on the surface of an axis-aligned box centred at 0."""
    size = np.asarray(size, float)
    areas = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]] * 2)
    face = rng.choice(6, size=n, p=areas / areas.sum())
    P = rng.uniform(-0.5, 0.5, size=(n, 3))
    axis = face % 3
    P[np.arange(n), axis] = np.where(face < 3, 0.5, -0.5)
    return P * size


def _rotation(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def rigid_icp() -> dict:
    """Problem document ``rigid_icp`` (open3d point-to-point ICP on a noisy moved box)."""
    from flowtrack._graph import apply_transform
    from flowtrack.sceneflow import rigid_scene_flow

    cases = []
    for seed, n, axis, deg, t in [
        (40, 400, [0.2, 0.3, 1.0], 4.0, [0.01, -0.005, 0.003]),
        (41, 600, [1.0, -0.5, 0.4], 8.0, [-0.015, 0.01, 0.008]),
    ]:
        rng = np.random.default_rng(seed)
        src = np.round(_box_surface(rng, n, [0.12, 0.08, 0.05]) + np.array([0.0, 0.0, 0.8]), 6)
        T_true = np.eye(4)
        T_true[:3, :3] = _rotation(axis, np.deg2rad(deg))
        # rotate about the box centre, then translate
        T_true[:3, 3] = np.array([0.0, 0.0, 0.8]) - T_true[:3, :3] @ [0.0, 0.0, 0.8] + np.asarray(t)
        dst = np.round(apply_transform(T_true, src) + rng.normal(scale=0.001, size=(n, 3)), 6)
        threshold, max_iter = 0.05, 100
        _, T = rigid_scene_flow(src, dst, 1.0, threshold, max_iter=max_iter)
        T = np.array([[float(f"{v:.12e}") for v in row] for row in T])  # drop last-bit threading noise
        inp = {"source": src, "target": dst, "threshold": threshold, "max_iter": max_iter}
        cases.append(_case(f"box_n{n}_rot{deg:g}deg", inp, {"T": T, "T_true": T_true}, 0.0, 1e-4))
    return {"problem": "rigid_icp", "cases": cases}


# ----------------------------------------------------------------------------------------------------
# registry
# ----------------------------------------------------------------------------------------------------
#: Problem name -> generator of its document.
PROBLEMS: dict[str, Callable[[], dict]] = {
    "kalman_cv2d": kalman_cv2d,
    "white_noise_q": white_noise_q,
    "projection_jacobian": projection_jacobian,
    "mahalanobis_assignment": mahalanobis_assignment,
    "graph_scene_flow": graph_scene_flow,
    "variational_scene_flow": variational_scene_flow,
    "rigid_icp": rigid_icp,
    "lucas_kanade": lucas_kanade,
    "steady_state_scalar": steady_state_scalar,
}


#: Problem -> relative tolerance within which a regeneration must reproduce the committed file.
#: A float ``g`` regenerated for the committed ``e`` passes iff ``|g - e| <= rtol (|e| + s)``, with
#: ``s`` the largest magnitude of the same ``input``/``expected`` entry in that case (so a component
#: that is zero up to rounding is judged at the scale of its array, not by its own size). Each value
#: sits between two bounds: far above last-bit noise across machines (measured: 1e-16 to 3e-14
#: relative for CHOLMOD/BLAS and OpenCV-free rendering; closed forms stay within a few ulps) and far
#: below what a port is allowed (the case's ``rtol``/``atol``), so a real change of a committed value
#: (1e-5 relative, a test checks) is always caught.
REGENERATION_RTOL: dict[str, float] = {
    # 1000-step filter recursions with 4x4 BLAS products: noise ~1e-14; ports get 1e-9
    "kalman_cv2d": 1e-12,
    # closed-form polynomials in dt: a few ulps (1 ulp = 2.2e-16 relative); ports get 1e-12, so ~20 ulps
    "white_noise_q": 4e-15,
    # closed-form quotients: a few ulps; ports get 1e-12, so ~20 ulps
    "projection_jacobian": 4e-15,
    # 2x2 / 3x3 solves (LAPACK): ~1e-15; ports get 1e-10
    "mahalanobis_assignment": 2e-13,
    # sparse direct solve (SuperLU ordering/BLAS): measured up to 3e-14 across machines; ports get 1e-8
    "graph_scene_flow": 1e-11,
    # DCT (FFT) solves: ~1e-14 of the array scale; ports get 1e-8
    "variational_scene_flow": 1e-11,
    # open3d ICP (threaded reductions), T rounded to 12 significant digits: up to ~1e-12 from the
    # rounding alone; ports get 1e-4 absolute
    "rigid_icp": 1e-9,
    # exact projection differences of the rendered scene: measured 1.6e-13 across machines; ports get
    # 0.5 px absolute (about 1e-1 relative)
    "lucas_kanade": 1e-10,
    # closed-form scalar Riccati root (correctly rounded sqrt): a few ulps; ports get 1e-10
    "steady_state_scalar": 1e-13,
}


def vector_differences(committed: dict, regenerated: dict, rtol: float) -> list[str]:
    r"""What differs between two documents of one problem, numbers compared within ``rtol``.

    Structure (keys, list lengths, case ids), strings, booleans and integers must be equal; floats
    :math:`g` (regenerated) and :math:`e` (committed) must satisfy :math:`|g - e| \le
    \text{rtol}\,(|e| + s)`, :math:`s` the largest magnitude within the same top-level entry of
    the case's ``input`` or ``expected`` (or the value itself for scalars), so entries that are zero
    up to rounding are judged at the scale of their array. An integer may match a float of the same
    value (JSON writes ``1.0`` as ``1.0``, but a generator may produce either).

    Parameters
    ----------
    committed, regenerated : dict
        Problem documents (``json.loads`` of the files).
    rtol : float >= 0
        E.g. :data:`REGENERATION_RTOL` ``[problem]``.

    Returns
    -------
    list of str
        One line per difference (empty when the documents agree), naming the case and the path.

    Examples
    --------
    >>> a = {"problem": "p", "cases": [{"id": "c", "expected": {"x": [1.0, 1e-17]}}]}
    >>> b = {"problem": "p", "cases": [{"id": "c", "expected": {"x": [1.0 + 4e-16, -3e-17]}}]}
    >>> vector_differences(a, b, 1e-12)
    []
    >>> b["cases"][0]["expected"]["x"][0] = 1.00001
    >>> vector_differences(a, b, 1e-12)  # doctest: +ELLIPSIS
    ['case c: expected/x/0: 1.00001 regenerated vs 1.0 committed (...)']
    """
    if not (isinstance(rtol, (int, float)) and rtol >= 0):
        raise ValueError(f"rtol must be a number >= 0, got {rtol!r}")
    out: list[str] = []

    def scale(value) -> float:
        if isinstance(value, bool):
            return 0.0
        if isinstance(value, (int, float)):
            return abs(float(value))
        if isinstance(value, list):
            return max((scale(v) for v in value), default=0.0)
        if isinstance(value, dict):
            return max((scale(v) for v in value.values()), default=0.0)
        return 0.0

    def walk(e, g, path: str, where: str, s: float) -> None:
        if isinstance(e, bool) or isinstance(g, bool) or isinstance(e, str) or e is None:
            if type(e) is not type(g) or e != g:
                out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed")
            return
        if isinstance(e, (int, float)) and isinstance(g, (int, float)):
            if isinstance(e, int) and isinstance(g, int):
                if e != g:
                    out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed (integers differ)")
                return
            bound = rtol * (abs(e) + s)
            if not abs(g - e) <= bound:
                out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed (|diff| "
                           f"{abs(g - e):.3g} > {bound:.3g})")
            return
        if isinstance(e, list) and isinstance(g, list):
            if len(e) != len(g):
                out.append(f"{where}: {path}: length {len(g)} regenerated vs {len(e)} committed")
                return
            for i, (a, b) in enumerate(zip(e, g)):
                walk(a, b, f"{path}/{i}" if path else str(i), where, s)
            return
        if isinstance(e, dict) and isinstance(g, dict):
            if set(e) != set(g):
                out.append(f"{where}: {path or 'keys'}: {sorted(g)} regenerated vs {sorted(e)} committed")
                return
            for key in sorted(e):
                walk(e[key], g[key], f"{path}/{key}" if path else key, where, s)
            return
        out.append(f"{where}: {path}: {type(g).__name__} regenerated vs {type(e).__name__} committed")

    head_e = {k: v for k, v in committed.items() if k != "cases"}
    head_g = {k: v for k, v in regenerated.items() if k != "cases"}
    walk(head_e, head_g, "", "document", 0.0)
    cases_e, cases_g = committed.get("cases", []), regenerated.get("cases", [])
    ids_e = [c.get("id") for c in cases_e]
    ids_g = [c.get("id") for c in cases_g]
    if ids_e != ids_g:
        return [*out, f"document: case ids {ids_g} regenerated vs {ids_e} committed"]
    for ce, cg in zip(cases_e, cases_g):
        where = f"case {ce.get('id')}"
        if set(ce) != set(cg):
            out.append(f"{where}: keys {sorted(cg)} regenerated vs {sorted(ce)} committed")
            continue
        for key in sorted(ce):
            if isinstance(ce[key], dict) and isinstance(cg[key], dict) and set(ce[key]) == set(cg[key]):
                for sub in sorted(ce[key]):  # one scale per top-level entry of input / expected
                    walk(ce[key][sub], cg[key][sub], f"{key}/{sub}", where, scale(ce[key][sub]))
            else:
                walk(ce[key], cg[key], key, where, scale(ce[key]))
    return out


def problem_names() -> list[str]:
    """Names of all problems, sorted."""
    return sorted(PROBLEMS)


def generate(problem: str) -> dict:
    """Make the document of one problem.

    Parameters
    ----------
    problem : str
        One of :func:`problem_names`.

    Returns
    -------
    dict
        ``{"problem": problem, "cases": [...]}``.
    """
    if problem not in PROBLEMS:
        raise ValueError(f"problem must be one of {problem_names()}, got {problem!r}")
    doc = PROBLEMS[problem]()
    if doc.get("problem") != problem:
        raise RuntimeError(f"generator of {problem!r} returned problem {doc.get('problem')!r}")
    return doc


def write_vectors(
    out_dir: Path | str | None = None, problems: Iterable[str] | None = None, progress: bool = False
) -> list[Path]:
    """Write ``<out_dir>/<problem>.json`` for the given problems (default: all).

    Parameters
    ----------
    out_dir : path, optional
        Folder (created if missing; default: the course's ``cpp_java_matlab_ports/vectors``).
    problems : iterable of str, optional
        Subset of :func:`problem_names`.
    progress : bool
        Show a tqdm progress bar.

    Returns
    -------
    list of Path
        The files written.
    """
    names = problem_names() if problems is None else list(problems)
    for name in names:
        if name not in PROBLEMS:
            raise ValueError(f"problems must be among {problem_names()}, got {name!r}")
    out = Path(out_dir) if out_dir is not None else _course_vectors()
    out.mkdir(parents=True, exist_ok=True)
    written = []
    iterator: Iterable[str] = names
    if progress:
        from tqdm import tqdm

        iterator = tqdm(names, desc="vectors", unit="problem")
    for name in iterator:
        path = out / f"{name}.json"
        path.write_text(dumps(generate(name)), encoding="utf-8")
        written.append(path)
    return written


def load_vectors(vectors_dir: Path | str | None = None) -> dict[str, dict]:
    """Read every ``*.json`` problem document of a folder (default: the course's vectors) into
    ``{problem: doc}``."""
    d = Path(vectors_dir) if vectors_dir is not None else _course_vectors()
    if not d.is_dir():
        raise FileNotFoundError(f"vectors_dir {d} is not a folder (run `flowtrack ports --regenerate`)")
    return {p.stem: json.loads(p.read_text(encoding="utf-8")) for p in sorted(d.glob("*.json"))}
