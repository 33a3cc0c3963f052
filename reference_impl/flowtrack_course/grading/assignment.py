"""What counts in an assignment: which exercises, and in which other languages, as the instructor
fixes it in ``assignment.toml`` (read by ``flowtrack grade`` and the Gradescope autograder).

A class's maximum is the instructor's, never the students': a file a student uploads outside the
assignment (an answer in a language that is not assigned, an exercise that is not) is ignored, with
a note in that student's feedback, and never adds a column to ``grades.csv`` nor points to anyone's
maximum (the ``max`` column, Canvas' "Points Possible", Moodle's grade items, Gradescope's total).

The file
--------
``assignment.toml`` in the course folder (``flowtrack grade --assignment-file FILE`` names
another; ``flowtrack gradescope`` puts it into the zip)::

    # the notebook exercises that count: ids or their exNN prefixes (default: every exercise)
    exercises = ["ex05", "ex06", "ex07"]

    # the other languages answers count in: cpp, java, octave, mathics (default: none)
    languages = ["cpp", "java"]

    # which exercises are to be answered in those languages (default: every exercise above that
    # has a form in them: ex01, ex05, ex06, ex07, ex08)
    language_exercises = ["ex05", "ex06"]

    # "one" (default): each student answers in ONE of the languages, their choice (the language of
    # the files they submit; a student who submits none is graded in the first one listed, 0 points);
    # "all": every student answers in every language listed
    language_choice = "one"

Every key is optional. **Without a file** every notebook exercise of the course counts and no answer
in another language does (a class answering in Python only is graded as it always was; files in other
languages are ignored, with a note). With ``language_choice = "one"`` every listed exercise must be
set in every listed language (so that every choice is worth the same); the class's ``grades.csv`` has
a column per language item, blank for a student who chose another language, and every student's
``max`` is the same.

Examples
--------
>>> a = parse_assignment('exercises = ["ex05"]\\nlanguages = ["cpp", "java"]\\n')
>>> a.exercises, a.languages, a.language_exercises, a.language_choice
(('ex05',), ('cpp', 'java'), None, 'one')
>>> Assignment().describe()
'every exercise of the course; no other languages'
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["FILE_NAME", "Assignment", "assignment_of", "parse_assignment", "read_assignment"]

#: the assignment file of a course folder
FILE_NAME = "assignment.toml"
_CHOICES = ("one", "all")
_KEYS = ("exercises", "languages", "language_exercises", "language_choice")


@dataclass(frozen=True)
class Assignment:
    """What counts (see the module docstring).

    Attributes
    ----------
    exercises : tuple of str or None
        The notebook exercises (ids or ``exNN`` prefixes, resolved against the course); None: all.
    languages : tuple of str
        The other languages whose answers count; empty: none.
    language_exercises : tuple of str or None
        The exercises to be answered in ``languages``; None: each of ``exercises`` that has a form in
        them.
    language_choice : str
        ``"one"`` (each student answers in one of ``languages``) or ``"all"``.
    source : str
        Where it was read (``""``: the default).
    """

    exercises: tuple[str, ...] | None = None
    languages: tuple[str, ...] = ()
    language_exercises: tuple[str, ...] | None = None
    language_choice: str = "one"
    source: str = ""

    def __post_init__(self) -> None:
        if self.language_choice not in _CHOICES:
            raise ValueError(
                f"{self._where()}language_choice must be 'one' or 'all', got {self.language_choice!r}")
        for name in ("exercises", "languages", "language_exercises"):
            value = getattr(self, name)
            if value is None and name != "languages":
                continue
            if isinstance(value, str) or not all(isinstance(v, str) and v.strip() for v in value):
                raise ValueError(f"{self._where()}{name} must be a list of names, got {value!r}")
            object.__setattr__(self, name, tuple(v.strip() for v in value))
        if len(set(self.languages)) != len(self.languages):
            raise ValueError(f"{self._where()}languages lists a language twice: {list(self.languages)}")

    def _where(self) -> str:
        return f"{self.source}: " if self.source else ""

    def describe(self) -> str:
        """One line for the run's summary: what counts."""
        ex = "every exercise of the course" if self.exercises is None else ", ".join(self.exercises)
        if not self.languages:
            return f"{ex}; no other languages"
        forms = "each of them" if self.language_exercises is None else ", ".join(self.language_exercises)
        how = "one of" if self.language_choice == "one" and len(self.languages) > 1 else "each of"
        return f"{ex}; {forms} also answered in {how} {', '.join(self.languages)}"


def parse_assignment(text: str, source: str = "") -> Assignment:
    """The :class:`Assignment` of an ``assignment.toml`` text.

    Raises
    ------
    ValueError
        Not TOML, an unknown key (with the known ones), or a value of the wrong kind.
    """
    import tomllib

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source or 'assignment'}: not a TOML file ({exc})") from None
    unknown = sorted(set(data) - set(_KEYS))
    if unknown:
        raise ValueError(f"{source or 'assignment'}: unknown key(s) {unknown}; known: {', '.join(_KEYS)}")
    for key in ("exercises", "languages", "language_exercises"):
        if key in data and not isinstance(data[key], list):
            raise ValueError(f"{source or 'assignment'}: {key} must be a list, e.g. {key} = [\"...\"]")
    return Assignment(
        exercises=tuple(data["exercises"]) if "exercises" in data else None,
        languages=tuple(data.get("languages", ())),
        language_exercises=tuple(data["language_exercises"]) if "language_exercises" in data else None,
        language_choice=str(data.get("language_choice", "one")),
        source=source,
    )


def read_assignment(path: str | os.PathLike) -> Assignment:
    """:func:`parse_assignment` of the file ``path``.

    Raises
    ------
    FileNotFoundError
        No such file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"assignment: no such file: {path}")
    return parse_assignment(path.read_text(encoding="utf-8"), str(path))


def assignment_of(course: str | os.PathLike, path: str | os.PathLike | None = None) -> Assignment:
    """The assignment of a course folder: the file ``path`` when given, else the course's
    ``assignment.toml`` when it has one, else the default (every notebook exercise, no languages)."""
    if path is not None:
        return read_assignment(path)
    own = Path(course) / FILE_NAME
    return read_assignment(own) if own.is_file() else Assignment()
