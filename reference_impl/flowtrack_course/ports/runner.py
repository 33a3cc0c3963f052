"""``flowtrack ports``: build and run every port on the shared vectors and print one table.

Each language of :data:`flowtrack_course.polyglot.toolchains.LANGUAGES` has a module
(:data:`LANG_MODULES`) that exposes ``PORTS`` (the port names it reports, e.g. ``("cpp-eigen",
"cpp-pcl")``) and ``run(vectors_dir, build_dir) -> list[CaseResult]``. The command fails (exit 1) on
any failed case, on a missing toolchain (never a silent skip), on a build or harness error and on a
port that reports no case at all.
"""

from __future__ import annotations

import argparse
import importlib
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

from ..course import add_course_option, ports_dir, use_course
from ..course import vectors_dir as _course_vectors
from ..polyglot.base import ToolchainMissing
from ..polyglot.toolchains import LANGUAGES
from ..polyglot.vectors import CaseResult, failure

__all__ = ["LANG_MODULES", "format_table", "register", "run_ports"]

#: ``--lang`` value -> module implementing that language family's ports (imported when run).
LANG_MODULES: dict[str, str] = {lang: f"flowtrack_course.polyglot.{lang}" for lang in LANGUAGES}


def __getattr__(name: str) -> Path:
    if name == "DEFAULT_BUILD_DIR":  # the build cache inside the course folder, looked up when read
        return ports_dir() / "build"
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def run_ports(
    langs: Iterable[str] | None = None,
    vectors_dir: Path | str | None = None,
    build_dir: Path | str | None = None,
    progress: bool = False,
) -> list[CaseResult]:
    """Build and run the ports of the given language families on a vectors folder.

    Parameters
    ----------
    langs : iterable of str, optional
        Keys of :data:`LANG_MODULES` (default: all).
    vectors_dir : path, optional
        Folder of ``<problem>.json`` vector files (default: the course's
        ``cpp_java_matlab_ports/vectors``, see :mod:`flowtrack_course.course`).
    build_dir : path, optional
        Build cache shared by the languages (each uses its own sub-folder; default: the course's
        ``cpp_java_matlab_ports/build``).
    progress : bool
        Show a tqdm progress bar over the language families.

    Returns
    -------
    list of CaseResult
        Every case result; a missing toolchain, a build/harness error or a port that reports no case
        becomes a failed result with problem ``toolchain``, ``error`` or ``no-cases``.
    """
    names = list(LANG_MODULES) if langs is None else list(langs)
    vectors_dir = _course_vectors() if vectors_dir is None else vectors_dir
    build_dir = ports_dir() / "build" if build_dir is None else build_dir
    for name in names:
        if name not in LANG_MODULES:
            raise ValueError(f"langs must be among {sorted(LANG_MODULES)}, got {name!r}")
    vectors_dir = Path(vectors_dir)
    if not vectors_dir.is_dir() or not any(vectors_dir.glob("*.json")):
        raise FileNotFoundError(
            f"vectors_dir {vectors_dir} holds no vector files (flowtrack ports --regenerate)"
        )
    build_dir = Path(build_dir)
    iterator: Iterable[str] = names
    if progress:
        from tqdm import tqdm

        iterator = tqdm(names, desc="ports", unit="language")
    results: list[CaseResult] = []
    for name in iterator:
        try:
            module = importlib.import_module(LANG_MODULES[name])
        except ImportError as exc:
            results.append(failure(name, "error", f"cannot import {LANG_MODULES[name]}: {exc}"))
            continue
        languages: Sequence[str] = getattr(module, "PORTS", (name,))
        try:
            got = list(module.run(vectors_dir, build_dir))
        except ToolchainMissing as exc:
            results += [failure(lang, "toolchain", str(exc)) for lang in languages]
            continue
        except Exception as exc:  # a broken build or harness is a reported failure, not a crash
            results += [failure(lang, "error", f"{type(exc).__name__}: {exc}") for lang in languages]
            continue
        results += got
        for lang in languages:
            if not any(r.language == lang for r in got):
                results.append(failure(lang, "no-cases", "the port reported no case"))
    return results


def _fmt_err(values: list[float]) -> str:
    finite = [v for v in values if not math.isnan(v)]
    if len(finite) < len(values):
        return "nan" if not finite else f"{max(finite):.2e} (+nan)"
    return f"{max(finite):.2e}" if finite else "-"


def format_table(results: Sequence[CaseResult]) -> str:
    """Markdown table: language, problem, cases passed, cases failed, worst absolute error.

    Examples
    --------
    >>> r = [CaseResult("cpp-eigen", "white_noise_q", "a", True, 0.0),
    ...      CaseResult("cpp-eigen", "white_noise_q", "b", False, 0.5, "off")]
    >>> print(format_table(r))
    | language  | problem       | passed | failed | worst error |
    |-----------|---------------|--------|--------|-------------|
    | cpp-eigen | white_noise_q |      1 |      1 |    5.00e-01 |
    """
    groups: dict[tuple[str, str], list[CaseResult]] = {}
    for r in results:
        groups.setdefault((r.language, r.problem), []).append(r)
    rows = [
        (
            lang,
            prob,
            str(sum(r.passed for r in rs)),
            str(sum(not r.passed for r in rs)),
            _fmt_err([r.max_error for r in rs]),
        )
        for (lang, prob), rs in groups.items()
    ]
    header = ("language", "problem", "passed", "failed", "worst error")
    widths = [max([len(header[i])] + [len(row[i]) for row in rows]) for i in range(5)]

    def line(cells) -> str:
        return (
            "| "
            + " | ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))
            + " |"
        )

    out = [line(header), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    out += [line(row) for row in rows]
    return "\n".join(out)


def _cmd_ports(args: argparse.Namespace) -> int:
    use_course(args.course, need=("cpp_java_matlab_ports",))
    if args.vectors is None:
        args.vectors = _course_vectors()
    if args.build_dir is None:
        args.build_dir = ports_dir() / "build"
    if args.regenerate:
        from .vectors import write_vectors

        written = write_vectors(args.vectors, progress=not args.no_progress)
        print(f"wrote {len(written)} vector files to {args.vectors}")
        if not args.lang:
            return 0
    results = run_ports(args.lang, args.vectors, args.build_dir, progress=not args.no_progress)
    print(format_table(results))
    failed = [r for r in results if not r.passed]
    for r in failed:
        print(f"FAIL {r.language} {r.problem} {r.case_id}: {r.message}")
    print(f"{len(results) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


def register(subparsers) -> None:
    """Add the ``ports`` sub-command to the ``flowtrack`` parser."""
    p = subparsers.add_parser(
        "ports",
        help="build and run the C++/Java/Octave/Mathics/block-diagram ports against the shared vectors",
        description=(
            "Builds every port (or those of --lang), runs it on every case of the vector files, prints "
            "a table (language, problem, cases passed/failed, worst error) and exits 1 on any mismatch, "
            "missing toolchain or port without cases. --regenerate rewrites the vector files from the "
            "Python reference (and runs the ports only when --lang is given too)."
        ),
    )
    p.add_argument(
        "--lang",
        action="append",
        choices=sorted(LANG_MODULES),
        help="language family to run (repeatable; default: all)",
    )
    p.add_argument("--regenerate", action="store_true", help="rewrite the vector files from the reference")
    add_course_option(p)
    p.add_argument("--vectors", type=Path, default=None,
                   help="vector folder (default: COURSE/cpp_java_matlab_ports/vectors)")
    p.add_argument("--build-dir", type=Path, default=None,
                   help="build cache (default: COURSE/cpp_java_matlab_ports/build)")
    p.add_argument("--no-progress", action="store_true", help="do not show progress bars")
    p.set_defaults(func=_cmd_ports)
