"""Run every benchmark script and collect their tables into benchmarks/RESULTS.md.

Each ``bench_*.py`` measures flowtrack against a peer in the same process (these machines are noisy,
so only ratios measured side by side are meaningful) and writes its table to ``results/<name>.md``.
Usage: ``python benchmarks/run_all.py [--quick]``; ``--collect`` only rebuilds RESULTS.md from the
tables already in ``results/`` (after running one script by hand). Either then regenerates the
README's headline numbers (``benchmarks/headline.py``).
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small problem sizes (smoke run)")
    parser.add_argument(
        "--collect", action="store_true", help="run nothing: rebuild RESULTS.md from results/*.md"
    )
    args = parser.parse_args()
    scripts = [] if args.collect else sorted(HERE.glob("bench_*.py"))
    failed = []
    for script in scripts:
        print(f"== {script.name}", flush=True)
        cmd = [sys.executable, str(script)] + (["--quick"] if args.quick else [])
        if subprocess.call(cmd) != 0:
            failed.append(script.name)
    if args.quick:
        return 1 if failed else 0
    parts = [
        "# Benchmark results",
        "",
        "Every number below is a ratio (or an absolute figure beside its peer) measured in one run on the",
        "machine named here; rerun with `make bench`. Targets come from the issues.",
        "",
        f"- machine: {platform.machine()}, {platform.processor() or 'unknown CPU'}, "
        f"Python {platform.python_version()}",
        f"- date: {time.strftime('%Y-%m-%d')}",
        "",
    ]
    for md in sorted((HERE / "results").glob("*.md")):
        parts += [md.read_text().rstrip(), ""]
    (HERE / "RESULTS.md").write_text("\n".join(parts))
    print("wrote", HERE / "RESULTS.md")
    sys.path.insert(0, str(HERE))
    import headline  # the README's table of headline numbers, from the new results

    headline.main([])
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
