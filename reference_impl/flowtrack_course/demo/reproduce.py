"""The report's "Reproduce" command: the ``flowtrack demo`` command line of a run, built from the
CLI's own parser (:func:`flowtrack_course.demo.options.add_demo_arguments`), or a ``python -c`` call
when a setting has no option."""

from __future__ import annotations

import json
import numbers
import shlex
from dataclasses import fields
from pathlib import Path

import numpy as np

from .config import DEFAULT_NOISE, DemoConfig
from .options import DEMO_INPUT_OPTIONS, STEREO_DT, demo_parser

__all__ = ["reproduce_command"]

#: ``run_demo``'s arguments that ``flowtrack demo`` has an option for -> the option's ``dest``, in
#: the order of ``flowtrack demo --help`` (``image_size`` is two options; ``gif`` and ``real_data``
#: are switched off by ``--no-gif`` and ``--no-real-data``)
_OPTION_OF = {
    "n_objects": "objects", "n_frames": "frames", "image_size": ("height", "width"), "seed": "seed",
    "scenario": "scenario", "predict_ahead": "predict_ahead", "gif": "no_gif", "real_data": "no_real_data",
}


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _command_line_defaults() -> dict:
    """``run_demo``'s arguments as ``flowtrack demo`` sets them without options (read from its parser)."""
    d = vars(demo_parser().parse_args([]))
    out = {}
    for k, dest in _OPTION_OF.items():
        if isinstance(dest, tuple):
            out[k] = tuple(d[x] for x in dest)
        elif k in ("gif", "real_data"):
            out[k] = not d[dest]
        else:
            out[k] = d[dest]
    return out


def _intrinsics_text(spec) -> str:
    """``--intrinsics`` for an ``intrinsics`` value: a string or path as is, else ``fx,fy,cx,cy``."""
    from flowtrack.camera import PinholeCamera

    if isinstance(spec, (str, Path)):
        return str(spec)
    if isinstance(spec, PinholeCamera):
        spec = (spec.fx, spec.fy, spec.cx, spec.cy)
    return ",".join(repr(float(v)) for v in spec)


def _number_text(v) -> str:
    """A number as the command line reads it back exactly (``repr`` of the float, or the integer)."""
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        return repr(float(v))
    return str(v)


def _py(v) -> str:
    """A Python literal of ``v`` with double-quoted strings (so that it sits well in a shell's '...')."""
    if isinstance(v, (str, Path)):
        return json.dumps(str(v))
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_py(k)}: {_py(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        inner = ", ".join(_py(x) for x in v) + ("," if isinstance(v, tuple) and len(v) == 1 else "")
        return f"({inner})" if isinstance(v, tuple) else f"[{inner}]"
    if isinstance(v, (numbers.Number, np.generic)) and not isinstance(v, bool):
        return _number_text(v)
    return repr(v)


def reproduce_command(out, *, n_objects, n_frames, image_size, seed, noise, config, scenario, predict_ahead,
                       input_dir, input_options, real_data, gif) -> str:
    """The shell command that runs :func:`run_demo` again with these arguments (the report's "Reproduce").

    A ``flowtrack demo`` command line with the options whose value is not the default (arguments that
    the input ignores are left out); when an argument has no command-line option (``noise``, a
    non-default ``config``, an ``input_options`` key the command line does not know), a
    ``python -c`` call of :func:`run_demo` with the non-default arguments instead. Quoted for a POSIX
    shell.

    Examples
    --------
    >>> kw = dict(n_objects=3, n_frames=24, image_size=(240, 320), seed=0, noise=0.002, config=None,
    ...           scenario="mixed", predict_ahead=5, input_dir=None, input_options=None, real_data=True,
    ...           gif=True)
    >>> reproduce_command("out", **kw)
    'flowtrack demo --out out'
    >>> reproduce_command("my out", **(kw | {"n_frames": 12, "seed": 3, "gif": False}))
    "flowtrack demo --out 'my out' --frames 12 --seed 3 --no-gif"
    >>> opts = {"intrinsics": "tum-fr1", "step": 2, "dt": None}
    >>> reproduce_command("out", **(kw | {"input_dir": "seq", "input_options": opts, "n_frames": None}))
    'flowtrack demo --out out --input seq --intrinsics tum-fr1 --step 2'
    >>> cmd = reproduce_command("out", **(kw | {"noise": 0.004, "config": DemoConfig(lam=2.0)}))
    >>> shlex.split(cmd)[:2]
    ['python', '-c']
    >>> shlex.split(cmd)[2].split("; ")  # doctest: +NORMALIZE_WHITESPACE
    ['from flowtrack_course.demo import DemoConfig, run_demo',
     'run_demo(out="out", noise=0.004, config=DemoConfig(lam=2.0))']
    """
    default = {**_command_line_defaults(), "noise": DEFAULT_NOISE}
    synthetic = input_dir is None
    if synthetic and default["n_frames"] is None:  # --frames' default: 24 frames of the synthetic scene
        default["n_frames"] = 24
    opts = dict(input_options or {}) if not synthetic else {}
    stereo = bool(opts.pop("stereo", False))
    config = config if config is not None else DemoConfig()
    changed = {f.name: getattr(config, f.name) for f in fields(DemoConfig)
               if getattr(config, f.name) != f.default}
    args = {"n_objects": n_objects, "image_size": tuple(image_size), "scenario": scenario, "noise": noise}
    if not synthetic:  # the synthetic scene's settings do not matter
        args = {}
    args.update(n_frames=n_frames, seed=seed, predict_ahead=predict_ahead, real_data=real_data, gif=gif)
    args = {k: v for k, v in args.items() if v != default[k]}

    if "noise" in args or changed or set(opts) - set(DEMO_INPUT_OPTIONS):
        text = [f"out={_py(out)}"] + [f"{k}={_py(v)}" for k, v in args.items()]
        if changed:
            text.append("config=DemoConfig(" + ", ".join(f"{k}={_py(v)}" for k, v in changed.items()) + ")")
        if not synthetic:
            opts = dict(opts, stereo=True) if stereo else opts
            text += [f"input_dir={_py(input_dir)}", f"input_options={_py(opts)}"]
        return "python -c " + shlex.quote(
            f"from flowtrack_course.demo import DemoConfig, run_demo; run_demo({', '.join(text)})")

    cmd = ["flowtrack", "demo", "--out", str(out)]  # the options in the order of `flowtrack demo --help`
    switches = []
    for k, dest in _OPTION_OF.items():
        if k not in args:
            continue
        if isinstance(dest, tuple):
            for d, v in zip(dest, args[k]):
                cmd += [_flag(d), _number_text(v)]
        elif k in ("gif", "real_data"):
            switches.append(_flag(dest))
        else:
            cmd += [_flag(dest), _number_text(args[k])]
    cmd += switches
    if not synthetic:
        cmd += ["--input", str(input_dir)] + ["--stereo"] * stereo
        for k, v in opts.items():
            flag, kwargs = DEMO_INPUT_OPTIONS[k]
            if v is not None and v != (STEREO_DT if k == "dt" and stereo else kwargs["default"]):
                cmd += [flag, _intrinsics_text(v) if k == "intrinsics" else _number_text(v)]
    return " ".join(shlex.quote(c) for c in cmd)
