"""Ex07: Mahalanobis cost with chi-square gating: the trusted tests of ``exercises/ex07_mahalanobis_gating.ipynb``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..spec import Exercise, Outcome, as_float_array, compare_arrays
from .checks import Check, array_check, graded_test, pinhole, points_in_front, tuple_check

def _ex07_cost(z_pred, S, Z):
    from flowtrack.association import mahalanobis_cost

    return mahalanobis_cost(z_pred, S, Z)


def _ex07_gated(z_pred, S, Z, prob):
    from flowtrack.association import chi2_gate

    C = _ex07_cost(z_pred, S, Z)
    return np.where(C <= chi2_gate(z_pred.shape[1], prob), C, np.inf)


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
    return [("mahalanobis_cost", args, {}, array_check(_ex07_cost(*args)))]


@graded_test("cost: random tracks and detections", "test_cost", 3.0, hidden=True)
def _ex07_cost_hidden(rng):
    out = []
    for M, N, m in ((1, 1, 1), (3, 5, 2), (6, 4, 3), (5, 8, 2)):
        args = _ex07_random(rng, M, N, m)
        out.append(("mahalanobis_cost", args, {}, array_check(_ex07_cost(*args))))
    return out


@graded_test("gating: two tracks, three detections, p = 0.99", "test_gating", 2.0, hidden=False)
def _ex07_gate_public(rng):
    args = (_EX07_ZP, _EX07_S, _EX07_Z, 0.99)
    return [("gated_cost", args, {}, array_check(_ex07_gated(*args)))]


@graded_test("gating: random tracks, detections and gate probabilities", "test_gating", 3.0, hidden=True)
def _ex07_gate_hidden(rng):
    out = []
    for (M, N, m), prob in (((3, 5, 2), 0.9), ((6, 4, 3), 0.99), ((5, 8, 1), 0.95), ((4, 4, 2), 0.5)):
        z_pred, S, Z = _ex07_random(rng, M, N, m)
        args = (z_pred, S, Z, prob)
        out.append(("gated_cost", args, {}, array_check(_ex07_gated(*args))))
    return out


EXERCISE = Exercise(
    id="ex07_mahalanobis_gating",
    title="The Mahalanobis cost matrix with chi-square gating",
    notebook="ex07_mahalanobis_gating.ipynb",
    answer_cells=("mahalanobis_cost", "gated_cost"),
    blocked=("flowtrack.association", "flowtrack.tracking"),
    allowed=('numpy', 'scipy.stats', 'scipy.linalg'),
    tests=(_ex07_cost_public, _ex07_cost_hidden, _ex07_gate_public, _ex07_gate_hidden),
)
