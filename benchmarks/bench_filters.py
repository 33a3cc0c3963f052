"""Benchmarks of flowtrack's filters against peers measured in the same run.

Usage: ``.venv/bin/python benchmarks/bench_filters.py [--quick]``. Writes
``benchmarks/results/filters.md`` and prints it. Ratios, not absolute times, are the result.

1. ``BatchKalmanFilter``, M tracks of a 4-D CV model (predict + update, 80 % of tracks measured)
   vs a Python loop over M ``filterpy.kalman.KalmanFilter`` objects doing the same work (predict
   and update of every track each step, ``update(None)`` for the unmeasured ones, the same
   measurements); only the steps are timed (the filters are built outside the timed region, for
   both); agreement of the states and covariances is reported.
2. ``ParticleFilter`` step (predict + update + systematic resampling every step + estimate) at
   100k particles of a 4-D CV model, ns per particle per step, vs the same step resampled with
   ``filterpy.monte_carlo.systematic_resample`` (a Python while-loop) and vs a naive step
   (linear weights, ``rng.choice`` multinomial resampling). All three use the same model functions
   (written column by column on column-major particle arrays, see ``cv_model``) and the same
   layout-preserving gather. Floors measured in the same run: the model alone (transition +
   log-likelihood, no filter) and numpy's cost of the 2 normals per particle the model draws. The
   step with the previous C-ordered model is reported too, and where the time of one step goes.
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

from _results import publish
from flowtrack.kalman import BatchKalmanFilter, constant_velocity_model
from flowtrack.particle import ParticleFilter, systematic_resample


def best_of(fn, repeat, setup=None):
    """Best time of ``repeat`` calls of ``fn()`` (or ``fn(setup())``, the setup not timed)."""
    times = []
    for _ in range(repeat):
        args = () if setup is None else (setup(),)
        t = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t)
    return min(times)


def loadavg():
    try:
        return Path("/proc/loadavg").read_text().split()[:3]
    except OSError:
        return ["?", "?", "?"]


def bench_kalman(M, steps, repeat):
    dt = 0.1
    F, H, Q, R = constant_velocity_model(dt, 1.0, 0.25, dim=2)
    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(M, 4))
    Zs = rng.normal(size=(steps, M, 2))
    masks = rng.random((steps, M)) < 0.8

    def make_batch():
        return BatchKalmanFilter(F, H, Q, R, x0, np.eye(4))

    def make_filterpy():
        fs = []
        for i in range(M):
            f = FPKalmanFilter(dim_x=4, dim_z=2)
            f.F, f.H, f.Q, f.R = F, H, Q, R
            f.x, f.P = x0[i].reshape(4, 1).copy(), np.eye(4)
            fs.append(f)
        return fs

    def run_batch(b):
        for t in range(steps):
            b.predict()
            b.update(Zs[t], masks[t])
        return b

    def run_filterpy(fs):
        for t in range(steps):
            for i, f in enumerate(fs):
                f.predict()
                f.update(Zs[t, i] if masks[t, i] else None)
        return fs

    b = run_batch(make_batch())
    fs = run_filterpy(make_filterpy())
    err_x = max(np.abs(b.x[i] - f.x.ravel()).max() for i, f in enumerate(fs))
    err_P = max(np.abs(b.P[i] - f.P).max() for i, f in enumerate(fs))
    t_b = best_of(run_batch, repeat, make_batch)
    t_f = best_of(run_filterpy, max(1, repeat // 2), make_filterpy)
    n = M * steps
    return dict(M=M, steps=steps, batch_ns=1e9 * t_b / n, fp_ns=1e9 * t_f / n, err=max(err_x, err_P))


DT, QA, RZ = 0.1, 1.0, 0.25  # particle benchmark: time step, acceleration variance, measurement variance


def cv_model(N):
    """``(transition, loglik, init)`` of the 4-D CV model on column-major ``(N, 4)`` particles.

    x' = F x + G a with F = [[I, dt I], [0, I]], G = [dt²/2 I; dt I], a ~ N(0, q I); z = p + N(0, r I).
    Written column by column on arrays laid out as ``np.empty((4, N)).T``, so every numpy inner loop
    runs over N contiguous numbers (on a C-ordered (N, 4) array the same code loops over 2).
    """
    sq = np.sqrt(QA)
    a = np.empty((2, N))                      # the 2 normals per particle, drawn in place

    def transition(p, rng):
        rng.standard_normal(out=a)
        out = np.empty((4, p.shape[0])).T
        pos, vel = out[:, :2], out[:, 2:]
        np.multiply(p[:, 2:], DT, out=pos)
        pos += p[:, :2]
        pos += (0.5 * DT * DT * sq) * a.T
        np.multiply(a.T, DT * sq, out=vel)
        vel += p[:, 2:]
        return out

    def loglik(z, p):
        d = p[:, 0] - z[0]
        d *= d
        e = p[:, 1] - z[1]
        e *= e
        d += e
        d *= -0.5 / RZ
        return d

    def init(n, rng):
        return rng.standard_normal((4, n)).T

    return transition, loglik, init


def cv_model_c_order():
    """The previous model functions: the same maths on C-ordered ``(N, 4)`` particles."""
    sq = np.sqrt(QA)

    def transition(p, rng):
        a = sq * rng.standard_normal((p.shape[0], 2))
        out = np.empty_like(p)
        np.multiply(p[:, 2:], DT, out=out[:, :2])
        out[:, :2] += p[:, :2]
        out[:, :2] += (0.5 * DT * DT) * a
        np.multiply(a, DT, out=out[:, 2:])
        out[:, 2:] += p[:, 2:]
        return out

    def loglik(z, p):
        d = p[:, :2] - z
        return (-0.5 / RZ) * (d * d).sum(1)

    def init(n, rng):
        return rng.standard_normal((n, 4))

    return transition, loglik, init


def gather(p, idx):
    """``p[idx]`` keeping a column-major layout (what ParticleFilter does), for the peers."""
    out = np.empty((p.shape[1], idx.shape[0])).T
    for j in range(p.shape[1]):
        np.take(p[:, j], idx, out=out[:, j])
    return out


def bench_particle(N, steps, repeat):
    transition, loglik, init = cv_model(N)
    zs = np.random.default_rng(1).normal(size=(steps, 2))

    def run_ours(model=(transition, loglik, init)):
        pf = ParticleFilter(N, *model, seed=0, resample_threshold=1.0)
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
            p = gather(p, fp_systematic_resample(w))
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
            p = gather(p, rng.choice(N, size=N, p=w))
            w = np.full(N, 1.0 / N)
            np.average(p, axis=0, weights=w), np.cov(p.T, aweights=w)

    def run_model_only():
        rng = np.random.default_rng(0)
        p = init(N, rng)
        for z in zs:
            p = transition(p, rng)
            loglik(z, p)

    normals = np.empty((2, N))
    rng_n = np.random.default_rng(0)

    def run_normals():
        for _ in zs:
            rng_n.standard_normal(out=normals)

    t_o = best_of(run_ours, repeat)
    t_f = best_of(run_fp_resample, max(1, repeat // 2))
    t_n = best_of(run_naive, repeat)
    t_m = best_of(run_model_only, repeat)
    t_g = best_of(run_normals, repeat)
    t_c = best_of(lambda: run_ours(cv_model_c_order()), max(1, repeat // 2))
    w = np.random.default_rng(2).random(N)
    w /= w.sum()
    rng = np.random.default_rng(3)
    t_rs = best_of(lambda: systematic_resample(w, rng), repeat * 3)
    t_rs_fp = best_of(lambda: fp_systematic_resample(w), max(1, repeat // 2))
    n = N * steps
    return dict(
        N=N, steps=steps, ours=1e9 * t_o / n, fp=1e9 * t_f / n, naive=1e9 * t_n / n,
        model=1e9 * t_m / n, normals=1e9 * t_g / n, c_order=1e9 * t_c / n,
        rs=1e9 * t_rs / N, rs_fp=1e9 * t_rs_fp / N, stages=particle_stages(N, zs, repeat),
    )


def particle_stages(N, zs, repeat):
    """Where one ParticleFilter step goes: per-stage best-of times, ns per particle."""
    transition, loglik, init = cv_model(N)
    pf = ParticleFilter(N, transition, loglik, init, seed=0, resample_threshold=1.0)
    best = {}

    def lap(name, t0):
        t1 = time.perf_counter()
        best[name] = min(best.get(name, np.inf), t1 - t0)
        return t1

    for _ in range(repeat):
        for z in zs:
            t = time.perf_counter()
            p = transition(pf.particles, pf.rng)
            t = lap("model: transition (2 normals + 6 column ops)", t)
            pf.particles = pf._check_particles(p, "transition(particles, rng)")
            t = lap("filter: check particles finite", t)
            loglik(z, pf.particles)
            t = lap("model: log-likelihood", t)
            pf.update(z)  # calls the log-likelihood again; subtracted below
            t = lap("filter: update (log-likelihood + weights + ESS + resample)", t)
            pf.estimate()
            lap("filter: estimate (weighted mean, covariance)", t)
    ns = {k: 1e9 * v / N for k, v in best.items()}
    key = "filter: update (log-likelihood + weights + ESS + resample)"
    ns["filter: update without the log-likelihood (weights + ESS + resample)"] = (
        ns.pop(key) - ns["model: log-likelihood"]
    )
    return ns


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer steps and repeats")
    args = ap.parse_args()
    steps_k, rep = (5, 2) if args.quick else (20, 5)
    load0 = loadavg()
    k = bench_kalman(1000, steps_k, rep)
    load1 = loadavg()
    p = bench_particle(100_000, 5 if args.quick else 20, rep)
    load2 = loadavg()
    lines = [
        "# Filter benchmarks",
        "",
        f"`benchmarks/bench_filters.py{' --quick' if args.quick else ''}`; "
        f"Python {platform.python_version()}, NumPy {np.__version__}, {platform.machine()}, "
        f"{os.cpu_count()} CPUs; best of {rep} runs; peers measured in the same run. "
        f"Load average (1, 5, 15 min) at start / after Kalman / at end: {' '.join(load0)} / "
        f"{' '.join(load1)} / {' '.join(load2)} (a shared machine: compare the ratios).",
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
        f"| same step with the previous C-ordered (N, 4) model functions "
        f"| {p['c_order']:.0f} | | | | |",
        f"| floor: the model alone (transition + log-likelihood, no filter) "
        f"| {p['ours']:.0f} | {p['model']:.0f} | {p['model'] / p['ours']:.2f}× | | |",
        f"| floor: numpy drawing the 2 normals per particle (`standard_normal(out=)`) "
        f"| {p['ours']:.0f} | {p['normals']:.0f} | {p['normals'] / p['ours']:.2f}× | | |",
        f"| systematic resampling alone, N={p['N']}: ns per particle "
        f"| {p['rs']:.1f} (searchsorted) | {p['rs_fp']:.1f} (filterpy while-loop) "
        f"| {p['rs_fp'] / p['rs']:.0f}× | | |",
        "",
        f"Where one ParticleFilter step goes (N={p['N']}, best of {rep} per stage, ns per particle):",
        "",
        "| stage | ns per particle |",
        "|---|---|",
        *[f"| {name} | {v:.1f} |" for name, v in p["stages"].items()],
        "",
    ]
    publish("filters", "\n".join(lines), args.quick)


if __name__ == "__main__":
    main()
