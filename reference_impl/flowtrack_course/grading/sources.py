"""Where a command's exercises come from: the course folder's exercises (discovered) and the answers
in other languages (:mod:`.languages`), as one :class:`~.engine.catalog.Catalog`, with what the
instructor's assignment counts (:mod:`.assignment`).

The course folder is found as every tool finds it (:func:`flowtrack_course.course.course_root`:
``--course``, else ``$FLOWTRACK_COURSE``, else the current folder); a student's check also looks
above the file it checks (:func:`course_near`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..course import ENV, CourseNotFound, course_root
from .assignment import Assignment, assignment_of
from .engine.catalog import Catalog
from .engine.discovery import EXERCISES_DIR, discover
from .languages import LanguageSource

__all__ = ["LanguageSource", "course_catalog", "course_near"]


def course_catalog(course: str | os.PathLike | None = None,
                   assignment: Assignment | str | os.PathLike | None = None) -> Catalog:
    """The catalog of the course folder ``course`` (else ``$FLOWTRACK_COURSE``, else the current
    folder): its discovered exercises and their answers in other languages
    (:class:`~.languages.LanguageSource`), counted as ``assignment`` says (an :class:`Assignment`, or
    the path of an ``assignment.toml``; default: the course's own file when it has one, else every
    notebook exercise and no other language).

    Raises
    ------
    CourseNotFound
        The folder has no ``exercises/``.
    ValueError
        The assignment names an exercise or a language the course does not have.
    """
    root = course_root(course, need=(EXERCISES_DIR,))
    found = discover(root)
    if not isinstance(assignment, Assignment):
        assignment = assignment_of(root, assignment)
    plain = Catalog(found)
    where = f"{assignment.source}: " if assignment.source else ""
    try:
        notebooks = None if assignment.exercises is None else tuple(plain.resolve_ids(assignment.exercises))
        owners = (notebooks if assignment.language_exercises is None
                  else tuple(plain.resolve_ids(assignment.language_exercises)))
        languages = LanguageSource(found, assignment.languages, owners, assignment.language_choice)
        forms = {ex.exercise for ex in languages.exercises()}
        formless = [e for e in owners or () if e not in forms]
        if assignment.language_exercises is not None and formless:
            raise ValueError(f"language_exercises: {', '.join(formless)} has no form in other languages "
                             f"(those that have one: {', '.join(sorted(forms))})")
    except ValueError as exc:
        raise ValueError(f"{where}{exc}") from None
    return Catalog(found, (languages,), notebooks)


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
