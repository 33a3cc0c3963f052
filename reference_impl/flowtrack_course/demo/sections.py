"""The demo report's sections and tables (HTML and Markdown through :mod:`flowtrack_course.report`), and
the summary printed at the end of a run."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..report import Figure, Section, Table

__all__ = ["ablation_table", "echo_summary", "flow_table", "prediction_table", "report_sections",
           "tracking_table"]

#: the runs of metrics.json["tracking_ablation"] and their names in the report
ABLATION_RUNS = {"position_only": "position only", "flow_aided": "flow-aided (RGB-D velocity)"}


def flow_table(metrics: dict[str, dict[str, dict[str, float]]], caption: str = "") -> Table:
    """FlowNet3D metrics of each scene-flow method, as a report table."""
    rows = []
    for name, m in metrics.items():
        a, mv = m["all"], m["moving"]
        rows.append([name, 1000 * a["epe3d"], 1000 * mv["epe3d"], mv["acc3d_strict"], mv["acc3d_relax"],
                     mv["outliers"]])
    return Table(["method", "EPE3D all (mm)", "EPE3D moving (mm)", "Acc3DS", "Acc3DR", "Outliers"], rows,
                 caption or "Acc3DS, Acc3DR and outliers are over the moving points (FlowNet3D thresholds).",
                 digits=[None, 2, 2, 3, 3, 3])


def tracking_table(tr: dict) -> Table:
    """CLEAR-MOT of the demo's tracks, as a report table."""
    return Table(["MOTA", "MOTP (mm)", "IDF1", "ID switches", "FP", "FN", "matches"],
                 [[tr["mota"], 1000 * tr["motp"], tr["idf1"], int(tr["id_switches"]), int(tr["fp"]),
                   int(tr["fn"]), int(tr["matches"])]],
                 "CLEAR-MOT (flowtrack.metrics.clear_mot) of the confirmed, detected tracks against the "
                 f"centroid of each object's visible surface; match distance {tr['max_dist_m']} m; "
                 f"objects with fewer than {tr['min_visible_pixels']} visible pixels are not expected.",
                 digits=[3, 1, 3, None, None, None, None])


def ablation_table(ablation: dict, ahead: int, max_dist: float) -> Table:
    """Position-only vs flow-aided tracking (``metrics.json["tracking_ablation"]``) as a report table."""
    rows = [[ABLATION_RUNS.get(k, k), r["mota"], r["idf1"], int(r["id_switches"]), r["prediction_error_mm"]]
            for k, r in ablation.items()]
    return Table(["tracker", "MOTA", "IDF1", "ID switches", f"prediction error {ahead} frames ahead (mm)"],
                 rows,
                 "The same detections tracked twice (flowtrack.tracking_eval.tracking_ablation): positions "
                 "only, and positions with each detection's RGB-D velocity and its covariance in the update "
                 f"(the run above). CLEAR-MOT at {max_dist} m; the prediction error is the mean distance "
                 f"between a matched track's prediction {ahead} frames ahead and the object's true surface "
                 "centroid then.", digits=[None, 3, 3, None, 1])


def prediction_table(preds: list, has_truth: bool, ahead: int) -> Table:
    """Every track's prediction ``ahead`` frames on (and, with ground truth, its errors)."""
    def mm(v):
        return None if v is None else 1000.0 * v

    rows = []
    for p in preds:
        sigma = float(np.sqrt(np.max(np.linalg.eigvalsh(np.asarray(p["covariance"])))))
        row = [p["track"], p["status"], *p["predicted"], mm(2 * sigma)]
        if has_truth:
            row += [p.get("object", "—"), mm(p.get("error")), mm(p.get("error_constant_position")),
                    p.get("mahalanobis")]
        rows.append(row)
    header = ["track", "status", "X (m)", "Y (m)", "Z (m)", "2σ largest (mm)"]
    digits = [None, None, 3, 3, 3, 1]
    if has_truth:
        header += ["object", "error (mm)", "constant-position error (mm)", "Mahalanobis"]
        digits += [None, 1, 1, 2]
    cap = (f"Each track predicted {ahead} frames ahead with the tracker's constant-velocity Kalman "
           "filter and no updates (camera coordinates).")
    if has_truth:
        cap += (" Error against the true centroid of the object's visible surface in that frame (its "
                "centre if hidden); the constant-position baseline keeps the last estimate; the "
                "Mahalanobis distance √(eᵀP⁻¹e) should mostly stay below 2.8 (95 % in 3-D).")
    return Table(header, rows, cap, digits=digits)


def report_sections(inp, summary, figures, real, tud) -> list[Section]:
    """The report's sections: input and pipeline, scene flow, tracking and prediction, real data,
    reproduce."""
    scene = inp.scene
    secs = []
    cam = inp.camera
    if scene is not None:
        sc = summary["scene"]
        intro = (f"{sc['n_objects']} rigid objects move on a table, rendered by exact ray casting at "
                 f"{sc['image_size'][1]}×{sc['image_size'][0]} px with {1000 * sc['noise_m']:.0f} mm "
                 f"depth noise; "
                 f"{inp.n} frames, Δt = {inp.dt} s (scenario '{sc['scenario']}': a tall object crosses "
                 f"in front of "
                 "another and hides it for a few frames, a third slides behind a static grey box).")
    else:
        intro = (f"{inp.name}: {inp.n} frames, Δt = {inp.dt:.4f} s, intrinsics fx={cam.fx}, fy={cam.fy}, "
                 f"cx={cam.cx}, cy={cam.cy}.")
    nog = "No ground truth for this input: the metrics need the synthetic scene (or your own labels)."
    s = Section("Input and pipeline", paragraphs=[
        intro,
        "Per frame pair: back-projection X = Z K⁻¹(u, v, 1)ᵀ; dense variational RGB-D scene flow from "
        "the two colour and depth images (brightness and depth constancy through the projection "
        "Jacobian, §2–3; flowtrack.sceneflow.rgbd_scene_flow); for comparison nearest neighbour, graph "
        "smoothing (§4), graph smoothing with re-matching and rigid ICP per motion cluster (§8); motion "
        "clustering of the RGB-D flow (Problem 5); one MultiObjectTracker step (§7) with the cluster "
        "pieces' centroids as detections and, as velocity measurements, the velocity of each piece's "
        "visible-surface centroid (its pixels carried into the next depth image by the flow) with the "
        "covariance of that estimate (visible_velocity_std), widened where the visible extent changes. "
        + ("A track is confirmed when its log-likelihood ratio of 'moving object' against 'clutter' "
           "(static surface leaking through the motion segmentation: flying pixels, depth-edge noise) "
           "passes Wald's threshold (flowtrack.tracking.SequentialScoreConfirmer). "
           if summary["config"].get("confirmation") == "score" else
           f"A track is confirmed after {summary['config']['min_hits']} detections. ")
        + "Every track of every frame is in tracks.csv (frame, track_id, status, x, y, z, vx, vy, vz; "
        "camera frame, m and m/s).",
        f"{summary['points_per_cloud']} points per cloud, {summary['detections_per_frame']:.1f} detections "
        f"per frame on average; seconds per frame pair: "
        + ", ".join(f"{k} {v:.3f}" for k, v in summary["seconds_per_pair"].items()) + ".",
    ])
    secs.append(s)
    s = Section("Scene flow", figures=[
        Figure(figures["flow_field"], "Scene flow of the first frame pair as image-plane arrows."),
        Figure(figures["clusters_3d"], "The first frame pair's cloud coloured by motion cluster (grey: "
               "static), each cluster in the colour of the true object it overlaps most. Graph "
               "smoothing leaks motion into the table, which can join objects; detection removes "
               "the support planes before tracking."
               if inp.scene is not None else
               "The first frame pair's cloud coloured by motion cluster (grey: static)."),
    ])
    if summary["scene_flow"] is not None:
        s.tables.append(flow_table(summary["scene_flow"]))
        s.paragraphs.append(
            "EPE3D is the mean end-point error of the per-frame displacement. Nearest-neighbour "
            "correspondences only see motion normal to a surface; graph smoothing removes noise but not "
            "that bias; re-matching recovers part of the tangential motion; rigid ICP per motion cluster "
            "more where the clusters are right. The variational RGB-D flow reads the tangential motion "
            "from the images' texture and is the flow that clustering and the tracker use. Motion "
            f"clustering: adjusted Rand index {summary['clustering_adjusted_rand_index']:.3f} against "
            "the true objects.")
    else:
        s.note = nog
    secs.append(s)
    s = Section("Tracking and prediction", figures=[Figure(figures["trajectories"],
                "Tracks with 2σ covariance ellipses and the final prediction.")])
    if "tracks" in figures:
        s.figures.append(Figure(figures["tracks"], "The tracks over the sequence (dashed ellipse: "
                                                   "coasting)."))
    if summary["tracking"] is not None:
        s.tables.append(tracking_table(summary["tracking"]))
    else:
        s.note = nog + " Tracks and predictions are still drawn."
    s.tables.append(prediction_table(summary["prediction"], scene is not None, summary["predict_ahead"]))

    if "prediction_mean_error_m" in summary:
        s.paragraphs.append(
            f"Mean prediction error {1000 * summary['prediction_mean_error_m']:.1f} mm "
            "(keeping the last position: "
            f"{1000 * summary['prediction_mean_error_constant_position_m']:.1f} mm).")
    secs.append(s)
    s = Section("Tracking ablation: position only vs flow-aided")
    ab = summary.get("tracking_ablation")
    if ab is not None:
        s.tables.append(ablation_table(ab, summary["predict_ahead"], summary["tracking"]["max_dist_m"]))
        s.paragraphs.append(
            "Scene flow enters the filter as a measurement (syllabus §5 and §7): with the velocity in the "
            "update a track's velocity follows the object's within a frame or two, so its prediction "
            "through an occlusion or a crossing is better and its gate tighter.")
    else:
        s.note = nog + " The ablation (position only vs flow-aided) is skipped."
    secs.append(s)
    if real is not None:
        s = Section("Real geometry: Middlebury Motorcycle", tables=[flow_table(real["scene_flow"])],
                    figures=[Figure(figures["motorcycle"], "Known and estimated scene flow on the "
                                    "Motorcycle cloud (300 random points as arrows).")],
                    paragraphs=[
                        f"The Middlebury 2014 Motorcycle stereo pair (shipped inside scikit-image) as a "
                        f"metric "
                        f"cloud of {real['points']} points, moved by a known global rigid motion with "
                        f"the front "
                        f"wheel turning: the same four methods against that exact flow. Motion "
                        f"clustering gives "
                        f"{real['clusters']} clusters (the cloud is spatially fragmented), purity "
                        f"{real['clustering_purity']:.3f} against the two true motions."])
        secs.append(s)
    if tud is not None:
        secs.append(Section("Real trajectories: MOT15 TUD-Campus", tables=[Table(
            ["people", "frames", "MOTA", "IDF1", "MOTP (px)", "ID switches", "FP", "FN"],
            [[int(tud["objects"]), int(tud["frames"]), tud["mota"], tud["idf1"], tud["motp"],
              int(tud["id_switches"]),
              int(tud["fp"]), int(tud["fn"])]],
            "MultiObjectTracker on the ground-truth box centres with 3 px noise and 10 % of detections "
            "dropped.")],
            paragraphs=["Real pedestrian trajectories (the MOT15 TUD-Campus ground truth that ships with "
                        "py-motmetrics), tracked by the same MultiObjectTracker in the image plane."],
            figures=[Figure(figures["tud_campus"],
                            "Left: the image x of every person's box centre (thick grey, P and the "
                            "person's id) and of every track (one colour per track id) over the "
                            f"{tud['frames']} frames; where people cross, identities get swapped. Right: "
                            "the track that the CLEAR-MOT matching assigns to each person in each frame, "
                            "so an ID switch is a change of colour (red bar) and a miss a hatched frame.")]))
    code = summary["reproduce"] + f"\n# this run took {summary['total_seconds']:.1f} s"
    if inp.scene is not None:
        code += "\n# your own TUM RGB-D sequence: flowtrack demo --input DIR --intrinsics fx,fy,cx,cy"
    secs.append(Section("Reproduce", code=code))
    return secs


def echo_summary(echo, inp, summary, sections, out) -> None:
    """Print the run's summary (tables in Markdown) through ``echo``."""
    echo("")
    echo(f"flowtrack demo: {inp.name}, {inp.n} frames, {inp.camera.width}x{inp.camera.height} px, "
         f"{summary['points_per_cloud']} points per cloud")
    if summary["scene_flow"] is not None:
        echo(flow_table(summary["scene_flow"]).markdown().split("\n\n")[0])
        echo(f"motion clustering: adjusted Rand index {summary['clustering_adjusted_rand_index']:.3f}")
        tr = summary["tracking"]
        ab = summary.get("tracking_ablation")
        if ab is not None:
            echo(ablation_table(ab, summary["predict_ahead"], tr["max_dist_m"]).markdown().split("\n\n")[0])
        echo(f"tracking: MOTA {tr['mota']:.3f}, MOTP {1000 * tr['motp']:.1f} mm, IDF1 {tr['idf1']:.3f}, "
             f"ID switches {tr['id_switches']}, FP {tr['fp']}, FN {tr['fn']}")
    else:
        echo("no ground truth for this input: scene-flow and tracking metrics are not computed")
    n_ahead = summary["predict_ahead"]
    line = f"prediction {n_ahead} frames ahead: {len(summary['prediction'])} tracks"
    if "prediction_mean_error_m" in summary:
        line += (f", mean error {1000 * summary['prediction_mean_error_m']:.1f} mm (constant position "
                 f"{1000 * summary['prediction_mean_error_constant_position_m']:.1f} mm)")
    echo(line)
    if "motorcycle" in summary:
        rows = summary["motorcycle"]["scene_flow"]
        echo("Motorcycle (real geometry), EPE3D mm: " + ", ".join(
            f"{m} {1000 * v['all']['epe3d']:.1f}" for m, v in rows.items()))
        t = summary["tud_campus_tracking"]
        echo(f"TUD-Campus (real trajectories): MOTA {t['mota']:.3f}, IDF1 {t['idf1']:.3f}, "
             f"ID switches {t['id_switches']}")
    echo(f"wrote {out}/: " + ", ".join(Path(p).name for p in summary["figures"].values())
         + ", tracks.csv, metrics.json, metrics.md, report.html")
    echo(f"done in {summary['total_seconds']:.1f} s")
