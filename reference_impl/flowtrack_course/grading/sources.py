"""Where a command's exercises come from: the course folder's exercises (discovered) and the answers
in other languages (:mod:`.languages`), as one :class:`~.engine.catalog.Catalog`.

The course folder is found as every tool finds it (:func:`flowtrack_course.course.course_root`:
``--course``, else ``$FLOWTRACK_COURSE``, else the current folder); a student's check also looks
above the file it checks (:func:`course_near`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ..course import ENV, CourseNotFound, course_root
from .engine.catalog import Catalog
from .engine.discovery import EXERCISES_DIR, discover
from .engine.spec import Exercise
from .languages import (
    LANGUAGE_EXERCISES,
    answered_exercises,
    find_language_exercise,
    release_languages,
    submitted_exercises,
)

__all__ = ["LanguageSource", "course_catalog", "course_near"]


class LanguageSource:
    """The answers in C++, Java, Octave and Mathematica as a source of exercises: each (problem,
    language) is graded when a student submitted its file (:mod:`.languages`)."""

    def exercises(self) -> Sequence[Exercise]:
        return LANGUAGE_EXERCISES

    def find(self, key: str | Path) -> Exercise | None:
        return find_language_exercise(key)

    def answered(self, student_dir: Path) -> Sequence[Exercise]:
        return answered_exercises(student_dir)

    def submitted(self, submissions: Path) -> Sequence[Exercise]:
        return submitted_exercises(submissions)

    def release(self, source: Path, dest: Path) -> list[str]:
        """Write the stubs of the language exercises found under ``source`` into ``dest``."""
        return release_languages(source, dest)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LanguageSource)

    def __hash__(self) -> int:
        return hash(LanguageSource)


def course_catalog(course: str | os.PathLike | None = None) -> Catalog:
    """The catalog of the course folder ``course`` (else ``$FLOWTRACK_COURSE``, else the current
    folder): its discovered exercises and the answers in other languages.

    Raises
    ------
    CourseNotFound
        The folder has no ``exercises/``.
    """
    return Catalog(discover(course_root(course, need=(EXERCISES_DIR,))), (LanguageSource(),))


def course_near(path: str | os.PathLike, course: str | os.PathLike | None = None) -> Catalog:
    """The catalog for a file or folder ``path`` of a course: the course folder ``course`` (or
    ``$FLOWTRACK_COURSE``) when given, else the current folder when it holds ``exercises/``, else the
    nearest folder above ``path`` whose ``exercises/`` holds ``path`` (a bundle's
    ``exercises/<file>``, a course's ``exercises/<id>/<file>``).

    Raises
    ------
    CourseNotFound
        No such folder.
    """
    if course is not None or os.environ.get(ENV):
        return course_catalog(course)
    try:
        return course_catalog(None)
    except CourseNotFound as exc:
        here = Path(path).resolve()
        for parent in here.parents:
            if (parent / EXERCISES_DIR).is_dir() and here.is_relative_to(parent / EXERCISES_DIR):
                return course_catalog(parent)
        raise exc
