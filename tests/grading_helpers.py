"""Shared test doubles and the course's exercises for the grader's tests.

The exercises are discovered in this checkout (``exercises/<id>/``), as the grader finds them; each
folder's ``cases.py`` holds the answers the tests grade it with (see :func:`answer`).
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from typing import ClassVar

from flowtrack_course.grading.engine.discovery import discover
from flowtrack_course.grading.engine.jobs import ClassJob, GradingOptions, StudentJob
from flowtrack_course.grading.engine.spec import Outcome
from flowtrack_course.grading.languages import LanguageSource
from flowtrack_course.grading.sources import course_catalog
from grading_sandbox.testing import SANDBOX_MODES, use_sandbox_mode
from grading_sandbox.wire import plain_data

__all__ = [
    "COURSE",
    "COURSE_SET",
    "EXERCISES",
    "LANGUAGES",
    "LANGUAGE_EXERCISES",
    "SANDBOX_MODES",
    "RecordingSandbox",
    "StandInSandbox",
    "answer",
    "answer_sources",
    "cases",
    "catalog",
    "class_job",
    "run_grade_with",
    "student_job",
    "exercise_module",
    "find_language_exercise",
    "get_exercise",
    "instructor_source",
    "replace_solution",
    "source_notebook",
    "use_sandbox_mode",
]

#: this checkout: the course folder under test
COURSE = Path(__file__).resolve().parents[1]
#: the course's exercises, as the grader discovers them
COURSE_SET = discover(COURSE)
EXERCISES = COURSE_SET.exercises
#: the course's answers in other languages, as the grader discovers them
LANGUAGES = LanguageSource(COURSE_SET)
LANGUAGE_EXERCISES = LANGUAGES.exercises()


def catalog():
    """The catalog ``flowtrack grade`` uses for this course (the notebooks and the other languages)."""
    return course_catalog(COURSE)


def get_exercise(key):
    """An exercise of the course by id, notebook name or path (``KeyError`` when there is none)."""
    return COURSE_SET.get(key)


def find_language_exercise(key):
    """A language exercise of the course by id or source file name (None when there is none)."""
    return LANGUAGES.find(key)


def instructor_source(ex) -> Path:
    """The instructor's source of a language exercise (with its solution)."""
    path = LANGUAGES.instructor_source(ex)
    assert path is not None, ex.id
    return path


def exercise_module(exercise_id: str):
    """The grading module of an exercise (its reference computations and input generators)."""
    return COURSE_SET.module(exercise_id)


def source_notebook(ex) -> Path:
    """The instructor's notebook of ``ex``: ``exercises/<id>/<notebook>``."""
    return COURSE_SET.source_notebook(ex)


def cases(exercise_id: str):
    """The exercise folder's ``cases.py`` (answers the course's tests grade it with)."""
    path = COURSE_SET.folder(exercise_id) / "cases.py"
    spec = importlib.util.spec_from_file_location(f"_cases_{exercise_id}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def answer_sources(nb, ex) -> dict[str, str]:
    """``{grade_id: source}`` of the answer cells of an nbformat notebook, in ``ex``'s order."""
    src = {
        c.metadata.get("nbgrader", {}).get("grade_id"): c.source
        for c in nb.cells
        if c.cell_type == "code" and c.metadata.get("nbgrader", {}).get("solution")
    }
    return {gid: src[gid] for gid in ex.answer_cells}


def replace_solution(source: str, body: str) -> str:
    """Put ``body`` (unindented) between the solution markers of an answer cell."""
    m = re.search(r"^( *)### BEGIN SOLUTION\n.*?^ *### END SOLUTION", source, flags=re.S | re.M)
    assert m, "no solution region"
    indent = m.group(1)
    new = "\n".join(indent + line if line else line for line in body.strip("\n").splitlines())
    return source[: m.start()] + new + source[m.end() :]


def _apply(source: str, edit) -> str:
    kind, *args = edit
    if kind == "body":
        return replace_solution(source, args[0])
    if kind == "replace":
        assert args[0] in source, (args[0], source[:200])
        return source.replace(args[0], args[1])
    if kind == "prepend":
        return args[0] + source
    if kind == "append":
        return source + args[0]
    if kind == "source":
        return args[0]
    raise ValueError(f"unknown edit {kind!r}")


def answer(solution: dict[str, str], edits: dict) -> dict[str, str]:
    """The solution's answer cells with ``edits`` (``{grade_id: edit or [edits]}``, see ``cases.py``)
    applied."""
    src = dict(solution)
    for gid, ops in edits.items():
        for op in ops if isinstance(ops, list) else [ops]:
            src[gid] = _apply(src[gid], op)
    return src


_JOB = ("exercises", "jobs", "progress", "allow_unsafe_sandbox", "renamed", "log", "catalog")


def _split(kwargs: dict) -> tuple[dict, GradingOptions]:
    job = {k: kwargs.pop(k) for k in _JOB if k in kwargs}
    if "hidden_paths" in kwargs:
        kwargs["hidden_paths"] = tuple(str(p) for p in kwargs["hidden_paths"])
    return job, GradingOptions(**kwargs)


def class_job(submissions, out, **kwargs) -> ClassJob:
    """A :class:`ClassJob` of this course from keywords (tests' shorthand): those of the job
    (``exercises``, ``jobs``, ``progress`` (default False), ...) and those of its
    :class:`GradingOptions` (``secret``, ``force``, ``sandbox_factory``, ...)."""
    kwargs.setdefault("progress", False)
    job, options = _split(dict(kwargs))
    job.setdefault("catalog", catalog())
    if job.get("exercises") is not None:
        job["exercises"] = tuple(job["exercises"])
    return ClassJob(Path(submissions), Path(out), options=options, **job)


def student_job(student, folder, exercises, out, **kwargs) -> StudentJob:
    """A :class:`StudentJob` from keywords (``renamed`` and :class:`GradingOptions`' fields)."""
    renamed = kwargs.pop("renamed", None) or {}
    if "hidden_paths" in kwargs:
        kwargs["hidden_paths"] = tuple(str(p) for p in kwargs["hidden_paths"])
    return StudentJob(student, Path(folder), Path(out), tuple(exercises), GradingOptions(**kwargs),
                      renamed=renamed)


def run_grade_with(submissions, out, **kwargs):
    """``run_grade`` from keywords: its own (``assignment``, ``accept_renamed``, ``roster``, ``lms``,
    ``lms_mode``) and :func:`class_job`'s."""
    from flowtrack_course.grading.grade import run_grade

    names = ("assignment", "accept_renamed", "roster", "lms", "lms_mode", "ignore_flat")
    own = {k: kwargs.pop(k) for k in names if k in kwargs}
    return run_grade(class_job(submissions, out, **kwargs), **own)


class StandInSandbox:
    """Base of the sandbox stand-ins for ``run_exercise``: no process, no student code run.

    Subclasses set :attr:`isolation` and define ``run(calls, timeout) -> list[Outcome]``; the
    constructor takes the answer cells (``[(grade_id, source), ...]``) and ignores the limits.
    """

    isolation = "stand-in"

    def __init__(self, cells, **kwargs):
        self.cells = list(cells)
        self.cell_errors: dict[str, str] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class RecordingSandbox(StandInSandbox):
    """Sandbox stand-in for ``run_exercise``: records the calls it is sent and echoes their argument.

    ``sent`` holds ``(function, plain data of the arguments)`` of every call since the caller last
    emptied it; nothing of the student's code is run (what is checked is the inputs sent).
    """

    sent: ClassVar[list[tuple[str, list]]] = []
    isolation = "recording"

    def run(self, calls, timeout):
        self.sent.extend((c.function, plain_data(list(c.args))) for c in calls)
        return [Outcome(True, plain_data(c.args[0])) for c in calls]
