"""Build and run the Java ports (plain arrays, EJML, OpenCV) on the shared test vectors.

Sources: ``cpp_java_matlab_ports/java/src/{main,test}/java/flowtrack/ports/``. The build uses only
``javac``/``java`` and Debian's jars under ``/usr/share/java`` (gson, EJML, OpenCV + its JNI library,
the JUnit 5 console launcher); no Maven. Classes go to ``<build_dir>/java/``.

The harness ``flowtrack.ports.Harness <language> <vectors_dir>`` is run once per language in
:data:`LANGUAGES` and prints ``CASE`` lines (see :mod:`flowtrack_course.ports.base`); :func:`run_junit`
runs the JUnit 5 suite over the same vectors.
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
from pathlib import Path

from ..course import ports_dir
from .base import CaseResult, ToolchainMissing, harness_results

__all__ = ["LANGUAGES", "run", "run_junit", "build"]

LANGUAGES: tuple[str, ...] = ("java", "java-ejml", "java-opencv")


def _src_dir() -> Path:
    """The Java sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "java" / "src"


def __getattr__(name: str) -> Path:
    if name == "SRC_DIR":  # read lazily: the course folder is chosen at run time
        return _src_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
JAR_DIR = Path("/usr/share/java")
JNI_DIRS = (
    Path("/usr/lib/jni"),
    Path("/usr/lib/x86_64-linux-gnu/jni"),
    Path("/usr/lib/aarch64-linux-gnu/jni"),
)

# jar (file name under /usr/share/java) -> Debian package that provides it
_MAIN_JARS = {
    "gson.jar": "libgoogle-gson-java",
    "ejml-simple.jar": "libejml-java",
    "ejml-core.jar": "libejml-java",
    "ejml-ddense.jar": "libejml-java",
    "ejml-fdense.jar": "libejml-java",
    "ejml-cdense.jar": "libejml-java",
    "ejml-zdense.jar": "libejml-java",
    "ejml-dsparse.jar": "libejml-java",
    "ejml-fsparse.jar": "libejml-java",
    "opencv.jar": "libopencv-java",
}
_TEST_JARS = {
    "junit-jupiter-api.jar": "junit5",
    "apiguardian-api.jar": "junit5",
    "opentest4j.jar": "junit5",
    "junit-platform-commons.jar": "junit5",
    "junit-platform-console-standalone.jar": "junit5",
}


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise ToolchainMissing(f"{name} not found: install Debian openjdk-17-jdk-headless")
    return path


def _jars(names: dict[str, str]) -> list[str]:
    paths, missing = [], set()
    for name, pkg in names.items():
        p = JAR_DIR / name
        if not p.exists():
            missing.add(pkg)
        paths.append(str(p))
    if missing:
        raise ToolchainMissing(
            f"Java jars missing under {JAR_DIR}: install Debian {' '.join(sorted(missing))}"
        )
    return paths


def _jni_dir() -> str:
    for d in JNI_DIRS:
        if glob.glob(str(d / "libopencv_java*.so")):
            return str(d)
    raise ToolchainMissing("OpenCV JNI library libopencv_java*.so not found: install Debian libopencv-java")


def _javac(javac: str, out: Path, classpath: list[str], sources: list[Path]) -> None:
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    cmd = [javac, "-implicit:none", "-sourcepath", "", "-Xlint:all,-path,-processing", "-Werror"]
    cmd += ["-d", str(out), "-cp", os.pathsep.join(classpath), *map(str, sources)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"javac failed:\n{proc.stdout}\n{proc.stderr}")


def build(build_dir: Path, tests: bool = False) -> tuple[Path, list[str]]:
    """Compile the main sources (and the JUnit tests with ``tests=True``) into ``build_dir/java``.

    Returns
    -------
    (Path, list of str)
        The Java build directory and the run-time class path (classes first, then the jars).

    Raises
    ------
    flowtrack_course.ports.base.ToolchainMissing
        ``javac``/``java`` or one of the Debian jars is not installed.
    """
    javac = _tool("javac")
    _tool("java")
    jars = _jars(_MAIN_JARS)
    out = Path(build_dir) / "java"
    _javac(javac, out / "classes", jars, sorted((_src_dir() / "main").rglob("*.java")))
    classpath = [str(out / "classes"), *jars]
    if tests:
        tjars = _jars(_TEST_JARS)
        _javac(javac, out / "test-classes", classpath + tjars, sorted((_src_dir() / "test").rglob("*.java")))
        classpath = [str(out / "test-classes"), *classpath]
    return out, classpath


def run(vectors_dir: Path, build_dir: Path) -> list[CaseResult]:
    """Build the Java ports and run the harness for every language in :data:`LANGUAGES`.

    Parameters
    ----------
    vectors_dir : Path
        Directory with the ``<problem>.json`` vector files.
    build_dir : Path
        The ports' build root; classes go to ``build_dir/java``.

    Returns
    -------
    list of CaseResult
        One per (language, problem, case); a missing vector file gives one failing result.

    Raises
    ------
    flowtrack_course.ports.base.ToolchainMissing
        A JDK tool, a Debian jar or the OpenCV JNI library is missing.
    """
    _, classpath = build(build_dir)
    java = _tool("java")
    jni = _jni_dir()
    results: list[CaseResult] = []
    for lang in LANGUAGES:
        cmd = [java, f"-Djava.library.path={jni}", "-cp", os.pathsep.join(classpath)]
        cmd += ["flowtrack.ports.Harness", lang, str(vectors_dir)]
        results += harness_results(lang, subprocess.run(cmd, capture_output=True, text=True))
    return results


def run_junit(vectors_dir: Path, build_dir: Path) -> tuple[bool, str]:
    """Build main + test sources and run the JUnit 5 suite (console launcher) over ``vectors_dir``.

    Returns
    -------
    (bool, str)
        Whether every test passed, and the launcher's output.
    """
    _, classpath = build(build_dir, tests=True)
    java = _tool("java")
    launcher = str(JAR_DIR / "junit-platform-console-standalone.jar")
    cmd = [java, f"-Djava.library.path={_jni_dir()}", f"-Dflowtrack.vectors={vectors_dir}", "-jar", launcher]
    cmd += [
        "--disable-banner",
        "--disable-ansi-colors",
        "--details=tree",
        "--class-path",
        os.pathsep.join(classpath),
    ]
    cmd += ["--select-class", "flowtrack.ports.PortsTest"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    return proc.returncode == 0, proc.stdout + proc.stderr
