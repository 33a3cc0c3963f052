"""The answers in other languages of one course as a source of exercises (the engine's
:class:`~flowtrack_course.grading.engine.catalog.ExerciseSource`), and their files in the bundle.

A course's language exercises are discovered with its notebooks (:func:`.exercises.language_exercises`);
each is graded when a student submitted its file. The instructor's sources, with their solutions
between ``BEGIN SOLUTION`` / ``END SOLUTION`` comment lines, are in the folder of the exercise they
are a form of, one sub-folder per language::

    exercises/ex05_cv_model/cpp/cv_model.cpp
    exercises/ex05_cv_model/java/CvModel.java
    exercises/ex05_cv_model/octave/cv_model.m
    exercises/ex05_cv_model/mathics/cv_model.wl

and each language's guide for students in ``exercises/languages/<lang>.md``. A course folder laid
out the earlier way (``exercises/<lang>/<problem>/<file>``, ``exercises/<lang>/README.md``) is read
too. The bundle and the submissions keep the students' paths, ``exercises/<lang>/<problem>/<file>``
(the exercise's ``notebook``), whatever the course's layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ...polyglot.toolchains import GRADED_LANGUAGES, TOOLCHAINS
from ..engine.discovery import EXERCISES_DIR, ExerciseSet
from ..engine.mistakes import Catalogue
from .exercises import LanguageExercise, language_catalogue, language_exercises, materialise

__all__ = ["GUIDES_DIR", "LanguageSource"]

#: the folder of ``exercises/`` holding each language's guide for students (``<lang>.md``)
GUIDES_DIR = "languages"


class LanguageSource:
    """The answers in C++, Java, Octave and Mathematica of the course ``course`` (see the module
    docstring): each (problem, language) is graded when a student submitted its file.

    Picklable (by its course, discovered again on the other side), as a class run's workers need.
    """

    def __init__(self, course: ExerciseSet) -> None:
        self.course = course
        self._exercises = language_exercises(course)

    def __reduce__(self):
        return (LanguageSource, (self.course,))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LanguageSource) and other.course.root == self.course.root

    def __hash__(self) -> int:
        return hash((LanguageSource, self.course.root))

    @property
    def catalogue(self) -> Catalogue:
        """The mistakes the language exercises may name, with their messages."""
        return language_catalogue(self.course)

    def exercises(self) -> Sequence[LanguageExercise]:
        return self._exercises

    def find(self, key: str | Path) -> LanguageExercise | None:
        """The language exercise with id ``key`` or whose source file is named like ``key`` (a path or
        a name; the file names are unique: ``cv_model.cpp``, ``CvModel.java``, ``cv_model.m``, ...)."""
        key = str(key)
        name = Path(key).name
        for ex in self._exercises:
            if key == ex.id or name == ex.source_name:
                return ex
        return None

    def answered(self, student_dir: Path) -> Sequence[LanguageExercise]:
        """The language exercises one student's folder holds a source file of (by file name, anywhere
        below it: Gradescope uploads are often flat)."""
        root = Path(student_dir)
        if not root.is_dir():
            return ()
        exts = {TOOLCHAINS[lang].extension for lang in GRADED_LANGUAGES}
        names = {p.name for p in root.rglob("*") if p.suffix in exts}
        return tuple(ex for ex in self._exercises if ex.source_name in names)

    def submitted(self, submissions: Path) -> Sequence[LanguageExercise]:
        """The language exercises at least one student folder of ``submissions`` holds a source file of.

        ``flowtrack grade`` adds them to the notebooks, so a class answering only in Python gets the
        same ``grades.csv`` as before, and every answered (exercise, language) item gets its column.
        """
        root = Path(submissions)
        found: set[str] = set()
        for d in sorted(root.iterdir()) if root.is_dir() else []:
            if d.is_dir() and not d.name.startswith("."):
                found.update(ex.id for ex in self.answered(d))
        return tuple(ex for ex in self._exercises if ex.id in found)

    # -- the instructor's sources and the bundle -----------------------------------------------------
    def instructor_source(self, ex: LanguageExercise) -> Path | None:
        """The instructor's file of ``ex`` (with its solution): in the folder of the exercise it is a
        form of, else at the earlier layout's path; None when the course has neither."""
        exercises = self.course.root / EXERCISES_DIR
        for path in (self.course.folder(ex.exercise) / ex.language / ex.source_name, exercises / ex.notebook):
            if path.is_file():
                return path
        return None

    def guide(self, language: str) -> Path | None:
        """The students' guide to answering in ``language`` (``exercises/languages/<lang>.md``, or
        the earlier layout's ``exercises/<lang>/README.md``), None when the course has none."""
        exercises = self.course.root / EXERCISES_DIR
        for path in (exercises / GUIDES_DIR / f"{language}.md", exercises / language / "README.md"):
            if path.is_file():
                return path
        return None

    def release(self, source: Path, dest: Path) -> list[str]:
        """Write the stub of every language exercise the course has a source of into ``dest`` (the
        bundle's ``exercises/``) at the students' paths, with the public tests, the build files and
        each language's guide as ``<lang>/README.md``; return the student files written (relative
        to ``dest``). ``source`` is the course's ``exercises/`` folder (this source's course)."""
        if Path(source).resolve() != (self.course.root / EXERCISES_DIR).resolve():
            raise ValueError(f"source: {source} is not the exercises folder of {self.course.root}")
        written = []
        for ex in self._exercises:
            src = self.instructor_source(ex)
            if src is None:
                continue
            materialise(ex, src.parent, Path(dest) / ex.language / ex.problem, stub=True)
            guide = self.guide(ex.language)
            if guide is not None:
                (Path(dest) / ex.language / "README.md").write_text(
                    guide.read_text(encoding="utf-8"), encoding="utf-8"
                )
            written.append(ex.notebook)
        return written
