"""Ex08: the Hungarian algorithm: the trusted tests of the notebook next to this file."""

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
    safe_error,
)


def greedy_pairs(cost: np.ndarray) -> set[tuple[int, int]]:
    """The greedy assignment: the cheapest remaining pair first (ties: lowest row, then column)."""
    C = np.asarray(cost, dtype=np.float64)
    cols = np.tile(np.arange(C.shape[1]), C.shape[0])
    rows = np.repeat(np.arange(C.shape[0]), C.shape[1])
    order = np.lexsort((cols, rows, C.ravel()))
    rows, cols, pairs = set(), set(), set()
    for flat in order:
        i, j = divmod(int(flat), C.shape[1])
        if i not in rows and j not in cols:
            rows.add(i)
            cols.add(j)
            pairs.add((i, j))
    return pairs


def greedy_trap(rng: np.random.Generator, C: np.ndarray) -> np.ndarray:
    """``C`` with a 2x2 trap: rows r1 < r2, columns c1, c2 with C[r1, c1] the smallest entry, C[r1, c2]
    and C[r2, c1] the next smallest, and the rest of row r2 and column c2 far larger.

    Taking the cheapest pair (r1, c1) first (global or row-by-row greedy) leaves r2 and c2 only
    expensive partners, while the optimum pairs (r1, c2) and (r2, c1).
    """
    C = np.array(C, dtype=np.float64)
    M, N = C.shape
    r1, r2 = sorted(int(i) for i in rng.choice(M, 2, replace=False))
    c1, c2 = (int(j) for j in rng.choice(N, 2, replace=False))
    lo, hi = float(C.min()), float(C.max())
    C[r2, :] = hi + 100.0
    C[:, c2] = hi + 100.0
    C[r1, c1] = lo - 2.0
    C[r1, c2] = lo - 1.0
    C[r2, c1] = lo - 1.0
    return C


def row_greedy_pairs(cost: np.ndarray) -> set[tuple[int, int]]:
    """Row by row, each row takes its cheapest free column (the other common greedy)."""
    C = np.asarray(cost, dtype=np.float64)
    transposed = C.shape[0] > C.shape[1]
    if transposed:
        C = C.T
    used, pairs = set(), set()
    for i in range(C.shape[0]):
        j = min((j for j in range(C.shape[1]) if j not in used), key=lambda j: (C[i, j], j))
        used.add(j)
        pairs.add((j, i) if transposed else (i, j))
    return pairs


def assignment_check(cost: np.ndarray, rtol: float = 1e-9) -> Check:
    """Valid min(M, N) pairs whose total cost is scipy's optimum (trusted ``linear_sum_assignment``).

    A valid but worse assignment that is the greedy one (``greedy-assignment``) or a maximal one
    (``assignment-maximises``) is named; a time-out on a matrix of 10 rows or more is named
    ``brute-force-assignment`` (trying all n! permutations).
    """
    from scipy.optimize import linear_sum_assignment

    r, c = linear_sum_assignment(cost)
    best = float(cost[r, c].sum())
    rmax, cmax = linear_sum_assignment(cost, maximize=True)
    worst = float(cost[rmax, cmax].sum())
    greedy = [greedy_pairs(cost), row_greedy_pairs(cost)]
    M, N = cost.shape
    K = min(M, N)
    greedy_total = min(sum(cost[i, j] for i, j in g) for g in greedy)
    visible = [m for m, total in (("greedy-assignment", greedy_total), ("assignment-maximises", worst))
               if total > best + rtol * max(1.0, abs(best))]

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            mistakes = ["brute-force-assignment"] if "timed out" in err and min(M, N) >= 10 else []
            return 0.0, Report(err, safe_error(err), mistakes)
        pairs = as_float_array(outcome.value)
        if pairs is None or (pairs.size == 0 and K == 0):
            return (1.0, "ok") if pairs is not None else (0.0, "the result is not an array of index pairs")
        if pairs.ndim != 2 or pairs.shape != (K, 2):
            return 0.0, f"expected {K} (row, col) pairs, shape ({K}, 2), got shape {pairs.shape}"
        if not np.all(pairs == np.round(pairs)):
            return 0.0, "indices must be integers"
        rows = pairs[:, 0].astype(np.int64)
        cols = pairs[:, 1].astype(np.int64)
        if rows.min() < 0 or rows.max() >= M or cols.min() < 0 or cols.max() >= N:
            return 0.0, "an index is out of range"
        if len(set(rows.tolist())) != K or len(set(cols.tolist())) != K:
            return 0.0, "a row or a column is used twice"
        total = float(cost[rows, cols].sum())
        tol = rtol * max(1.0, abs(best))
        if abs(total - best) <= tol:
            return 1.0, Report("ok", checked=visible)
        mistakes = []
        if set(zip(rows.tolist(), cols.tolist())) in greedy:
            mistakes.append("greedy-assignment")
        elif abs(total - worst) <= rtol * max(1.0, abs(worst)):
            mistakes.append("assignment-maximises")
        # (by how much it exceeds the minimum is the answer's choice: not in the hidden-safe text)
        return 0.0, Report(
            f"a valid assignment but not a minimal one (total {total:.6g}, the minimum is {best:.6g})",
            "a valid assignment but not a minimal one (its total exceeds the minimum)",
            mistakes,
            visible,
        )

    return check


_EX08_C = np.array([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])
_EX08_RECT = np.array([[10.0, 1.0, 7.0, 3.0], [2.0, 8.0, 9.0, 4.0]])
# The optima above pair rows and columns both ways ((0, 1) and (1, 0)): (column, row) pairs are the
# same set there. This one's optimum is a 3-cycle, (0, 1), (1, 2), (2, 0) for 6; read the other way
# round it is (0, 2), (1, 0), (2, 1) for 18 (neither the minimum nor the maximum).
_EX08_CYCLE = np.array([[9.0, 2.0, 6.0], [5.0, 9.0, 1.0], [3.0, 7.0, 9.0]])


@graded_test("small matrices: two 3x3, 2x4, 4x2, 1x1", "test_small", 2.0, hidden=False)
def _ex08_public(rng):
    mats = [_EX08_C, _EX08_CYCLE, _EX08_RECT, _EX08_RECT.T.copy(), np.array([[7.0]])]
    return [("hungarian", (C,), {}, assignment_check(C)) for C in mats]


def medium_matrix() -> np.ndarray:
    """The public 11x11 matrix: the greedy assignment is not minimal, and 11! = 4e7 permutations do
    not fit in the time limit (tests/test_mistakes.py checks both)."""
    rng = np.random.default_rng(20261201)
    return np.round(rng.uniform(0.0, 10.0, size=(11, 11)), 2)


@graded_test(
    "a medium matrix: 11x11, where greedy is not optimal", "test_small", 1.0, hidden=False, timeout=5.0
)
def _ex08_medium(rng):
    C = medium_matrix()
    return [("hungarian", (C,), {}, assignment_check(C))]


@graded_test(
    "random matrices 12x12 to 30x30, with ties, rectangular", "test_random", 7.0, hidden=True, timeout=10.0
)
def _ex08_hidden(rng):
    mats = []
    # diagonally dominant (greedy finds it too), then hard ones
    # (12! = 4.8e8 permutations: every matrix is out of reach of brute force within the time limit)
    n = 12
    D = rng.uniform(5.0, 10.0, size=(n, n))
    D[np.arange(n), rng.permutation(n)] = rng.uniform(0.0, 1.0, size=n)
    mats.append(D)
    mats.append(rng.uniform(0.0, 1.0, size=(13, 13)))
    mats.append(rng.integers(0, 4, size=(12, 12)).astype(np.float64))  # many ties
    mats.append(rng.normal(size=(11, 17)))  # negative costs, wide
    mats.append(rng.integers(0, 3, size=(18, 13)).astype(np.float64))  # tall with ties
    mats.append(np.outer(rng.uniform(1, 2, 14), rng.uniform(1, 2, 14)))  # rank one
    mats.append(rng.uniform(0.0, 100.0, size=(30, 30)))
    # every matrix but the first holds a greedy trap, so a greedy answer fails the same six matrices
    # for every student (on random matrices alone it failed a varying number: unequal scores)
    mats = [mats[0]] + [greedy_trap(rng, C) for C in mats[1:]]
    return [("hungarian", (C,), {}, assignment_check(C)) for C in mats]


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L5 = "lesson 05_multi_object_tracking"

MISTAKES = (
    Mistake(
        "greedy-assignment",
        "this is a greedy assignment (cheapest pair first): it is not optimal when a cheap pair "
        "blocks two others; the Hungarian algorithm finds the minimum total cost; see "
        f"{_L5} §2 (the assignment problem)",
    ),
    Mistake(
        "assignment-maximises",
        "the assignment maximises the total cost instead of minimising it; "
        f"see {_L5} §2 (the assignment problem)",
    ),
    Mistake(
        "brute-force-assignment",
        "right on small matrices but out of time on larger ones: trying every permutation costs "
        f"n! (10! = 3.6 million); the Hungarian algorithm is O(n^3); see {_L5} §2 (the assignment problem)",
    ),
)


EXERCISE = Exercise(
    id="ex08_hungarian",
    title="The Hungarian algorithm",
    notebook="ex08_hungarian.ipynb",
    answer_cells=("hungarian",),
    blocked=(
        "flowtrack.association",
        "flowtrack.tracking",
        "flowtrack.metrics",
        "scipy.optimize",
        "scipy.sparse.csgraph",
    ),
    allowed=('numpy',),
    tests=(_ex08_public, _ex08_medium, _ex08_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)


# The same exercise answered in C++, Java and Octave (the problem of other languages,
# flowtrack_course.polyglot.problems): their mistakes are this exercise's.
LANGUAGE_PROBLEM = "assignment"
