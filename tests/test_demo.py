"""The main job end to end on a small scene: files written, metrics sane, report self-contained."""

import base64
import io
import json
import shutil
from html.parser import HTMLParser

import numpy as np
import pytest
from PIL import Image

from flowtrack.pipeline import METHODS, RGBD_METHOD, detection_pieces, detections_from_clusters
from flowtrack.synth import make_scene
from flowtrack_course.cli import main
from flowtrack_course.demo import DemoConfig
from oracles import assert_same_run, assert_same_text_numbers

FRAMES, AHEAD = 12, 3
PROMISED = ("flow_field.png", "clusters_3d.png", "trajectories.png", "tracks.gif", "motorcycle_flow.png",
            "tud_campus_tracks.png", "tracks.csv", "metrics.json", "metrics.md", "report.html")
TRACKS_HEADER = "frame,track_id,status,x,y,z,vx,vy,vz"  # the contract (shared/API.md), spelled out


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
    # the Motorcycle case is a cloud without images: the point-cloud methods only
    assert list(summary["motorcycle"]["scene_flow"]) == list(METHODS)
    assert list(sf) == [*METHODS, RGBD_METHOD]


def test_the_rgbd_flow_row_meets_the_issue_bar(summary):
    """Moving-point EPE3D of the variational RGB-D flow <= 0.5x nearest neighbour's, and
    static points (all points' EPE is mostly static ones) within 2 mm per frame."""
    sf = summary["scene_flow"]
    rgbd = sf[RGBD_METHOD]
    assert rgbd["moving"]["epe3d"] <= 0.5 * sf["nearest-neighbour"]["moving"]["epe3d"], rgbd
    assert rgbd["all"]["epe3d"] <= 0.002, rgbd
    assert "variational RGB-D" in summary["seconds_per_pair"]


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
    assert len(parser.imgs) >= 6  # flow field, clusters, trajectories, GIF, Motorcycle, TUD-Campus
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
    from flowtrack_course.demo.figures import cluster_colours

    truth = np.array([0, 1, 1, 1, 2, 2, 0, 3, 3])
    clusters = np.array([-1, 5, 5, 0, 0, 0, 2, 2, -1])  # 5 ~ object 1, 0 ~ object 2, 2 ~ object 3
    assert cluster_colours(clusters, truth) == {0: 2, 2: 3, 5: 1}
    # two clusters on one object: the larger keeps its colour, the other a free one (not 1..3)
    clusters = np.array([-1, 4, 4, 7, -1, -1, -1, -1, -1])
    got = cluster_colours(clusters, truth)
    assert got[4] == 1 and got[7] not in (0, 1, 2, 3)
    assert cluster_colours(np.array([0, 1, -1]), None) == {0: 1, 1: 2}


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
    Z, V = detections_from_clusters(P, labels, flow, cfg)
    assert len(Z) == 3  # without the next frame the static patch cannot be told apart
    dt = 0.1
    Y = np.vstack([table, blobs[0] + dt * flow[6000], blobs[1] + dt * flow[6400], patch])
    Z, V = detections_from_clusters(P, labels, flow, cfg, next_points=Y, dt=dt)
    order = np.argsort(Z[:, 0])
    np.testing.assert_allclose(Z[order], [blobs[1].mean(axis=0), blobs[0].mean(axis=0)], atol=1e-12)
    np.testing.assert_allclose(V[order], [[0.0, -0.1, 0.0], [0.1, 0.0, 0.0]], atol=1e-12)
    # the pieces behind those detections are the two blobs' index sets, in the detections' order
    pieces = detection_pieces(P, labels, flow, cfg, next_points=Y, dt=dt)
    assert sorted(map(tuple, pieces)) == [tuple(range(6000, 6400)), tuple(range(6400, 6800))]
    np.testing.assert_allclose([P[p].mean(axis=0) for p in pieces], Z, atol=1e-12)
    with pytest.raises(ValueError, match="dt"):
        detections_from_clusters(P, labels, flow, cfg, next_points=Y)


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
        detections_from_clusters(config=DemoConfig(), **args)


# ------------------------------------------------------------------------------------------------
# the TUD-Campus figure
# ------------------------------------------------------------------------------------------------
def _section_html(text: str, title_part: str) -> str:
    """The HTML of the report section whose title contains ``title_part`` (up to the next one)."""
    parts = text.split("<h2 ")
    hits = [p for p in parts[1:] if title_part in p.split("</h2>")[0]]
    assert len(hits) == 1, title_part
    return hits[0]


def test_tud_campus_section_has_its_figure(demo_out, summary):
    html = _section_html((demo_out / "report.html").read_text(encoding="utf-8"), "TUD-Campus")
    assert html.count("<img ") == 1 and "data:image/png;base64," in html
    assert "<table>" in html  # the metrics table is still there
    assert summary["figures"]["tud_campus"].endswith("tud_campus_tracks.png")
    with Image.open(demo_out / "tud_campus_tracks.png") as im:
        assert im.format == "PNG" and im.width >= 1000


def test_tud_campus_figure_shows_the_scored_run():
    """The frames behind the figure are the run that track_tud_campus scores, matched as clear_mot does."""
    from flowtrack.datasets import track_tud_campus
    from flowtrack.metrics import clear_mot

    for seed in (0, 1):
        scored, centres, hyp = track_tud_campus(seed=seed, return_frames=True)
        assert scored == track_tud_campus(seed=seed)  # the same run either way
        max_dist = scored["max_dist"]
        mine = clear_mot(centres, hyp, max_dist)
        for key in ("mota", "motp", "idf1", "id_switches", "fp", "fn", "matches", "num_objects"):
            assert mine[key] == scored[key], (seed, key)
        _, matches, switches = clear_mot(centres, hyp, max_dist, return_matches=True)
        assert len(switches) == mine["id_switches"] > 0
        assert sum(map(len, matches)) == mine["matches"] + mine["id_switches"]
        assert sum(len(f) for f in hyp) - sum(map(len, matches)) == mine["fp"]


# ------------------------------------------------------------------------------------------------
# the "Reproduce" box
# ------------------------------------------------------------------------------------------------
def _reproduce_box(out) -> str:
    html = _section_html((out / "report.html").read_text(encoding="utf-8"), "Reproduce")
    return html.split("<pre>")[1].split("</pre>")[0]


def test_reproduce_box_shows_the_options_of_this_run(demo_out, summary):
    import html
    import shlex

    cmd = summary["reproduce"]
    assert shlex.split(cmd) == ["flowtrack", "demo", "--out", str(demo_out), "--frames", str(FRAMES),
                                "--height", "180", "--width", "240", "--predict-ahead", str(AHEAD)]
    assert html.unescape(_reproduce_box(demo_out)).splitlines()[0] == cmd


_SYNTH = dict(n_objects=3, n_frames=24, image_size=(240, 320), seed=0, noise=0.002, config=None,
              scenario="mixed", predict_ahead=5, input_dir=None, input_options=None, real_data=True, gif=True)
# what `flowtrack demo` passes as input_options (TUM RGB-D and stereo), and options an API caller may pass
_TUM_CLI = {"intrinsics": "tum-fr1", "step": 1, "depth_scale": 5000.0, "max_difference": 0.02, "dt": None}
_STEREO_CLI = {"intrinsics": "1,1,1,1", "step": 1, "stereo": True, "baseline": 0.5, "disparity_scale": 256.0,
               "doffs": 0.0, "dt": 0.1}


@pytest.mark.parametrize("change", [
    {},
    {"n_frames": 7, "seed": 4, "predict_ahead": 2, "gif": False, "real_data": False},
    {"n_objects": 4, "scenario": "crossing", "image_size": (120, 160)},
    {"input_dir": "my seq", "input_options": _TUM_CLI},
    {"input_dir": "seq", "seed": 2, "n_frames": 9, "n_objects": 5,  # n_objects: ignored with input
     "input_options": _TUM_CLI | {"step": 3, "depth_scale": 1000.0, "max_difference": 0.05, "dt": 1 / 30,
                                  "intrinsics": (525.0, 525.0, 319.5, 239.5)}},
    {"input_dir": "st", "input_options": _STEREO_CLI},
    {"input_dir": "st", "gif": False,
     "input_options": _STEREO_CLI | {"disparity_scale": 100.0, "doffs": 31.086, "dt": 0.2, "step": 2}},
    {"input_dir": "seq", "input_options": {"intrinsics": "2,2,1,1"}},  # an API call: CLI defaults omitted
])
def test_reproduce_command_round_trips_through_the_cli(change, monkeypatch, tmp_path):
    """The command of the box, parsed by `flowtrack demo`, calls run_demo with the same arguments."""
    import inspect
    import shlex

    import flowtrack_course.demo.run as demo_run
    from flowtrack.rgbd_io import load_stereo_sequence, load_tum_sequence
    from flowtrack_course.demo.reproduce import reproduce_command

    kwargs = _SYNTH | {"out": str(tmp_path / "o u t")} | change
    cmd = reproduce_command(**kwargs)
    argv = shlex.split(cmd)
    assert argv[:2] == ["flowtrack", "demo"], cmd
    seen = {}
    monkeypatch.setattr(demo_run, "run_demo", lambda **kw: seen.update(kw))
    assert main(argv[1:]) == 0
    keys = ["n_frames", "seed", "predict_ahead", "real_data", "gif", "input_dir"]
    if kwargs["input_dir"] is None:
        keys += ["n_objects", "image_size", "scenario"]
    assert str(seen["out"]) == kwargs["out"]
    assert {k: seen[k] for k in keys} == {k: kwargs[k] for k in keys}, cmd
    if kwargs["input_dir"] is not None:
        def effective(opts):  # every loader keyword the CLI can set, None and absent meaning the default
            opts = dict(opts)
            loader = load_stereo_sequence if opts.pop("stereo", False) else load_tum_sequence
            d = {k: p.default for k, p in inspect.signature(loader).parameters.items()
                 if k not in ("root", "max_frames")}
            d.update({k: v for k, v in opts.items() if v is not None})
            if not isinstance(d["intrinsics"], str):
                d["intrinsics"] = ",".join(repr(float(v)) for v in d["intrinsics"])
            return d

        assert bool(seen["input_options"].get("stereo")) == bool(kwargs["input_options"].get("stereo"))
        assert effective(seen["input_options"]) == effective(kwargs["input_options"]), cmd


@pytest.mark.parametrize("change", [
    {"noise": 0.004},
    {"config": DemoConfig(lam=2.0, max_points=5000), "seed": 3},
    {"input_dir": "it's here", "input_options": {"intrinsics": "1,1,1,1", "max_frames": 3}},
])
def test_reproduce_command_without_cli_options_is_a_python_call(change, monkeypatch):
    """Arguments the command line cannot express give a `python -c` call of run_demo with them all."""
    import inspect
    import shlex

    import flowtrack_course.demo.run as demo_run
    from flowtrack_course.demo.reproduce import reproduce_command

    kwargs = _SYNTH | {"out": "out"} | change
    argv = shlex.split(reproduce_command(**kwargs))
    assert argv[:2] == ["python", "-c"]
    seen = {}
    signature = inspect.signature(demo_run.run_demo)
    monkeypatch.setattr(demo_run, "run_demo", lambda **kw: seen.update(kw))
    exec(argv[2], {})
    bound = signature.bind(**seen)
    bound.apply_defaults()
    got = dict(bound.arguments)
    want = dict(kwargs)
    if want["input_dir"] is not None:  # the synthetic scene's settings are not written out then
        for k in ("n_objects", "image_size", "noise", "scenario"):
            want[k] = got[k]
    want["config"] = want["config"] or DemoConfig()
    got["config"] = got["config"] or DemoConfig()
    got["image_size"] = tuple(got["image_size"])
    assert {k: got[k] for k in want} == want


#: Reruns of the demo: metrics are means over thousands of points and frames, so last-bit differences
#: of the solvers (BLAS, CHOLMOD, open3d) move them by ~1e-14 relative; 1e-9 is far above that and far
#: below any real change (a changed estimate moves a metric in its 2nd or 3rd digit).
RERUN_RTOL = 1e-9


def _comparable(summary: dict) -> dict:
    """A summary without what legitimately changes between runs (timings, output paths)."""
    drop = ("seconds_per_pair", "total_seconds", "figures", "reproduce")
    s = {k: v for k, v in summary.items() if k not in drop}
    if "motorcycle" in s:
        s["motorcycle"] = {k: v for k, v in s["motorcycle"].items() if k != "seconds"}
    return s


def test_the_command_in_the_box_reproduces_a_run_on_a_tum_sequence(tmp_path):
    """`--input` with options: the box shows them, and running the box's command gives the same report."""
    import html
    import shlex

    from flowtrack.rgbd_io import write_tum_sequence

    scene = make_scene(n_objects=2, n_frames=6, image_size=(96, 128), seed=3)
    seq = write_tum_sequence(tmp_path / "my seq", [f.rgb for f in scene.frames],
                             [f.depth for f in scene.frames], [100.0 + i * scene.dt for i in range(6)],
                             depth_scale=1000.0)
    cam = scene.camera
    intrinsics = f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}"
    out = tmp_path / "out"
    argv = ["demo", "--out", str(out), "--input", str(seq), "--intrinsics", intrinsics, "--depth-scale",
            "1000", "--step", "1", "--seed", "2", "--frames", "5", "--predict-ahead", "2", "--no-real-data",
            "--no-gif", "--no-progress"]
    assert main(argv) == 0
    first = json.loads((out / "metrics.json").read_text())
    cmd = html.unescape(_reproduce_box(out)).splitlines()[0]
    assert cmd == first["reproduce"]
    assert shlex.split(cmd) == ["flowtrack", "demo", "--out", str(out), "--frames", "5", "--seed", "2",
                                "--predict-ahead", "2", "--no-gif", "--no-real-data", "--input", str(seq),
                                "--intrinsics", intrinsics, "--depth-scale", "1000.0"]
    assert "your own TUM RGB-D sequence" not in _reproduce_box(out)  # the hint is for synthetic runs
    shutil.rmtree(out)
    assert main([*shlex.split(cmd)[1:], "--no-progress"]) == 0
    rerun = json.loads((out / "metrics.json").read_text())
    assert_same_run(_comparable(rerun), _comparable(first), RERUN_RTOL)


def test_two_runs_with_the_same_seed_are_identical(demo_out, summary, tmp_path):
    """Same seed, same tracks: every count and id exactly, every float metric to RERUN_RTOL.

    open3d runs on one thread (see run_demo), so on one machine the runs are in fact bit-identical;
    the tolerance keeps the test true where BLAS/CHOLMOD kernels reduce in an alignment-dependent order.
    """
    import open3d as o3d

    from flowtrack_course.demo import run_demo

    before = o3d.utility.get_max_threads()
    during = []
    again = run_demo(tmp_path / "again", n_frames=FRAMES, image_size=(180, 240), predict_ahead=AHEAD,
                     progress=False, echo=lambda *a: during.append(o3d.utility.get_max_threads()))
    assert set(during) == {1}
    assert o3d.utility.get_max_threads() == before
    again = json.loads(json.dumps(again, default=str))  # as metrics.json has it
    assert_same_run(_comparable(again), _comparable(summary), RERUN_RTOL)
    assert_same_text_numbers((tmp_path / "again" / "metrics.md").read_text(),
                             (demo_out / "metrics.md").read_text(), "metrics.md")


def test_support_planes_is_repeatable():
    """open3d's RANSAC, seeded but multi-threaded, picked different planes from run to run."""
    from flowtrack.camera import backproject
    from flowtrack.pipeline import support_planes

    scene = make_scene(n_objects=3, n_frames=6, image_size=(120, 160), seed=0)
    for f in scene.frames:
        P = backproject(f.depth, scene.camera)[f.depth > 0]
        masks = {support_planes(P, DemoConfig()).tobytes() for _ in range(30)}
        assert len(masks) == 1


def test_open3d_threads_without_set_max_threads_limits_openmp(monkeypatch):
    """open3d 0.19 (OpenMP, no set_max_threads): the OpenMP runtimes are limited instead."""
    import open3d as o3d
    from threadpoolctl import threadpool_info

    from flowtrack.pipeline import open3d_threads

    def openmp_threads():
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "openmp"}

    if not openmp_threads():
        pytest.skip("no OpenMP runtime loaded in this process")
    before = openmp_threads()
    monkeypatch.delattr(o3d.utility, "set_max_threads", raising=False)
    with open3d_threads(1):
        assert openmp_threads() == {1}
    assert openmp_threads() == before
    with pytest.raises(ValueError, match="n"):
        with open3d_threads(0):
            pass


# ------------------------------------------------------------------------------------------------
# tracks.csv and the tracking ablation
# ------------------------------------------------------------------------------------------------
def _read_tracks(path):
    """tracks.csv with the csv module (not flowtrack.tracking_io): header line and typed rows."""
    import csv

    text = path.read_text()
    header = text.splitlines()[0]
    rows = []
    for r in csv.DictReader(io.StringIO(text)):
        rows.append({"frame": int(r["frame"]), "track_id": int(r["track_id"]), "status": r["status"],
                     "p": np.array([float(r[c]) for c in "xyz"]),
                     "v": np.array([float(r[c]) for c in ("vx", "vy", "vz")])})
    return header, rows


def _demo_scene(summary):
    """The demo's synthetic scene, rebuilt from metrics.json (as flowtrack_course.demo.inputs does)."""
    from flowtrack_course.demo.inputs import MIN_LAYOUT_FRAMES

    sc = summary["scene"]
    return make_scene(n_objects=sc["n_objects"], n_frames=max(sc["n_frames"] + AHEAD, MIN_LAYOUT_FRAMES),
                      image_size=tuple(sc["image_size"]), dt=summary["dt"], noise=sc["noise_m"],
                      seed=sc["seed"], scenario=sc["scenario"])


def test_tracks_csv_has_the_contract_columns_and_agrees_with_the_final_tracks(demo_out, summary):
    header, rows = _read_tracks(demo_out / "tracks.csv")
    assert header == TRACKS_HEADER
    # one block per processed frame t = 0 .. n-2 (the last frame has no flow pair), in order
    frames = [r["frame"] for r in rows]
    assert frames == sorted(frames) and set(frames) == set(range(FRAMES - 1))
    assert {r["status"] for r in rows} <= {"tentative", "confirmed", "coasting"}
    assert {r["status"] for r in rows if r["frame"] == 0} == {"tentative"}  # min_hits = 2
    for f in set(frames):
        ids = [r["track_id"] for r in rows if r["frame"] == f]
        assert ids == sorted(set(ids))
    # the last frame's rows are the tracks whose prediction metrics.json reports (reported tracks)
    last = {r["track_id"]: r for r in rows if r["frame"] == FRAMES - 2}
    for p in summary["prediction"]:
        row = last[p["track"]]
        assert row["status"] == p["status"] and p["from_frame"] == FRAMES - 2
        np.testing.assert_allclose(row["p"], p["last_position"], rtol=1e-15, atol=0)
        np.testing.assert_allclose(row["v"], p["velocity"], rtol=1e-15, atol=0)
    # every track that metrics.json counts appears, with its number of reported frames at most its rows
    for tid, n in summary["tracks"].items():
        assert sum(r["track_id"] == int(tid) for r in rows) >= n


def test_tracks_csv_positions_are_in_the_camera_frame_of_their_frame(demo_out, summary):
    """Independent of the tracker: the rendered scene's true surface centroids of the same frame."""
    from flowtrack_course.demo.inputs import surface_centroids

    scene = _demo_scene(summary)
    min_pixels = summary["tracking"]["min_visible_pixels"]
    _, rows = _read_tracks(demo_out / "tracks.csv")
    d_same, d_next, v_err, speed = [], [], [], []
    for r in rows:
        if r["status"] != "confirmed":
            continue
        now = surface_centroids(scene.frames[r["frame"]], min_pixels)
        nxt = surface_centroids(scene.frames[r["frame"] + 1], min_pixels)
        k = min(now, key=lambda k: np.linalg.norm(now[k] - r["p"]))
        d_same.append(np.linalg.norm(now[k] - r["p"]))
        if k in nxt:
            d_next.append(np.linalg.norm(nxt[k] - r["p"]))
            true_v = (nxt[k] - now[k]) / summary["dt"]  # m/s
            v_err.append(np.linalg.norm(r["v"] - true_v))
            speed.append(np.linalg.norm(true_v))
    assert len(d_same) >= 2 * (FRAMES - 3)
    # metres in the frame's own camera frame: well inside the match distance, and closer to this
    # frame's truth than to the next one's (objects move about 1.5 cm per frame)
    assert np.median(d_same) < 0.2 * summary["tracking"]["max_dist_m"]
    assert np.median(d_same) < np.median(d_next)
    # m/s (not m per frame): the velocity error is a fraction of the speed
    assert np.median(v_err) < 0.5 * np.median(speed), (np.median(v_err), np.median(speed))


def test_tracking_ablation_keys_and_sanity(summary):
    ab = summary["tracking_ablation"]
    assert set(ab) == {"position_only", "flow_aided"}
    for run in ab.values():
        assert {"mota", "idf1", "id_switches", "prediction_error_mm"} <= set(run)
        assert -1.0 <= run["mota"] <= 1.0 and 0.0 <= run["idf1"] <= 1.0
        assert isinstance(run["id_switches"], int) and run["id_switches"] >= 0
        # objects move ~15 mm per frame: predicting AHEAD frames must beat standing still by far
        assert 0.0 < run["prediction_error_mm"] < 15.0 * AHEAD, run
        assert run["ahead"] == AHEAD == summary["predict_ahead"]
    # the flow-aided run is the demo's own tracker on the same detections, scored the same way
    tr, fa, po = summary["tracking"], ab["flow_aided"], ab["position_only"]
    assert fa["mota"] == pytest.approx(tr["mota"], abs=1e-12)
    assert fa["idf1"] == pytest.approx(tr["idf1"], abs=1e-12)
    assert fa["id_switches"] == tr["id_switches"]
    # the bars: flow never costs identities nor MOTA (by more than 0.02), and predicts better
    assert fa["id_switches"] <= po["id_switches"]
    assert fa["mota"] >= po["mota"] - 0.02
    assert fa["prediction_error_mm"] < po["prediction_error_mm"]


def test_report_shows_the_ablation_table(demo_out, summary):
    import html as html_lib

    sec = _section_html((demo_out / "report.html").read_text(encoding="utf-8"), "Tracking ablation")
    assert sec.count("<table>") == 1
    text = html_lib.unescape(sec)
    assert f"prediction error {AHEAD} frames ahead (mm)" in text
    for name, key in (("position only", "position_only"), ("flow-aided", "flow_aided")):
        run = summary["tracking_ablation"][key]
        row = text.split("</caption>", 1)[1].split(name, 1)[1].split("</tr>")[0]
        assert f"{run['mota']:.3f}" in row and f"{run['idf1']:.3f}" in row, row
        assert f"{run['prediction_error_mm']:.1f}" in row, row
    md = (demo_out / "metrics.md").read_text()
    assert "| tracker | MOTA | IDF1 | ID switches |" in md


@pytest.mark.parametrize("layout", ["tum", "stereo", "tum-step"])
def test_input_sequence_writes_tracks_csv_from_the_trackers_history(layout, tmp_path, monkeypatch):
    """--input (TUM layout, or stereo with disparities): tracks.csv read back equals the demo tracker's
    history row by row, every frame read is tracked (the last one too) under its input frame index
    (``--step 2``: 0, 2, 4, ...), the ablation is skipped with a note, and the tracks sit on the objects."""
    import flowtrack.tracking as tracking_mod
    from flowtrack.rgbd_io import write_pfm
    from flowtrack_course.demo.inputs import surface_centroids
    from test_rgbd_io import _write_tum  # the TUM layout written with PIL alone (not by flowtrack)

    made = []

    class Spy(tracking_mod.MultiObjectTracker):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            made.append(self)

    monkeypatch.setattr(tracking_mod, "MultiObjectTracker", Spy)
    step = 2 if layout == "tum-step" else 1
    n = 7 * step
    scene = make_scene(n_objects=2, n_frames=n, image_size=(96, 128), seed=3, dt=0.1 / step)
    cam = scene.camera
    if layout.startswith("tum"):
        seq = _write_tum(tmp_path / "seq", scene)
        extra = ["--step", str(step)]
    else:
        seq, B = tmp_path / "stereo", 0.1
        for sub in ("left", "disparity"):
            (seq / sub).mkdir(parents=True)
        for i, f in enumerate(scene.frames):
            Image.fromarray(f.rgb).save(seq / "left" / f"{i:03d}.png")
            write_pfm(seq / "disparity" / f"{i:03d}.pfm", cam.fx * B / f.depth)
        extra = ["--stereo", "--baseline", str(B), "--dt", str(scene.dt)]
    out = tmp_path / "out"
    assert main(["demo", "--out", str(out), "--input", str(seq), "--intrinsics",
                 f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}", *extra, "--frames", str(n), "--no-real-data",
                 "--no-gif", "--no-progress"]) == 0
    assert len(made) == 1  # the demo's tracker (the ablation is skipped: no ground truth)
    trk = made[0]
    header, rows = _read_tracks(out / "tracks.csv")
    assert header == TRACKS_HEADER
    want = [(f * step, tr.id, tr.status, tr.position, tr.velocity) for f, tracks in trk.history()
            for tr in sorted(tracks, key=lambda t: t.id)]
    assert len(rows) == len(want) > 0
    assert {f for f, *_ in want} == set(range(0, n, step))
    for r, (f, tid, status, p, v) in zip(rows, want):
        assert (r["frame"], r["track_id"], r["status"]) == (f, tid, status)
        np.testing.assert_allclose(r["p"], p, rtol=1e-15, atol=0)  # repr() round-trips a float
        np.testing.assert_allclose(r["v"], v, rtol=1e-15, atol=0)
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["tracking_ablation"] is None
    sec = _section_html((out / "report.html").read_text(encoding="utf-8"), "Tracking ablation")
    assert "<table>" not in sec and "skipped" in sec
    # the confirmed tracks are on the two moving objects (true surface centroids, this frame)
    d = [min(np.linalg.norm(c - r["p"]) for c in surface_centroids(scene.frames[r["frame"]], 30).values())
         for r in rows if r["status"] == "confirmed"]
    assert len(d) >= n // step - 3 and np.median(d) < 0.03, d
