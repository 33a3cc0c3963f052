"""Benchmarks of flowtrack's filters against peers measured in the same run.

Usage: ``.venv/bin/python benchmarks/bench_filters.py [--quick]``. Writes
``benchmarks/results/filters.md`` and prints it. Ratios, not absolute times, are the result.

1. ``BatchKalmanFilter``, M tracks of a 4-D CV model (predict + update, 80 % of tracks measured)
   vs a Python loop over M ``filterpy.kalman.KalmanFilter`` objects doing the same work;
   agreement of the states and covariances is reported.
2. ``ParticleFilter`` step (predict + update + systematic resampling every step) at 100k particles
   of a 4-D CV model, ns per particle per step, vs the same step resampled with
   ``filterpy.monte_carlo.systematic_resample`` (a Python while-loop) and vs a naive step
   (linear weights, ``rng.choice`` multinomial resampling).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from filterpy.kalman import KalmanFilter as FPKalmanFilter
from filterpy.monte_carlo import systematic_resample as fp_systematic_resample
from flowtrack.kalman import BatchKalmanFilter, constant_velocity_model
from flowtrack.particle import ParticleFilter, systematic_resample


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def bench_kalman(M, steps, repeat):
    dt = 0.1
    F, H, Q, R = constant_velocity_model(dt, 1.0, 0.25, dim=2)
    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(M, 4))
    Zs = rng.normal(size=(steps, M, 2))
    masks = rng.random((steps, M)) < 0.8

    def run_batch():
        b = BatchKalmanFilter(F, H, Q, R, x0, np.eye(4))
        for t in range(steps):
            b.predict()
            b.update(Zs[t], masks[t])
        return b

    def run_filterpy():
        fs = []
        for i in range(M):
            f = FPKalmanFilter(dim_x=4, dim_z=2)
            f.F, f.H, f.Q, f.R = F, H, Q, R
            f.x, f.P = x0[i].reshape(4, 1).copy(), np.eye(4)
            fs.append(f)
        for t in range(steps):
            for i, f in enumerate(fs):
                f.predict()
                f.update(Zs[t, i] if masks[t, i] else None)
        return fs

    b = run_batch()
    fs = run_filterpy()
    err_x = max(np.abs(b.x[i] - f.x.ravel()).max() for i, f in enumerate(fs))
    err_P = max(np.abs(b.P[i] - f.P).max() for i, f in enumerate(fs))
    t_b = best_of(run_batch, repeat)
    t_f = best_of(run_filterpy, max(1, repeat // 2))
    n = M * steps
    return dict(M=M, steps=steps, batch_ns=1e9 * t_b / n, fp_ns=1e9 * t_f / n, err=max(err_x, err_P))


def bench_particle(N, steps, repeat):
    dt, q, r = 0.1, 1.0, 0.25
    sq = np.sqrt(q)

    def transition(p, rng):
        # x' = F x + G a with F = [[I, dt I], [0, I]], G = [dt²/2 I; dt I], a ~ N(0, q I); written
        # with slices (a tall-skinny (N,4)@(4,4) GEMM is slower than this in OpenBLAS)
        a = sq * rng.standard_normal((p.shape[0], 2))
        out = np.empty_like(p)
        np.multiply(p[:, 2:], dt, out=out[:, :2])
        out[:, :2] += p[:, :2]
        out[:, :2] += (0.5 * dt * dt) * a
        np.multiply(a, dt, out=out[:, 2:])
        out[:, 2:] += p[:, 2:]
        return out

    def loglik(z, p):
        d = p[:, :2] - z
        return (-0.5 / r) * (d * d).sum(1)

    def init(n, rng):
        return rng.standard_normal((n, 4))

    zs = np.random.default_rng(1).normal(size=(steps, 2))

    def run_ours():
        pf = ParticleFilter(N, transition, loglik, init, seed=0, resample_threshold=1.0)
        for z in zs:
            pf.predict()
            pf.update(z)
            pf.estimate()

    def run_fp_resample():
        rng = np.random.default_rng(0)
        p = init(N, rng)
        lw = np.full(N, -np.log(N))
        for z in zs:
            p = transition(p, rng)
            lw = lw + loglik(z, p)
            w = np.exp(lw - lw.max())
            w /= w.sum()
            p = p[fp_systematic_resample(w)]
            lw = np.full(N, -np.log(N))
            np.average(p, axis=0), np.cov(p.T)

    def run_naive():
        rng = np.random.default_rng(0)
        p = init(N, rng)
        w = np.full(N, 1.0 / N)
        for z in zs:
            p = transition(p, rng)
            w = w * np.exp(loglik(z, p))
            w /= w.sum()
            p = p[rng.choice(N, size=N, p=w)]
            w = np.full(N, 1.0 / N)
            np.average(p, axis=0, weights=w), np.cov(p.T, aweights=w)

    t_o = best_of(run_ours, repeat)
    t_f = best_of(run_fp_resample, max(1, repeat // 2))
    t_n = best_of(run_naive, repeat)
    w = np.random.default_rng(2).random(N)
    w /= w.sum()
    rng = np.random.default_rng(3)
    t_rs = best_of(lambda: systematic_resample(w, rng), repeat * 3)
    t_rs_fp = best_of(lambda: fp_systematic_resample(w), max(1, repeat // 2))
    n = N * steps
    return dict(
        N=N, steps=steps, ours=1e9 * t_o / n, fp=1e9 * t_f / n, naive=1e9 * t_n / n,
        rs=1e9 * t_rs / N, rs_fp=1e9 * t_rs_fp / N,
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer steps and repeats")
    args = ap.parse_args()
    steps_k, rep = (5, 2) if args.quick else (20, 5)
    k = bench_kalman(1000, steps_k, rep)
    p = bench_particle(100_000, 5 if args.quick else 20, rep)
    lines = [
        "# Filter benchmarks",
        "",
        f"`benchmarks/bench_filters.py{' --quick' if args.quick else ''}`; "
        f"Python {platform.python_version()}, NumPy {np.__version__}, {platform.machine()}, "
        f"{os.cpu_count()} CPUs; best of {rep} runs; peers measured in the same run.",
        "",
        "| benchmark | flowtrack | peer | ratio (peer / flowtrack) | target | check |",
        "|---|---|---|---|---|---|",
        f"| Kalman, M={k['M']} tracks × {k['steps']} steps, 4-D CV, 80 % measured: ns per track-step "
        f"| {k['batch_ns']:.0f} (BatchKalmanFilter) | {k['fp_ns']:.0f} (loop of filterpy KalmanFilter) "
        f"| {k['fp_ns'] / k['batch_ns']:.0f}× | ≥ 100× | max abs diff x, P = {k['err']:.1e} (≤ 1e-10) |",
        f"| Particle filter step, N={p['N']}, 4-D CV, resample every step: ns per particle-step "
        f"| {p['ours']:.0f} (ParticleFilter) | {p['fp']:.0f} (filterpy systematic_resample) "
        f"| {p['fp'] / p['ours']:.1f}× | ≤ 200 ns | |",
        f"| same step, naive peer (linear weights, rng.choice multinomial) "
        f"| {p['ours']:.0f} | {p['naive']:.0f} | {p['naive'] / p['ours']:.1f}× | | |",
        f"| systematic resampling alone, N={p['N']}: ns per particle "
        f"| {p['rs']:.1f} (searchsorted) | {p['rs_fp']:.1f} (filterpy while-loop) "
        f"| {p['rs_fp'] / p['rs']:.0f}× | | |",
        "",
    ]
    text = "\n".join(lines)
    out = Path(__file__).resolve().parent / "results" / "filters.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
