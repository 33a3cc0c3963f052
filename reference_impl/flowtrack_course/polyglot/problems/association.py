r"""The data-association problems: Mahalanobis costs, chi-square gating, the linear assignment.

``mahalanobis_assignment`` (ports)
    ``{"z_pred" (M, m), "S" (M, m, m), "detections" (N, m), "gate"}`` ->
    ``{"cost" (M, N), "matches" (K, 2)}``: ``cost[i][j]`` is the squared Mahalanobis distance
    :math:`(z_j - \hat z_i)^\top S_i^{-1} (z_j - \hat z_i)` of *every* pair (no entry is gated or
    replaced by a sentinel); ``matches`` are the ``[track, detection]`` pairs, sorted by track, of
    the matching that uses only pairs with ``cost <= gate``, has the most pairs and among those the
    least total cost (unique in every case: the generator checks it by brute force; case
    ``gate_trap`` shows why solving first and dropping gated pairs afterwards is wrong).
``mahalanobis_gating`` (graded)
    ``{"z_pred" (m,), "S" (m, m), "Z" (N, m), "gate"}`` -> ``{"d2" (N,), "inside" (N,)}``:
    :math:`d^2_j = (z_j - \hat z)^\top S^{-1} (z_j - \hat z)` and ``inside[j] = 1`` iff
    :math:`d^2_j \le` ``gate`` (else 0).
``assignment`` (graded in C++, Octave and Java: the student writes the solver)
    ``{"C" (n, m)}``, :math:`n \le m` -> ``{"assignment" (n,)}``: the column given to each row, distinct,
    minimising :math:`\sum_i C_{i, a_i}` (reference :func:`scipy.optimize.linear_sum_assignment`).
    Hidden costs are continuous random draws, so the optimum is unique; two of the three hidden
    cases (and one public case) are drawn so that the greedy answer (each row in turn takes its
    cheapest free column) is not optimal.
"""

from __future__ import annotations

import numpy as np

from .base import Case, Problem, as_inputs, spd

__all__ = ["ASSIGNMENT", "MAHALANOBIS_ASSIGNMENT", "MAHALANOBIS_GATING", "lsa_greedy"]


# -- mahalanobis_assignment -----------------------------------------------------------------------------
def _gated_reference(inp: dict) -> dict:
    from flowtrack.association import assign, mahalanobis_cost

    cost = mahalanobis_cost(inp["z_pred"], inp["S"], inp["detections"])
    return {"cost": cost, "matches": assign(cost, inp["gate"])[0]}


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


def _gated_case(case_id: str, z_pred, S, Z, gate) -> Case:
    inp = {"z_pred": z_pred, "S": S, "detections": Z, "gate": gate}
    out = _gated_reference(inp)
    brute, unique = _brute_force_assignment(out["cost"], gate)
    if not unique or brute != out["matches"].tolist():
        raise RuntimeError(f"assignment case {case_id} is ambiguous or disagrees with brute force")
    return Case(case_id, inp)


def _gated_cases() -> list[Case]:
    from flowtrack.association import chi2_gate

    # The gate trap of the most-pairs rule: with costs [[0, 6], [6, 11]] and gate 10, solving ungated
    # and dropping the (1,1) pair afterwards loses a pair; the rule's answer keeps two, crossed.
    s6 = np.sqrt(6.0)
    x = 1.0 / (2.0 * s6)
    t1 = [x, float(np.sqrt(6.0 - x * x))]
    z_pred, S, Z = np.array([[0.0, 0.0], t1]), np.stack([np.eye(2)] * 2), np.array([[0.0, 0.0], [s6, 0.0]])
    cases = [_gated_case("gate_trap", z_pred, S, Z, 10.0)]
    seed = 10
    for M, N, m in [(3, 4, 2), (4, 3, 2), (4, 4, 2), (5, 5, 2), (3, 5, 3), (2, 6, 2)]:
        while True:  # the next seed until the optimum is unique
            rng = np.random.default_rng(seed)
            seed += 1
            z_pred = np.round(rng.uniform(0, 10, size=(M, m)), 4)
            A = rng.normal(size=(M, m, m))
            S = np.round(np.einsum("kij,klj->kil", A, A) * 0.3 + 0.5 * np.eye(m), 6)
            near = z_pred[rng.integers(0, M, size=N)] + rng.normal(scale=1.2, size=(N, m))
            Z = np.round(near, 4)
            try:
                cases.append(_gated_case(f"random_M{M}_N{N}_m{m}", z_pred, S, Z, chi2_gate(m, 0.99)))
                break
            except RuntimeError:
                continue
    return cases


MAHALANOBIS_ASSIGNMENT = Problem(
    "mahalanobis_assignment",
    "Mahalanobis costs and the gated assignment with the most pairs",
    ("cost", "matches"),
    _gated_reference,
    rtol=1e-10,
    atol=1e-10,
    vector_cases=_gated_cases,
)


# -- mahalanobis_gating -------------------------------------------------------------------------
def _maha_reference(inp: dict) -> dict:
    from flowtrack.association import mahalanobis_cost

    zp = np.atleast_1d(np.asarray(inp["z_pred"], float))
    S = np.atleast_2d(np.asarray(inp["S"], float))
    Z = np.asarray(inp["Z"], float).reshape(-1, zp.size)
    d2 = mahalanobis_cost(zp[None, :], S[None, :, :], Z)[0]
    return {"d2": d2, "inside": (d2 <= float(inp["gate"])).astype(float)}


def _maha_no_inverse(inp: dict) -> dict:
    zp = np.atleast_1d(np.asarray(inp["z_pred"], float))
    S = np.atleast_2d(np.asarray(inp["S"], float))
    r = np.asarray(inp["Z"], float).reshape(-1, zp.size) - zp
    return {"d2": np.einsum("ni,ij,nj->n", r, S, r)}


def _maha_sqrt(inp: dict) -> dict:
    return {"d2": np.sqrt(_maha_reference(inp)["d2"])}


def _maha_case(rng: np.random.Generator, m: int, n: int, prob: float) -> dict:
    from flowtrack.association import chi2_gate

    zp = rng.normal(scale=2.0, size=m)
    S = spd(rng, m, float(rng.uniform(0.5, 3.0)))
    Z = zp + rng.normal(scale=2.5, size=(n, m))
    # one detection surely inside the gate and one surely outside (d2 = |u|^2 for r = L u), so an
    # answer that never (or always) gates cannot score on ``inside``
    L = np.linalg.cholesky(S)
    u = rng.normal(size=(2, m))
    Z[0] = zp + L @ (0.2 * u[0] / np.linalg.norm(u[0]))
    Z[-1] = zp + L @ (8.0 * u[1] / np.linalg.norm(u[1]))
    return as_inputs({"z_pred": zp, "S": S, "Z": Z, "gate": chi2_gate(m, prob)})


def _maha_public() -> list[dict]:
    return [
        {
            "z_pred": [0.0, 0.0],
            "S": [[4.0, 0.0], [0.0, 1.0]],
            "Z": [[2.0, 0.0], [0.0, 2.0], [6.0, 1.0]],
            "gate": 9.21,
        },
        _maha_case(np.random.default_rng(7), 3, 4, 0.95),
    ]


MAHALANOBIS_GATING = Problem(
    "mahalanobis_gating",
    "Mahalanobis distances and chi-square gating",
    ("d2", "inside"),
    _maha_reference,
    rtol=1e-8,
    atol=1e-10,
    public=_maha_public,
    hidden=lambda rng: [_maha_case(rng, 2, 5, 0.9), _maha_case(rng, 3, 4, 0.99), _maha_case(rng, 2, 6, 0.5)],
    mistakes=(("covariance-not-inverted", _maha_no_inverse), ("distance-not-squared", _maha_sqrt)),
)


# -- assignment ---------------------------------------------------------------------------------
def _lsa(inp: dict, maximize: bool = False) -> dict:
    from scipy.optimize import linear_sum_assignment

    C = np.atleast_2d(np.asarray(inp["C"], float))
    rows, cols = linear_sum_assignment(C, maximize=maximize)
    out = np.full(C.shape[0], -1.0)
    out[rows] = cols
    return {"assignment": out}


def lsa_greedy(inp: dict) -> dict:
    """The greedy answer: each row in turn takes its cheapest free column."""
    C = np.atleast_2d(np.asarray(inp["C"], float))
    free = list(range(C.shape[1]))
    out = []
    for row in C:
        j = min(free, key=lambda k: row[k])
        free.remove(j)
        out.append(float(j))
    return {"assignment": np.array(out)}


def _lsa_case(rng: np.random.Generator, greedy_fails: bool) -> dict:
    """A random cost matrix (n in 3..6, m in n..n+2) on which the greedy answer is (or is not) optimal."""
    for _ in range(10_000):
        n = int(rng.integers(3, 7))
        C = rng.uniform(0.0, 10.0, size=(n, n + int(rng.integers(0, 3))))
        inp = {"C": C.tolist()}
        same = np.array_equal(lsa_greedy(inp)["assignment"], _lsa(inp)["assignment"])
        if same != greedy_fails:
            return inp
    raise RuntimeError("no cost matrix of the requested kind was drawn")  # pragma: no cover


ASSIGNMENT = Problem(
    "assignment",
    "The linear assignment problem (write the solver)",
    ("assignment",),
    _lsa,
    rtol=0.0,
    atol=1e-9,
    public=lambda: [
        {"C": [[1.0, 2.0, 9.0], [2.0, 9.0, 9.0], [9.0, 9.0, 3.0]]},  # greedy: 1 + 9 + 3; optimum 2 + 2 + 3
        {"C": [[4.0, 1.0, 3.0, 7.0], [2.0, 0.5, 5.0, 8.0], [3.0, 2.0, 2.0, 6.0]]},  # 3 x 4, greedy optimal
    ],
    hidden=lambda rng: [_lsa_case(rng, False), _lsa_case(rng, True), _lsa_case(rng, True)],
    mistakes=(
        ("greedy-assignment", lsa_greedy),
        ("assignment-maximises", lambda inp: _lsa(inp, maximize=True)),
    ),
    languages=("cpp", "octave", "java"),
)
