"""Ex04: kNN graph Laplacian and graph scene flow: the trusted tests of the notebook next to this file."""

from __future__ import annotations

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Dependency,
    Exercise,
    Mistake,
    Variant,
    array_check,
    graded_test,
)


def _ex04_L(P, k, sigma):
    from flowtrack.sceneflow import graph_laplacian, knn_graph

    return graph_laplacian(knn_graph(P, k=k, sigma=sigma)).toarray()


def knn_laplacian_variant(P, k, sigma, *, symmetrise=True, sigma_power=2) -> np.ndarray:
    """The kNN Laplacian written out here, with the catalogued mistakes as options (dense, small N)."""
    P = np.asarray(P, dtype=np.float64)
    n = P.shape[0]
    d2 = np.sum((P[:, None, :] - P[None, :, :]) ** 2, axis=2)
    np.fill_diagonal(d2, np.inf)
    nearest = np.argsort(d2, axis=1, kind="stable")[:, :k]
    A = np.zeros((n, n), dtype=bool)
    A[np.repeat(np.arange(n), k), nearest.ravel()] = True
    if symmetrise:
        A = A | A.T
    W = np.where(A, np.exp(-np.where(A, d2, 0.0) / sigma**sigma_power), 0.0)
    return np.diag(W.sum(axis=1)) - W


def _ex04_L_check(P, k, sigma) -> Check:
    variants = [
        Variant("knn-not-symmetrised", knn_laplacian_variant(P, k, sigma, symmetrise=False)),
        Variant("affinity-sigma-not-squared", knn_laplacian_variant(P, k, sigma, sigma_power=1)),
    ]
    return array_check(_ex04_L(P, k, sigma), variants=variants)


def _ex04_flow(P, Y, dt, lam, k, sigma):
    from flowtrack.sceneflow import graph_scene_flow

    return graph_scene_flow(P, Y, dt, lam, k=k, sigma=sigma, solver="splu")


_EX04_P = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 1.0, 0.0]])
_EX04_Y = _EX04_P + np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.2, 0.0]])


@graded_test("Laplacian: four points", "test_laplacian", 2.0, hidden=False)
def _ex04_L_public(rng):
    return [
        ("knn_laplacian", (_EX04_P, 1, 1.0), {}, _ex04_L_check(_EX04_P, 1, 1.0)),
        ("knn_laplacian", (_EX04_P, 2, 2.0), {}, _ex04_L_check(_EX04_P, 2, 2.0)),
    ]


@graded_test("Laplacian: random clouds", "test_laplacian", 3.0, hidden=True)
def _ex04_L_hidden(rng):
    out = []
    for n, k in ((6, 5), (12, 2), (30, 4), (40, 6)):
        P = rng.normal(size=(n, 3))
        sigma = float(rng.uniform(0.3, 1.5))
        out.append(("knn_laplacian", (P, k, sigma), {}, _ex04_L_check(P, k, sigma)))
    return out


@graded_test("graph scene flow: four points", "test_graph_flow", 2.0, hidden=False)
def _ex04_flow_public(rng):
    return [
        (
            "graph_scene_flow",
            (_EX04_P, _EX04_Y, 0.1, 0.0, 1, 1.0),
            {},
            array_check(_ex04_flow(_EX04_P, _EX04_Y, 0.1, 0.0, 1, 1.0)),
        ),
        (
            "graph_scene_flow",
            (_EX04_P, _EX04_Y, 0.1, 0.01, 1, 1.0),
            {},
            array_check(_ex04_flow(_EX04_P, _EX04_Y, 0.1, 0.01, 1, 1.0)),
        ),
    ]


@graded_test("graph scene flow: random clouds", "test_graph_flow", 3.0, hidden=True)
def _ex04_flow_hidden(rng):
    out = []
    for n, k in ((8, 3), (25, 4), (40, 6)):
        P = rng.normal(size=(n, 3))
        Y = P + 0.05 * rng.normal(size=(n, 3))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(0.1, 2.0)) * dt**2
        sigma = float(rng.uniform(0.5, 1.5))
        out.append(
            (
                "graph_scene_flow",
                (P, Y, dt, lam, k, sigma),
                {},
                array_check(_ex04_flow(P, Y, dt, lam, k, sigma)),
            )
        )
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L3 = "lesson 03_graph_scene_flow"

MISTAKES = (
    Mistake(
        "knn-not-symmetrised",
        "the kNN graph is not symmetrised: j being among the k nearest of i does not make i one of "
        "j's; the graph keeps an edge when either holds, so W and L are symmetric; "
        f"see {_L3} §1 (the k-NN graph and its Laplacian)",
    ),
    Mistake(
        "affinity-sigma-not-squared",
        "the affinity divides by sigma instead of sigma^2: w_ij = exp(-|X_i - X_j|^2 / sigma^2); see "
        f"{_L3} §1 (the graph's weights)",
    ),
)


EXERCISE = Exercise(
    id="ex04_graph_scene_flow",
    title="The kNN graph Laplacian and graph scene flow",
    notebook="ex04_graph_scene_flow.ipynb",
    answer_cells=("knn_laplacian", "graph_scene_flow"),
    blocked=("flowtrack.sceneflow", "flowtrack._graph", "flowtrack.variational", "flowtrack.clustering"),
    allowed=('numpy', 'scipy'),
    tests=(_ex04_L_public, _ex04_L_hidden, _ex04_flow_public, _ex04_flow_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
    depends=(
        Dependency(
            "test_graph_flow", on="test_laplacian", function="knn_laplacian", builds="graph_scene_flow"
        ),
    ),
)
