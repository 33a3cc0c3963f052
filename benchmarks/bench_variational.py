"""Variational scene flow: exact DCT solve vs conjugate gradients (and Gauss–Seidel) on one system.

Every solver is timed in this process on the same system
``(dt^2 I + lam L_grid) v_k = dt (X_t1 - X_t)_k`` (k = 1, 2, 3) of a synthetic 480 x 640 RGB-D pair:

- ``flowtrack dct``: ``variational_scene_flow(..., method="dct")``;
- ``scipy cg``: the peer, ``scipy.sparse.linalg.cg(A, b_k, rtol=1e-8)`` on the assembled sparse
  matrix, one call per component (assembly not timed);
- ``flowtrack cg``: ``method="cg"`` (Jacobi-PCG, three components in one block solve, rtol 1e-8,
  assembly included);
- ``flowtrack gauss_seidel``: red-black Gauss–Seidel, on a smaller grid (it needs thousands of sweeps);
- a floor: the forward and inverse 2-D DCT of the three components alone (``scipy.fft``), the least
  any DCT solve can cost, so scipy CG / floor bounds the speed-up any DCT solver can show.

Targets (issue): DCT >= 50x faster than scipy CG, max |v_dct - v_cg| <= 1e-6 m/s.
BLAS is limited to one thread (unless ``OPENBLAS_NUM_THREADS`` is set): every solver here is then
single-threaded (scipy.fft uses one worker by default), and on a shared, over-subscribed machine a
multi-threaded OpenBLAS made CG's vector operations up to 100x slower and the ratios meaningless.

Usage: ``python benchmarks/bench_variational.py [--quick]``; writes ``results/variational.md``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.fft  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.sparse.linalg import cg  # noqa: E402

from _results import publish  # noqa: E402
from flowtrack.variational import grid_laplacian, variational_scene_flow  # noqa: E402


def synthetic_pair(H, W, dt, seed=0):
    """Point maps of a tilted table with a box moving on it, seen by a 525 px pinhole camera."""
    rng = np.random.default_rng(seed)
    f = 525.0 * W / 640
    u, v = np.meshgrid(np.arange(W) - W / 2, np.arange(H) - H / 2)
    depth = 1.2 + 0.3 * v / H
    box = (np.abs(u - W * 0.1) < W * 0.15) & (np.abs(v) < H * 0.15)
    depth = np.where(box, depth - 0.15, depth)
    X = np.stack([u * depth / f, v * depth / f, depth], axis=-1)
    vel = np.zeros_like(X)
    vel[box] = [0.3, -0.1, 0.05]
    X1 = X + vel * dt + 0.002 * rng.normal(size=X.shape)
    return X, X1


def timed(fn, repeats):
    """Best of ``repeats`` wall times (the least disturbed run on a shared machine) and the result."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def scipy_cg(X, X1, dt, lam, rtol):
    H, W, _ = X.shape
    A = (dt**2 * sp.identity(H * W, format="csr") + lam * grid_laplacian(H, W)).tocsr()
    B = (dt * (X1 - X)).reshape(H * W, 3)

    def run():
        cols, its = [], [0]

        def count(_):
            its[0] += 1

        for k in range(3):
            x, info = cg(A, np.ascontiguousarray(B[:, k]), rtol=rtol, atol=0.0, callback=count)
            if info != 0:
                raise RuntimeError(f"scipy cg did not converge (info={info})")
            cols.append(x)
        return np.stack(cols, axis=-1).reshape(H, W, 3), its[0]

    return run


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small grids, fewer repeats (smoke run)")
    args = parser.parse_args()
    if args.quick:
        H, W, gs_shape, alphas, rep_fast, rep_slow = 48, 64, (16, 20), (25.0,), 2, 1
    else:
        H, W, gs_shape, alphas, rep_fast, rep_slow = 480, 640, (60, 80), (1.0, 25.0, 100.0), 7, 3
    dt, rtol = 0.1, 1e-8
    X, X1 = synthetic_pair(H, W, dt)

    rows = []
    verdicts = []
    # The floor of any DCT solve: the forward and inverse 2-D transforms of the three components
    # alone (no eigenvalue division, no checks), same library, same single thread.
    D = dt * (X1 - X)

    def dct_pair():
        spectrum = scipy.fft.dctn(D, type=2, axes=(0, 1), norm="ortho")
        return scipy.fft.idctn(spectrum, type=2, axes=(0, 1), norm="ortho")

    dct_pair()
    t_floor, _ = timed(dct_pair, rep_fast)
    for alpha in alphas:
        lam = alpha * dt**2
        variational_scene_flow(X, X1, dt, lam)  # warm the FFT plan cache
        t_dct, v_dct = timed(lambda lam=lam: variational_scene_flow(X, X1, dt, lam), rep_fast)
        t_scg, (v_scg, it_scg) = timed(scipy_cg(X, X1, dt, lam, rtol), rep_slow)
        t_fcg, (v_fcg, info) = timed(
            lambda lam=lam: variational_scene_flow(X, X1, dt, lam, method="cg", tol=rtol, return_info=True),
            rep_slow,
        )
        d_scg = float(np.abs(v_scg - v_dct).max())
        d_fcg = float(np.abs(v_fcg - v_dct).max())
        grid = f"{H}x{W}"
        rows += [
            (grid, alpha, "flowtrack dct", t_dct, "direct", 1.0, 0.0),
            (grid, alpha, "scipy cg (peer)", t_scg, str(it_scg), t_scg / t_dct, d_scg),
            (grid, alpha, "flowtrack cg (Jacobi)", t_fcg, str(info["iterations"]), t_fcg / t_dct, d_fcg),
            (grid, alpha, "floor: scipy.fft dctn + idctn alone", t_floor, "", t_floor / t_dct, None),
        ]
        verdicts.append((alpha, t_scg / t_dct, d_scg, t_scg / t_floor))

    # Gauss–Seidel for reference on a smaller grid (same scene, same alpha as the middle case)
    h, w = gs_shape
    Xs, X1s = synthetic_pair(h, w, dt)
    alpha = alphas[len(alphas) // 2]
    lam = alpha * dt**2
    t_d, v_d = timed(lambda: variational_scene_flow(Xs, X1s, dt, lam), rep_fast)
    t_c, (v_c, it_c) = timed(scipy_cg(Xs, X1s, dt, lam, rtol), rep_fast)
    t_g, (v_g, info_g) = timed(
        lambda: variational_scene_flow(Xs, X1s, dt, lam, method="gauss_seidel", tol=rtol, return_info=True),
        rep_slow,
    )
    grid = f"{h}x{w}"
    rows += [
        (grid, alpha, "flowtrack dct", t_d, "direct", 1.0, 0.0),
        (grid, alpha, "scipy cg (peer)", t_c, str(it_c), t_c / t_d, float(np.abs(v_c - v_d).max())),
        (
            grid,
            alpha,
            "flowtrack gauss_seidel",
            t_g,
            f"{info_g['iterations']} sweeps",
            t_g / t_d,
            float(np.abs(v_g - v_d).max()),
        ),
    ]

    lines = [
        "## Variational scene flow (`flowtrack.variational`)",
        "",
        f"System `(dt² I + lam L_grid) v = dt (X_t1 − X_t)`, 3 components, dt = {dt}, "
        f"alpha = lam/dt²; iterative solvers at rtol = {rtol:g}. Best wall time of "
        f"{rep_fast} (fast) / {rep_slow} (slow) runs{' (--quick)' if args.quick else ''}. "
        "Ratio = time / DCT time on the same grid; max |Δv| against the DCT solution (m/s). "
        f"BLAS threads: {os.environ['OPENBLAS_NUM_THREADS']} (all solvers single-threaded).",
        "",
        "| grid | alpha | solver | time (ms) | iterations | ratio vs DCT | max abs Δv vs DCT |",
        "|---|---:|---|---:|---:|---:|---:|",
    ]
    for grid, a, name, t, its, ratio, diff in rows:
        shown = "" if diff is None else f"{diff:.2e}"
        lines.append(f"| {grid} | {a:g} | {name} | {1e3 * t:.1f} | {its} | {ratio:.1f}x | {shown} |")
    lines += [
        "",
        "CG needs O(sqrt(1 + 8 alpha)) iterations per decade of residual (condition number 1 + 8 alpha of",
        "the full-data system) while the DCT cost does not depend on alpha, so the speed-up grows with",
        "the smoothing length sqrt(alpha) (in pixels).",
        "",
        "Targets: DCT ≥ 50x faster than scipy CG, max |Δv| ≤ 1e-6.",
    ]
    for a, ratio, diff, ceiling in verdicts:
        ok = "met" if ratio >= 50 and diff <= 1e-6 else "NOT met"
        lines.append(
            f"- alpha = {a:g} (lam = {a * dt**2:g} at dt = {dt}): speed-up {ratio:.1f}x, "
            f"max |Δv| {diff:.2e} → {ok} (ceiling for any DCT solve: scipy CG / transforms alone = "
            f"{ceiling:.1f}x)"
        )
    lines += [
        "",
        "With weak smoothing (alpha = 1, a smoothing length of one pixel) the system is nearly",
        "diagonal and CG needs few iterations, so the speed-up of any direct method is smallest",
        "there; it grows with alpha (see the verdicts above for where the 50x bar is met).",
    ]
    text = "\n".join(lines) + "\n"
    publish("variational", text, args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
