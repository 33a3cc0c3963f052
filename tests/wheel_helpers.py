"""Build this checkout's wheel from a copy of its sources and run commands in fresh environments
(shared by the tests that install flowtrack outside the checkout)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(cmd, cwd, env, timeout=900) -> str:
    """Run ``cmd``; its stdout, or an assertion error that shows the end of both streams."""
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, (
        f"{cmd} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
    return proc.stdout


def clean_env() -> dict[str, str]:
    """This process's environment without what points at the checkout (FLOWTRACK_COURSE, PYTHONPATH)."""
    return {k: v for k, v in os.environ.items() if k not in ("FLOWTRACK_COURSE", "PYTHONPATH")}


def build_wheel(tmp: Path, env: dict[str, str]) -> Path:
    """The flowtrack wheel, built from a copy of the sources under ``tmp`` (building in the checkout
    would leave build/ and egg-info there)."""
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "reference_impl", src / "reference_impl",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info"))
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", tmp / "dist", src], tmp, env)
    (wheel,) = (tmp / "dist").glob("flowtrack-*.whl")
    return wheel
