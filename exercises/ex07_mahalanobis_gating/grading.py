"""Ex07: Mahalanobis cost with chi-square gating: the trusted tests of the notebook next to this file."""

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
    tuple_check,
)


def _ex07_cost(z_pred, S, Z):
    from flowtrack.association import mahalanobis_cost

    return mahalanobis_cost(z_pred, S, Z)


def _ex07_gated(z_pred, S, Z, prob):
    from flowtrack.association import chi2_gate

    C = _ex07_cost(z_pred, S, Z)
    return np.where(C <= chi2_gate(z_pred.shape[1], prob), C, np.inf)


def _wrong_costs(z_pred, S, Z) -> dict[str, np.ndarray]:
    """The catalogued wrong cost matrices on these inputs (trusted, written out here)."""
    d = Z[None, :, :] - z_pred[:, None, :]
    C = _ex07_cost(z_pred, S, Z)
    return {
        "euclidean-not-mahalanobis": np.sum(d**2, axis=2),
        "covariance-not-inverted": np.einsum("mni,mij,mnj->mn", d, S, d),
        "distance-not-squared": np.sqrt(C),
    }


def _ex07_cost_check(z_pred, S, Z) -> Check:
    variants = [Variant(k, v) for k, v in _wrong_costs(z_pred, S, Z).items()]
    return array_check(_ex07_cost(z_pred, S, Z), variants=variants)


def _ex07_gate_check(z_pred, S, Z, prob) -> Check:
    from scipy.stats import chi2

    m = z_pred.shape[1]
    C = _ex07_cost(z_pred, S, Z)
    variants = [
        Variant("gate-wrong-dof", np.where(C <= chi2.ppf(prob, dof), C, np.inf))
        for dof in range(1, max(m, 4) + 3)
        if dof != m
    ]
    variants.append(Variant("gate-prob-as-threshold", np.where(C <= prob, C, np.inf)))
    gate = chi2.ppf(prob, m)
    variants += [Variant(k, np.where(W <= gate, W, np.inf)) for k, W in _wrong_costs(z_pred, S, Z).items()]
    return array_check(_ex07_gated(z_pred, S, Z, prob), variants=variants)


def _plant(rng, z_pred, S, Z, prob) -> np.ndarray:
    """Put detections at squared distances between the gates of m-1, m and m+1 degrees of freedom.

    Every gate with the wrong number of degrees of freedom then misjudges at least one pair, for
    every student's inputs (the same mistake costs everybody the same).
    """
    from scipy.stats import chi2

    M, m = z_pred.shape
    Z = Z.copy()
    targets = [0.5 * (chi2.ppf(prob, m) + chi2.ppf(prob, m + 1))]
    if m > 1:
        targets.append(0.5 * (chi2.ppf(prob, m - 1) + chi2.ppf(prob, m)))
    for j, target in enumerate(targets):
        i = int(rng.integers(M))
        u = rng.normal(size=m)
        u /= np.linalg.norm(u)
        Z[j] = z_pred[i] + np.linalg.cholesky(S[i]) @ u * np.sqrt(target)
    return Z


_EX07_ZP = np.array([[0.0, 0.0], [10.0, 0.0]])
_EX07_S = np.stack([np.eye(2), 4.0 * np.eye(2)])
_EX07_Z = np.array([[1.0, 0.0], [10.0, 2.0], [3.0, 0.0]])


def _ex07_random(rng, M, N, m):
    z_pred = rng.normal(scale=3.0, size=(M, m))
    A = rng.normal(size=(M, m, m))
    S = A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(m)
    Z = rng.normal(scale=3.0, size=(N, m))
    return z_pred, S, Z


@graded_test("cost: two tracks, three detections", "test_cost", 2.0, hidden=False)
def _ex07_cost_public(rng):
    args = (_EX07_ZP, _EX07_S, _EX07_Z)
    return [("mahalanobis_cost", args, {}, _ex07_cost_check(*args))]


@graded_test("cost: random tracks and detections", "test_cost", 2.0, hidden=True)
def _ex07_cost_hidden(rng):
    out = []
    for M, N, m in ((1, 1, 1), (3, 5, 2), (6, 4, 3), (5, 8, 2)):
        args = _ex07_random(rng, M, N, m)
        out.append(("mahalanobis_cost", args, {}, _ex07_cost_check(*args)))
    return out


_EX07_ZP3 = np.zeros((1, 3))
_EX07_S3 = np.eye(3)[None]
_EX07_Z3 = np.array([[3.2, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 4.0]])  # 10.24: inside only with 3 dof
_EX07_ZP1 = np.zeros((1, 1))
_EX07_S1 = np.ones((1, 1, 1))
_EX07_Z1 = np.array([[2.8], [1.0]])  # 7.84: outside the 1-dof gate, inside a 2-dof one


@graded_test(
    "gating: p = 0.99 with 2-D, 3-D and 1-D measurements (the gate's degrees of freedom)",
    "test_gating", 2.0, hidden=False,
)
def _ex07_gate_public(rng):
    out = []
    cases = ((_EX07_ZP, _EX07_S, _EX07_Z), (_EX07_ZP3, _EX07_S3, _EX07_Z3), (_EX07_ZP1, _EX07_S1, _EX07_Z1))
    for zp, S, Z in cases:
        out.append(("gated_cost", (zp, S, Z, 0.99), {}, _ex07_gate_check(zp, S, Z, 0.99)))
    return out


@graded_test("gating: random tracks, detections and gate probabilities", "test_gating", 2.0, hidden=True)
def _ex07_gate_hidden(rng):
    out = []
    for (M, N, m), prob in (((3, 5, 2), 0.9), ((6, 4, 3), 0.99), ((5, 8, 1), 0.95), ((4, 4, 2), 0.5)):
        z_pred, S, Z = _ex07_random(rng, M, N, m)
        Z = _plant(rng, z_pred, S, Z, prob)
        args = (z_pred, S, Z, prob)
        out.append(("gated_cost", args, {}, _ex07_gate_check(*args)))
    return out


def association_gamma(S: np.ndarray, P_D: float, lam_c: float) -> np.ndarray:
    """gamma_i = 2 ln(P_D / ((1 - P_D) lam_c sqrt(det(2 pi S_i)))), shape (M,) (lesson 5 §3):
    a pair (i, j) is worth taking when C_ij < gamma_i (its negative log-likelihood ratio is
    (C_ij - gamma_i) / 2)."""
    S = np.asarray(S, dtype=float)
    m = S.shape[-1]
    logdet = np.linalg.slogdet(S)[1] + m * np.log(2.0 * np.pi)
    return 2.0 * np.log(P_D / ((1.0 - P_D) * lam_c)) - logdet


def _ex07_take_check(C, S, P_D, lam_c):
    g = association_gamma(S, P_D, lam_c)
    S = np.asarray(S, dtype=float)
    base = 2.0 * np.log(P_D / ((1.0 - P_D) * lam_c))
    logdet_2pi_s = base - g
    variants = [
        Variant("gamma-det-without-2pi", base - np.linalg.slogdet(S)[1]),
        Variant("gamma-det-not-square-rooted", base - 2.0 * logdet_2pi_s),
    ]
    take = (np.asarray(C, dtype=float) < g[:, None]).astype(float)
    return tuple_check([array_check(g, variants=variants), array_check(take)], ["gamma", "take"])


_EX07_C = np.array([[1.0, 12.0, 5.0], [8.0, 0.5, 3.0]])


@graded_test("worth taking: gamma from P_D, clutter and S; two tracks", "test_take", 0.5, hidden=False)
def _ex07_take_public(rng):
    args = (_EX07_C, _EX07_S, 0.9, 0.01)
    return [("worth_taking", args, {}, _ex07_take_check(*args))]


@graded_test("worth taking: random S, P_D, clutter densities and costs", "test_take", 1.5, hidden=True)
def _ex07_take_hidden(rng):
    """Strata of equal difficulty: each call's P_D, clutter density, the eigenvalues of each S_i and
    the offsets of the costs from gamma_i are a fixed script; the rotations of S_i and the order of
    the offsets are drawn per student (a wrong gamma then flips the same number of decisions)."""
    out = []
    offsets = np.array([-3.0, -1.2, -0.4, 0.3, 1.0, 2.5])
    script = (((1, 1), 0.9, 1e-4, [[2.0]]), ((3, 2), 0.8, 3e-4, [[0.5, 2.0], [1.0, 1.0], [3.0, 0.7]]),
              ((2, 3), 0.95, 1e-3, [[0.6, 1.5, 2.5], [1.0, 1.0, 1.0]]))
    for (M, m), P_D, lam_c, eigs in script:
        S = np.empty((M, m, m))
        for i in range(M):
            Q = np.linalg.qr(rng.normal(size=(m, m)))[0]
            S[i] = Q @ np.diag(eigs[i]) @ Q.T
        S = 0.5 * (S + np.swapaxes(S, 1, 2))
        g = association_gamma(S, P_D, lam_c)
        C = g[:, None] + np.array([rng.permutation(offsets) for _ in range(M)])
        args = (C, S, P_D, lam_c)
        out.append(("worth_taking", args, {}, _ex07_take_check(*args)))
    return out

# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L5 = "lesson 05_multi_object_tracking"

MISTAKES = (
    Mistake(
        "euclidean-not-mahalanobis",
        "this is the squared Euclidean distance: the Mahalanobis cost weighs the difference by "
        "S^-1, d^T S^-1 d, so an uncertain track accepts farther detections; "
        f"see {_L5} §1 (the Mahalanobis cost)",
    ),
    Mistake(
        "covariance-not-inverted",
        "S is used instead of its inverse: d^T S d grows with the uncertainty instead of "
        "shrinking; the cost is d^T S^-1 d (solve with S, or its Cholesky factor); "
        f"see {_L5} §1 (the Mahalanobis cost)",
    ),
    Mistake(
        "distance-not-squared",
        "this is the Mahalanobis distance, not its square: the chi-square gate applies to "
        "d^T S^-1 d, which is chi-square distributed with m degrees of freedom; "
        f"see {_L5} §1 (the chi-square gate)",
    ),
    Mistake(
        "gate-wrong-dof",
        "the gate uses the wrong degrees of freedom: d^T S^-1 d is chi-square with m = the "
        "measurement dimension (z_pred.shape[1]) degrees of freedom; "
        f"see {_L5} §1 and §3 (the chi-square gate)",
    ),
    Mistake(
        "gate-prob-as-threshold",
        "the gate probability is used as the threshold: the threshold is the chi-square "
        f"quantile chi2.ppf(prob, m), not prob itself; see {_L5} §1 (the chi-square gate)",
    ),    Mistake(
        "gamma-det-without-2pi",
        "gamma uses det(S) where the Gaussian's normaliser has det(2 pi S) = (2 pi)^m det(S): "
        "gamma = 2 ln(P_D / ((1 - P_D) lam_c sqrt(det(2 pi S)))); "
        f"see {_L5} §3 (which objective?)",
    ),
    Mistake(
        "gamma-det-not-square-rooted",
        "gamma uses det(2 pi S) where the Gaussian's normaliser is its square root: "
        "2 ln(sqrt(det(2 pi S))) = ln det(2 pi S); "
        f"see {_L5} §3 (which objective?)",
    ),
)


EXERCISE = Exercise(
    id="ex07_mahalanobis_gating",
    title="The Mahalanobis cost matrix with chi-square gating",
    notebook="ex07_mahalanobis_gating.ipynb",
    answer_cells=("mahalanobis_cost", "gated_cost", "worth_taking"),
    blocked=("flowtrack.association", "flowtrack.tracking"),
    allowed=('numpy', 'scipy.stats', 'scipy.linalg'),
    tests=(_ex07_cost_public, _ex07_cost_hidden, _ex07_gate_public, _ex07_gate_hidden, _ex07_take_public,
           _ex07_take_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
    depends=(
        Dependency("test_gating", on="test_cost", function="mahalanobis_cost", builds="gated_cost"),
    ),
)


# The same exercise answered in C++, Java, Octave and Mathematica (the problem of other languages,
# flowtrack_course.polyglot.problems): their mistakes are this exercise's.
LANGUAGE_PROBLEM = "mahalanobis_gating"
