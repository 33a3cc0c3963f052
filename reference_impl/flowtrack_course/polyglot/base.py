"""What every language of the polyglot stack shares: its requirements, its grading recipe, its cache.

A :class:`Toolchain` is one language family (``cpp``, ``octave``, ``java``, ``mathics``, ``blocks``):

- the tools it needs, as :class:`Requirement`\\ s: ``requirements`` for building and running a
  student's answer, ``port_requirements`` for what the course's own ports need beyond that (CMake,
  PCL, OpenCV, JUnit, ...). :meth:`Toolchain.check` raises :class:`ToolchainMissing` naming the
  packages to install; a missing tool is never a silent skip, for the ports or the grader.
- the grader's recipe for an answer (only languages with an ``extension`` are graded): the file the
  student writes, the grader's files beside it, the build and run commands (each run inside the
  student's sandbox, in a ``build`` folder of its home), the files of the student's bundle. The
  methods here are the defaults of an interpreted language; each language module overrides what
  differs.

:func:`cached_artefact` is the build cache of what is compiled from the course's own sources only
(never a student's file): a file named by the hash of everything it was built from, made once
under a lock. The grader passes the folder (its sandbox cache); the stack imports nothing of the
grader.
"""

from __future__ import annotations

import fcntl
import glob
import importlib.util
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

__all__ = [
    "FILES",
    "Requirement",
    "Toolchain",
    "ToolchainMissing",
    "cached_artefact",
    "executable",
    "path_glob",
    "python_module",
    "support_text",
]

#: The grader's harness and declaration files, per language (``files/<language>/...``): what the
#: sandbox gets beside a student's file and what the student's bundle holds.
FILES = resources.files("flowtrack_course.polyglot") / "files"


class ToolchainMissing(RuntimeError):
    """A compiler, interpreter, library or jar a language needs is not installed.

    Raised by :meth:`Toolchain.check` with the packages to install; the ports report it as a failed
    result, the grader as the reason it cannot grade that language on this machine.
    """


def support_text(language: str, name: str) -> str:
    """The text of one of the grader's files of ``language`` (e.g. ``harness.cpp``, ``api/CvModel.java``)."""
    return (FILES / language / name).read_text(encoding="utf-8")


@dataclass(frozen=True)
class Requirement:
    """One thing a toolchain needs: ``what`` is shown, ``package`` installs it.

    ``kind`` says how it is found: ``"executable"`` (any of ``targets`` on ``PATH``), ``"path"`` (any
    of the glob patterns ``targets`` matches a file) or ``"python"`` (the module ``targets[0]`` is
    importable). ``pip`` marks a PyPI requirement (the ``ports`` extra) instead of a Debian package.
    """

    what: str
    package: str
    kind: str
    targets: tuple[str, ...]
    pip: bool = False

    def found(self) -> bool:
        if self.kind == "executable":
            return any(shutil.which(t) is not None for t in self.targets)
        if self.kind == "path":
            return any(glob.glob(t) for t in self.targets)
        if self.kind == "python":
            return importlib.util.find_spec(self.targets[0]) is not None
        raise ValueError(f"kind must be executable, path or python, got {self.kind!r}")


def executable(*names: str, package: str) -> Requirement:
    """A program on ``PATH`` (any of ``names``)."""
    return Requirement(names[0], package, "executable", names)


def path_glob(what: str, *patterns: str, package: str) -> Requirement:
    """A header, jar or library file matching one of the glob ``patterns``."""
    return Requirement(what, package, "path", patterns)


def python_module(name: str, package: str) -> Requirement:
    """A Python package from PyPI (``package``: the pip requirement)."""
    return Requirement(name, package, "python", (name,), pip=True)


@dataclass(frozen=True)
class Toolchain:
    """One language family: its requirements and the grader's recipe (see the module docstring).

    ``extension`` is that of a student's answer (empty: the language is not graded, only ported);
    ``todo`` is the comment a stub holds where the solution was; ``compile_seconds`` limits each
    build command of an answer, ``run_seconds`` one run of its program.
    """

    language: str
    title: str
    requirements: tuple[Requirement, ...] = ()
    port_requirements: tuple[Requirement, ...] = ()
    extension: str = ""
    todo: str = "// YOUR CODE HERE"
    compile_seconds: float = 60.0
    run_seconds: float = 20.0

    @property
    def graded(self) -> bool:
        """Whether students answer in this language (the grader has a recipe for it)."""
        return bool(self.extension)

    def missing(self, ports: bool = False) -> list[Requirement]:
        """The requirements that are not installed (with ``ports=True`` the ports' ones too)."""
        needed = self.requirements + (self.port_requirements if ports else ())
        return [r for r in needed if not r.found()]

    def check(self, ports: bool = False) -> None:
        """Raise :class:`ToolchainMissing` naming what is missing and the packages that install it."""
        missing = self.missing(ports)
        if not missing:
            return
        debian = sorted({r.package for r in missing if not r.pip})
        pip = sorted({r.package for r in missing if r.pip})
        how = [f"apt-get install -y {' '.join(debian)}"] if debian else []
        how += [f"pip install {' '.join(pip)}"] if pip else []
        also = ", or `make test` does it" if ports else ""
        raise ToolchainMissing(
            f"{self.title}: {', '.join(r.what for r in missing)} not found (install: {'; '.join(how)}{also})"
        )

    # -- the grader's recipe: the defaults of an interpreted language ---------------------------------
    def source_name(self, problem: str) -> str:
        """The file the student writes for ``problem``."""
        return f"{problem}{self.extension}"

    def support_files(self, problem: str) -> dict[str, str]:
        """The grader's files written beside the student's in the sandbox (name -> text)."""
        return {}

    def blobs(self, problem: str, cache_dir: Path) -> dict[str, bytes]:
        """Binary artefacts built from the grader's own sources, cached in ``cache_dir`` (name -> bytes)."""
        return {}

    def build_commands(self, problem: str) -> list[list[str]]:
        """The commands that build the student's answer in the sandbox, in order."""
        return []

    def run_command(self, problem: str) -> list[str]:
        """The command that runs the built answer on ``cases.json`` and prints ``OUTPUT`` lines."""
        raise NotImplementedError(f"{self.title} answers are not graded")

    def inproc(self, problem: str) -> dict | None:
        """The harness the sandboxed child runs in its own process (``{"file", "function", "args"}``),
        or None when the child starts the program as a process."""
        return None

    def bundle_files(self, problem: str) -> dict[str, str]:
        """The files a student's bundle holds beside the answer to build and run the public tests
        locally (relative path -> text; ``public.json`` is added by the grader)."""
        return {}


def cached_artefact(directory: Path, name: str, build: Callable[[Path], Path]) -> Path:
    """``directory/name``, made once by ``build(tmp) -> built file`` under a lock.

    The cache holds only what is built from the course's own sources (never a student's code); the
    caller puts the hash of everything it was built from into ``name``, so a stale artefact is never
    used. Concurrent graders wait for the first one's build instead of repeating it.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    obj = directory / name
    if obj.exists():
        return obj
    with open(directory / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if obj.exists():
            return obj
        with tempfile.TemporaryDirectory(dir=directory) as tmp:
            os.replace(build(Path(tmp)), obj)
    return obj
