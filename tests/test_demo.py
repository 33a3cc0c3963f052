"""The main job end to end on a small scene: files written, metrics sane."""

import json

import pytest

from flowtrack.cli import main


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    code = main(["demo", "--out", str(out), "--frames", "4", "--height", "120", "--width", "160",
                 "--no-progress"])
    assert code == 0
    return out


def test_demo_writes_every_promised_file(demo_out):
    for name in ("flow_field.png", "clusters_3d.png", "metrics.json", "metrics.md"):
        f = demo_out / name
        assert f.is_file() and f.stat().st_size > 0, name


def test_demo_metrics_are_sane(demo_out):
    summary = json.loads((demo_out / "metrics.json").read_text())
    sf = summary["scene_flow"]
    nn, graph = sf["nearest-neighbour"]["all"]["epe3d"], sf["graph"]["all"]["epe3d"]
    assert graph < nn, (graph, nn)
    assert sf["rigid per cluster"]["moving"]["epe3d"] < sf["nearest-neighbour"]["moving"]["epe3d"]
    for m in sf.values():
        assert 0.0 <= m["moving"]["acc3d_strict"] <= m["moving"]["acc3d_relax"] <= 1.0


def test_demo_rejects_a_single_frame(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--frames", "1", "--no-progress"]) == 2
    assert "n_frames" in capsys.readouterr().err
