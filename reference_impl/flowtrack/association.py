r"""Data association: Mahalanobis costs, chi-square gating and gated linear assignment.

Syllabus section 7 and Problem 4. With :math:`M` tracks whose predicted measurements are
:math:`\hat z_i = H \hat x^{(i)}_{t|t-1}` with innovation covariances
:math:`S_i = H P^{(i)}_{t|t-1} H^\top + R`, and :math:`N` detections :math:`z_j`, the cost of
pairing track :math:`i` with detection :math:`j` is the squared Mahalanobis distance

.. math::  C_{ij} = (z_j - \hat z_i)^\top S_i^{-1} (z_j - \hat z_i).

If detection :math:`j` really comes from track :math:`i`, :math:`C_{ij} \sim \chi^2_m`, so the
*gate* :math:`\gamma = F^{-1}_{\chi^2_m}(p)` keeps the true detection with probability :math:`p`.

Association is the linear assignment problem over the bipartite graph of *admissible* pairs
(:math:`C_{ij} \le \gamma`), with binary variables :math:`y_{ij}`:

.. math::  \min \sum_{ij} C_{ij} y_{ij} \quad \text{s.t.}\quad \sum_j y_{ij} \le 1,\;
           \sum_i y_{ij} \le 1,\; y_{ij} = 0 \text{ if } C_{ij} > \gamma.

Minimising the cost alone would match nothing (all costs are :math:`\ge 0`), so :func:`assign`
solves the tracking version: among the matchings with the **most** admissible pairs, the one of
**least** total cost. It is *not* the same as solving the ungated problem and discarding the pairs
above the gate afterwards (that can lose pairs, see :func:`assign`).

:func:`hungarian` is a plain :math:`O(n^3)` Kuhn–Munkres implementation for teaching; the library
itself calls :func:`scipy.optimize.linear_sum_assignment`.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.special import gammaincinv

from ._validation import as_array, check_symmetric, cholesky, positive_int, probability

__all__ = [
    "assign",
    "chi2_gate",
    "greedy_assign",
    "hungarian",
    "mahalanobis_cost",
    "mahalanobis_from_cholesky",
    "masked_mahalanobis",
    "nllr_cost",
]


def _mahalanobis_from_cholesky(z_pred: np.ndarray, L: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distances from the Cholesky factors; no validation (hot path)."""
    m = z_pred.shape[1]
    ys: list[np.ndarray] = []  # ys[k][i, j] = k-th component of y_ij
    cost = np.zeros((z_pred.shape[0], Z.shape[0]))
    for k in range(m):
        acc = Z[None, :, k] - z_pred[:, k, None]  # (M, N) k-th innovation component
        for l in range(k):
            acc -= L[:, k, l, None] * ys[l]
        acc /= L[:, k, k, None]
        ys.append(acc)
        cost += acc * acc
    return cost


def mahalanobis_from_cholesky(z_pred, L, Z, *, validate: bool = True) -> np.ndarray:
    r"""Squared Mahalanobis distances :math:`\|L_i^{-1}(z_j - \hat z_i)\|^2` from Cholesky factors.

    Solves :math:`L_i y_{ij} = z_j - \hat z_i` by forward substitution, vectorised over all
    :math:`(i, j)` pairs (the loops run over the ``m`` measurement components only), and returns
    :math:`\|y_{ij}\|^2`. With :math:`S_i = L_i L_i^\top` this is :func:`mahalanobis_cost`
    without the factorisation, for a caller that already has the factors (the tracker also needs
    their log-determinants).

    Parameters
    ----------
    z_pred : array_like, shape (M, m)
        Predicted measurements.
    L : array_like, shape (M, m, m)
        Lower Cholesky factors of the innovation covariances (only the lower triangle is read);
        positive diagonal.
    Z : array_like, shape (N, m)
        Detections.
    validate : bool
        ``False`` skips the checks (the tracker's hot path, which built the arrays itself): then
        the inputs must be float ndarrays of the shapes above, finite, with ``L``'s diagonal > 0.

    Returns
    -------
    numpy.ndarray, shape (M, N)

    Raises
    ------
    ValueError
        Wrong shapes, NaN/inf, or a diagonal entry of ``L`` that is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> L = np.stack([np.eye(2), 2.0 * np.eye(2)])
    >>> mahalanobis_from_cholesky([[0.0, 0.0], [10.0, 0.0]], L, [[1.0, 0.0], [10.0, 2.0]])
    array([[  1.  , 104.  ],
           [ 20.25,   1.  ]])
    """
    if validate:
        z_pred = as_array(z_pred, "z_pred", (None, None))
        M, m = z_pred.shape
        if m < 1:
            raise ValueError(f"z_pred must have shape (M, m) with m >= 1, got {z_pred.shape}")
        L = as_array(L, "L", (M, m, m))
        Z = as_array(Z, "Z", (None, m))
        if not (np.diagonal(L, axis1=-2, axis2=-1) > 0).all():
            raise ValueError("L must have a positive diagonal (lower Cholesky factors)")
    return _mahalanobis_from_cholesky(z_pred, L, Z)


def mahalanobis_cost(z_pred, S, Z) -> np.ndarray:
    r"""Squared Mahalanobis distance of every detection to every predicted measurement.

    .. math::  C_{ij} = (z_j - \hat z_i)^\top S_i^{-1} (z_j - \hat z_i)
                     = \| L_i^{-1} (z_j - \hat z_i) \|^2, \qquad S_i = L_i L_i^\top,

    computed with one batched Cholesky factorisation and forward substitution (no matrix inverse).

    Parameters
    ----------
    z_pred : array_like, shape (M, m)
        Predicted measurements :math:`H \hat x_{t|t-1}` of the M tracks.
    S : array_like, shape (M, m, m)
        Innovation covariances :math:`H P_{t|t-1} H^\top + R`, symmetric positive definite.
    Z : array_like, shape (N, m)
        Detections.

    Returns
    -------
    numpy.ndarray, shape (M, N)
        ``C[i, j]`` is the squared distance of detection ``j`` from track ``i``.

    Raises
    ------
    ValueError
        Wrong shapes, NaN/inf, or a non-symmetric / non-positive-definite ``S``.

    Examples
    --------
    >>> import numpy as np
    >>> z_pred = np.array([[0.0, 0.0], [10.0, 0.0]])
    >>> S = np.stack([np.eye(2), 4.0 * np.eye(2)])
    >>> Z = np.array([[1.0, 0.0], [10.0, 2.0]])
    >>> mahalanobis_cost(z_pred, S, Z)
    array([[  1.  , 104.  ],
           [ 20.25,   1.  ]])
    """
    z_pred = as_array(z_pred, "z_pred", (None, None))
    M, m = z_pred.shape
    if m < 1:
        raise ValueError(f"z_pred must have shape (M, m) with m >= 1, got {z_pred.shape}")
    S = as_array(S, "S", (M, m, m))
    Z = as_array(Z, "Z", (None, m))
    check_symmetric(S, "S", atol=1e-12)
    if M == 0 or Z.shape[0] == 0:
        return np.zeros((M, Z.shape[0]))
    L = cholesky(S, "S")
    return _mahalanobis_from_cholesky(z_pred, L, Z)


def chi2_gate(dim, prob=0.99) -> float:
    r"""Chi-square gate :math:`\gamma = F^{-1}_{\chi^2_{\mathrm{dim}}}(p)` for squared Mahalanobis costs.

    A correct detection's squared Mahalanobis distance is :math:`\chi^2` distributed with ``dim``
    degrees of freedom, so it falls inside the gate with probability ``prob``.

    Parameters
    ----------
    dim : int
        Measurement dimension m (>= 1).
    prob : float
        Gate probability, ``0 < prob < 1``.

    Returns
    -------
    float
        The gate threshold.

    Examples
    --------
    >>> round(chi2_gate(2, 0.99), 4)
    9.2103
    >>> round(chi2_gate(3, 0.95), 4)
    7.8147
    """
    dim = positive_int(dim, "dim")
    prob = probability(prob, "prob")
    # F^-1_{chi2_dim}(p) = 2 P^-1(dim/2, p) with P the regularised lower incomplete gamma function:
    # bit-for-bit what scipy.stats.chi2.ppf computes, without importing scipy.stats (~0.2 s). (Not
    # scipy.special.chdtri(dim, 1 - p): forming 1 - p loses the relative precision of small p.)
    return float(2.0 * gammaincinv(0.5 * dim, prob))


def _empty_result(M: int, N: int):
    return (
        np.empty((0, 2), dtype=np.intp),
        np.arange(M, dtype=np.intp),
        np.arange(N, dtype=np.intp),
    )


def _check_cost_gate(cost, gate):
    cost = as_array(cost, "cost", ("M", "N"), finite=False)
    if np.isnan(cost).any():
        raise ValueError("cost (M, N) contains NaN")
    if np.isneginf(cost).any():
        raise ValueError("cost (M, N) contains -inf")
    if isinstance(gate, (bool, np.bool_)):
        raise TypeError("gate must be a real number, got bool")
    try:
        gate = float(gate)
    except (TypeError, ValueError):
        raise TypeError(f"gate must be a real number, got {type(gate).__name__}") from None
    if np.isnan(gate):
        raise ValueError("gate must not be NaN")
    return cost, gate


def _assign(cost: np.ndarray, gate: float):
    """Gated max-cardinality / min-cost assignment on a validated NaN-free cost matrix."""
    M, N = cost.shape
    if M == 0 or N == 0:
        return _empty_result(M, N)
    admissible = np.isfinite(cost) if gate == np.inf else cost <= gate
    row_deg = admissible.sum(axis=1)
    col_deg = admissible.sum(axis=0)
    # Isolated pairs: row i admits only column j and column j admits only row i. Such a pair is a
    # connected component of the admissible bipartite graph on its own, so every optimal matching
    # contains it; take it directly (the common case for well-separated objects).
    single_row = row_deg == 1
    j_of_row = admissible.argmax(axis=1)
    iso = single_row & (col_deg[j_of_row] == 1)
    iso_rows = np.flatnonzero(iso)
    iso_cols = j_of_row[iso_rows]
    rest_rows = np.flatnonzero((row_deg > 0) & ~iso)
    pairs_r = [iso_rows]
    pairs_c = [iso_cols]
    if rest_rows.size:
        col_used = np.zeros(N, dtype=bool)
        col_used[iso_cols] = True
        rest_cols = np.flatnonzero((col_deg > 0) & ~col_used)
        sub_ok = admissible[np.ix_(rest_rows, rest_cols)]
        sub = cost[np.ix_(rest_rows, rest_cols)]
        lo = np.where(sub_ok, sub, np.inf).min()
        span = np.where(sub_ok, sub, -np.inf).max() - lo
        # Shift (and scale) the admissible costs into [0, 1]. A constant shift adds k*lo to every
        # matching with k admissible pairs and a positive scale multiplies all totals, so the order
        # of matchings of equal cardinality is unchanged.
        scaled = (sub - lo) * (1.0 / span) if span > 0 else np.zeros(sub.shape)
        # Big-M: any matching has at most K = min(M, N) pairs, each admissible pair costs <= 1, so
        # every sum of admissible costs is <= K < big. Trading an inadmissible pair (cost big) for an
        # admissible one therefore always lowers the total: the optimum has the most admissible
        # pairs and, among those, the least admissible cost.
        big = min(sub.shape) + 1.0
        r, c = linear_sum_assignment(np.where(sub_ok, scaled, big))
        keep = sub_ok[r, c]
        pairs_r.append(rest_rows[r[keep]])
        pairs_c.append(rest_cols[c[keep]])
    rows = np.concatenate(pairs_r)
    cols = np.concatenate(pairs_c)
    order = np.argsort(rows)
    matches = np.empty((rows.size, 2), dtype=np.intp)
    matches[:, 0] = rows[order]
    matches[:, 1] = cols[order]
    free_rows = np.ones(M, dtype=bool)
    free_cols = np.ones(N, dtype=bool)
    free_rows[rows] = False
    free_cols[cols] = False
    return matches, np.flatnonzero(free_rows), np.flatnonzero(free_cols)


def assign(cost, gate=np.inf, *, objective="most_pairs", validate: bool = True):
    r"""Gated linear assignment: the most admissible pairs, then the least total cost.

    A pair ``(i, j)`` is *admissible* when ``cost[i, j] <= gate`` and ``cost[i, j]`` is finite
    (``inf`` marks a forbidden pair). Among all matchings (each row and each column used at most
    once) made only of admissible pairs, the result has the largest number of pairs and, among
    those, the smallest total cost.

    Isolated admissible pairs (row ``i`` admits only column ``j`` and column ``j`` only row ``i``)
    belong to every optimum and are taken directly. The rest is solved with
    :func:`scipy.optimize.linear_sum_assignment` on the remaining rows/columns that have an
    admissible pair, with admissible costs rescaled to ``[0, 1]`` and every other pair given the
    prohibitive cost ``min(M, N) + 1`` (more than any matching's total admissible cost, so
    cardinality dominates); pairs assigned at that cost are reported as unmatched.

    Solving the ungated problem and discarding gated pairs afterwards is wrong for this rule (it
    can lose a pair): with ``cost = [[0, 6], [6, 11]]`` and ``gate = 10`` the ungated optimum
    ``(0,0), (1,1)`` (total 11) loses the pair ``(1,1)``, leaving one match, while ``(0,1), (1,0)``
    (total 12) keeps two. It is also wrong for the course's likelihood-ratio objective (lesson 5),
    where discarding can keep a worse matching (e.g. ``[[1, 9.5], [2, 50]] - 10``: −8.5 instead
    of −9).

    With ``objective="min_cost"`` the result instead minimises :math:`\sum_{ij} C_{ij} y_{ij}` over
    the matchings of admissible pairs, an unmatched row or column costing 0: a pair is taken only if
    it lowers the sum. That is the right objective for costs that are negative log-likelihood
    *ratios* against "clutter / missed" (:func:`nllr_cost`), where a pair of positive cost is worse
    than leaving both unmatched. The two objectives differ: with ``cost = [[1, 9.5], [2, 50]] - 10``
    the most pairs are ``(0, 1), (1, 0)`` (total -8.5; also what solving the ungated problem and
    discarding gives), the least cost is ``(0, 0)`` alone (total -9). It is solved exactly with
    :func:`scipy.optimize.linear_sum_assignment` on :math:`\min(C_{ij}, 0)` (inadmissible pairs 0),
    dropping the pairs of cost >= 0 from its result: a matching of the clipped problem without its
    zero pairs is a matching of the original one of the same total, and no original matching has a
    larger clipped total.

    Parameters
    ----------
    cost : array_like, shape (M, N)
        Pair costs (e.g. from :func:`mahalanobis_cost`); ``inf`` allowed (never matched), NaN
        rejected. ``M`` or ``N`` may be 0.
    gate : float
        Pairs with ``cost > gate`` are never matched (default: no gate).
    objective : {"most_pairs", "min_cost"}
        ``"most_pairs"`` (default): the most admissible pairs, then the least total cost.
        ``"min_cost"``: the least total cost, unmatched rows and columns costing 0.
    validate : bool
        ``False`` skips the checks of ``cost`` and ``gate`` (the tracker's hot path, which built
        ``cost`` itself): then ``cost`` must be a float ndarray of shape ``(M, N)`` without NaN or
        ``-inf`` and ``gate`` a float that is not NaN.

    Returns
    -------
    matches : numpy.ndarray of int, shape (K, 2)
        ``(track, detection)`` index pairs, sorted by track index.
    unmatched_tracks : numpy.ndarray of int, shape (M - K,)
        Row indices not matched, increasing.
    unmatched_detections : numpy.ndarray of int, shape (N - K,)
        Column indices not matched, increasing.

    Raises
    ------
    ValueError
        ``cost`` not 2-D or containing NaN or ``-inf``; ``gate`` NaN.

    Examples
    --------
    >>> import numpy as np
    >>> matches, ut, ud = assign(np.array([[0.0, 6.0], [6.0, 11.0]]), gate=10.0)
    >>> matches
    array([[0, 1],
           [1, 0]])
    >>> ut, ud
    (array([], dtype=int64), array([], dtype=int64))
    >>> matches, ut, ud = assign(np.array([[0.5, 50.0, 3.0]]), gate=9.21)
    >>> matches, ut, ud
    (array([[0, 0]]), array([], dtype=int64), array([1, 2]))
    >>> assign(np.array([[1.0, 9.5], [2.0, 50.0]]) - 10.0, objective="min_cost")[0]
    array([[0, 0]])
    """
    if validate:
        cost, gate = _check_cost_gate(cost, gate)
    if objective == "most_pairs":
        return _assign(cost, gate)
    if objective == "min_cost":
        return _min_cost_unchecked(cost, gate)
    raise ValueError(f"objective must be 'most_pairs' or 'min_cost', got {objective!r}")


def _min_cost_unchecked(cost: np.ndarray, gate: float):
    """Least total cost over matchings of admissible pairs, unmatched rows/columns costing 0."""
    M, N = cost.shape
    if M == 0 or N == 0:
        return _empty_result(M, N)
    useful = np.isfinite(cost) & (cost <= gate) & (cost < 0)
    clipped = np.where(useful, cost, 0.0)
    r, c = linear_sum_assignment(clipped)
    keep = useful[r, c]
    rows, cols = r[keep], c[keep]
    order = np.argsort(rows)
    matches = np.stack([rows[order], cols[order]], axis=1).astype(np.intp).reshape(-1, 2)
    free_rows = np.ones(M, dtype=bool)
    free_cols = np.ones(N, dtype=bool)
    free_rows[rows] = False
    free_cols[cols] = False
    return matches, np.flatnonzero(free_rows), np.flatnonzero(free_cols)


# ----------------------------------------------------------------------------------------------------
# one association objective for every tracker: the negative log-likelihood ratio against clutter
# ----------------------------------------------------------------------------------------------------
def masked_mahalanobis(z_pred, S, Z):
    r"""Squared Mahalanobis distances over the measured components of each detection.

    A detection may leave components unmeasured (NaN), e.g. the velocity of a detection without
    scene flow. For the pair ``(i, j)`` only the components :math:`o_j` that detection ``j``
    measures count: the marginal of the Gaussian :math:`\mathcal N(\hat z_i, S_{ij})` on them,

    .. math::  d^2_{ij} = (z_j - \hat z_i)_{o_j}^\top [S_{ij}]_{o_j o_j}^{-1} (z_j - \hat z_i)_{o_j},
               \qquad \ell_{ij} = \ln\det [S_{ij}]_{o_j o_j},

    with :math:`d^2_{ij} \sim \chi^2_{|o_j|}` for a correct pair.

    Parameters
    ----------
    z_pred : array_like, shape (M, m)
        Predicted (joint) measurements.
    S : array_like, shape (M, m, m) or (M, N, m, m)
        Innovation covariances per track, or per pair (when the measurement noise differs by
        detection); symmetric positive definite on the measured blocks.
    Z : array_like, shape (N, m)
        Detections; NaN marks an unmeasured component (at least one component measured).

    Returns
    -------
    d2 : numpy.ndarray, shape (M, N)
    logdet : numpy.ndarray, shape (M, N)
    dof : numpy.ndarray of int, shape (N,)
        :math:`|o_j|`.

    Examples
    --------
    >>> import numpy as np
    >>> d2, ld, dof = masked_mahalanobis(np.zeros((1, 2)), 4.0 * np.eye(2)[None], np.array([[2.0, np.nan]]))
    >>> d2, np.exp(ld), dof
    (array([[1.]]), array([[4.]]), array([1]))
    """
    z_pred = as_array(z_pred, "z_pred", ("M", "m"))
    M, m = z_pred.shape
    Z = as_array(Z, "Z", ("N", m), allow_nan=True)
    N = Z.shape[0]
    S = as_array(S, "S")
    if S.shape == (M, m, m):
        S = np.broadcast_to(S[:, None], (M, N, m, m))
    elif S.shape != (M, N, m, m):
        raise ValueError(f"S must have shape ({M}, {m}, {m}) or ({M}, {N}, {m}, {m}), got {S.shape}")
    seen = ~np.isnan(Z)
    dof = seen.sum(axis=1)
    if N and (dof == 0).any():
        raise ValueError("Z has a row without any measured (non-NaN) component")
    d2 = np.zeros((M, N))
    logdet = np.zeros((M, N))
    if M == 0 or N == 0:
        return d2, logdet, dof
    patterns, which = np.unique(seen, axis=0, return_inverse=True)
    for k, pat in enumerate(patterns):
        cols = np.flatnonzero(which.ravel() == k)
        o = np.flatnonzero(pat)
        Ssub = S[:, cols][:, :, o][..., o]  # (M, n_k, |o|, |o|)
        check_symmetric(Ssub, "S", atol=1e-12)
        L = cholesky(Ssub, "S")
        nu = Z[cols][:, o][None] - z_pred[:, o][:, None]  # (M, n_k, |o|)
        y = np.linalg.solve(L, nu[..., None])[..., 0]
        d2[:, cols] = (y * y).sum(axis=-1)
        logdet[:, cols] = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)
    return d2, logdet, dof


def nllr_cost(z_pred, S, Z, p_detect, clutter_density, gate_prob=None):
    r"""Negative log-likelihood ratio of "detection j comes from track i" against "clutter or new".

    With detection probability :math:`P_D` and clutter (false alarm / newborn object) density
    :math:`\lambda_c` in measurement space, the global-nearest-neighbour association maximises the
    likelihood ratio of a joint hypothesis against "everything is clutter and every track missed";
    its log is a sum over the pairs of

    .. math::  C_{ij} = -\ln\frac{P_D\,\mathcal N(z_j; \hat z_i, S_{ij})}{\lambda_c (1 - P_D)}
                      = \tfrac12\left(d^2_{ij} - \gamma_{ij}\right), \qquad
               \gamma_{ij} = 2\ln\frac{P_D}{(1 - P_D)\,\lambda_c\sqrt{\det(2\pi S_{ij})}},

    (:math:`d^2_{ij}` the squared Mahalanobis distance of the innovation), minimised with
    ``assign(C, objective="min_cost")``: a pair is taken only when it is more likely than
    clutter-plus-miss (:math:`C_{ij} < 0`, i.e. :math:`d^2_{ij} < \gamma_{ij}`), and among the
    matchings the one of least total :math:`C`. The :math:`\ln\det S` inside :math:`\gamma` makes
    an uncertain (newborn) track pay for its spread, so it cannot steal the detection of an
    established one; the :math:`\lambda_c` and :math:`P_D` terms set how far a detection may be before
    it is better explained as clutter. A detection that carries a velocity (scene flow) is scored on
    the joint innovation ``[position, velocity]`` (its measured components, see
    :func:`masked_mahalanobis`); then :math:`\lambda_c` is a density in the joint space (e.g. the
    position density times a velocity density), which ``clutter_density`` may give per detection.

    Parameters
    ----------
    z_pred : array_like, shape (M, m)
    S : array_like, shape (M, m, m) or (M, N, m, m)
    Z : array_like, shape (N, m)
        NaN marks unmeasured components (e.g. no velocity).
    p_detect : float
        :math:`P_D`, ``0 < p_detect < 1``.
    clutter_density : float or array_like, shape (N,)
        :math:`\lambda_c > 0` per unit volume of the detection's measured components.
    gate_prob : float, optional
        Also gate on the joint innovation: pairs with :math:`d^2_{ij} > F^{-1}_{\chi^2_{m_j}}(p)`
        (``m_j`` = measured components of detection j) get ``inf``.

    Returns
    -------
    numpy.ndarray, shape (M, N)
        :math:`C_{ij}` (``inf`` outside the gate).

    Examples
    --------
    >>> import numpy as np
    >>> C = nllr_cost(np.zeros((1, 2)), np.eye(2)[None], np.array([[0.0, 0.0], [3.0, 0.0]]),
    ...               p_detect=0.9, clutter_density=0.01)
    >>> np.round(C, 3)   # -ln(0.9 / (2 pi) / (0.01 * 0.1)) = -4.965; the second: + 9/2
    array([[-4.965, -0.465]])
    """
    d2, logdet, dof = masked_mahalanobis(z_pred, S, Z)
    pd = probability(p_detect, "p_detect")
    lam = as_array(clutter_density, "clutter_density")
    if lam.ndim == 0:
        lam = np.full(d2.shape[1], float(lam))
    elif lam.shape != (d2.shape[1],):
        raise ValueError(f"clutter_density must be a number or of shape ({d2.shape[1]},), got {lam.shape}")
    if (lam <= 0).any():
        raise ValueError("clutter_density must be > 0")
    cost = 0.5 * d2 + 0.5 * (logdet + dof * np.log(2.0 * np.pi)) - np.log(pd / ((1.0 - pd) * lam))
    if gate_prob is not None:
        gates = np.array([chi2_gate(int(k), gate_prob) for k in dof]) if dof.size else np.zeros(0)
        cost = np.where(d2 <= gates[None, :], cost, np.inf)
    return cost


def greedy_assign(cost, gate=np.inf, *, validate: bool = True):
    r"""Greedy (locally nearest-neighbour) gated assignment, for comparison with :func:`assign`.

    Repeatedly takes the cheapest remaining admissible pair (``cost <= gate``, finite) whose row and
    column are both still free. It is what many simple trackers do; it can match fewer pairs and
    reach a larger total cost than :func:`assign` (with ``cost = [[1, 2], [2, 9]]`` it takes
    ``(0, 0)`` then ``(1, 1)``, total 10, against 4).

    Parameters
    ----------
    cost : array_like, shape (M, N)
        Pair costs; ``inf`` allowed (never matched), NaN and ``-inf`` rejected.
    gate : float
        Pairs with ``cost > gate`` are never matched (default: no gate).
    validate : bool
        ``False`` skips the checks of ``cost`` and ``gate`` (the tracker's hot path, which built
        ``cost`` itself): then ``cost`` must be a float ndarray of shape ``(M, N)`` without NaN or
        ``-inf`` and ``gate`` a float that is not NaN.

    Returns
    -------
    matches, unmatched_tracks, unmatched_detections
        As for :func:`assign`.

    Examples
    --------
    >>> import numpy as np
    >>> greedy_assign(np.array([[1.0, 2.0], [2.0, 9.0]]))[0]
    array([[0, 0],
           [1, 1]])
    """
    if validate:
        cost, gate = _check_cost_gate(cost, gate)
    return _greedy_assign(cost, gate)


def _greedy_assign(cost: np.ndarray, gate: float):
    M, N = cost.shape
    ok = np.isfinite(cost) & (cost <= gate)
    cand = np.flatnonzero(ok)
    order = cand[np.argsort(cost.ravel()[cand], kind="stable")]
    row_free = np.ones(M, dtype=bool)
    col_free = np.ones(N, dtype=bool)
    pairs = []
    for flat in order.tolist():
        i, j = divmod(flat, N)
        if row_free[i] and col_free[j]:
            row_free[i] = col_free[j] = False
            pairs.append((i, j))
    matches = np.array(sorted(pairs), dtype=np.intp).reshape(-1, 2)
    return matches, np.flatnonzero(row_free), np.flatnonzero(col_free)


def hungarian(cost):
    r"""Minimum-cost assignment by the Hungarian (Kuhn–Munkres) algorithm with potentials.

    A readable :math:`O(n^2 m)` implementation for teaching (``n = min(M, N)`` rows are matched,
    ``m = max(M, N)``). It keeps dual potentials :math:`u_i` (rows) and :math:`v_j` (columns) with
    :math:`u_i + v_j \le C_{ij}` (reduced costs :math:`C_{ij} - u_i - v_j \ge 0`) and adds one
    row at a time, growing a shortest augmenting path over tight edges (a Dijkstra on reduced
    costs). When every row is matched along tight edges, complementary slackness proves the
    matching optimal: its cost equals the dual objective :math:`\sum_i u_i + \sum_j v_j`.

    Parameters
    ----------
    cost : array_like, shape (M, N)
        Finite costs; rectangular allowed.

    Returns
    -------
    row_ind, col_ind : numpy.ndarray of int, shape (min(M, N),)
        As :func:`scipy.optimize.linear_sum_assignment`: pairs ``(row_ind[k], col_ind[k])``,
        sorted by row, minimising ``cost[row_ind, col_ind].sum()``.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.array([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])
    >>> r, c = hungarian(C)
    >>> c, C[r, c].sum()
    (array([1, 0, 2]), np.float64(5.0))
    """
    C = as_array(cost, "cost", ("M", "N"))
    transposed = C.shape[0] > C.shape[1]
    if transposed:
        C = C.T
    n, m = C.shape  # n <= m: every row gets a column
    if n == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty.copy()
    INF = np.inf
    # 1-based arrays; column 0 is a virtual column holding the row being inserted.
    u = np.zeros(n + 1)  # row potentials
    v = np.zeros(m + 1)  # column potentials
    p = np.zeros(m + 1, dtype=np.intp)  # p[j] = row matched to column j (0 = free)
    way = np.zeros(m + 1, dtype=np.intp)  # previous column on the alternating path
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv = np.full(m + 1, INF)  # minv[j]: smallest reduced cost to reach column j
        used = np.zeros(m + 1, dtype=bool)  # columns in the alternating tree
        while True:
            used[j0] = True
            i0 = p[j0]
            # Relax all free columns from row i0 (vectorised over columns).
            cur = C[i0 - 1, :] - u[i0] - v[1:]
            free = ~used[1:]
            better = free & (cur < minv[1:])
            minv[1:][better] = cur[better]
            way[1:][better] = j0
            # Column with the smallest slack, then move the duals by that slack.
            cand = np.where(free, minv[1:], INF)
            j1 = int(np.argmin(cand)) + 1
            delta = cand[j1 - 1]
            tree = np.flatnonzero(used)
            u[p[tree]] += delta
            v[tree] -= delta
            minv[1:][free] -= delta
            j0 = j1
            if p[j0] == 0:  # reached a free column: augment
                break
        while j0:  # flip the alternating path back to the root
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    cols = np.flatnonzero(p[1:]) + 0
    rows = p[1:][cols] - 1
    if transposed:
        rows, cols = cols, rows
    order = np.argsort(rows)
    return rows[order].astype(np.intp), cols[order].astype(np.intp)
