"""The ``flowtrack`` command line.

Every sub-command has ``--help``. The contracts (names, options, files written) are listed in the
project's API document; this module only parses arguments and calls the library.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from . import __version__

# Modules that add their own sub-commands: each has ``register(subparsers)`` which adds one or more
# parsers and sets ``func`` (called with the parsed namespace, returns the exit code). Keep their
# top-level imports light: ``flowtrack --help`` imports all of them.
_SUBCOMMAND_MODULES: tuple[str, ...] = (
)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {value}")
    return value


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    run_demo(
        out=Path(args.out),
        n_objects=args.objects,
        n_frames=args.frames,
        image_size=(args.height, args.width),
        seed=args.seed,
        progress=not args.no_progress,
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
        help="run the main job on a synthetic RGB-D sequence and write figures and metrics",
        description=(
            "Synthetic RGB-D frames -> point clouds -> scene flow (nearest-neighbour, graph, rigid per "
            "cluster) -> motion clusters; prints a metrics table and writes figures to --out."
        ),
    )
    demo.add_argument("--out", default="out", help="output folder (default: out)")
    demo.add_argument("--objects", type=_positive_int, default=3, help="moving objects (default: 3)")
    demo.add_argument("--frames", type=_positive_int, default=12, help="frames to render (default: 12)")
    demo.add_argument("--height", type=_positive_int, default=240, help="image height in pixels")
    demo.add_argument("--width", type=_positive_int, default=320, help="image width in pixels")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the synthetic scene")
    demo.add_argument("--no-progress", action="store_true", help="do not show progress bars")
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
