r"""The scene-flow problems of the ports: graph flow, variational flow on a grid, rigid ICP.

``graph_scene_flow``
    ``{"points" (N, 3), "targets" (N, 3), "dt", "lam"}`` plus either ``{"k", "sigma"}`` (ports build
    the graph: every point is joined to its ``k`` nearest other points, Euclidean, no ties occur,
    the edge set is symmetrised by union and weighted
    :math:`w_{ij} = \exp(-\lVert X_i - X_j\rVert^2/\sigma^2)`) or ``{"edges": [[i, j, w_ij], ...]}``
    (each undirected edge once, ``i < j``, 0-based) -> ``{"flow" (N, 3)}`` solving
    :math:`(\Delta t^2 I + \lambda L) V = \Delta t (Y - X)`, :math:`L = D - W`.
``variational_scene_flow``
    ``{"a" (C, H, W), "b" (C, H, W), "dt", "lam"}`` with ``C`` = 1 or 3 components ->
    ``{"v" (C, H, W)}`` solving :math:`(\Delta t^2 I + \lambda L_{grid}) v_c = \Delta t (b_c - a_c)`
    per component, :math:`L_{grid}` the Laplacian of the 4-neighbour grid graph (5-point stencil,
    Neumann boundary: a pixel's diagonal entry is its number of neighbours), pixel ``(r, c)`` <->
    index ``r W + c``.
``rigid_icp``
    ``{"source" (N, 3), "target" (N, 3), "threshold", "max_iter"}`` -> ``{"T" (4, 4), "T_true"
    (4, 4)}``: ``T`` is the reference's open3d point-to-point ICP from the identity (pairs farther
    than ``threshold`` ignored); the case tolerance is for ``T``. ``T_true`` is the motion that made
    ``target`` (before 1 mm noise), for information; the vector tests check ``T`` against it.
"""

from __future__ import annotations

import numpy as np

from .base import Case, Problem

__all__ = ["GRAPH_SCENE_FLOW", "RIGID_ICP", "VARIATIONAL_SCENE_FLOW"]


# -- graph_scene_flow -----------------------------------------------------------------------------
def _graph_reference(inp: dict) -> dict:
    import scipy.sparse as sp

    from flowtrack.sceneflow import graph_scene_flow

    X, Y = np.asarray(inp["points"], float), np.asarray(inp["targets"], float)
    if "edges" not in inp:
        V = graph_scene_flow(X, Y, inp["dt"], inp["lam"], k=inp["k"], sigma=inp["sigma"], solver="splu")
        return {"flow": V}
    ii, jj, ww = (np.array([e[c] for e in inp["edges"]]) for c in range(3))
    n = len(X)
    W = sp.coo_matrix((ww, (ii.astype(int), jj.astype(int))), shape=(n, n))
    return {"flow": graph_scene_flow(X, Y, inp["dt"], inp["lam"], W=(W + W.T).tocsr(), solver="splu")}


def _cloud_and_targets(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A cloud of two blobs moving differently, with noisy targets, rounded to 1e-6 m."""
    X = rng.uniform(-0.1, 0.1, size=(n, 3))
    X[: n // 2, 0] += 0.15
    motion = np.where(np.arange(n)[:, None] < n // 2, [0.01, 0.0, 0.002], [-0.005, 0.008, 0.0])
    Y = X + motion + rng.normal(scale=0.002, size=(n, 3))
    return np.round(X, 6), np.round(Y, 6)


def _graph_cases() -> list[Case]:
    """kNN-graph cases, and explicit-edge ones (the kNN graph's edges, weights rounded to 1e-12)."""
    from flowtrack.sceneflow import knn_graph

    cases = []
    for seed, n, k, sigma, dt, lam in [(20, 60, 6, 0.04, 0.1, 0.02), (21, 150, 8, 0.03, 0.1, 0.05)]:
        X, Y = _cloud_and_targets(np.random.default_rng(seed), n)
        inp = {"points": X, "targets": Y, "dt": dt, "lam": lam, "k": k, "sigma": sigma}
        cases.append(Case(f"knn_n{n}_k{k}", inp))
    for seed, n, dt, lam in [(22, 100, 0.1, 0.03), (23, 50, 0.05, 0.01)]:
        X, Y = _cloud_and_targets(np.random.default_rng(seed), n)
        W = knn_graph(X, k=5, sigma=0.05).tocoo()
        keep = W.row < W.col
        w = np.round(W.data[keep], 12)
        edges = sorted([int(i), int(j), float(v)] for i, j, v in zip(W.row[keep], W.col[keep], w))
        cases.append(Case(f"edges_n{n}", {"points": X, "targets": Y, "dt": dt, "lam": lam, "edges": edges}))
    return cases


GRAPH_SCENE_FLOW = Problem(
    "graph_scene_flow",
    "Graph scene flow on a kNN graph",
    ("flow",),
    _graph_reference,
    rtol=1e-8,
    atol=1e-9,
    vector_cases=_graph_cases,
)


# -- variational_scene_flow -----------------------------------------------------------------------
def _variational_reference(inp: dict) -> dict:
    from flowtrack.variational import solve_component

    a, b = np.asarray(inp["a"], float), np.asarray(inp["b"], float)
    v = [solve_component(a[c], b[c], inp["dt"], inp["lam"], method="dct") for c in range(len(a))]
    return {"v": np.stack(v)}


def _variational_cases() -> list[Case]:
    """Grids of 1 or 3 components: smooth motion plus noise on random intensities."""
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
        cases.append(Case(f"grid{H}x{W}_c{C}", {"a": a, "b": b, "dt": dt, "lam": lam}))
    return cases


VARIATIONAL_SCENE_FLOW = Problem(
    "variational_scene_flow",
    "Variational scene flow on a pixel grid",
    ("v",),
    _variational_reference,
    rtol=1e-8,
    atol=1e-10,
    vector_cases=_variational_cases,
)


# -- rigid_icp ----------------------------------------------------------------------------------
def _icp_reference(inp: dict) -> dict:
    from flowtrack.sceneflow import rigid_scene_flow

    src, dst = np.asarray(inp["source"], float), np.asarray(inp["target"], float)
    _, T = rigid_scene_flow(src, dst, 1.0, inp["threshold"], max_iter=inp["max_iter"])
    return {"T": np.array([[float(f"{v:.12e}") for v in row] for row in T])}  # drop last-bit threading noise


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


def _icp_cases() -> list[Case]:
    """A noisy box moved by a known rigid motion (kept in the case as ``T_true``)."""
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
        moved = src @ T_true[:3, :3].T + T_true[:3, 3]  # R x + t on the rows
        dst = np.round(moved + rng.normal(scale=0.001, size=(n, 3)), 6)
        inp = {"source": src, "target": dst, "threshold": 0.05, "max_iter": 100}
        cases.append(Case(f"box_n{n}_rot{deg:g}deg", inp, {"T_true": T_true}))
    return cases


RIGID_ICP = Problem(
    "rigid_icp",
    "Rigid point-to-point ICP",
    ("T",),
    _icp_reference,
    rtol=0.0,
    atol=1e-4,
    vector_cases=_icp_cases,
)
