"""Build and run the C++ ports (Eigen, PCL) on the shared test vectors.

Sources: ``cpp_java_matlab_ports/cpp/`` (a CMake project, C++17). It is configured once into
``<build_dir>/cpp`` (Release) and rebuilt incrementally, so a second run with unchanged sources only
checks time stamps. Then

- ``harness_eigen VECTORS_DIR`` runs the Eigen port on every case of ``kalman_cv2d``,
  ``white_noise_q``, ``projection_jacobian``, ``mahalanobis_assignment``, ``graph_scene_flow`` and
  ``variational_scene_flow`` (language ``cpp-eigen``);
- ``harness_pcl VECTORS_DIR`` runs the PCL port on ``rigid_icp`` (language ``cpp-pcl``);
- ``ctest`` runs the GoogleTest unit tests, reported as problem ``unit_tests`` of the language whose
  part they test (``Eigen.*`` -> ``cpp-eigen``, ``Pcl.*`` -> ``cpp-pcl``).

Debian packages: ``g++ cmake make libeigen3-dev libpcl-dev nlohmann-json3-dev libgtest-dev``.
"""

from __future__ import annotations

import fcntl
import glob
import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

from ..course import ports_dir
from .base import CaseResult, ToolchainMissing, parse_case_lines

__all__ = [
    "LANGUAGES",
    "DEBIAN_PACKAGES",
    "build",
    "check_toolchain",
    "run",
    "run_harness",
    "run_unit_tests",
]

LANGUAGES: tuple[str, ...] = ("cpp-eigen", "cpp-pcl")

def _src_dir() -> Path:
    """The C++ sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "cpp"


def __getattr__(name: str) -> Path:
    if name == "SRC_DIR":  # read lazily: the course folder is chosen at run time
        return _src_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
DEBIAN_PACKAGES = (
    "g++",
    "cmake",
    "make",
    "libeigen3-dev",
    "libpcl-dev",
    "nlohmann-json3-dev",
    "libgtest-dev",
)

_HARNESS = {"cpp-eigen": "harness_eigen", "cpp-pcl": "harness_pcl"}
_TEST_PREFIX = {"Eigen.": "cpp-eigen", "Pcl.": "cpp-pcl"}
_EXECUTABLES = {"cmake": "cmake", "make": "make", "g++": "g++"}
_HEADERS = {
    "/usr/include/eigen3/Eigen/Dense": "libeigen3-dev",
    "/usr/include/nlohmann/json.hpp": "nlohmann-json3-dev",
    "/usr/include/gtest/gtest.h": "libgtest-dev",
    "/usr/include/pcl-*/pcl/registration/icp.h": "libpcl-dev",
}


def check_toolchain() -> None:
    """Raise :class:`~flowtrack_course.ports.base.ToolchainMissing` naming the Debian packages to
    install, if any is missing."""
    missing = [pkg for exe, pkg in _EXECUTABLES.items() if shutil.which(exe) is None]
    missing += [pkg for pattern, pkg in _HEADERS.items() if not glob.glob(pattern)]
    if missing:
        raise ToolchainMissing(
            f"C++ ports: missing Debian packages {' '.join(missing)} "
            f"(install: apt-get install -y {' '.join(DEBIAN_PACKAGES)}, or `make test` does it)"
        )


def _run(cmd: list[str], what: str, timeout: float, cwd: Path | None = None) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=cwd)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-40:])
        raise RuntimeError(f"C++ ports: {what} failed (exit {proc.returncode}): {' '.join(cmd)}\n{tail}")
    return proc


def _configured_for(cache: Path, src: Path) -> bool:
    if not cache.exists():
        return False
    for line in cache.read_text(errors="replace").splitlines():
        if line.startswith("CMAKE_HOME_DIRECTORY:INTERNAL="):
            return Path(line.split("=", 1)[1]).resolve() == src.resolve()
    return False


def build(build_dir: Path | str, src_dir: Path | str | None = None) -> Path:
    """Configure (first time only) and build the CMake project; return ``<build_dir>/cpp``.

    Parameters
    ----------
    build_dir : path
        The ports' build cache (``cpp_java_matlab_ports/build`` by default in the runner).
    src_dir : path
        The CMake project.

    Raises
    ------
    flowtrack_course.ports.base.ToolchainMissing
        A compiler, CMake or a library is not installed.
    RuntimeError
        Configuration or compilation failed (the message holds the end of the compiler output).
    """
    check_toolchain()
    src = Path(src_dir) if src_dir is not None else _src_dir()
    out = Path(build_dir) / "cpp"
    out.mkdir(parents=True, exist_ok=True)
    with open(out / ".flowtrack-build.lock", "w") as lock:  # one build at a time in this folder
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not _configured_for(out / "CMakeCache.txt", src):
            shutil.rmtree(out / "CMakeFiles", ignore_errors=True)
            (out / "CMakeCache.txt").unlink(missing_ok=True)
            _run(
                ["cmake", "-S", str(src), "-B", str(out), "-DCMAKE_BUILD_TYPE=Release"],
                "cmake configure",
                600,
            )
        jobs = str(max(1, min(4, os.cpu_count() or 1)))
        _run(["cmake", "--build", str(out), "--parallel", jobs], "build", 1800)
    return out


def run_harness(language: str, vectors_dir: Path | str, out: Path) -> list[CaseResult]:
    """Run one built harness on a vectors folder and parse its ``CASE`` lines.

    A case that fails is reported (``passed=False``); a missing vector file or a crash raises
    ``RuntimeError``.
    """
    if language not in _HARNESS:
        raise ValueError(f"language must be one of {LANGUAGES}, got {language!r}")
    exe = Path(out) / _HARNESS[language]
    proc = subprocess.run([str(exe), str(vectors_dir)], capture_output=True, text=True, timeout=600)
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"C++ ports: {exe.name} exited {proc.returncode}: {proc.stderr.strip()[-2000:]}")
    return parse_case_lines(language, proc.stdout)


def run_unit_tests(out: Path) -> list[CaseResult]:
    """Run the GoogleTest suite through ctest; one :class:`CaseResult` per test (problem ``unit_tests``)."""
    report = Path(out) / "ctest-junit.xml"
    report.unlink(missing_ok=True)
    proc = subprocess.run(
        ["ctest", "--output-on-failure", "--output-junit", str(report)],
        cwd=out,
        capture_output=True,
        text=True,
        timeout=600,
    )
    if not report.exists():
        raise RuntimeError(
            f"C++ ports: ctest wrote no report (exit {proc.returncode}): {proc.stdout[-2000:]}"
        )
    results = []
    for tc in ET.parse(report).getroot().iter("testcase"):
        name = tc.get("name", "")
        language = next(
            (lang for prefix, lang in _TEST_PREFIX.items() if name.startswith(prefix)), LANGUAGES[0]
        )
        failed = tc.get("status") not in ("run", "passed") or tc.find("failure") is not None
        message = ""
        if failed:
            text = (tc.findtext("system-out") or "").strip().splitlines()
            message = " | ".join(
                line for line in text if "Failure" in line or "Expected" in line or "Which" in line
            )
            message = message[:500] or "failed"
        results.append(
            CaseResult(language, "unit_tests", name, not failed, math.nan if failed else 0.0, message)
        )
    if not results:
        raise RuntimeError(f"C++ ports: ctest ran no tests (exit {proc.returncode}): {proc.stdout[-2000:]}")
    return results


def run(vectors_dir: Path | str, build_dir: Path | str) -> list[CaseResult]:
    """Build the C++ ports and run both harnesses and the unit tests.

    Parameters
    ----------
    vectors_dir : path
        Folder of ``<problem>.json`` vector files.
    build_dir : path
        Build cache; the CMake build lives in ``<build_dir>/cpp``.

    Returns
    -------
    list of CaseResult
        Languages ``cpp-eigen`` and ``cpp-pcl``: one result per vector case and per unit test.
    """
    out = build(build_dir)
    results: list[CaseResult] = []
    for language in LANGUAGES:
        results += run_harness(language, vectors_dir, out)
    results += run_unit_tests(out)
    return results
