"""`flowtrack demo --input` on a TUM-layout sequence that flowtrack did not render.

The sequence comes from ``benchmarks/_boxes.py``, a renderer that shares no code with flowtrack (numpy
and PIL only: its own ray caster, TUM fr1 camera, textures, Kinect-like depth model and sensor
clocks): three boxes at 30 Hz, 640x480, one second from the middle of their motions (two boxes cross,
the far one partly hidden; the third turns). The demo runs by its command line as a user's would, and
``tracks.csv`` is read with the csv module and scored against the box *centres* at 15 cm, against the
bars (MOTA >= 0.75, at most one ID switch). The full-length runs are in
``benchmarks/bench_tum_input.py``.
"""

import csv
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from flowtrack.metrics import clear_mot
from flowtrack_course.cli import main

COURSE = Path(__file__).resolve().parents[1]


def _renderer():
    spec = importlib.util.spec_from_file_location("_boxes", COURSE / "benchmarks" / "_boxes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tum_input")
    made = _renderer().render_sequence(tmp / "boxes", seed=5, n_frames=30, rate_hz=30.0, first=30)
    assert main(["demo", "--input", str(tmp / "boxes"), "--intrinsics", made["intrinsics"], "--out",
                 str(tmp / "out"), "--no-real-data", "--no-gif", "--no-progress"]) == 0
    with open(tmp / "out" / "tracks.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return made["truth"], rows


def test_renderer_shares_no_code_with_flowtrack():
    text = (COURSE / "benchmarks" / "_boxes.py").read_text()
    assert "flowtrack" not in "\n".join(line for line in text.splitlines()
                                        if line.startswith(("import ", "from ")))


def test_every_input_frame_has_rows(run):
    truth, rows = run
    assert {int(r["frame"]) for r in rows} == set(truth)  # the last frame too: 0 ... 29


def test_tracks_csv_follows_every_box_within_15_cm(run):
    truth, rows = run
    hyp = {f: {} for f in truth}
    for r in rows:
        if r["status"] == "confirmed":
            hyp[int(r["frame"])][int(r["track_id"])] = np.array([float(r[k]) for k in "xyz"])
    frames = sorted(truth)
    m = clear_mot([truth[f] for f in frames], [hyp[f] for f in frames], 0.15)
    assert m["mota"] >= 0.75 and m["id_switches"] <= 1, m
    # every box is followed for part of the sequence, none is lost (without the colour test,
    # PipelineConfig.colour_check, geometry calls the turning box static and it is only partly tracked)
    assert m["num_unique_objects"] == 3 and m["mostly_lost"] == 0, m


@pytest.fixture(scope="module")
def small_sequence(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tum_small")
    made = _renderer().render_sequence(tmp / "boxes", seed=5, n_frames=8, rate_hz=30.0, first=30,
                                       size=(240, 320))
    return tmp / "boxes", made


def test_moving_first_cloud_keeps_every_moving_voxel(small_sequence):
    """``PipelineConfig.moving_first_speed``: the subsample holds every voxel whose RGB-D flow is that
    fast (checked against the flow of the whole voxel cloud), the flow it returns is the flow at its
    points, and the even-density surface is the whole voxel cloud."""
    from flowtrack.pipeline import PipelineConfig, rgbd_cloud_flow
    from flowtrack_course.demo.inputs import frame_cloud, load_input

    root, made = small_sequence
    inp = load_input(root, None, 3, None, 0, 0.0, 0, "mixed", {"intrinsics": made["intrinsics"]})
    cfg = PipelineConfig(moving_first_speed=0.02, max_points=2000)
    fc = frame_cloud(inp, 0, cfg, np.random.default_rng(0), partner=3)
    assert fc.voxels is not None and fc.surface is fc.voxels and len(fc.voxels) > len(fc.points) == 2000
    dt = inp.interval(0, 3)
    v_all = rgbd_cloud_flow(inp.rgb[0], inp.depth[0], inp.rgb[3], inp.depth[3], inp.camera, dt, fc.voxels)
    fast = {tuple(p) for p in fc.voxels[np.linalg.norm(v_all, axis=1) >= 0.02]}
    assert 0 < len(fast) < 2000  # the boxes move; the rest is filled at random
    assert fast <= {tuple(p) for p in fc.points}
    v_own = rgbd_cloud_flow(inp.rgb[0], inp.depth[0], inp.rgb[3], inp.depth[3], inp.camera, dt, fc.points)
    np.testing.assert_allclose(fc.flow, v_own, atol=1e-9)
    plain = frame_cloud(inp, 0, PipelineConfig(max_points=2000), np.random.default_rng(0), partner=3)
    assert plain.flow is None and plain.voxels is None and plain.surface is plain.points


def test_demo_runs_with_moving_first_subsample(small_sequence, tmp_path):
    """The demo's path that estimates each frame's flow with its cloud (off by default) runs end to end
    and writes a row for every input frame."""
    from flowtrack_course.demo.config import DemoConfig
    from flowtrack_course.demo.run import run_demo

    root, made = small_sequence
    run_demo(tmp_path / "out", config=DemoConfig(moving_first_speed=0.02), input_dir=root,
             input_options={"intrinsics": made["intrinsics"]}, n_frames=None, real_data=False, gif=False,
             progress=False, echo=lambda *a, **k: None)
    with open(tmp_path / "out" / "tracks.csv", newline="") as fh:
        frames = {int(r["frame"]) for r in csv.DictReader(fh)}
    assert frames == set(made["truth"])
