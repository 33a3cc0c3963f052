"""The answers in other languages of one course as a source of exercises (the engine's
:class:`~flowtrack_course.grading.engine.catalog.ExerciseSource`), and their files in the bundle.

A course's language exercises are discovered with its notebooks (:func:`.exercises.language_exercises`);
those the instructor's assignment lists count (:mod:`flowtrack_course.grading.assignment`: which
languages, which exercises, one language of each student's choice or all), whatever the students
upload: a file outside the assignment is ignored with a note. The instructor's sources, with their solutions
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
    docstring). ``languages`` are the assigned languages (none by default), ``exercises`` the ids of
    the course's exercises whose forms in them count (None: all), ``choice`` ``"one"`` (each student
    answers in one of ``languages``, their choice) or ``"all"``.

    Picklable (by its course, discovered again on the other side), as a class run's workers need.

    Raises
    ------
    ValueError
        An unknown language or exercise, or (``choice="one"``) an exercise that is not set in every
        listed language (every choice must be worth the same).
    """

    def __init__(self, course: ExerciseSet, languages: Sequence[str] = (),
                 exercises: Sequence[str] | None = None, choice: str = "one") -> None:
        self.course = course
        self._exercises = language_exercises(course)
        self.languages = tuple(languages)
        self.owners = None if exercises is None else tuple(exercises)
        self.choice = choice
        unknown = [lang for lang in self.languages if lang not in GRADED_LANGUAGES]
        if unknown:
            raise ValueError(f"languages: no graded language {unknown}; known: {', '.join(GRADED_LANGUAGES)}")
        if choice not in ("one", "all"):
            raise ValueError(f"choice must be 'one' or 'all', got {choice!r}")
        self._assigned = tuple(ex for ex in self._exercises if ex.language in self.languages
                               and (self.owners is None or ex.exercise in self.owners))
        if choice == "one" and len(self.languages) > 1:
            owners = sorted({ex.exercise for ex in self._assigned})
            for owner in owners:
                missing = [lang for lang in self.languages
                           if not any(ex.exercise == owner and ex.language == lang for ex in self._assigned)]
                if missing:
                    raise ValueError(
                        f"{owner} is not set in {', '.join(missing)}: with language_choice = 'one' every "
                        "listed exercise must be set in every listed language (each choice is worth the "
                        "same); list the exercises that are (language_exercises) or use "
                        "language_choice = 'all'")

    def __reduce__(self):
        return (LanguageSource, (self.course, self.languages, self.owners, self.choice))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LanguageSource) and (other.course.root, other.languages, other.owners,
                                                      other.choice) == (self.course.root, self.languages,
                                                                        self.owners, self.choice)

    def __hash__(self) -> int:
        return hash((LanguageSource, self.course.root, self.languages, self.owners, self.choice))

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

    def _files(self, student_dir: Path) -> dict[str, Path]:
        """``{file name: first path}`` of the source files below a student's folder (by file name,
        anywhere: Gradescope uploads are often flat)."""
        root = Path(student_dir)
        if not root.is_dir():
            return {}
        exts = {TOOLCHAINS[lang].extension for lang in GRADED_LANGUAGES}
        out: dict[str, Path] = {}
        for p in sorted(root.rglob("*")):
            if p.suffix in exts and p.name not in out:
                out[p.name] = p
        return out

    def answered(self, student_dir: Path) -> Sequence[LanguageExercise]:
        """The language exercises (assigned or not) one student's folder holds a source file of."""
        names = self._files(student_dir)
        return tuple(ex for ex in self._exercises if ex.source_name in names)

    def assigned(self) -> Sequence[LanguageExercise]:
        """The assigned items: each listed exercise in each listed language."""
        return self._assigned

    def chosen(self, student_dir: Path) -> str | None:
        """The language a student is graded in (``choice="one"``): the listed one they submitted most
        assigned files in (the first listed on a tie, or when they submitted none)."""
        if not self.languages:
            return None
        names = self._files(student_dir)
        count = {lang: sum(ex.language == lang and ex.source_name in names for ex in self._assigned)
                 for lang in self.languages}
        return max(self.languages, key=lambda lang: (count[lang], -self.languages.index(lang)))

    def for_student(self, student_dir: Path) -> Sequence[LanguageExercise]:
        """The assigned items of the student's language (``"one"``), or all of them (``"all"``)."""
        if self.choice == "all" or len(self.languages) <= 1:
            return self._assigned
        lang = self.chosen(student_dir)
        return tuple(ex for ex in self._assigned if ex.language == lang)

    def ignored(self, student_dir: Path) -> list[str]:
        """A note per submitted source file that is not graded, and why."""
        files = self._files(student_dir)
        graded = {ex.id for ex in self.for_student(student_dir)}
        lang = self.chosen(student_dir) if self.choice == "one" and len(self.languages) > 1 else None
        assigned = {ex.id for ex in self._assigned}
        notes = []
        for ex in self._exercises:
            path = files.get(ex.source_name)
            if path is None or ex.id in graded:
                continue
            shown = path.relative_to(student_dir).as_posix()
            title = TOOLCHAINS[ex.language].title
            if ex.language not in self.languages:
                why = f"answers in {title} are not part of this assignment"
            elif ex.id not in assigned:
                why = f"{ex.exercise} answered in {title} is not part of this assignment"
            else:
                chosen = TOOLCHAINS[lang].title if lang else ""
                why = (f"this assignment is answered in one language of your choice, and yours is {chosen} "
                       "(the listed language you submitted most files in)")
            notes.append(f"ignored {shown}: {why}")
        return notes

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
