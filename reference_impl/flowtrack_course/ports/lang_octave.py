"""Run the MATLAB port on GNU Octave against the shared test vectors.

Sources: ``cpp_java_matlab_ports/octave/`` (``kalman_cv2d.m``, ``white_noise_q.m``,
``projection_jacobian.m``, ``variational_component.m`` and the test script ``run_vectors.m``, which
reads the vectors with ``jsondecode`` and prints ``CASE`` lines, see :mod:`flowtrack_course.ports.base`).
Nothing is compiled; ``build_dir`` is not used.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

from ..course import ports_dir
from .base import CaseResult, ToolchainMissing, harness_results

__all__ = ["LANGUAGES", "run"]

LANGUAGES: tuple[str, ...] = ("octave",)

def _src_dir() -> Path:
    """The Octave sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "octave"


def __getattr__(name: str) -> Path:
    if name == "SRC_DIR":  # read lazily: the course folder is chosen at run time
        return _src_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _octave() -> str:
    for name in ("octave-cli", "octave"):
        path = shutil.which(name)
        if path is not None:
            return path
    raise ToolchainMissing("octave not found: install Debian octave")


def _quote(path: Path) -> str:
    return "'" + str(path).replace("'", "''") + "'"


def run(vectors_dir: Path, build_dir: Path) -> list[CaseResult]:
    """Run ``run_vectors.m`` on ``vectors_dir`` with Octave.

    Parameters
    ----------
    vectors_dir : Path
        Directory with the ``<problem>.json`` vector files.
    build_dir : Path
        Unused (Octave needs no build); accepted for the common interface.

    Returns
    -------
    list of CaseResult
        One per (problem, case) of ``kalman_cv2d``, ``white_noise_q``, ``projection_jacobian``,
        ``variational_scene_flow``.

    Raises
    ------
    flowtrack_course.ports.base.ToolchainMissing
        Octave is not installed.
    """
    octave = _octave()
    cmd = [octave, "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--no-history"]
    cmd += ["--path", str(_src_dir()), "--eval", f"run_vectors({_quote(Path(vectors_dir).resolve())});"]
    return harness_results("octave", subprocess.run(cmd, capture_output=True, text=True, cwd=_src_dir()))
