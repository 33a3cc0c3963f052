"""Ex03: red-black Gauss-Seidel: the trusted tests of ``exercises/ex03_gauss_seidel.ipynb``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..spec import Exercise, Outcome, as_float_array, compare_arrays
from .checks import Check, array_check, graded_test, pinhole, points_in_front, tuple_check
from .feedback import Variant

def grid_sweep(v, rhs, c, lam, *, red_first=True, jacobi=False, degree4=False) -> np.ndarray:
    """One sweep for (diag(c) + lam L) v = rhs written out here, with the catalogued mistakes as options.

    The defaults are red-black Gauss-Seidel (red pixels, i + j even, first); ``jacobi`` updates every
    pixel from the old iterate, ``red_first=False`` does black before red, ``degree4`` gives every
    pixel 4 neighbours. (tests/test_mistakes.py checks the defaults against
    :func:`flowtrack.variational.red_black_sweep`.)
    """
    v = np.array(v, dtype=np.float64)
    H, W = v.shape
    deg = np.full((H, W), 4.0)
    if not degree4:
        deg = np.zeros((H, W))
        deg[1:, :] += 1
        deg[:-1, :] += 1
        deg[:, 1:] += 1
        deg[:, :-1] += 1
    diag = c + lam * deg

    def nsum(u):
        s = np.zeros((H, W))
        s[1:] += u[:-1]
        s[:-1] += u[1:]
        s[:, 1:] += u[:, :-1]
        s[:, :-1] += u[:, 1:]
        return s

    if jacobi:
        return (rhs + lam * nsum(v)) / diag
    i, j = np.indices((H, W))
    red = (i + j) % 2 == 0
    for colour in ((red, ~red) if red_first else (~red, red)):
        v[colour] = ((rhs + lam * nsum(v)) / diag)[colour]
    return v


def _sweep_variants(v, rhs, c, lam) -> list[Variant]:
    return [
        Variant("jacobi-not-gauss-seidel", grid_sweep(v, rhs, c, lam, jacobi=True)),
        Variant("black-before-red", grid_sweep(v, rhs, c, lam, red_first=False)),
        Variant("neumann-boundary-degree", grid_sweep(v, rhs, c, lam, degree4=True)),
    ]


def _ex03_sweep_check(v, rhs, c, lam) -> Check:
    return array_check(_ex03_sweep_expected(v, rhs, c, lam), variants=_sweep_variants(v, rhs, c, lam))


def _ex03_iterate_check(a, b, dt, lam, sweeps: int) -> Check:
    """The iterate after ``sweeps`` red-black sweeps from zero (tol = 0: no early stop).

    A direct solve returns the solution instead (``dense-solve-not-sweeps``); Jacobi or black-first
    sweeps give other iterates.
    """
    H, W = np.shape(a)
    c = np.full((H, W), dt**2)
    rhs = dt * (np.asarray(b, dtype=np.float64) - np.asarray(a, dtype=np.float64))
    iterates = {}
    for name, opts in (("ok", {}), ("jacobi-not-gauss-seidel", {"jacobi": True}),
                       ("black-before-red", {"red_first": False}),
                       ("neumann-boundary-degree", {"degree4": True})):
        v = np.zeros((H, W))
        for _ in range(sweeps):
            v = grid_sweep(v, rhs, c, lam, **opts)
        iterates[name] = v
    variants = [Variant(k, v) for k, v in iterates.items() if k != "ok"]
    variants.append(Variant("dense-solve-not-sweeps", _ex03_solve_expected(a, b, dt, lam)))
    scale = float(np.abs(iterates["ok"]).max() + 1e-300)
    return array_check(iterates["ok"], rtol=1e-8, atol=1e-10 * scale, variants=variants)


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
            _ex03_sweep_check(_EX03_V0, _EX03_RHS, _EX03_C, 0.0),
        ),
        (
            "red_black_sweep",
            (_EX03_V0, _EX03_RHS, _EX03_C, 1.0),
            {},
            _ex03_sweep_check(_EX03_V0, _EX03_RHS, _EX03_C, 1.0),
        ),
    ]


@graded_test("sweep: random grids, iterates and weights", "test_sweep", 2.0, hidden=True)
def _ex03_sweep_hidden(rng):
    out = []
    for H, W in ((1, 5), (4, 4), (5, 7), (8, 6)):
        v = rng.normal(size=(H, W))
        rhs = rng.normal(size=(H, W))
        c = rng.uniform(0.1, 2.0, size=(H, W))
        lam = float(rng.uniform(0.1, 3.0))
        out.append(("red_black_sweep", (v, rhs, c, lam), {}, _ex03_sweep_check(v, rhs, c, lam)))
    return out


@graded_test("solver: a step edge on a 3x4 grid", "test_solver", 1.0, hidden=False)
def _ex03_solve_public(rng):
    return [
        (
            "solve_gauss_seidel",
            (_EX03_A, _EX03_B, 0.5, 0.1),
            {},
            _ex03_solve_check(_EX03_A, _EX03_B, 0.5, 0.1),
        )
    ]


@graded_test("solver: random components", "test_solver", 2.0, hidden=True, timeout=20.0)
def _ex03_solve_hidden(rng):
    out = []
    for H, W in ((2, 3), (6, 5), (8, 10)):
        a = rng.normal(size=(H, W))
        b = a + rng.normal(scale=0.1, size=(H, W))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(0.5, 5.0)) * dt**2
        out.append(("solve_gauss_seidel", (a, b, dt, lam), {}, _ex03_solve_check(a, b, dt, lam)))
    return out


@graded_test(
    "solver: the iterate after 3 and 5 sweeps on the step edge (tol=0)", "test_iterates", 1.0, hidden=False
)
def _ex03_iterates_public(rng):
    out = []
    for k in (3, 5):
        check = _ex03_iterate_check(_EX03_A, _EX03_B, 0.5, 1.0, k)
        out.append(("solve_gauss_seidel", (_EX03_A, _EX03_B, 0.5, 1.0), {"tol": 0.0, "max_sweeps": k}, check))
    return out


@graded_test("solver: iterates after a few sweeps on random components (tol=0)", "test_iterates", 2.0, hidden=True)
def _ex03_iterates_hidden(rng):
    # lam >> dt^2: the iteration converges slowly, so after k sweeps it is far from the solution
    out = []
    for (H, W), k in (((4, 5), 2), ((6, 6), 4), ((7, 9), 6)):
        a = rng.normal(size=(H, W))
        b = a + rng.normal(scale=0.1, size=(H, W))
        dt = float(rng.uniform(0.05, 0.5))
        lam = float(rng.uniform(5.0, 20.0)) * dt**2
        check = _ex03_iterate_check(a, b, dt, lam, k)
        out.append(("solve_gauss_seidel", (a, b, dt, lam), {"tol": 0.0, "max_sweeps": k}, check))
    return out


EXERCISE = Exercise(
    id="ex03_gauss_seidel",
    title="Red-black Gauss-Seidel for variational scene flow",
    notebook="ex03_gauss_seidel.ipynb",
    answer_cells=("red_black_sweep", "solve_gauss_seidel"),
    blocked=("flowtrack.variational", "flowtrack.sceneflow"),
    allowed=('numpy',),
    tests=(
        _ex03_sweep_public, _ex03_sweep_hidden, _ex03_solve_public, _ex03_solve_hidden,
        _ex03_iterates_public, _ex03_iterates_hidden,
    ),
)
