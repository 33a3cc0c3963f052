"""``flowtrack demo``'s options, defined once: the CLI's parser is built from
:func:`add_demo_arguments`, and the report's "Reproduce" command (:mod:`.reproduce`) reads the same
parser back. Standard library only: ``flowtrack --help`` imports this module."""

from __future__ import annotations

import argparse

from ..argtypes import positive_float, positive_int

__all__ = ["DEMO_INPUT_OPTIONS", "STEREO_DT", "add_demo_arguments", "demo_parser"]

#: ``run_demo``'s ``input_options`` that ``flowtrack demo`` has an option for: key -> (option, its
#: argparse keywords).
DEMO_INPUT_OPTIONS: dict[str, tuple[str, dict]] = {
    "intrinsics": ("--intrinsics", dict(
        default=None, metavar="FX,FY,CX,CY",
        help="camera intrinsics: 'fx,fy,cx,cy', a file (fx fy cx cy or K) or a preset tum-fr1, "
        "tum-fr2, tum-fr3, ros-default (default: DIR/intrinsics.txt)")),
    "depth_scale": ("--depth-scale", dict(
        type=positive_float, default=5000.0, help="depth PNG units per metre (default: 5000, TUM)")),
    "max_difference": ("--max-difference", dict(
        type=positive_float, default=0.02,
        help="largest rgb/depth timestamp difference when associating (s, default: 0.02)")),
    "step": ("--step", dict(type=positive_int, default=1, help="use every STEP-th frame (default: 1)")),
    "dt": ("--dt", dict(
        type=positive_float, default=None,
        help="frame interval (s) when there are no timestamps (default: 1/30; stereo 0.1)")),
    "baseline": ("--baseline", dict(type=positive_float, default=None, help="stereo baseline (m)")),
    "disparity_scale": ("--disparity-scale", dict(
        type=positive_float, default=256.0,
        help="16-bit disparity PNG units per pixel (default: 256, KITTI); PFM is in pixels")),
    "doffs": ("--doffs", dict(
        type=float, default=0.0,
        help="added to the disparity d in Z = f B / (d + doffs) (Middlebury's doffs; 0)")),
}
STEREO_DT = 0.1  #: frame interval (s) of stereo input without --dt


def add_demo_arguments(demo: argparse.ArgumentParser) -> None:
    """Add every option of ``flowtrack demo`` to ``demo`` (the CLI's sub-parser, or :func:`demo_parser`)."""
    demo.add_argument("--out", default="out", help="output folder (default: out)")
    demo.add_argument("--objects", type=positive_int, default=3, help="moving objects (default: 3)")
    demo.add_argument("--frames", type=positive_int, default=None,
                      help="frames to process (default: 24; with --input: every frame of the sequence)")
    demo.add_argument("--height", type=positive_int, default=240, help="image height in pixels")
    demo.add_argument("--width", type=positive_int, default=320, help="image width in pixels")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the synthetic scene")
    demo.add_argument("--scenario", default="mixed", choices=("mixed", "default", "crossing", "occlusion"),
                      help="synthetic scenario (default: mixed = a crossing and an occlusion)")
    demo.add_argument("--predict-ahead", type=positive_int, default=5, metavar="N",
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


def demo_parser() -> argparse.ArgumentParser:
    """A parser of ``flowtrack demo``'s arguments alone (the same options as the CLI's sub-command).

    Examples
    --------
    >>> args = demo_parser().parse_args(["--frames", "12", "--input", "seq", "--step", "2"])
    >>> args.frames, args.input, args.step, args.out
    (12, 'seq', 2, 'out')
    """
    parser = argparse.ArgumentParser(prog="flowtrack demo", add_help=False)
    add_demo_arguments(parser)
    return parser
