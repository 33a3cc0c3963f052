"""Java: the plain-array, EJML and OpenCV ports on the shared vectors, and the grader's recipe for an answer.

Everything is built with ``javac``/``java`` and Debian's jars under ``/usr/share/java`` (gson, EJML,
OpenCV and its JNI library, the JUnit 5 console launcher); no Maven.

**Ports.** Sources: ``cpp_java_matlab_ports/java/src/{main,test}/java/flowtrack/ports/``; classes go
to ``<build_dir>/java/``. The harness ``flowtrack.ports.Harness <port> <vectors_dir>`` is run once
per port of :data:`PORTS` and prints ``CASE`` lines (see :mod:`flowtrack_course.polyglot.vectors`);
:func:`run_junit` runs the JUnit 5 suite over the same vectors.

**Answers.** A student writes the class ``CvModel.java`` (for ``cv_model``; plain arrays or EJML).
The grader's ``files/java/Harness.java`` (JSON through gson) is compiled once, outside any sandbox,
against the signature files ``files/java/api/*.java`` into the grader's cache
(:func:`harness_class`); in the sandbox only the student's class is compiled (``javac`` ~0.5 s with
``-proc:none``, ~0.75 s without; a run ~0.1 s), and ``java Harness`` runs with :data:`JVM_FLAGS`,
which fit the sandbox's memory and process limits.
"""

from __future__ import annotations

import glob
import hashlib
import os
import shutil
import subprocess
from dataclasses import dataclass, replace
from pathlib import Path

from ..course import ports_dir
from .base import FILES, Toolchain, cached_artefact, executable, path_glob, support_text
from .vectors import CaseResult, harness_results

__all__ = [
    "JAVA_CLASSPATH",
    "JVM_FLAGS",
    "PORTS",
    "TOOLCHAIN",
    "build",
    "harness_class",
    "java_class",
    "run",
    "run_junit",
]

#: The ports this module runs (the names in ``flowtrack ports``' table).
PORTS: tuple[str, ...] = ("java", "java-ejml", "java-opencv")

JAR_DIR = Path("/usr/share/java")
JNI_DIRS = (
    Path("/usr/lib/jni"),
    Path("/usr/lib/x86_64-linux-gnu/jni"),
    Path("/usr/lib/aarch64-linux-gnu/jni"),
)

#: What a student's answer is compiled and run against (plain arrays or EJML; JSON through gson).
JAVA_JARS = ("gson.jar", "ejml-core.jar", "ejml-ddense.jar", "ejml-simple.jar")
JAVA_CLASSPATH = ":".join(f"/usr/share/java/{j}" for j in JAVA_JARS)
# The JVM inside the sandbox's limits (2 GiB of address space, 64 processes/threads): a small heap and
# code cache, one GC thread, the C1 compiler only.
JVM_FLAGS = (
    "-Xmx256m",
    "-Xss1m",
    "-XX:ReservedCodeCacheSize=32m",
    "-XX:CompressedClassSpaceSize=64m",
    "-XX:MaxMetaspaceSize=128m",
    "-XX:+UseSerialGC",
    "-XX:TieredStopAtLevel=1",
    "-XX:CICompilerCount=1",
    "-Xshare:auto",
    "-XX:-UsePerfData",  # no /tmp/hsperfdata_<uid> file (outside bubblewrap /tmp is the machine's)
    "-Djava.awt.headless=true",
)
# -proc:none: no search of the class path for annotation processors (a third of javac's CPU time here)
JAVAC_FLAGS = (
    *(f"-J{f}" for f in JVM_FLAGS), "-encoding", "UTF-8", "-nowarn", "-proc:none", "-implicit:none"
)

# jar (file name under /usr/share/java) -> Debian package that provides it
_PORT_JARS = {
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


def _jar(name: str, package: str):
    return path_glob(name, str(JAR_DIR / name), package=package)


def java_class(problem: str) -> str:
    """The Java class (and file stem) of ``problem``: ``cv_model`` -> ``CvModel``."""
    return "".join(part.capitalize() for part in problem.split("_"))


@dataclass(frozen=True)
class JavaToolchain(Toolchain):
    """An answer in Java: the student's class compiled in the sandbox, run by the cached harness."""

    def source_name(self, problem: str) -> str:
        return java_class(problem) + self.extension

    def blobs(self, problem: str, cache_dir: Path) -> dict[str, bytes]:
        return {"Harness.class": harness_class(cache_dir).read_bytes()}

    def build_commands(self, problem: str) -> list[list[str]]:
        return [["javac", *JAVAC_FLAGS, "-cp", JAVA_CLASSPATH, "-d", ".", self.source_name(problem)]]

    def run_command(self, problem: str) -> list[str]:
        return ["java", *JVM_FLAGS, "-cp", ".:" + JAVA_CLASSPATH, "Harness", problem, "cases.json"]

    def bundle_files(self, problem: str) -> dict[str, str]:
        name = self.source_name(problem)
        files = {"Harness.java": support_text("java", "Harness.java")}
        for p in sorted((FILES / "java" / "api").iterdir(), key=lambda p: p.name):
            if p.name.endswith(".java") and p.name != name:  # the other exercises' signatures
                files[f"api/{p.name}"] = p.read_text(encoding="utf-8")
        files["run_public_tests.sh"] = (
            f"#!/bin/sh\n# Compile and run the public tests of {problem}:  sh run_public_tests.sh\n"
            f"set -e\nCP={JAVA_CLASSPATH}\nmkdir -p classes\n"
            'javac -encoding UTF-8 -cp "$CP" -sourcepath api -implicit:class -d classes '
            f"Harness.java {name}\n"
            f'java -cp "classes:$CP" Harness --check {problem} public.json\n'
        )
        return files


TOOLCHAIN = JavaToolchain(
    "java",
    "Java (plain arrays or EJML)",
    requirements=(
        executable("javac", package="openjdk-17-jdk-headless"),
        executable("java", package="openjdk-17-jdk-headless"),
        *(_jar(j, _PORT_JARS[j]) for j in JAVA_JARS),
    ),
    port_requirements=(
        *(_jar(j, p) for j, p in _PORT_JARS.items() if j not in JAVA_JARS),
        path_glob("OpenCV's JNI library", *(str(d / "libopencv_java*.so") for d in JNI_DIRS),
                  package="libopencv-java"),
    ),
    extension=".java",
)


# -- the grader's harness class ----------------------------------------------------------------------
def harness_class(cache_dir: Path) -> Path:
    """The cached ``Harness.class`` (compiled from the grader's ``Harness.java`` and signature files)."""
    TOOLCHAIN.check()
    harness = support_text("java", "Harness.java")
    api_dir = FILES / "java" / "api"
    api = {
        p.name: p.read_text(encoding="utf-8")
        for p in sorted(api_dir.iterdir(), key=lambda p: p.name)
        if p.name.endswith(".java")
    }
    version = subprocess.run(["javac", "-version"], capture_output=True, text=True, timeout=120)
    text = "\0".join([harness, *api.values(), JAVA_CLASSPATH, version.stdout + version.stderr])
    key = hashlib.sha256(text.encode()).hexdigest()[:24]

    def compile_harness(tmp: Path) -> Path:
        Path(tmp, "Harness.java").write_text(harness, encoding="utf-8")
        for name, body in api.items():
            Path(tmp, name).write_text(body, encoding="utf-8")
        cmd = ["javac", "-encoding", "UTF-8", "-nowarn", "-cp", JAVA_CLASSPATH, "-d", "classes",
               "Harness.java", *api]
        proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            raise RuntimeError(f"the Java harness does not compile:\n{proc.stderr[-3000:]}")
        return Path(tmp, "classes", "Harness.class")

    return cached_artefact(cache_dir, f"Harness-{key}.class", compile_harness)


# -- the ports -------------------------------------------------------------------------------------
def _src_dir() -> Path:
    """The Java sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "java" / "src"



def _jni_dir() -> str:
    """The folder holding OpenCV's JNI library (:meth:`Toolchain.check` made sure there is one)."""
    return next(str(d) for d in JNI_DIRS if glob.glob(str(d / "libopencv_java*.so")))


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
    flowtrack_course.polyglot.base.ToolchainMissing
        ``javac``/``java``, one of the Debian jars, OpenCV's JNI library or (``tests=True``) JUnit 5
        is not installed.
    """
    junit = tuple(_jar(j, p) for j, p in _TEST_JARS.items()) if tests else ()
    replace(TOOLCHAIN, port_requirements=TOOLCHAIN.port_requirements + junit).check(ports=True)
    javac = shutil.which("javac")
    jars = [str(JAR_DIR / j) for j in _PORT_JARS]
    out = Path(build_dir) / "java"
    _javac(javac, out / "classes", jars, sorted((_src_dir() / "main").rglob("*.java")))
    classpath = [str(out / "classes"), *jars]
    if tests:
        tjars = [str(JAR_DIR / j) for j in _TEST_JARS]
        _javac(javac, out / "test-classes", classpath + tjars, sorted((_src_dir() / "test").rglob("*.java")))
        classpath = [str(out / "test-classes"), *classpath]
    return out, classpath


def run(vectors_dir: Path, build_dir: Path) -> list[CaseResult]:
    """Build the Java ports and run the harness for every port in :data:`PORTS`.

    Parameters
    ----------
    vectors_dir : Path
        Directory with the ``<problem>.json`` vector files.
    build_dir : Path
        The ports' build root; classes go to ``build_dir/java``.

    Returns
    -------
    list of CaseResult
        One per (port, problem, case); a missing vector file gives one failing result.

    Raises
    ------
    flowtrack_course.polyglot.base.ToolchainMissing
        A JDK tool, a Debian jar or the OpenCV JNI library is missing.
    """
    _, classpath = build(build_dir)
    java = shutil.which("java")
    jni = _jni_dir()
    results: list[CaseResult] = []
    for lang in PORTS:
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
    java = shutil.which("java")
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
