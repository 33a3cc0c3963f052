"""Where a command's exercises come from: the course folder's exercises (discovered) and the answers
in other languages (:mod:`.languages`), as one :class:`~.engine.catalog.Catalog`.

The course folder is found as every tool finds it (:func:`flowtrack_course.course.course_root`:
``--course``, else ``$FLOWTRACK_COURSE``, else the current folder); a student's check also looks
above the file it checks (:func:`course_near`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..course import ENV, CourseNotFound, course_root
from .engine.catalog import Catalog
from .engine.discovery import EXERCISES_DIR, discover
from .languages import LanguageSource

__all__ = ["LanguageSource", "course_catalog", "course_near"]


def course_catalog(course: str | os.PathLike | None = None) -> Catalog:
    """The catalog of the course folder ``course`` (else ``$FLOWTRACK_COURSE``, else the current
    folder): its discovered exercises and their answers in other languages
    (:class:`~.languages.LanguageSource`).

    Raises
    ------
    CourseNotFound
        The folder has no ``exercises/``.
    """
    found = discover(course_root(course, need=(EXERCISES_DIR,)))
    return Catalog(found, (LanguageSource(found),))


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
