"""Ex03: red-black Gauss-Seidel: the trusted tests of ``exercises/ex03_gauss_seidel.ipynb``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..spec import Exercise, Outcome, as_float_array, compare_arrays
from .checks import Check, array_check, graded_test, pinhole, points_in_front, tuple_check

def _ex03_sweep_expected(v, rhs, c, lam):
    from flowtrack.variational import red_black_sweep

    return red_black_sweep(np.array(v, dtype=np.float64), rhs, c, lam)


def _ex03_solve_expected(a, b, dt, lam):
    from flowtrack.variational import solve_component

    return solve_component(a, b, dt, lam, method="dct")


def _ex03_solve_check(a, b, dt, lam) -> Check:
    d = (b - a) / dt
    # the solver stops at a relative residual < 1e-10, so |v - v*| <= 1e-10 |d|_F (M = I)
    return array_check(
        _ex03_solve_expected(a, b, dt, lam), rtol=1e-6, atol=1e-7 * float(np.abs(d).max() + 1e-300)
    )


_EX03_V0 = np.zeros((3, 4))
_EX03_RHS = np.arange(12.0).reshape(3, 4)
_EX03_C = np.full((3, 4), 1.0)
_EX03_A = np.zeros((3, 4))
_EX03_B = np.array([[0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0]])


@graded_test("sweep: one sweep from zero on a 3x4 grid", "test_sweep", 2.0, hidden=False)
def _ex03_sweep_public(rng):
    return [
        (
            "red_black_sweep",
            (_EX03_V0, _EX03_RHS, _EX03_C, 0.0),
            {},
            array_check(_ex03_sweep_expected(_EX03_V0, _EX03_RHS, _EX03_C, 0.0)),
        ),
        (
            "red_black_sweep",
            (_EX03_V0, _EX03_RHS, _EX03_C, 1.0),
            {},
            array_check(_ex03_sweep_expected(_EX03_V0, _EX03_RHS, _EX03_C, 1.0)),
        ),
    ]


@graded_test("sweep: random grids, iterates and weights", "test_sweep", 3.0, hidden=True)
def _ex03_sweep_hidden(rng):
    out = []
    for H, W in ((1, 5), (4, 4), (5, 7), (8, 6)):
        v = rng.normal(size=(H, W))
        rhs = rng.normal(size=(H, W))
        c = rng.uniform(0.1, 2.0, size=(H, W))
        lam = float(rng.uniform(0.1, 3.0))
        out.append(
            ("red_black_sweep", (v, rhs, c, lam), {}, array_check(_ex03_sweep_expected(v, rhs, c, lam)))
        )
    return out


@graded_test("solver: a step edge on a 3x4 grid", "test_solver", 2.0, hidden=False)
def _ex03_solve_public(rng):
    return [
        (
            "solve_gauss_seidel",
            (_EX03_A, _EX03_B, 0.5, 0.1),
            {},
            _ex03_solve_check(_EX03_A, _EX03_B, 0.5, 0.1),
        )
    ]


@graded_test("solver: random components", "test_solver", 3.0, hidden=True, timeout=20.0)
def _ex03_solve_hidden(rng):
    out = []
    for H, W in ((2, 3), (6, 5), (8, 10)):
        a = rng.normal(size=(H, W))
        b = a + rng.normal(scale=0.1, size=(H, W))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(0.5, 5.0)) * dt**2
        out.append(("solve_gauss_seidel", (a, b, dt, lam), {}, _ex03_solve_check(a, b, dt, lam)))
    return out


EXERCISE = Exercise(
    id="ex03_gauss_seidel",
    title="Red-black Gauss-Seidel for variational scene flow",
    notebook="ex03_gauss_seidel.ipynb",
    answer_cells=("red_black_sweep", "solve_gauss_seidel"),
    blocked=("flowtrack.variational", "flowtrack.sceneflow"),
    allowed=('numpy',),
    tests=(_ex03_sweep_public, _ex03_sweep_hidden, _ex03_solve_public, _ex03_solve_hidden),
)
