"""Real RGB-D input: the TUM layout and stereo disparity, round trips, association, clear errors."""

import json

import numpy as np
import pytest
from PIL import Image

from flowtrack.camera import PinholeCamera
from flowtrack.rgbd_io import (
    associate,
    load_stereo_sequence,
    load_tum_sequence,
    parse_intrinsics,
    read_pfm,
    write_pfm,
    write_tum_sequence,
)
from flowtrack.synth import make_scene
from flowtrack_course.cli import main

SCALE = 5000.0


@pytest.fixture(scope="module")
def scene():
    return make_scene(n_objects=2, n_frames=5, image_size=(96, 128), seed=3)


def _intrinsics(cam) -> str:
    return f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}"


def _write_tum(root, scene, depth_delay=0.004, lists=True):
    """The TUM layout written here with PIL alone (not by flowtrack), depth in 1/5000 m units."""
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    rgb_lines, depth_lines = ["# timestamp filename"], ["# timestamp filename"]
    for i, f in enumerate(scene.frames):
        t = 1305031102.0 + i * scene.dt
        Image.fromarray(f.rgb).save(root / "rgb" / f"{t:.6f}.png")
        raw = np.round(f.depth * SCALE).astype(np.uint16)
        Image.fromarray(raw).save(root / "depth" / f"{t + depth_delay:.6f}.png")
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth_lines.append(f"{t + depth_delay:.6f} depth/{t + depth_delay:.6f}.png")
    if lists:
        (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
        (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    return root


@pytest.fixture()
def tum(tmp_path, scene):
    return _write_tum(tmp_path / "seq", scene)


def test_tum_round_trip_to_a_fifth_of_a_millimetre(tum, scene):
    seq = load_tum_sequence(tum, intrinsics=_intrinsics(scene.camera))
    assert len(seq) == len(scene.frames)
    for f, rgb, depth in zip(scene.frames, seq.rgb, seq.depth):
        np.testing.assert_array_equal(rgb, f.rgb)
        assert np.abs(depth - f.depth).max() <= 0.5 / SCALE + 1e-12
    assert seq.camera.K.tolist() == scene.camera.K.tolist()
    assert (seq.camera.width, seq.camera.height) == (128, 96)
    assert seq.dt == pytest.approx(scene.dt, abs=1e-6)


def test_names_in_order_without_lists_and_intrinsics_file(tmp_path, scene):
    root = _write_tum(tmp_path / "seq", scene, depth_delay=0.0, lists=False)
    c = scene.camera
    (root / "intrinsics.txt").write_text(f"# K\n{c.fx} 0 {c.cx}\n0 {c.fy} {c.cy}\n0 0 1\n")
    seq = load_tum_sequence(root, max_frames=3, step=1)
    assert len(seq) == 3 and seq.camera.fx == c.fx and seq.camera.cy == c.cy
    assert seq.dt == pytest.approx(scene.dt, abs=1e-6)  # timestamps from the file names


def _associate_reference(first, second, offset, max_difference):
    """TUM's associate.py (Sturm et al.), transcribed: all candidate pairs, closest first, greedy."""
    first_keys, second_keys = list(first), list(second)
    potential = [(abs(a - (b + offset)), a, b) for a in first_keys for b in second_keys
                 if abs(a - (b + offset)) < max_difference]
    potential.sort()
    matches = []
    for _, a, b in potential:
        if a in first_keys and b in second_keys:
            first_keys.remove(a)
            second_keys.remove(b)
            matches.append((a, b))
    matches.sort()
    return matches


@pytest.mark.parametrize("seed", range(6))
def test_associate_matches_tums_associate_py(seed):
    rng = np.random.default_rng(seed)
    a = np.sort(rng.uniform(0, 3, 60)) if seed % 2 else np.arange(60) / 30 + rng.normal(0, 0.004, 60)
    b = np.sort(rng.uniform(0, 3, 45))
    offset = 0.01 * (seed - 3)
    got = [(a[i], b[j]) for i, j in associate(a, b, offset=offset, max_difference=0.02)]
    assert got == _associate_reference(a.tolist(), b.tolist(), offset, 0.02)


def test_write_tum_sequence_round_trips(tmp_path, scene):
    root = write_tum_sequence(tmp_path / "w", [f.rgb for f in scene.frames], [f.depth for f in scene.frames],
                              np.arange(5) * 0.1, camera=scene.camera, depth_delay=0.003)
    seq = load_tum_sequence(root)
    assert len(seq) == 5
    assert max(np.abs(d - f.depth).max() for d, f in zip(seq.depth, scene.frames)) <= 0.5 / SCALE + 1e-12


def test_stereo_pfm_and_png_disparity_give_depth(tmp_path, scene):
    cam, B = scene.camera, 0.12
    for kind in ("pfm", "png"):
        root = tmp_path / kind
        for sub in ("left", "right", "disparity"):
            (root / sub).mkdir(parents=True)
        for i, f in enumerate(scene.frames[:3]):
            Image.fromarray(f.rgb).save(root / "left" / f"{i:04d}.png")
            Image.fromarray(f.rgb).save(root / "right" / f"{i:04d}.png")
            disp = cam.fx * B / f.depth
            if kind == "pfm":
                write_pfm(root / "disparity" / f"{i:04d}.pfm", disp)
            else:
                raw = np.round(disp * 256).astype(np.uint16)
                Image.fromarray(raw).save(root / "disparity" / f"{i:04d}.png")
        seq = load_stereo_sequence(root, intrinsics=_intrinsics(cam), baseline=B)
        assert len(seq) == 3
        for f, Z in zip(scene.frames, seq.depth):
            if kind == "pfm":  # float32 disparity: relative error ~1e-7
                np.testing.assert_allclose(Z, f.depth, rtol=1e-6)
            else:  # dZ = Z^2 / (f B) * dd with |dd| <= 0.5 / 256 px
                assert (np.abs(Z - f.depth) <= f.depth**2 / (cam.fx * B) * 0.5 / 256 * 1.001 + 1e-12).all()


def _stereo_folder(root, disparity, kind):
    """One frame: a grey left image and ``disparity`` as a PFM (pixels) or a raw 16-bit PNG."""
    for sub in ("left", "disparity"):
        (root / sub).mkdir(parents=True)
    Image.fromarray(np.full((*disparity.shape, 3), 128, dtype=np.uint8)).save(root / "left" / "0.png")
    if kind == "pfm":
        write_pfm(root / "disparity" / "0.pfm", disparity)
    else:
        Image.fromarray(disparity.astype(np.uint16)).save(root / "disparity" / "0.png")
    return root


def test_stereo_invalid_disparities_by_hand(tmp_path):
    """f B = 100 px * 0.5 m = 50 px m. PFM: NaN, +-inf and d + doffs <= 0 give depth 0; with doffs = 5 a
    disparity of 0 or -4 is a real point. PNG: a raw 0 is KITTI's "no measurement", whatever doffs."""
    disparity = np.array([[25.0, 50.0, 0.0, -4.0], [np.nan, np.inf, -np.inf, -5.0]])
    pfm = _stereo_folder(tmp_path / "pfm", disparity, "pfm")
    Z = load_stereo_sequence(pfm, intrinsics="100,100,2,1", baseline=0.5, doffs=5.0).depth[0]
    np.testing.assert_allclose(Z, [[50 / 30, 50 / 55, 50 / 5, 50 / 1], [0, 0, 0, 0]], rtol=1e-15, atol=0)
    Z = load_stereo_sequence(pfm, intrinsics="100,100,2,1", baseline=0.5).depth[0]
    np.testing.assert_allclose(Z, [[2, 1, 0, 0], [0, 0, 0, 0]], rtol=1e-15, atol=0)

    png = _stereo_folder(tmp_path / "png", np.array([[0, 256, 512, 1280]]), "png")
    Z = load_stereo_sequence(png, intrinsics="100,100,2,1", baseline=0.5, doffs=5.0).depth[0]
    np.testing.assert_allclose(Z, [[0, 50 / 6, 50 / 7, 50 / 10]], rtol=1e-15, atol=0)
    Z = load_stereo_sequence(png, intrinsics="100,100,2,1", baseline=0.5, disparity_scale=128.0).depth[0]
    np.testing.assert_allclose(Z, [[0, 25, 12.5, 5]], rtol=1e-15, atol=0)


@pytest.mark.parametrize(("doffs", "exc"), [(np.nan, ValueError), (np.inf, ValueError), ("5", TypeError)])
def test_stereo_bad_doffs_is_named(tmp_path, doffs, exc):
    root = _stereo_folder(tmp_path / "s", np.ones((2, 3)), "pfm")
    with pytest.raises(exc, match="doffs"):
        load_stereo_sequence(root, intrinsics="100,100,2,1", baseline=0.5, doffs=doffs)


def test_pfm_reader_is_bottom_to_top_and_checks_the_header(tmp_path):
    img = np.arange(12, dtype=np.float64).reshape(3, 4)
    # a big-endian file written by hand: rows bottom to top, positive scale
    raw = b"Pf\n4 3\n1.0\n" + img[::-1].astype(">f4").tobytes()
    (tmp_path / "a.pfm").write_bytes(raw)
    np.testing.assert_array_equal(read_pfm(tmp_path / "a.pfm"), img)
    (tmp_path / "b.pfm").write_bytes(b"P6\n4 3\n1.0\n" + bytes(48))
    with pytest.raises(ValueError, match="PF"):
        read_pfm(tmp_path / "b.pfm")
    (tmp_path / "c.pfm").write_bytes(raw[:-8])
    with pytest.raises(ValueError, match="too short"):
        read_pfm(tmp_path / "c.pfm")


def test_intrinsics_forms_and_errors(tmp_path):
    assert parse_intrinsics("1,2,3,4").K.tolist() == [[1, 0, 3], [0, 2, 4], [0, 0, 1]]
    assert parse_intrinsics("tum-fr2").fx == 520.9
    assert parse_intrinsics([5, 6, 7, 8], width=10, height=9) == PinholeCamera(5, 6, 7, 8, width=10, height=9)
    (tmp_path / "k.txt").write_text("fx: 500\nfy: 501\ncx: 320\ncy: 240\n")
    assert parse_intrinsics(tmp_path / "k.txt").fy == 501
    with pytest.raises(ValueError, match="4 numbers"):
        parse_intrinsics("1,2,3")
    with pytest.raises(ValueError, match="fx > 0"):
        parse_intrinsics("0,2,3,4")
    with pytest.raises(FileNotFoundError, match="intrinsics"):
        parse_intrinsics(tmp_path / "nope.txt")


# -- clear errors, each naming the problem ------------------------------------------------------------
def test_missing_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"input folder .*nope.* not found"):
        load_tum_sequence(tmp_path / "nope", intrinsics="1,1,1,1")
    (tmp_path / "x" / "rgb").mkdir(parents=True)
    with pytest.raises(FileNotFoundError, match="depth/ folder"):
        load_tum_sequence(tmp_path / "x", intrinsics="1,1,1,1")


def test_unreadable_png(tum):
    victim = sorted((tum / "depth").iterdir())[2]
    victim.write_bytes(b"this is not a PNG")
    with pytest.raises(ValueError, match=f"unreadable depth PNG .*{victim.name}"):
        load_tum_sequence(tum, intrinsics="1,1,1,1")


def test_eight_bit_depth_is_refused(tum):
    victim = sorted((tum / "depth").iterdir())[0]
    Image.fromarray(np.zeros((96, 128), dtype=np.uint8)).save(victim)
    with pytest.raises(ValueError, match="16-bit"):
        load_tum_sequence(tum, intrinsics="1,1,1,1")


def test_mismatched_frame_counts(tmp_path, scene):
    root = _write_tum(tmp_path / "seq", scene, lists=False)
    sorted((root / "depth").iterdir())[-1].unlink()
    with pytest.raises(ValueError, match=r"mismatched frame counts: .*5 PNGs .* 4"):
        load_tum_sequence(root, intrinsics="1,1,1,1")
    # with lists: timestamps that never come within max_difference of each other
    root = _write_tum(tmp_path / "far", scene, depth_delay=0.5)
    with pytest.raises(ValueError, match="mismatched frame counts"):
        load_tum_sequence(root, intrinsics="1,1,1,1")


def test_missing_intrinsics(tum):
    with pytest.raises(ValueError, match="intrinsics missing"):
        load_tum_sequence(tum)


def test_missing_listed_file_and_missing_baseline(tum, tmp_path):
    sorted((tum / "rgb").iterdir())[1].unlink()
    with pytest.raises(FileNotFoundError, match=r"rgb image .* not found"):
        load_tum_sequence(tum, intrinsics="1,1,1,1")
    with pytest.raises(ValueError, match="baseline"):
        load_stereo_sequence(tmp_path, intrinsics="1,1,1,1")


def test_cli_reports_input_errors(tmp_path, tum, capsys):
    out = str(tmp_path / "o")
    assert main(["demo", "--input", str(tmp_path / "nope"), "--out", out, "--no-progress"]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["demo", "--input", str(tum), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    assert "intrinsics missing" in capsys.readouterr().err


def test_demo_runs_on_a_tum_sequence(tum, scene, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["demo", "--input", str(tum), "--intrinsics", _intrinsics(scene.camera), "--out", str(out),
                 "--no-progress", "--no-real-data", "--predict-ahead", "2"])
    assert code == 0
    for name in ("flow_field.png", "clusters_3d.png", "trajectories.png", "tracks.gif", "metrics.json",
                 "metrics.md", "report.html"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["frames"] == 5 and summary["scene_flow"] is None and summary["tracking"] is None
    assert summary["dt"] == pytest.approx(scene.dt, abs=1e-6)
    assert "No ground truth" in (out / "report.html").read_text()
    assert "no ground truth" in capsys.readouterr().out


def test_demo_runs_on_a_stereo_sequence(scene, tmp_path):
    cam, B = scene.camera, 0.1
    root = tmp_path / "stereo"
    for sub in ("left", "disparity"):
        (root / sub).mkdir(parents=True)
    for i, f in enumerate(scene.frames):
        Image.fromarray(f.rgb).save(root / "left" / f"{i:03d}.png")
        write_pfm(root / "disparity" / f"{i:03d}.pfm", cam.fx * B / f.depth)
    out = tmp_path / "out"
    args = ["demo", "--input", str(root), "--stereo", "--intrinsics", _intrinsics(cam), "--out", str(out),
            "--no-progress", "--no-real-data", "--no-gif", "--dt", "0.1"]
    assert main([*args, "--baseline", str(B)]) == 0
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["frames"] == 5 and summary["input"].startswith("stereo")
    assert not (out / "tracks.gif").exists()
    assert main(args) == 2  # no baseline
