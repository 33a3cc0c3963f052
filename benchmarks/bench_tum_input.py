"""Benchmark: `flowtrack demo --input` on TUM-layout sequences that flowtrack did not render.

The issue's last bar: on an RGB-D sequence in the TUM layout that no one here made, ``tracks.csv``
follows every object: MOTA >= 0.75 at 15 cm against the objects' centres, at most one ID switch.
No outside sequence with object ground truth can be reached from this machine (PyPI, Debian and npm
only; the TUM benchmark's own sequences have no object ground truth), so the sequences here come from
``benchmarks/_boxes.py``, a renderer that shares no code with flowtrack (its own ray caster, camera,
textures, Kinect-like depth model and sensor clocks; three boxes: two crossing, one hidden behind the
other for a while, one turning on an arc). Each is run as a user would, by the command line
(``flowtrack demo --input DIR --intrinsics fx,fy,cx,cy --no-real-data --no-gif``), and its
``tracks.csv`` is read with the csv module and scored against the box centres of ``objects.csv``
(CLEAR-MOT at 15 cm: ``flowtrack.metrics.clear_mot``, which the tests check against py-motmetrics).

The peer, in the same run, on the first (30 Hz) sequence: the same sequence and pipeline with every
frame paired with the next one (``DemoConfig(flow_interval=1e-9)``: what the demo did before it paired
frames at least 0.1 s apart).

Usage::

    .venv/bin/python benchmarks/bench_tum_input.py [--quick] [--check]

Prints its table and, unless ``--quick``, writes it to ``benchmarks/results/tum_input.md``.
``--check`` exits with status 1 when a bar is missed.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _boxes import render_sequence
from _results import publish
from flowtrack.metrics import clear_mot

MAX_DIST = 0.15
SEQUENCES = [
    ("30 Hz, textured boxes, 640x480", dict(seed=0, n_frames=90, rate_hz=30.0)),
    ("30 Hz, plain-coloured boxes, 640x480", dict(seed=1, n_frames=90, rate_hz=30.0, plain=True)),
    ("10 Hz, textured boxes, 640x480", dict(seed=2, n_frames=30, rate_hz=10.0)),
]
PEER_ON = {0}  # the peer runs on the first sequence only (its frame rate is what the peer lacks)
QUICK = [("30 Hz, textured boxes, 320x240, the first second (quick)",
          dict(seed=0, n_frames=30, rate_hz=30.0, size=(240, 320)))]
PEER_CONFIG = "DemoConfig(flow_interval=1e-9)"


def run_cli(seq: Path, intrinsics: str, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "from flowtrack_course.cli import main; raise SystemExit(main())",
                    "demo", "--input", str(seq), "--intrinsics", intrinsics, "--out", str(out),
                    "--no-real-data", "--no-gif", "--no-progress"], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def run_peer(seq: Path, intrinsics: str, out: Path) -> float:
    code = ("from flowtrack_course.demo import DemoConfig, run_demo; "
            f"run_demo({str(out)!r}, n_frames=None, config={PEER_CONFIG}, input_dir={str(seq)!r}, "
            f"input_options={{'intrinsics': {intrinsics!r}}}, real_data=False, gif=False, progress=False, "
            "echo=lambda *a, **k: None)")
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def score(seq: Path, out: Path, statuses: tuple[str, ...]) -> dict:
    truth: dict[int, dict[int, np.ndarray]] = {}
    with open(seq / "objects.csv") as fh:
        for r in csv.DictReader(fh):
            truth.setdefault(int(r["frame"]), {})[int(r["id"])] = np.array([float(r[k]) for k in "xyz"])
    hyp: dict[int, dict[int, np.ndarray]] = {f: {} for f in truth}
    with open(out / "tracks.csv") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        if r["status"] in statuses:
            hyp.setdefault(int(r["frame"]), {})[int(r["track_id"])] = np.array([float(r[k]) for k in "xyz"])
    frames = sorted(truth)  # every frame of the sequence: a frame without rows counts its objects missed
    m = clear_mot([truth[f] for f in frames], [hyp[f] for f in frames], MAX_DIST)
    m["frames_with_rows"] = len({int(r["frame"]) for r in rows})
    m["frames"] = len(frames)
    return m


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one small, short sequence")
    ap.add_argument("--check", action="store_true", help="exit 1 when a bar is missed")
    args = ap.parse_args()
    rows, ok = [], True
    with tempfile.TemporaryDirectory(prefix="flowtrack-tum-") as tmp:
        tmp = Path(tmp)
        for i, (name, kw) in enumerate(QUICK if args.quick else SEQUENCES):
            seq = tmp / f"seq{i}"
            t0 = time.perf_counter()
            made = render_sequence(seq, **kw)
            t_render = time.perf_counter() - t0
            secs = run_cli(seq, made["intrinsics"], tmp / f"out{i}")
            ours = score(seq, tmp / f"out{i}", ("confirmed",))
            reported = score(seq, tmp / f"out{i}", ("confirmed", "coasting"))
            peer_text, peer_secs = "-", None
            if i in PEER_ON or args.quick:
                peer_secs = run_peer(seq, made["intrinsics"], tmp / f"peer{i}")
                peer = score(seq, tmp / f"peer{i}", ("confirmed",))
                peer_text = f"{peer['mota']:.3f} / {peer['id_switches']}"
            met = ours["mota"] >= 0.75 and ours["id_switches"] <= 1
            ok &= met
            rows.append(
                f"| {name} | {ours['frames']} ({ours['frames_with_rows']}) | {ours['mota']:.3f} | "
                f"{ours['id_switches']} | {ours['fp']} | {ours['fn']} | {ours['motp']:.3f} | "
                f"{reported['mota']:.3f} / {reported['id_switches']} | "
                f"{peer_text} | {secs:.0f} s ({t_render:.0f} s render"
                f"{'' if peer_secs is None else f'; peer {peer_secs:.0f} s'}) | {'yes' if met else 'NO'} |")
            print(rows[-1], flush=True)
    lines = [
        "# `flowtrack demo --input` on sequences flowtrack did not render (issue 15)",
        "",
        "Three boxes on a table rendered by `benchmarks/_boxes.py` (shares no code with flowtrack: its own "
        "ray caster, TUM fr1 camera, textures, Kinect-like depth and sensor clocks; two boxes cross and the "
        "far one is partly hidden, the third turns on an arc), run by the command line as a user would "
        "(`flowtrack demo --input DIR --intrinsics ... --no-real-data --no-gif`, every frame), `tracks.csv` "
        "scored against the box centres (`objects.csv`) with CLEAR-MOT at 15 cm over every frame of the "
        "sequence. Bar: MOTA >= 0.75 and at most one ID switch, on the confirmed rows. *Reported* also "
        "counts the coasting rows (a confirmed track predicted through a miss). The peer: the same "
        f"sequence with `{PEER_CONFIG}` (every frame paired with the next one, as before; run on the "
        "first sequence). Times are wall-clock on this machine, for scale only. MOTP is the mean distance "
        "of a matched track from the box centre: the tracks follow the centroid of the visible surface, "
        "a few cm nearer the camera than the centre.",
        "",
        "| sequence | frames (with rows) | MOTA | ID switches | FP | misses | MOTP (m) "
        "| reported: MOTA / IDsw | peer: MOTA / IDsw | time | bar met |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|",
        *rows,
        "",
        "What no stand-in covers: a moving camera (the pipeline separates objects from a static "
        "background by their speed, so a hand-held sequence needs ego-motion compensation first), and "
        "real sensor effects beyond the depth model here (infrared interference, auto-exposure, motion "
        "blur, rolling shutter).",
    ]
    publish("tum_input", "\n".join(lines) + "\n", args.quick)
    return 0 if ok or not args.check else 1


if __name__ == "__main__":
    raise SystemExit(main())
