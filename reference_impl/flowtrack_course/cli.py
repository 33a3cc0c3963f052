"""The ``flowtrack`` command line.

Every sub-command has ``--help``. The contracts (names, options, files written) are listed in the
project's API document; this module only parses arguments and calls the library.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from flowtrack import __version__

# Modules that add their own sub-commands: each has ``register(subparsers)`` which adds one or more
# parsers and sets ``func`` (called with the parsed namespace, returns the exit code). Keep their
# top-level imports light: ``flowtrack --help`` imports all of them.
_SUBCOMMAND_MODULES: tuple[str, ...] = (
    "flowtrack_course.ports.runner",
    "flowtrack_course.grading.cli",
)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {value}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {value}")
    return value


#: ``run_demo``'s ``input_options`` that ``flowtrack demo`` has an option for: key -> (option, its
#: argparse keywords). The one definition of these options: the parser is built from it and
#: :mod:`flowtrack_course.demo` writes a run's command line back from it (the "Reproduce" box).
DEMO_INPUT_OPTIONS: dict[str, tuple[str, dict]] = {
    "intrinsics": ("--intrinsics", dict(
        default=None, metavar="FX,FY,CX,CY",
        help="camera intrinsics: 'fx,fy,cx,cy', a file (fx fy cx cy or K) or a preset tum-fr1, "
        "tum-fr2, tum-fr3, ros-default (default: DIR/intrinsics.txt)")),
    "depth_scale": ("--depth-scale", dict(
        type=_positive_float, default=5000.0, help="depth PNG units per metre (default: 5000, TUM)")),
    "max_difference": ("--max-difference", dict(
        type=_positive_float, default=0.02,
        help="largest rgb/depth timestamp difference when associating (s, default: 0.02)")),
    "step": ("--step", dict(type=_positive_int, default=1, help="use every STEP-th frame (default: 1)")),
    "dt": ("--dt", dict(
        type=_positive_float, default=None,
        help="frame interval (s) when there are no timestamps (default: 1/30; stereo 0.1)")),
    "baseline": ("--baseline", dict(type=_positive_float, default=None, help="stereo baseline (m)")),
    "disparity_scale": ("--disparity-scale", dict(
        type=_positive_float, default=256.0,
        help="16-bit disparity PNG units per pixel (default: 256, KITTI); PFM is in pixels")),
    "doffs": ("--doffs", dict(
        type=float, default=0.0,
        help="added to the disparity d in Z = f B / (d + doffs) (Middlebury's doffs; 0)")),
}
STEREO_DT = 0.1  #: frame interval (s) of stereo input without --dt


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    input_options = None
    if args.input is not None:
        input_options = {"intrinsics": args.intrinsics, "step": args.step}
        if args.stereo:
            input_options.update(stereo=True, baseline=args.baseline, disparity_scale=args.disparity_scale,
                                 doffs=args.doffs, dt=args.dt or STEREO_DT)
        else:
            input_options.update(depth_scale=args.depth_scale, max_difference=args.max_difference, dt=args.dt)
    elif args.stereo or args.intrinsics is not None:
        raise ValueError("--stereo and --intrinsics need --input DIR")
    run_demo(
        out=Path(args.out),
        n_objects=args.objects,
        n_frames=args.frames,
        image_size=(args.height, args.width),
        seed=args.seed,
        progress=not args.no_progress,
        scenario=args.scenario,
        predict_ahead=args.predict_ahead,
        input_dir=args.input,
        input_options=input_options,
        real_data=not args.no_real_data,
        gif=not args.no_gif,
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="flowtrack",
        description="Scene flow and object tracking for robot manipulation: the course's reference tools.",
    )
    parser.add_argument("--version", action="version", version=f"flowtrack {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    demo = sub.add_parser(
        "demo",
        help="run the main job (RGB-D -> scene flow -> clusters -> tracks -> prediction), write report.html",
        description=(
            "RGB-D frames -> point clouds -> scene flow (nearest-neighbour, graph, graph + re-matching, "
            "rigid "
            "per cluster) -> motion clusters -> multi-object tracks -> prediction N frames ahead. Default "
            "input: a synthetic sequence with exact ground truth (metrics tables); --input DIR: your own "
            "sequence in the TUM RGB-D layout (rgb/, depth/ 16-bit PNGs, rgb.txt, depth.txt) or, with "
            "--stereo, left/, disparity/ (PFM or 16-bit PNG). Writes figures, tracks.gif, metrics.json, "
            "metrics.md and a self-contained report.html to --out."
        ),
    )
    demo.add_argument("--out", default="out", help="output folder (default: out)")
    demo.add_argument("--objects", type=_positive_int, default=3, help="moving objects (default: 3)")
    demo.add_argument("--frames", type=_positive_int, default=24,
                      help="frames to process (default: 24; with --input: at most this many)")
    demo.add_argument("--height", type=_positive_int, default=240, help="image height in pixels")
    demo.add_argument("--width", type=_positive_int, default=320, help="image width in pixels")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the synthetic scene")
    demo.add_argument("--scenario", default="mixed", choices=("mixed", "default", "crossing", "occlusion"),
                      help="synthetic scenario (default: mixed = a crossing and an occlusion)")
    demo.add_argument("--predict-ahead", type=_positive_int, default=5, metavar="N",
                      help="predict every track N frames ahead at the end (default: 5)")
    demo.add_argument("--no-progress", action="store_true", help="do not show progress bars")
    demo.add_argument("--no-gif", action="store_true", help="skip the animated tracks.gif")
    demo.add_argument("--no-real-data", action="store_true",
                      help="skip the Motorcycle and TUD-Campus sections")
    real = demo.add_argument_group("real input (--input)")
    real.add_argument("--input", metavar="DIR", default=None,
                      help="a TUM RGB-D layout folder (or a stereo folder with --stereo) instead of the "
                           "synthetic scene")
    real.add_argument("--stereo", action="store_true",
                      help="DIR holds left/, disparity/ (and optionally right/) instead of rgb/, depth/")
    for flag, kwargs in DEMO_INPUT_OPTIONS.values():
        real.add_argument(flag, **kwargs)
    demo.set_defaults(func=_cmd_demo)
    for module_name in _SUBCOMMAND_MODULES:
        importlib.import_module(module_name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"flowtrack {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
