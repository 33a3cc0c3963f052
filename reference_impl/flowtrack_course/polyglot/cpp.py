"""C++: the Eigen and PCL ports on the shared vectors, and the grader's recipe for an Eigen answer.

**Ports.** Sources: ``cpp_java_matlab_ports/cpp/`` (a CMake project, C++17). It is configured once
into ``<build_dir>/cpp`` (Release) and rebuilt incrementally, so a second run with unchanged sources
only checks time stamps. Then

- ``harness_eigen VECTORS_DIR`` runs the Eigen port on every case of ``kalman_cv2d``,
  ``white_noise_q``, ``projection_jacobian``, ``mahalanobis_assignment``, ``graph_scene_flow`` and
  ``variational_scene_flow`` (port ``cpp-eigen``);
- ``harness_pcl VECTORS_DIR`` runs the PCL port on ``rigid_icp`` (port ``cpp-pcl``);
- ``ctest`` runs the GoogleTest unit tests, reported as problem ``unit_tests`` of the port whose
  part they test (``Eigen.*`` -> ``cpp-eigen``, ``Pcl.*`` -> ``cpp-pcl``).

**Answers.** A student writes ``<problem>.cpp`` against the declarations ``files/cpp/<problem>.hpp``
(written beside it as ``exercise.hpp``); the grader's ``files/cpp/harness.cpp`` (JSON through
nlohmann/json, Eigen) reads the cases and prints ``OUTPUT`` lines. The harness object is the slow part
of a build (Eigen's and nlohmann's headers), so it is compiled once per problem, outside any sandbox,
into the grader's cache (:func:`harness_object`; the name carries the hash of the harness, the
declarations, the flags and the compiler's version) and handed to every sandbox as bytes; only the
student's own file is compiled there (~0.7 s for Eigen's headers alone, ~3 s for ``kalman_step``'s
products and LDLT; -O0 is no faster).

Debian packages: ``g++ libeigen3-dev nlohmann-json3-dev`` (answers), and ``cmake make libpcl-dev
libgtest-dev`` besides for the ports.
"""

from __future__ import annotations

import fcntl
import hashlib
import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from ..course import ports_dir
from .base import Toolchain, cached_artefact, executable, path_glob, support_text
from .vectors import CaseResult, parse_case_lines

__all__ = [
    "CXX_FLAGS",
    "PORTS",
    "TOOLCHAIN",
    "build",
    "harness_object",
    "run",
    "run_harness",
    "run_unit_tests",
]

#: The ports this module runs (the names in ``flowtrack ports``' table).
PORTS: tuple[str, ...] = ("cpp-eigen", "cpp-pcl")

EIGEN_INCLUDE = "/usr/include/eigen3"
#: Flags of a student's file and of the harness (``-O1``: a quarter of -O2's compile time).
CXX_FLAGS = ("-std=c++17", "-O1", "-w", f"-I{EIGEN_INCLUDE}", "-I.")


def _src_dir() -> Path:
    """The C++ sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "cpp"



@dataclass(frozen=True)
class CppToolchain(Toolchain):
    """An answer in C++ with Eigen: compiled in the sandbox, linked with the cached harness object."""

    def support_files(self, problem: str) -> dict[str, str]:
        return {"exercise.hpp": support_text("cpp", f"{problem}.hpp")}

    def blobs(self, problem: str, cache_dir: Path) -> dict[str, bytes]:
        return {"harness.o": harness_object(problem, cache_dir).read_bytes()}

    def build_commands(self, problem: str) -> list[list[str]]:
        return [
            ["g++", *CXX_FLAGS, "-c", self.source_name(problem), "-o", "student.o"],
            ["g++", "student.o", "harness.o", "-o", "program"],
        ]

    def run_command(self, problem: str) -> list[str]:
        return ["./program", "cases.json"]

    def bundle_files(self, problem: str) -> dict[str, str]:
        return {
            "exercise.hpp": support_text("cpp", f"{problem}.hpp"),
            "harness.cpp": support_text("cpp", "harness.cpp"),
            "CMakeLists.txt": support_text("cpp", "CMakeLists.txt").replace("@PROBLEM@", problem),
        }


TOOLCHAIN = CppToolchain(
    "cpp",
    "C++ (Eigen)",
    requirements=(
        executable("g++", package="g++"),
        path_glob("Eigen", f"{EIGEN_INCLUDE}/Eigen/Dense", package="libeigen3-dev"),
        path_glob("nlohmann/json.hpp", "/usr/include/nlohmann/json.hpp", package="nlohmann-json3-dev"),
    ),
    port_requirements=(
        executable("cmake", package="cmake"),
        executable("make", package="make"),
        path_glob("GoogleTest", "/usr/include/gtest/gtest.h", package="libgtest-dev"),
        path_glob("PCL", "/usr/include/pcl-*/pcl/registration/icp.h", package="libpcl-dev"),
    ),
    extension=".cpp",
)


# -- the grader's harness object -------------------------------------------------------------------
def _compiler_version() -> str:
    try:
        return subprocess.run(["g++", "--version"], capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


def harness_object(problem: str, cache_dir: Path) -> Path:
    """The cached object of the C++ harness of ``problem`` (compiled from the grader's sources only).

    Raises
    ------
    flowtrack_course.polyglot.base.ToolchainMissing
        g++, Eigen or nlohmann/json is not installed.
    RuntimeError
        The harness does not compile (a bug of the course, never of a student).
    """
    TOOLCHAIN.check()
    harness = support_text("cpp", "harness.cpp")
    header = support_text("cpp", f"{problem}.hpp")
    flags = [*CXX_FLAGS, f"-DFT_PROBLEM_{problem}"]
    key = hashlib.sha256("\0".join([harness, header, *flags, _compiler_version()]).encode()).hexdigest()[:24]

    def compile_harness(tmp: Path) -> Path:
        Path(tmp, "harness.cpp").write_text(harness, encoding="utf-8")
        Path(tmp, "exercise.hpp").write_text(header, encoding="utf-8")
        proc = subprocess.run(
            ["g++", *flags, "-c", "harness.cpp", "-o", "harness.o"],
            cwd=tmp,
            capture_output=True,
            text=True,
            timeout=600,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"the C++ harness of {problem} does not compile:\n{proc.stderr[-3000:]}")
        return Path(tmp, "harness.o")

    return cached_artefact(cache_dir, f"harness-{problem}-{key}.o", compile_harness)


# -- the ports -----------------------------------------------------------------------------------
_HARNESS = {"cpp-eigen": "harness_eigen", "cpp-pcl": "harness_pcl"}
_TEST_PREFIX = {"Eigen.": "cpp-eigen", "Pcl.": "cpp-pcl"}


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
    flowtrack_course.polyglot.base.ToolchainMissing
        A compiler, CMake or a library is not installed.
    RuntimeError
        Configuration or compilation failed (the message holds the end of the compiler output).
    """
    TOOLCHAIN.check(ports=True)
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
    """Run one built harness (``language``: a port of :data:`PORTS`) on a vectors folder and parse its
    ``CASE`` lines.

    A case that fails is reported (``passed=False``); a missing vector file or a crash raises
    ``RuntimeError``.
    """
    if language not in _HARNESS:
        raise ValueError(f"language must be one of {PORTS}, got {language!r}")
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
        language = next((lang for prefix, lang in _TEST_PREFIX.items() if name.startswith(prefix)), PORTS[0])
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
        Ports ``cpp-eigen`` and ``cpp-pcl``: one result per vector case and per unit test.
    """
    out = build(build_dir)
    results: list[CaseResult] = []
    for language in PORTS:
        results += run_harness(language, vectors_dir, out)
    results += run_unit_tests(out)
    return results
