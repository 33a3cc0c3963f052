"""Ex03: red-black Gauss-Seidel: the trusted tests of the notebook next to this file."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Call,
    Check,
    Dependency,
    Exercise,
    GradedTest,
    Mistake,
    Outcome,
    Report,
    Variant,
    array_check,
    as_float_array,
    graded_test,
    safe_error,
)


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


#: The solver tests' sweep budget: red-black Gauss-Seidel reaches tol = 1e-10 on their grids (at most
#: 8x10, lam <= 5 dt^2: rho(G_GS) <= 0.91) in a few hundred sweeps, Jacobi in under a thousand; a
#: solver that stagnates (it converges to another system's solution) then stops after seconds, not
#: after the default 100000 sweeps (tests/test_mistakes.py checks the reference's count).
_SOLVE_SWEEPS = 5000

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
            {"max_sweeps": _SOLVE_SWEEPS},
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
        out.append(
            ("solve_gauss_seidel", (a, b, dt, lam), {"max_sweeps": _SOLVE_SWEEPS},
             _ex03_solve_check(a, b, dt, lam))
        )
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


@graded_test(
    "solver: iterates after a few sweeps on random components (tol=0)", "test_iterates", 1.0, hidden=True
)
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


# --------------------------------------------------------------------------------------------------
# the residual history against the theoretical rate


def model_matrix(H: int, W: int, c: float, lam: float) -> np.ndarray:
    """The dense ``(H W, H W)`` matrix ``c I + lam L`` of the exercise's statement (grid-graph
    Laplacian with the Neumann boundary, pixels numbered row-major), built edge by edge."""
    n = H * W
    A = np.diag(np.full(n, float(c)))
    idx = np.arange(n).reshape(H, W)
    edges = [(idx[i, j], idx[i + di, j + dj]) for i in range(H) for j in range(W)
             for di, dj in ((1, 0), (0, 1)) if i + di < H and j + dj < W]
    for p, q in edges:
        A[p, p] += lam
        A[q, q] += lam
        A[p, q] -= lam
        A[q, p] -= lam
    return A


def jacobi_radius(A: np.ndarray) -> float:
    """Spectral radius of the Jacobi iteration matrix ``I - D^-1 A`` (numpy eigenvalues).

    For this matrix (consistently ordered: a red-black colouring exists) Young's theorem gives the
    red-black Gauss-Seidel radius as its square (tests/test_mistakes.py checks it on the explicit
    Gauss-Seidel iteration matrix).
    """
    G = np.eye(len(A)) - A / np.diag(A)[:, None]
    return float(np.max(np.abs(np.linalg.eigvals(G))))


#: The model problem of the residual-history test: a 6x6 grid, dt = 0.2, lam = 2 dt^2, b - a a smooth
#: ramp from 1 to 1.5 (the residual is then dominated by the slowest mode from the first sweeps on).
_RATE_GRID, _RATE_DT, _RATE_LAM, _RATE_SWEEPS = (6, 6), 0.2, 2.0 * 0.2**2, 12


def _rate_scorer(a, b, dt, lam, sweeps: int):
    """Scorer of the calls ``solve_gauss_seidel(a, b, dt, lam, tol=0, max_sweeps=k)``, k = 1..sweeps:
    the relative residuals ``|r - A v_k| / |r|`` must shrink by rho(G_Jacobi)^2 per sweep
    (measured over the second half of the history, within 15 % of 1 - rho)."""

    H, W = np.shape(a)
    A = model_matrix(H, W, dt**2, lam)
    r = dt * (np.asarray(b, float) - np.asarray(a, float)).ravel()
    rho_j = jacobi_radius(A)
    rho_gs = rho_j**2
    tol = 0.15 * (1.0 - rho_gs)
    half = sweeps // 2

    def scorer(outcomes: Sequence[Outcome]) -> tuple[float, str]:
        res = []
        for k, o in enumerate(outcomes, start=1):
            if not o.ok:
                msg = f"solve_gauss_seidel(..., tol=0, max_sweeps={k}) failed: {o.error}"
                return 0.0, Report(msg, f"solve_gauss_seidel(..., tol=0, max_sweeps={k}) failed: "
                                   + safe_error(o.error))
            v = as_float_array(o.value, (H, W))
            if v is None or not np.all(np.isfinite(v)):
                msg = f"max_sweeps={k}: expected a finite array of shape {(H, W)}"
                return 0.0, Report(msg, msg)
            res.append(float(np.linalg.norm(r - A @ v.ravel()) / np.linalg.norm(r)))
        res = np.array(res)
        shown = ", ".join(f"{x:.3g}" for x in res[:4])
        if res[0] < 1e-8:
            msg = (f"the residual is {res[0]:.1e} after one sweep: that is a direct solve, one "
                   f"red-black sweep leaves about {rho_gs:.2f} of it")
            return 0.0, Report(msg, "the residual vanishes after one sweep: that is a direct solve",
                               ["dense-solve-not-sweeps"])
        if res[half - 1] <= 0 or res[-1] <= 0:
            msg = "the residual reaches 0 within a few sweeps: these are not Gauss-Seidel sweeps"
            return 0.0, Report(msg, msg, ["residual-rate-not-gauss-seidel"])
        rate = float((res[-1] / res[half - 1]) ** (1.0 / (sweeps - half)))
        if abs(rate - rho_gs) <= tol:
            return 1.0, Report("ok")
        msg = (f"relative residuals after 1, 2, 3, 4 sweeps: {shown}; they shrink by {rate:.3f} per "
               f"sweep, red-black Gauss-Seidel by rho(G_Jacobi)^2 = {rho_gs:.3f} here "
               f"(Jacobi: {rho_j:.3f})")
        ratios = res[half:] / res[half - 1 : -1]
        geometric = float(ratios.max() - ratios.min()) <= 0.05  # a linear iteration's asymptotic phase
        if geometric and abs(rate - rho_j) <= tol:
            mistakes = ["jacobi-not-gauss-seidel"]
        elif res[-1] <= 0.1 and rate < 1.0 - tol:  # converging to the solution, at another rate
            mistakes = ["residual-rate-not-gauss-seidel"]
        else:
            mistakes = []
            if rate > 0.95:
                msg += (
                    "; the residual (almost) stops shrinking: the sweeps do not converge to the solution "
                    "of A v = r"
                )
        # (the residuals are the answer's numbers: a hidden-safe text would not quote them)
        return 0.0, Report(msg, "the residuals do not shrink at the red-black Gauss-Seidel rate", mistakes)

    return scorer


def _build_rate(rng):
    H, W = _RATE_GRID
    a, b = np.zeros((H, W)), 1.0 + 0.5 * np.indices((H, W))[1] / (W - 1)
    calls = [Call("solve_gauss_seidel", (a, b, _RATE_DT, _RATE_LAM), {"tol": 0.0, "max_sweeps": k})
             for k in range(1, _RATE_SWEEPS + 1)]
    return calls, _rate_scorer(a, b, _RATE_DT, _RATE_LAM, _RATE_SWEEPS)


_ex03_rate = GradedTest(
    name="solver: the residual shrinks at the red-black Gauss-Seidel rate (tol=0, 1 to 12 sweeps)",
    grade_id="test_iterates",
    points=1.0,
    hidden=False,
    build=_build_rate,
)


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L2 = "lesson 02_variational_scene_flow"

MISTAKES = (
    Mistake(
        "jacobi-not-gauss-seidel",
        "this is a Jacobi sweep: every pixel is updated from the old iterate. In red-black "
        "Gauss-Seidel the black pixels use the red values just computed in the same sweep (which "
        f"is why it converges about twice as fast); see {_L2} §A.2 (red-black Gauss–Seidel, Young's theorem)",
    ),
    Mistake(
        "black-before-red",
        "black pixels are updated before red ones: the sweep must update the red pixels (i + j "
        f"even) first, then the black ones from the new red values; see {_L2} §A.2 (red-black Gauss–Seidel)",
    ),
    Mistake(
        "dense-solve-not-sweeps",
        "the result does not come from red-black sweeps: after max_sweeps sweeps the iterate is "
        "still far from the solution, yours is the exact solution of a direct solve. The exercise "
        "is the iteration (a dense solve needs O(N^2) memory on an image); "
        f"see {_L2} §A.2 (Gauss–Seidel sweeps, not a dense solve)",
    ),
    Mistake(
        "residual-rate-not-gauss-seidel",
        "the residual does not shrink at the red-black Gauss-Seidel rate: one sweep multiplies it by "
        "about rho(G_GS) = rho(G_Jacobi)^2 on the model problem, yours by another factor, so each "
        "sweep is not one Gauss-Seidel sweep (over- or under-relaxed updates, a sweep counted "
        "twice or skipped, pixels updated from stale values); "
        f"see {_L2} §A.2 (the convergence rate of Gauss–Seidel, Young's theorem)",
    ),
    Mistake(
        "neumann-boundary-degree",
        "every pixel is given 4 neighbours: with the Neumann boundary a border pixel has 3 and a "
        "corner 2 (deg_p counts only the neighbours inside the grid); "
        f"see {_L2} §A.1 (the grid Laplacian, Neumann boundary)",
    ),
)


EXERCISE = Exercise(
    id="ex03_gauss_seidel",
    title="Red-black Gauss-Seidel for variational scene flow",
    notebook="ex03_gauss_seidel.ipynb",
    answer_cells=("red_black_sweep", "solve_gauss_seidel"),
    blocked=("flowtrack.variational", "flowtrack.sceneflow"),
    allowed=('numpy',),
    tests=(
        _ex03_sweep_public, _ex03_sweep_hidden, _ex03_solve_public, _ex03_solve_hidden,
        _ex03_iterates_public, _ex03_iterates_hidden, _ex03_rate,
    ),
    packages=("flowtrack",),
    mistakes=MISTAKES,
    depends=(
        Dependency("test_solver", on="test_sweep", function="red_black_sweep", builds="solve_gauss_seidel"),
        Dependency("test_iterates", on="test_sweep", function="red_black_sweep", builds="solve_gauss_seidel"),
    ),
)
