"""MATLAB on GNU Octave: the port on the shared vectors, and the grader's recipe for an answer.

**Port.** Sources: ``cpp_java_matlab_ports/octave/`` (``kalman_cv2d.m``, ``white_noise_q.m``,
``projection_jacobian.m``, ``variational_component.m`` and the test script ``run_vectors.m``, which
reads the vectors with ``jsondecode`` and prints ``CASE`` lines, see
:mod:`flowtrack_course.polyglot.vectors`). Nothing is compiled; ``build_dir`` is not used.

**Answers.** A student writes the function file ``<problem>.m``; the grader's
``files/octave/ft_harness.m`` calls it on every case and prints ``OUTPUT`` lines (~0.4 s of CPU per
item). Nothing is built.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

from ..course import ports_dir
from .base import Toolchain, executable, support_text
from .vectors import CaseResult, harness_results

__all__ = ["PORTS", "TOOLCHAIN", "run"]

#: The ports this module runs (the names in ``flowtrack ports``' table).
PORTS: tuple[str, ...] = ("octave",)


@dataclass(frozen=True)
class OctaveToolchain(Toolchain):
    """An answer in Octave: a function file called by the grader's ``ft_harness.m``."""

    def support_files(self, problem: str) -> dict[str, str]:
        return {"ft_harness.m": support_text("octave", "ft_harness.m")}

    def run_command(self, problem: str) -> list[str]:
        return [
            "octave-cli",
            "--norc",
            "--no-history",
            "--quiet",
            "--no-window-system",
            "--eval",
            f"ft_harness('{problem}', 'cases.json', false);",
        ]

    def bundle_files(self, problem: str) -> dict[str, str]:
        return {
            "ft_harness.m": support_text("octave", "ft_harness.m"),
            "run_public_tests.m": (
                f"% Run the public tests of {problem}:  octave-cli --norc run_public_tests.m\n"
                f"ok = ft_harness('{problem}', 'public.json', true);\nif ~ok\n  exit(1);\nend\n"
            ),
        }


TOOLCHAIN = OctaveToolchain(
    "octave",
    "Octave (MATLAB syntax)",
    requirements=(executable("octave-cli", package="octave"),),
    extension=".m",
    todo="% YOUR CODE HERE",
)


def _src_dir() -> Path:
    """The Octave sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "octave"



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
    flowtrack_course.polyglot.base.ToolchainMissing
        Octave is not installed.
    """
    TOOLCHAIN.check(ports=True)
    cmd = ["octave-cli", "--no-gui", "--no-window-system", "--quiet", "--no-init-file", "--no-history"]
    cmd += ["--path", str(_src_dir()), "--eval", f"run_vectors({_quote(Path(vectors_dir).resolve())});"]
    return harness_results("octave", subprocess.run(cmd, capture_output=True, text=True, cwd=_src_dir()))
