"""How each language's answer is built and run inside the sandbox, and the toolchain caches.

A :class:`Toolchain` says which file a student writes for a problem (``source_name``), which of the
grader's own files go beside it (``support_files``: the harness and the declarations, the same
files :func:`flowtrack_course.grading.languages.materialise` writes into the bundle), the build commands
(each under ``compile_seconds``) and the run command (under ``run_seconds``). All of them run in
the student's sandbox, in a ``build`` folder of its home.

Caching (``blobs``): only artefacts made from the grader's own sources, never from a student's
file, are cached, per language: the C++ harness object (``harness.cpp`` with nlohmann/json and
Eigen, the slow part of a build) is compiled once per problem, outside any sandbox, into
``<sandbox cache>/languages/cpp/<hash>.o`` (the hash covers the harness, the declarations, the
flags and the compiler's version) and handed to every student's sandbox as bytes; only the
student's own file is compiled there. Octave needs no build.

The Java harness (``Harness.java``, JSON through gson) is compiled once, outside any sandbox, against
the signature files ``files/java/api/*.java`` into ``<sandbox cache>/languages/java/<hash>.class``;
in the sandbox only the student's class is compiled (``javac``), and ``java Harness`` runs with
:data:`JVM_FLAGS`, which fit the sandbox's memory and process limits.

Debian packages: ``g++ libeigen3-dev nlohmann-json3-dev`` (C++), ``octave`` (Octave),
``openjdk-17-jdk-headless libgoogle-gson-java libejml-java`` (Java); Mathics3 is the Python package
``mathics3`` (the ``ports`` extra). Its harness ``ft_mathics.py`` runs inside the sandbox's child
itself (:meth:`Toolchain.inproc`): in ``flowtrack grade`` the child is forked from a zygote that
loaded the interpreter and built one pristine set of definitions before any student code existed
(``MATHICS_ALLOWED`` in :mod:`flowtrack_course.grading.languages.exercises`), so an item starts
Mathics3 in milliseconds, not in the ~3 s (~10 s on a busy machine) of a fresh interpreter; each
exercise's child is a fresh fork, so no student's definitions reach another exercise or another
student. Every other language's build and run are processes the child starts
(``Sandbox(spawn=True)``).

CPU seconds per item measured by ``benchmarks/bench_grading.py --languages`` (3 students: solution,
stub, partial; the grader's own start-up included): C++ ~1.4 (compiling the student's Eigen code:
0.7 s for the headers alone, ~3 s for ``kalman_step``'s products and LDLT; -O0 is no faster, a
precompiled Eigen header saves ~0.5 s but is ~100 MB), Java ~1.0 (``javac`` ~0.5 s with ``-proc:none``,
~0.75 s without; a run ~0.1 s), Octave ~0.4, Mathics3 ~0.6 (was ~7.6 with a fresh interpreter per run).
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib.util
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

__all__ = ["LANGUAGES", "TOOLCHAINS", "Toolchain", "ToolchainMissing", "support_text"]

FILES = resources.files("flowtrack_course.grading.languages") / "files"
EIGEN_INCLUDE = "/usr/include/eigen3"
CXX_FLAGS = ("-std=c++17", "-O1", "-w", f"-I{EIGEN_INCLUDE}", "-I.")
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


def java_class(problem: str) -> str:
    """The Java class (and file stem) of ``problem``: ``cv_model`` -> ``CvModel``."""
    return "".join(part.capitalize() for part in problem.split("_"))


class ToolchainMissing(RuntimeError):
    """A compiler or interpreter a language needs is not installed.

    The grader's error; the port harnesses have their own,
    :class:`flowtrack_course.ports.base.ToolchainMissing`.
    """


def support_text(language: str, name: str) -> str:
    """The text of one of the grader's files of ``language`` (e.g. ``harness.cpp``)."""
    return (FILES / language / name).read_text(encoding="utf-8")


@dataclass(frozen=True)
class Toolchain:
    language: str
    title: str
    extension: str
    debian: tuple[str, ...]
    executables: tuple[str, ...]
    compile_seconds: float = 60.0
    run_seconds: float = 20.0

    def source_name(self, problem: str) -> str:
        """The file the student writes for ``problem`` (Java: the class name, ``CvModel.java``)."""
        if self.language == "java":
            return java_class(problem) + self.extension
        return f"{problem}{self.extension}"

    def check(self) -> None:
        """Raise :class:`~flowtrack_course.grading.languages.toolchains.ToolchainMissing` naming the
        Debian packages when a tool is missing."""
        missing = [e for e in self.executables if shutil.which(e) is None]
        if self.language == "mathics" and importlib.util.find_spec("mathics") is None:
            missing.append("the mathics Python package")
        if self.language == "cpp" and not Path(EIGEN_INCLUDE, "Eigen", "Dense").exists():
            missing.append("Eigen")
        if self.language == "cpp" and not Path("/usr/include/nlohmann/json.hpp").exists():
            missing.append("nlohmann/json.hpp")
        if missing:
            raise ToolchainMissing(
                f"{self.title}: {', '.join(missing)} not found: apt-get install -y {' '.join(self.debian)}"
            )

    # -- what the sandbox gets -----------------------------------------------------------------------
    def support_files(self, problem: str) -> dict[str, str]:
        """The grader's files written beside the student's (name -> text)."""
        if self.language == "cpp":
            return {"exercise.hpp": support_text("cpp", f"{problem}.hpp")}
        if self.language == "java":
            return {}
        if self.language == "mathics":
            return {"ft_mathics.py": support_text("mathics", "ft_mathics.py")}
        return {"ft_harness.m": support_text("octave", "ft_harness.m")}

    def blobs(self, problem: str) -> dict[str, bytes]:
        """Cached binary artefacts of the grader's own sources (name -> bytes)."""
        if self.language == "cpp":
            return {"harness.o": cpp_harness_object(problem).read_bytes()}
        if self.language == "java":
            return {"Harness.class": java_harness_class().read_bytes()}
        return {}

    def build_commands(self, problem: str) -> list[list[str]]:
        if self.language == "cpp":
            return [
                ["g++", *CXX_FLAGS, "-c", self.source_name(problem), "-o", "student.o"],
                ["g++", "student.o", "harness.o", "-o", "program"],
            ]
        if self.language == "java":
            return [["javac", *JAVAC_FLAGS, "-cp", JAVA_CLASSPATH, "-d", ".", self.source_name(problem)]]
        return []

    def inproc(self, problem: str) -> dict | None:
        """The harness the sandboxed child runs in its own process (Mathics3), else None."""
        if self.language == "mathics":
            return {"file": "ft_mathics.py", "function": "grade",
                    "args": [problem, self.source_name(problem)]}
        return None

    def run_command(self, problem: str) -> list[str]:
        if self.language == "cpp":
            return ["./program", "cases.json"]
        if self.language == "java":
            return ["java", *JVM_FLAGS, "-cp", ".:" + JAVA_CLASSPATH, "Harness", problem, "cases.json"]
        if self.language == "mathics":  # @PYTHON@: the sandbox's own interpreter (see the driver)
            return ["@PYTHON@", "-I", "-S", "ft_mathics.py", problem, "cases.json", self.source_name(problem)]
        return [
            "octave-cli",
            "--norc",
            "--no-history",
            "--quiet",
            "--no-window-system",
            "--eval",
            f"ft_harness('{problem}', 'cases.json', false);",
        ]


TOOLCHAINS: dict[str, Toolchain] = {
    "cpp": Toolchain("cpp", "C++ (Eigen)", ".cpp", ("g++", "libeigen3-dev", "nlohmann-json3-dev"), ("g++",)),
    "octave": Toolchain("octave", "Octave (MATLAB syntax)", ".m", ("octave",), ("octave-cli",)),
    "java": Toolchain(
        "java",
        "Java (plain arrays or EJML)",
        ".java",
        ("openjdk-17-jdk-headless", "libgoogle-gson-java", "libejml-java"),
        ("javac", "java"),
    ),
    "mathics": Toolchain(
        "mathics",
        "Mathematica (Mathics3)",
        ".wl",
        ('pip install -e ".[ports]" (PyPI mathics3)',),
        (),
        compile_seconds=0.0,  # nothing to build; a fresh interpreter's start-up is part of the run
        run_seconds=30.0,
    ),
}
LANGUAGES: tuple[str, ...] = tuple(TOOLCHAINS)


def _cache_dir(language: str) -> Path:
    from grading_sandbox.cache import cache_root

    d = cache_root() / "languages" / language
    d.mkdir(parents=True, exist_ok=True)
    return d


def _compiler_version() -> str:
    try:
        return subprocess.run(["g++", "--version"], capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


def cpp_harness_object(problem: str) -> Path:
    """The cached object of the C++ harness of ``problem`` (compiled from the grader's sources only).

    Raises
    ------
    flowtrack_course.grading.languages.toolchains.ToolchainMissing
        g++, Eigen or nlohmann/json is not installed.
    RuntimeError
        The harness does not compile (a bug of the course, never of a student).
    """
    TOOLCHAINS["cpp"].check()
    harness = support_text("cpp", "harness.cpp")
    header = support_text("cpp", f"{problem}.hpp")
    flags = [*CXX_FLAGS, f"-DFT_PROBLEM_{problem}"]
    key = hashlib.sha256("\0".join([harness, header, *flags, _compiler_version()]).encode()).hexdigest()[:24]

    def build(tmp: Path) -> Path:
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

    return _cached_artefact("cpp", f"harness-{problem}-{key}.o", build)


def _cached_artefact(lang: str, name: str, build) -> Path:
    """``name`` in the language's cache, made once by ``build(tmp) -> built file`` under a lock.

    The cache holds only what the grader builds from its own sources (never a student's code); the
    file name carries the hash of everything it was built from, so a stale artefact is never used.
    """
    out_dir = _cache_dir(lang)
    obj = out_dir / name
    if obj.exists():
        return obj
    with open(out_dir / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if obj.exists():
            return obj
        with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
            os.replace(build(Path(tmp)), obj)
    return obj


def java_harness_class() -> Path:
    """The cached ``Harness.class`` (compiled from the grader's ``Harness.java`` and signature files)."""
    TOOLCHAINS["java"].check()
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

    def build(tmp: Path) -> Path:
        Path(tmp, "Harness.java").write_text(harness, encoding="utf-8")
        for name, body in api.items():
            Path(tmp, name).write_text(body, encoding="utf-8")
        cmd = ["javac", "-encoding", "UTF-8", "-nowarn", "-cp", JAVA_CLASSPATH, "-d", "classes",
               "Harness.java", *api]
        proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            raise RuntimeError(f"the Java harness does not compile:\n{proc.stderr[-3000:]}")
        return Path(tmp, "classes", "Harness.class")

    return _cached_artefact("java", f"Harness-{key}.class", build)
