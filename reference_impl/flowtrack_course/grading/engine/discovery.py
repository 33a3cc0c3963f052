"""Finding a course's exercises: one folder per exercise, discovered, never listed.

A course folder holds ``exercises/<id>/``, one folder per exercise, with

- ``<id>.ipynb``: the notebook in nbgrader's authoring format (solutions and hidden tests marked);
- ``grading.py``: its grading module, which defines ``EXERCISE``, an :class:`~.spec.Exercise`
  (written with :mod:`.authoring`): the tests, the hidden-input generators, the catalogued
  mistakes with their messages;
- anything else the exercise's authors keep there: its worked solution (``*.md``), ``cases.py``
  (the answers the course's own tests grade: typical wrong ones, mistakes written as code), the
  same exercise's answers in other forms (sources in other languages, their solutions between
  ``BEGIN SOLUTION`` / ``END SOLUTION`` lines), helper modules or data the grading module reads.
  :func:`grading_files` are the files that go wherever the grader runs (the student bundle, the
  Gradescope zip): everything but notebooks, Markdown, ``cases.py`` and files holding a solution.

:func:`discover` imports every ``exercises/*/grading.py`` (folders starting with ``_`` or ``.`` and
folders without one, such as a folder of guides, are skipped) under a
module name of its own, checks that each defines an ``EXERCISE`` whose id is its folder's name, and
returns them sorted by id as an :class:`ExerciseSet` with the course's mistake
:class:`~.mistakes.Catalogue`. Adding an exercise is adding a folder. The set is made once per
process and course (again when a grading module changes).

A grading module is trusted code of the instructor: it runs in the grader's process. Never point
the grader at a course folder a student could have written.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import os
import sys
import types
from collections.abc import Iterator
from pathlib import Path

from .mistakes import Catalogue
from .spec import Exercise

__all__ = [
    "EXERCISES_DIR",
    "GRADING_MODULE",
    "SOLUTION_MARKER",
    "ExerciseSet",
    "discover",
    "exercise_folders",
    "grading_files",
]

#: the folder of a course holding one folder per exercise
EXERCISES_DIR = "exercises"
#: an exercise folder's grading module
GRADING_MODULE = "grading.py"


class ExerciseSet:
    """The exercises of one course folder (``root``), sorted by id, and the course's mistakes.

    Pickled by its folder: unpickling discovers the course again (once per process).
    """

    def __init__(self, root: Path, exercises: tuple[Exercise, ...], folders: dict[str, Path],
                 catalogue: Catalogue, modules: dict[str, types.ModuleType]) -> None:
        self.root = root
        self.exercises = exercises
        self.catalogue = catalogue
        self._folders = folders
        self._modules = modules

    def __iter__(self) -> Iterator[Exercise]:
        return iter(self.exercises)

    def __len__(self) -> int:
        return len(self.exercises)

    def __reduce__(self):
        return (discover, (str(self.root),))

    def folder(self, exercise_id: str) -> Path:
        """The exercise's folder ``<course>/exercises/<id>``."""
        return self._folders[exercise_id]

    def module(self, exercise_id: str) -> types.ModuleType:
        """The exercise's grading module (its helpers: reference computations, input generators)."""
        return self._modules[exercise_id]

    def source_notebook(self, exercise: Exercise) -> Path:
        """The instructor's notebook of ``exercise``: ``exercises/<id>/<notebook's file name>``."""
        return self.folder(exercise.id) / Path(exercise.notebook).name

    def find(self, key: str | os.PathLike | Exercise) -> Exercise | None:
        """The exercise with id ``key``, or whose notebook is named like ``key`` (a path or a file
        name, with or without ``.ipynb``); None when there is none."""
        if isinstance(key, Exercise):
            return key if key in self.exercises else None
        if not isinstance(key, (str, os.PathLike)):
            raise TypeError(f"an exercise is looked up by id or notebook path, got {type(key).__name__}")
        text = os.fspath(key)
        name = Path(text).name
        stem = name.removesuffix(".ipynb")
        for ex in self.exercises:
            if text == ex.id or stem == ex.id or name == Path(ex.notebook).name:
                return ex
        return None

    def get(self, key: str | os.PathLike | Exercise) -> Exercise:
        """:meth:`find`, raising ``KeyError`` (naming the known ids) when there is none."""
        found = self.find(key)
        if found is None:
            known = ", ".join(ex.id for ex in self.exercises) or "none"
            raise KeyError(f"no exercise {os.fspath(key)!r} in {self.root}; known: {known}")
        return found


def exercise_folders(root: str | os.PathLike) -> list[Path]:
    """The folders ``<root>/exercises/*/`` holding a grading module, sorted by name."""
    base = Path(root) / EXERCISES_DIR
    if not base.is_dir():
        return []
    return sorted(
        d for d in base.iterdir()
        if d.is_dir() and not d.name.startswith(("_", ".")) and (d / GRADING_MODULE).is_file()
    )


#: what stays in the course's exercise folder: the notebook (the solutions), the worked solution and
#: other Markdown, the answers of the course's own tests
_COURSE_ONLY = ("*.ipynb", "*.md", "cases.py")
#: the marker of a solution block in a source of any language (``### BEGIN SOLUTION`` in a
#: notebook, ``// BEGIN SOLUTION`` in C++ or Java, ``% BEGIN SOLUTION`` in Octave, ...)
SOLUTION_MARKER = b"BEGIN SOLUTION"


def grading_files(folder: str | os.PathLike) -> list[Path]:
    """The files of an exercise folder the grader needs (sorted): all but notebooks, Markdown,
    ``cases.py``, files holding a solution block (:data:`SOLUTION_MARKER`: the answers in other
    languages), hidden files and caches."""
    folder = Path(folder)
    out = []
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder)
        if not p.is_file() or any(part.startswith(".") or part == "__pycache__" for part in rel.parts):
            continue
        if p.suffix == ".pyc" or any(p.match(pattern) for pattern in _COURSE_ONLY):
            continue
        if rel != Path(GRADING_MODULE) and SOLUTION_MARKER in p.read_bytes():
            continue  # (the grading module always goes: a release scan then reports a marker in it)
        out.append(p)
    return out


def _signature(folders: list[Path]) -> str:
    """Names, sizes and mtimes of the grading modules (a change discovers the course again)."""
    h = hashlib.sha256()
    for d in folders:
        st = (d / GRADING_MODULE).stat()
        h.update(f"{d.name}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


_DISCOVERED: dict[tuple[str, str], ExerciseSet] = {}


def discover(root: str | os.PathLike) -> ExerciseSet:
    """The exercises of the course folder ``root`` (see the module docstring).

    Raises
    ------
    FileNotFoundError
        ``root`` has no ``exercises/`` folder.
    ValueError
        A grading module defines no ``EXERCISE``, or one whose id is not its folder's name, or two
        exercises give one mistake id different messages.
    """
    root = Path(root).resolve()
    if not (root / EXERCISES_DIR).is_dir():
        raise FileNotFoundError(f"course folder {root} has no {EXERCISES_DIR}/ folder")
    folders = exercise_folders(root)
    key = (str(root), _signature(folders))
    found = _DISCOVERED.get(key)
    if found is None:
        found = _DISCOVERED[key] = _load(root, folders, key[1])
    return found


def _load(root: Path, folders: list[Path], signature: str) -> ExerciseSet:
    tag = hashlib.sha256(f"{root}\0{signature}".encode()).hexdigest()[:12]
    exercises: list[Exercise] = []
    modules: dict[str, types.ModuleType] = {}
    for folder in folders:
        module = _load_module(folder, f"_course_exercises_{tag}")
        modules[folder.name] = module
        ex = module.__dict__.get("EXERCISE")
        if not isinstance(ex, Exercise):
            raise ValueError(f"{folder / GRADING_MODULE} must define EXERCISE, an Exercise")
        if ex.id != folder.name:
            raise ValueError(f"{folder / GRADING_MODULE}: EXERCISE.id is {ex.id!r}, not its folder's name")
        exercises.append(dataclasses.replace(ex, mistakes=tuple(m.of(ex.id) for m in ex.mistakes)))
    catalogue = Catalogue(m for ex in exercises for m in ex.mistakes)
    exercises = [dataclasses.replace(ex, catalogue=catalogue) for ex in exercises]
    folder_of = {ex.id: f for ex, f in zip(exercises, folders)}
    return ExerciseSet(root, tuple(exercises), folder_of, catalogue, modules)


def _load_module(folder: Path, namespace: str) -> types.ModuleType:
    """Import ``folder/grading.py`` as ``<namespace>.<folder name>.grading`` (the folder a package of
    its own, so that the module may import files next to it relatively)."""
    if namespace not in sys.modules:
        top = types.ModuleType(namespace)
        top.__path__ = []
        sys.modules[namespace] = top
    package_name = f"{namespace}.{folder.name}"
    if package_name not in sys.modules:
        package = types.ModuleType(package_name)
        package.__path__ = [str(folder)]
        sys.modules[package_name] = package
    name = f"{package_name}.grading"
    spec = importlib.util.spec_from_file_location(name, folder / GRADING_MODULE)
    if spec is None or spec.loader is None:  # pragma: no cover - a .py file always has a loader
        raise ValueError(f"cannot import {folder / GRADING_MODULE}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # before running it: dataclasses look their module up
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module
