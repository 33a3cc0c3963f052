"""The main job end to end on a small scene: files written, metrics sane, report self-contained."""

import base64
import io
import json
import shutil
from html.parser import HTMLParser

import numpy as np
import pytest
from PIL import Image

from flowtrack.cli import main
from flowtrack.demo import DemoConfig, detect_objects
from flowtrack.synth import make_scene

FRAMES, AHEAD = 12, 3
PROMISED = ("flow_field.png", "clusters_3d.png", "trajectories.png", "tracks.gif", "motorcycle_flow.png",
            "metrics.json", "metrics.md", "report.html")


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    code = main(["demo", "--out", str(out), "--frames", str(FRAMES), "--height", "180", "--width", "240",
                 "--predict-ahead", str(AHEAD), "--no-progress"])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def summary(demo_out):
    return json.loads((demo_out / "metrics.json").read_text())


def test_demo_writes_every_promised_file(demo_out):
    for name in PROMISED:
        f = demo_out / name
        assert f.is_file() and f.stat().st_size > 0, name


def test_scene_flow_metrics_are_sane(summary):
    sf = summary["scene_flow"]
    nn, graph = sf["nearest-neighbour"]["all"]["epe3d"], sf["graph"]["all"]["epe3d"]
    assert graph < nn, (graph, nn)
    assert sf["rigid per cluster"]["moving"]["epe3d"] < sf["nearest-neighbour"]["moving"]["epe3d"]
    for m in sf.values():
        assert 0.0 <= m["moving"]["acc3d_strict"] <= m["moving"]["acc3d_relax"] <= 1.0
    assert set(summary["motorcycle"]["scene_flow"]) == set(sf)


def test_tracking_metrics_are_sane(summary):
    tr = summary["tracking"]
    assert tr["mota"] >= 0.8, tr
    assert tr["idf1"] >= 0.8, tr
    # the track positions are centroids of the detected clusters: well inside the match distance
    assert 0.0 <= tr["motp"] < 0.3 * tr["max_dist_m"], tr
    assert tr["matches"] + tr["fn"] == tr["num_objects"]
    tud = summary["tud_campus_tracking"]
    assert tud["objects"] == 8 and tud["frames"] == 71 and tud["mota"] > 0.8


def test_prediction_is_the_kalman_filter_run_without_updates(summary):
    preds = summary["prediction"]
    assert len(preds) >= 3
    dt = summary["dt"]
    # independent of the tracker: F^N for the constant-velocity model [p, v] is [[I, N dt I], [0, I]]
    F = np.block([[np.eye(3), AHEAD * dt * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    for p in preds:
        x = np.concatenate([p["last_position"], p["velocity"]])
        np.testing.assert_allclose(p["predicted"], (F @ x)[:3], atol=1e-12)
        assert p["to_frame"] - p["from_frame"] == AHEAD
        assert np.linalg.eigvalsh(np.asarray(p["covariance"])).min() > 0
    scored = [p for p in preds if "error" in p]
    assert len(scored) == 3  # one per object
    # predicting with the estimated velocity beats standing still (objects move ~1.5 cm per frame)
    assert summary["prediction_mean_error_m"] < summary["prediction_mean_error_constant_position_m"]


def test_gif_has_one_frame_per_tracked_frame(demo_out):
    with Image.open(demo_out / "tracks.gif") as im:
        assert im.format == "GIF" and im.n_frames == FRAMES - 1


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.refs, self.tags = [], [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        for key in ("src", "href", "data", "poster"):
            if key in a and tag != "img":
                self.refs.append((tag, a[key]))


def test_report_is_self_contained(demo_out):
    text = (demo_out / "report.html").read_text(encoding="utf-8")
    parser = _Refs()
    parser.feed(text)
    assert "link" not in parser.tags and "iframe" not in parser.tags
    assert all(ref.startswith("#") for _, ref in parser.refs), parser.refs  # only in-page anchors
    assert "http://" not in text and "https://" not in text
    assert len(parser.imgs) >= 5  # flow field, clusters, trajectories, GIF, Motorcycle: all embedded
    formats = set()
    for src in parser.imgs:
        head, _, payload = src.partition(",")
        assert head in ("data:image/png;base64", "data:image/gif;base64"), head[:40]
        with Image.open(io.BytesIO(base64.b64decode(payload, validate=True))) as im:
            im.load()
            formats.add(im.format)
    assert formats == {"PNG", "GIF"}
    for section in ("Scene flow", "Tracking and prediction", "Middlebury Motorcycle", "TUD-Campus"):
        assert section in text, section


def test_metrics_md_holds_every_table(demo_out):
    md = (demo_out / "metrics.md").read_text()
    for header in ("| method | EPE3D all (mm)", "| MOTA | MOTP (mm) | IDF1 | ID switches", "| track | "
                                                                                          "status |",
                   "| people | frames | MOTA"):
        assert header in md, header


def test_demo_rejects_bad_options(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--frames", "1", "--no-progress"]) == 2
    assert "n_frames" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["demo", "--out", str(tmp_path), "--predict-ahead", "0"])
    assert "--predict-ahead" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path), "--objects", "2", "--no-progress"]) == 2
    assert "n_objects" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path), "--objects", "12", "--frames", "2", "--no-progress"]) == 2
    assert "n_objects=12 does not fit" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path), "--seed", "-1", "--no-progress"]) == 2
    assert "seed" in capsys.readouterr().err
    (tmp_path / "a_file").write_text("x")
    assert main(["demo", "--out", str(tmp_path / "a_file"), "--no-progress"]) == 2
    assert "out must be a folder" in capsys.readouterr().err


def test_full_report_opens_offline_in_headless_chromium(demo_out, tmp_path):
    """The report with every section (Motorcycle, TUD-Campus), alone in a folder, in a real browser."""
    from browser import check_pages

    alone = tmp_path / "alone" / "report.html"
    alone.parent.mkdir()
    shutil.copy(demo_out / "report.html", alone)
    problems = check_pages([alone], tmp_path / "shots")
    assert not problems, "\n".join(problems)
    assert len(list((tmp_path / "shots").glob("*.png"))) == 1


def test_cluster_colours_follow_the_largest_overlap():
    from flowtrack.demo import _cluster_colours

    truth = np.array([0, 1, 1, 1, 2, 2, 0, 3, 3])
    clusters = np.array([-1, 5, 5, 0, 0, 0, 2, 2, -1])  # 5 ~ object 1, 0 ~ object 2, 2 ~ object 3
    assert _cluster_colours(clusters, truth) == {0: 2, 2: 3, 5: 1}
    # two clusters on one object: the larger keeps its colour, the other a free one (not 1..3)
    clusters = np.array([-1, 4, 4, 7, -1, -1, -1, -1, -1])
    got = _cluster_colours(clusters, truth)
    assert got[4] == 1 and got[7] not in (0, 1, 2, 3)
    assert _cluster_colours(np.array([0, 1, -1]), None) == {0: 1, 1: 2}


def test_mixed_scenario_has_an_occlusion_and_a_crossing():
    sc = make_scene(n_objects=3, n_frames=24, image_size=(120, 160), scenario="mixed", seed=0)
    vis = np.array([[f.visible[k] for k in (1, 2, 3)] for f in sc.frames])
    # object 3 is fully hidden behind the static box for a while, in view before and after
    hidden3 = np.flatnonzero(vis[:, 2] == 0)
    assert len(hidden3) >= 2 and vis[0, 2] > 0 and vis[-1, 2] > 0
    assert np.all(np.diff(hidden3) == 1)
    # object 1 passes in front of object 2: 2 almost disappears, and their image order swaps
    assert vis[:, 1].min() < 0.05 * vis[:, 1].max()
    x = np.array([[sc.ground_truth_tracks("image", 0)[i][k][0] for k in (1, 2)] for i in (0, -1)])
    assert x[0, 0] < x[0, 1] and x[1, 0] > x[1, 1]
    with pytest.raises(ValueError, match="n_objects"):
        make_scene(n_objects=2, n_frames=3, scenario="mixed")


def test_detect_objects_removes_the_table_splits_pieces_and_skips_static_surface():
    rng = np.random.default_rng(0)
    table = np.column_stack([rng.uniform(-0.5, 0.5, 6000), rng.uniform(-0.5, 0.5, 6000),
                             rng.normal(0.0, 0.001, 6000)])
    blobs = [rng.uniform(-0.03, 0.03, (400, 3)) + c for c in ([0.1, 0.1, 0.05], [-0.2, 0.0, 0.05])]
    # a static vertical patch (the face of a box, too small to be a support plane)
    patch = np.column_stack([rng.uniform(0.2, 0.26, 300), np.full(300, 0.3), rng.uniform(0.02, 0.1, 300)])
    P = np.vstack([table, *blobs, patch])
    labels = np.full(len(P), -1)
    labels[6000:] = 0  # both blobs and the patch in one motion cluster (the graph reached them) ...
    near = np.flatnonzero(np.hypot(table[:, 0] - 0.1, table[:, 1] - 0.1) < 0.05)
    labels[near] = 0  # ... together with the table around the first blob (smoothed flow leaks there)
    flow = np.zeros_like(P)
    flow[6000:6400] = [0.1, 0.0, 0.0]
    flow[6400:6800] = [0.0, -0.1, 0.0]
    flow[6800:] = [0.1, 0.0, 0.0]  # the patch gets the first blob's rigid flow, tangential to it
    cfg = DemoConfig()
    Z, V = detect_objects(P, labels, flow, cfg)
    assert len(Z) == 3  # without the next frame the static patch cannot be told apart
    dt = 0.1
    Y = np.vstack([table, blobs[0] + dt * flow[6000], blobs[1] + dt * flow[6400], patch])
    Z, V = detect_objects(P, labels, flow, cfg, next_points=Y, dt=dt)
    order = np.argsort(Z[:, 0])
    np.testing.assert_allclose(Z[order], [blobs[1].mean(axis=0), blobs[0].mean(axis=0)], atol=1e-12)
    np.testing.assert_allclose(V[order], [[0.0, -0.1, 0.0], [0.1, 0.0, 0.0]], atol=1e-12)
    with pytest.raises(ValueError, match="dt"):
        detect_objects(P, labels, flow, cfg, next_points=Y)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"points": np.zeros((5, 2))}, "points"),
        ({"clusters": np.zeros(4, dtype=int)}, "clusters"),
        ({"clusters": np.zeros(5)}, "clusters"),
        ({"flow": np.zeros((5, 2))}, "flow"),
        ({"next_points": np.zeros((3, 2)), "dt": 0.1}, "next_points"),
        ({"next_points": np.zeros((3, 3)), "dt": 0.0}, "dt"),
    ],
)
def test_detect_objects_bad_input(kwargs, match):
    args = {"points": np.zeros((5, 3)), "clusters": np.zeros(5, dtype=int), "flow": np.zeros((5, 3))} | kwargs
    with pytest.raises(ValueError, match=match):
        detect_objects(cfg=DemoConfig(), **args)
