"""Tests of flowtrack.association against independent oracles (explicit inverses, scipy, brute force)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from flowtrack.association import (
    assign,
    chi2_gate,
    greedy_assign,
    hungarian,
    mahalanobis_cost,
    mahalanobis_from_cholesky,
)

# ----------------------------------------------------------------------------- helpers


def random_spd(rng, m, scale=1.0):
    A = rng.normal(size=(m, m))
    return scale * (A @ A.T + 0.5 * np.eye(m))


def brute_force_assignment(cost, gate):
    """Enumerate every matching of admissible pairs; return (max cardinality, min cost at it)."""
    M, N = cost.shape
    ok = np.isfinite(cost) & (cost <= gate)
    best = (0, 0.0)

    def rec(i, used, k, total):
        nonlocal best
        if i == M:
            if k > best[0] or (k == best[0] and total < best[1]):
                best = (k, total)
            return
        rec(i + 1, used, k, total)  # row i left unmatched
        for j in range(N):
            if ok[i, j] and not used & (1 << j):
                rec(i + 1, used | (1 << j), k + 1, total + cost[i, j])

    rec(0, 0, 0, 0.0)
    return best


def check_valid(result, cost, gate):
    matches, ut, ud = result
    M, N = cost.shape
    assert matches.ndim == 2 and matches.shape[1] == 2
    assert np.issubdtype(matches.dtype, np.integer)
    rows, cols = matches[:, 0], matches[:, 1]
    assert len(set(rows.tolist())) == len(rows) and len(set(cols.tolist())) == len(cols)
    assert np.all(np.isfinite(cost[rows, cols])) and np.all(cost[rows, cols] <= gate)
    assert sorted(rows.tolist() + ut.tolist()) == list(range(M))
    assert sorted(cols.tolist() + ud.tolist()) == list(range(N))
    assert np.all(np.diff(rows) > 0)


# ----------------------------------------------------------------------------- mahalanobis_cost


@pytest.mark.parametrize("m", [1, 2, 3])
def test_mahalanobis_cost_matches_explicit_inverse(rng, m):
    M, N = 6, 7
    z_pred = rng.normal(size=(M, m))
    S = np.stack([random_spd(rng, m, scale=10.0 ** rng.uniform(-2, 2)) for _ in range(M)])
    Z = rng.normal(size=(N, m)) * 3
    C = mahalanobis_cost(z_pred, S, Z)
    assert C.shape == (M, N)
    expected = np.empty((M, N))
    for i in range(M):
        Si = np.linalg.inv(S[i])
        for j in range(N):
            d = Z[j] - z_pred[i]
            expected[i, j] = d @ Si @ d
    np.testing.assert_allclose(C, expected, rtol=1e-9, atol=1e-12)


def test_mahalanobis_cost_empty_inputs(rng):
    S = np.stack([np.eye(2)] * 3)
    assert mahalanobis_cost(rng.normal(size=(3, 2)), S, np.empty((0, 2))).shape == (3, 0)
    assert mahalanobis_cost(np.empty((0, 2)), np.empty((0, 2, 2)), rng.normal(size=(4, 2))).shape == (0, 4)


def test_mahalanobis_cost_is_chi2_distributed(rng):
    # Oracle: for z ~ N(z_pred, S) the squared distance is chi2(m): compare the mean (= m).
    m, n = 3, 20000
    S = random_spd(rng, m)
    z_pred = rng.normal(size=(1, m))
    Z = rng.multivariate_normal(z_pred[0], S, size=n)
    C = mahalanobis_cost(z_pred, S[None], Z)[0]
    assert abs(C.mean() - m) < 5 * np.sqrt(2 * m / n)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(z_pred=np.zeros((2, 2)), S=np.zeros((2, 3, 3)), Z=np.zeros((1, 2))), "S"),
        (dict(z_pred=np.zeros((2, 2)), S=np.stack([np.eye(2)] * 2), Z=np.zeros((1, 3))), "Z"),
        (dict(z_pred=np.zeros(2), S=np.stack([np.eye(2)] * 2), Z=np.zeros((1, 2))), "z_pred"),
        (dict(z_pred=np.zeros((2, 2)), S=np.stack([np.eye(2), -np.eye(2)]), Z=np.zeros((1, 2))), "S"),
        (dict(z_pred=np.zeros((1, 2)), S=np.array([[[1.0, 0.5], [0.0, 1.0]]]), Z=np.zeros((1, 2))), "S"),
        (dict(z_pred=np.zeros((1, 2)), S=np.eye(2)[None], Z=np.array([[np.nan, 0.0]])), "Z"),
    ],
)
def test_mahalanobis_cost_rejects_bad_input(kwargs, name):
    with pytest.raises(ValueError, match=name):
        mahalanobis_cost(**kwargs)


# ----------------------------------------------------------------------------- chi2_gate


@pytest.mark.parametrize("dim", [1, 2, 3, 4])
@pytest.mark.parametrize("prob", [0.5, 0.9, 0.95, 0.99, 0.999])
def test_chi2_gate_matches_scipy(dim, prob):
    g = chi2_gate(dim, prob)
    assert isinstance(g, float)
    assert g == pytest.approx(chi2.ppf(prob, dim), rel=1e-12)
    assert chi2.cdf(g, dim) == pytest.approx(prob, rel=1e-9)


def test_chi2_gate_bad_input():
    with pytest.raises(ValueError, match="prob"):
        chi2_gate(2, 1.0)
    with pytest.raises(ValueError, match="prob"):
        chi2_gate(2, 0.0)
    with pytest.raises(ValueError, match="dim"):
        chi2_gate(0)
    with pytest.raises(TypeError, match="dim"):
        chi2_gate(2.5)


# ----------------------------------------------------------------------------- assign


def test_assign_against_brute_force(rng):
    for trial in range(400):
        M, N = rng.integers(0, 6, size=2)
        kind = trial % 4
        if kind == 0:
            cost = rng.uniform(0, 20, size=(M, N))
        elif kind == 1:  # integer costs: many ties
            cost = rng.integers(0, 5, size=(M, N)).astype(float)
        elif kind == 2:  # negative costs and forbidden (inf) pairs
            cost = rng.normal(0, 5, size=(M, N))
            cost[rng.random((M, N)) < 0.3] = np.inf
        else:  # chi2-like costs, wide range
            cost = rng.chisquare(2, size=(M, N)) * rng.choice([0.1, 1.0, 30.0])
        gate = [np.inf, 9.21, 3.0, 1.0][trial % 4 if kind != 2 else 0]
        if kind == 2 and trial % 8 == 2:
            gate = 0.0
        result = assign(cost, gate)
        check_valid(result, cost, gate)
        matches = result[0]
        k, best_total = brute_force_assignment(cost, gate)
        assert len(matches) == k, (cost, gate)
        total = cost[matches[:, 0], matches[:, 1]].sum() if k else 0.0
        assert total == pytest.approx(best_total, rel=1e-9, abs=1e-9), (cost, gate)


def test_assign_sparse_gates_against_brute_force(rng):
    """Sparse admissible graphs: isolated pairs mixed with contested components."""
    isolated_seen = 0
    for _ in range(300):
        M, N = rng.integers(1, 7, size=2)
        cost = rng.uniform(0, 10, size=(M, N))
        cost[rng.random((M, N)) > 0.25] = 100.0
        gate = 10.0
        ok = cost <= gate
        isolated_seen += int(np.sum(ok & (ok.sum(1, keepdims=True) == 1) & (ok.sum(0, keepdims=True) == 1)))
        result = assign(cost, gate)
        check_valid(result, cost, gate)
        matches = result[0]
        k, best_total = brute_force_assignment(cost, gate)
        assert len(matches) == k
        assert cost[matches[:, 0], matches[:, 1]].sum() == pytest.approx(best_total, abs=1e-9)
    assert isolated_seen > 50  # the isolated-pair shortcut was exercised


def test_assign_differs_from_solve_then_discard():
    cost = np.array([[0.0, 6.0], [6.0, 11.0]])
    gate = 10.0
    # The naive way: solve the ungated problem, then drop pairs above the gate.
    r, c = linear_sum_assignment(cost)
    naive = [(i, j) for i, j in zip(r, c) if cost[i, j] <= gate]
    assert naive == [(0, 0)]  # loses a track/detection pair
    matches, ut, ud = assign(cost, gate)
    assert sorted(map(tuple, matches.tolist())) == [(0, 1), (1, 0)]
    assert ut.size == 0 and ud.size == 0
    assert brute_force_assignment(cost, gate) == (2, 12.0)


def test_assign_cardinality_beats_cost_even_with_large_costs():
    # Two cheap pairs vs three expensive ones: the three-pair matching must win.
    cost = np.array(
        [
            [0.0, 1e6, np.inf],
            [1e6, 0.0, 1e6],
            [np.inf, 1e6, np.inf],
        ]
    )
    matches, _, _ = assign(cost)
    assert len(matches) == 3
    assert brute_force_assignment(cost, np.inf)[0] == 3


def test_assign_empty_and_degenerate():
    for shape in [(0, 0), (0, 4), (3, 0)]:
        m, ut, ud = assign(np.empty(shape), 5.0)
        assert m.shape == (0, 2)
        assert ut.tolist() == list(range(shape[0])) and ud.tolist() == list(range(shape[1]))
    # all gated
    m, ut, ud = assign(np.full((2, 3), 50.0), 9.0)
    assert m.shape == (0, 2) and ut.tolist() == [0, 1] and ud.tolist() == [0, 1, 2]
    # all inf
    m, ut, ud = assign(np.full((2, 2), np.inf))
    assert m.shape == (0, 2)
    # one all-gated row and one all-gated column
    cost = np.array([[1.0, 99.0, 2.0], [99.0, 99.0, 99.0], [3.0, 99.0, 1.0]])
    m, ut, ud = assign(cost, 10.0)
    assert sorted(map(tuple, m.tolist())) == [(0, 0), (2, 2)]
    assert ut.tolist() == [1] and ud.tolist() == [1]


def test_assign_gate_boundary_is_inclusive():
    m, _, _ = assign(np.array([[5.0]]), gate=5.0)
    assert m.tolist() == [[0, 0]]
    m, _, _ = assign(np.array([[5.0]]), gate=np.nextafter(5.0, 0.0))
    assert m.shape == (0, 2)


def test_assign_rejects_bad_input():
    with pytest.raises(ValueError, match="cost"):
        assign(np.array([[1.0, np.nan]]))
    with pytest.raises(ValueError, match="cost"):
        assign(np.array([[1.0, -np.inf]]))
    with pytest.raises(ValueError, match="cost"):
        assign(np.zeros(3))
    with pytest.raises(ValueError, match="gate"):
        assign(np.zeros((2, 2)), gate=np.nan)


def test_greedy_assign_is_a_valid_gated_matching_and_never_beats_assign(rng):
    worse = 0
    for _ in range(200):
        M, N = rng.integers(0, 6, size=2)
        cost = rng.uniform(0, 10, size=(M, N))
        gate = 6.0
        g = greedy_assign(cost, gate)
        check_valid(g, cost, gate)
        k_opt, best = brute_force_assignment(cost, gate)
        k_g = len(g[0])
        total_g = cost[g[0][:, 0], g[0][:, 1]].sum() if k_g else 0.0
        # greedy is a maximal matching: at least half the optimal cardinality
        assert 2 * k_g >= k_opt and k_g <= k_opt
        if k_g == k_opt:
            assert total_g >= best - 1e-9
        worse += (k_g < k_opt) or (total_g > best + 1e-9)
        # independent oracle for greedy itself: repeatedly take the global minimum
        C = np.where(cost <= gate, cost, np.inf)
        pairs = []
        while C.size and np.isfinite(C).any():
            i, j = np.unravel_index(np.argmin(C), C.shape)
            pairs.append((int(i), int(j)))
            C[i, :] = np.inf
            C[:, j] = np.inf
        assert sorted(pairs) == sorted(map(tuple, g[0].tolist()))
    assert worse > 0  # greedy is sometimes suboptimal
    m, _, _ = greedy_assign(np.array([[1.0, 2.0], [2.0, 9.0]]))
    assert m.tolist() == [[0, 0], [1, 1]]
    with pytest.raises(ValueError, match="cost"):
        greedy_assign(np.array([[np.nan]]))


# ----------------------------------------------------------------------------- hungarian


def test_hungarian_matches_linear_sum_assignment(rng):
    for _ in range(300):
        M, N = rng.integers(1, 9, size=2)
        if rng.random() < 0.3:
            N = M  # square
        C = rng.normal(size=(M, N)) * rng.choice([1.0, 1e3])
        if rng.random() < 0.3:
            C = np.round(C)  # ties
        r, c = hungarian(C)
        r2, c2 = linear_sum_assignment(C)
        assert len(r) == len(r2) == min(M, N)
        assert np.all(np.diff(r) > 0)
        assert len(set(c.tolist())) == len(c)
        assert C[r, c].sum() == pytest.approx(C[r2, c2].sum(), rel=1e-10, abs=1e-9)


def test_hungarian_small_brute_force(rng):
    from itertools import permutations

    for _ in range(50):
        C = rng.uniform(size=(4, 4))
        best = min(sum(C[i, p[i]] for i in range(4)) for p in permutations(range(4)))
        r, c = hungarian(C)
        assert C[r, c].sum() == pytest.approx(best)


def test_hungarian_empty_and_bad():
    r, c = hungarian(np.empty((0, 3)))
    assert r.size == 0 and c.size == 0
    with pytest.raises(ValueError, match="cost"):
        hungarian(np.array([[1.0, np.inf]]))


# ----------------------------------------------------------------------------- public hot-path forms


@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_mahalanobis_from_cholesky_matches_explicit_inverse(rng, m):
    S = np.stack([random_spd(rng, m) for _ in range(5)])
    z_pred, Z = rng.normal(size=(5, m)), rng.normal(size=(7, m))
    L = np.linalg.cholesky(S)
    d = Z[None, :, :] - z_pred[:, None, :]
    expected = np.einsum("ijk,ikl,ijl->ij", d, np.linalg.inv(S), d)
    for validate in (True, False):
        got = mahalanobis_from_cholesky(z_pred, L, Z, validate=validate)
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


def test_mahalanobis_from_cholesky_rejects_bad_factors():
    with pytest.raises(ValueError, match="L must have a positive diagonal"):
        mahalanobis_from_cholesky([[0.0]], [[[0.0]]], [[1.0]])
    with pytest.raises(ValueError, match="L"):
        mahalanobis_from_cholesky([[0.0, 0.0]], np.eye(2), [[1.0, 0.0]])
    with pytest.raises(ValueError, match="Z"):
        mahalanobis_from_cholesky([[0.0, 0.0]], [np.eye(2)], [[np.nan, 0.0]])


@pytest.mark.parametrize("solver", [assign, greedy_assign])
def test_unvalidated_assignment_is_the_validated_one(rng, solver):
    for _ in range(20):
        cost = rng.uniform(0, 10, size=(rng.integers(0, 5), rng.integers(0, 5)))
        cost[rng.random(cost.shape) < 0.2] = np.inf
        fast = solver(cost, 6.0, validate=False)
        for a, b in zip(fast, solver(cost, 6.0), strict=True):
            np.testing.assert_array_equal(a, b)
        if solver is assign:
            k, total = brute_force_assignment(cost, 6.0)
            assert len(fast[0]) == k
            assert np.isclose(cost[fast[0][:, 0], fast[0][:, 1]].sum(), total)
    with pytest.raises(ValueError, match="NaN"):
        solver(np.array([[np.nan]]), 1.0)


# ----------------------------------------------------------------------------------- min_cost, NLLR
def brute_force_min_cost(cost, gate):
    """Least sum of admissible pair costs over all matchings (unmatched rows/columns cost 0)."""
    M, N = cost.shape
    ok = np.isfinite(cost) & (cost <= gate)
    best = 0.0

    def rec(i, used, total):
        nonlocal best
        if i == M:
            best = min(best, total)
            return
        rec(i + 1, used, total)
        for j in range(N):
            if ok[i, j] and not used & (1 << j):
                rec(i + 1, used | (1 << j), total + cost[i, j])

    rec(0, 0, 0.0)
    return best


def test_assign_min_cost_against_brute_force(rng):
    for _ in range(300):
        M, N = rng.integers(0, 6, size=2)
        cost = rng.normal(size=(M, N)) * 5.0
        cost[rng.random(size=(M, N)) < 0.2] = np.inf
        gate = rng.choice([np.inf, 3.0, -1.0])
        matches, ut, ud = assign(cost, gate, objective="min_cost")
        total = float(cost[matches[:, 0], matches[:, 1]].sum()) if len(matches) else 0.0
        assert total == pytest.approx(brute_force_min_cost(cost, gate), abs=1e-9)
        # a valid matching of admissible pairs, each lowering the sum
        assert len(set(matches[:, 0].tolist())) == len(matches) == len(set(matches[:, 1].tolist()))
        if len(matches):
            c = cost[matches[:, 0], matches[:, 1]]
            assert (c <= gate).all() and (c < 0).all()
        assert sorted(ut.tolist() + matches[:, 0].tolist()) == list(range(M))
        assert sorted(ud.tolist() + matches[:, 1].tolist()) == list(range(N))


def test_assign_min_cost_worked_example():
    """C = [[1, 9.5], [2, 50]], gamma = 10: the least sum of C - gamma is -9 with (0, 0) alone; the most pairs
    (and solving ungated then discarding) give (0, 1), (1, 0) with -8.5."""
    C = np.array([[1.0, 9.5], [2.0, 50.0]]) - 10.0
    matches, ut, ud = assign(C, objective="min_cost")
    assert matches.tolist() == [[0, 0]] and ut.tolist() == [1] and ud.tolist() == [1]
    assert C[0, 0] == -9.0 == brute_force_min_cost(C, np.inf)
    most, _, _ = assign(C)  # default objective: most pairs
    assert most.tolist() == [[0, 1], [1, 0]] and C[0, 1] + C[1, 0] == -8.5
    r, c = linear_sum_assignment(C)
    assert C[r, c].sum() == -8.5  # solve-then-discard keeps both (both negative)


def test_assign_default_objective_unchanged_and_bad_objective(rng):
    cost = rng.random(size=(4, 5))
    a = assign(cost, 0.5)
    b = assign(cost, 0.5, objective="most_pairs")
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(ValueError, match="objective"):
        assign(cost, objective="fewest")


def test_nllr_cost_against_scipy_logpdf(rng):
    from scipy.stats import multivariate_normal

    from flowtrack.association import nllr_cost

    M, N, m = 3, 4, 4
    z_pred = rng.normal(size=(M, m))
    S = np.stack([[random_spd(rng, m) for _ in range(N)] for _ in range(M)])  # per pair
    Z = rng.normal(size=(N, m))
    Z[1, 2:] = np.nan  # detection 1: position only (no velocity)
    lam = np.array([0.01, 0.2, 0.01, 0.03])
    pd_ = 0.85
    C = nllr_cost(z_pred, S, Z, pd_, lam)
    for i in range(M):
        for j in range(N):
            o = ~np.isnan(Z[j])
            logp = multivariate_normal(z_pred[i, o], S[i, j][np.ix_(o, o)]).logpdf(Z[j, o])
            ref = -(np.log(pd_) + logp - np.log(lam[j] * (1 - pd_)))
            assert C[i, j] == pytest.approx(ref, rel=1e-10, abs=1e-10)
            # the normalised form 1/2 (d2 - gamma)
            So = S[i, j][np.ix_(o, o)]
            nu = Z[j, o] - z_pred[i, o]
            d2 = nu @ np.linalg.solve(So, nu)
            gamma = 2 * np.log(pd_ / ((1 - pd_) * lam[j] * np.sqrt(np.linalg.det(2 * np.pi * So))))
            assert C[i, j] == pytest.approx(0.5 * (d2 - gamma), rel=1e-10, abs=1e-10)


def test_nllr_cost_gates_on_the_joint_innovation_with_its_dof(rng):
    from flowtrack.association import nllr_cost

    z_pred = np.zeros((1, 4))
    S = np.eye(4)[None]
    g2, g4 = chi2.ppf(0.99, 2), chi2.ppf(0.99, 4)
    # position-only detection just inside its 2-dof gate; joint detection just outside its 4-dof gate
    Z = np.array([[np.sqrt(g2) - 1e-6, 0.0, np.nan, np.nan], [np.sqrt(g4) + 1e-6, 0.0, 0.0, 0.0],
                  [0.0, 0.0, np.sqrt(g4) - 1e-6, 0.0]])
    C = nllr_cost(z_pred, S, Z, 0.9, 1e-6, gate_prob=0.99)
    assert np.isfinite(C[0, 0]) and np.isinf(C[0, 1]) and np.isfinite(C[0, 2])
    # without gate_prob, nothing is inf
    assert np.isfinite(nllr_cost(z_pred, S, Z, 0.9, 1e-6)).all()


def test_nllr_cost_bad_input():
    from flowtrack.association import nllr_cost

    z, S, Z = np.zeros((1, 2)), np.eye(2)[None], np.zeros((2, 2))
    with pytest.raises(ValueError, match="p_detect"):
        nllr_cost(z, S, Z, 1.0, 0.1)
    with pytest.raises(ValueError, match="clutter_density"):
        nllr_cost(z, S, Z, 0.9, 0.0)
    with pytest.raises(ValueError, match="clutter_density"):
        nllr_cost(z, S, Z, 0.9, [0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="S must have shape"):
        nllr_cost(z, np.eye(3)[None], Z, 0.9, 0.1)
    with pytest.raises(ValueError, match="without any measured"):
        nllr_cost(z, S, np.full((1, 2), np.nan), 0.9, 0.1)
    with pytest.raises(ValueError, match="S"):
        nllr_cost(z, -np.eye(2)[None], Z, 0.9, 0.1)


def test_nllr_association_prefers_clutter_to_a_far_pair():
    """A pair is taken only when it beats "clutter + miss": with a low clutter density a far detection still
    matches, with a high one it is left as clutter (a new track)."""
    from flowtrack.association import nllr_cost

    z_pred, S, Z = np.zeros((1, 2)), np.eye(2)[None], np.array([[2.5, 0.0]])
    low = assign(nllr_cost(z_pred, S, Z, 0.9, 1e-4), objective="min_cost")[0]
    high = assign(nllr_cost(z_pred, S, Z, 0.9, 1.0), objective="min_cost")[0]
    assert low.tolist() == [[0, 0]] and high.shape == (0, 2)
