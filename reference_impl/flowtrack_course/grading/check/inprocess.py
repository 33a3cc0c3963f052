r"""The in-process path: an exercise's tests run on functions in a namespace (nbgrader; NOT a sandbox).

:func:`run_in_process` runs the same tests as ``flowtrack grade`` on functions found in a namespace
dict (the notebook's ``globals()``): it converts inputs and results to plain data exactly as the
sandboxed child does (:mod:`grading_sandbox.wire`), seeds public tests with the same fixed seed as
``flowtrack grade`` and ``flowtrack check`` (:func:`~flowtrack_course.grading.engine.seeds.public_seed`:
a student sees the same public inputs in every path), and applies the same scorers with the same
clipping (a NaN or infinite fraction earns 0). It is what the notebooks' own hidden-test blocks
call, so that ``nbgrader autograde`` also grades these notebooks (with partial credit). It executes
student code in the calling process and is therefore **not secure**: the grader runs student code
only in :mod:`grading_sandbox`.

An exercise named by its id is looked up in the course folder (``$FLOWTRACK_COURSE``, else the
current folder, else the folder above the current one that holds ``exercises/``: a notebook's
kernel runs in the notebook's folder).

Examples
--------
>>> import numpy as np
>>> from flowtrack_course.grading.engine.authoring import Exercise, array_check, graded_test
>>> @graded_test("twice", "test_twice", 1.0, hidden=False)
... def twice(rng):
...     return [("double", (2.0,), {}, array_check(np.array(4.0)))]
>>> ex = Exercise("ex99_demo", "demo", "ex99_demo.ipynb", ("double",), (), (twice,))
>>> [(name, earned) for name, earned, _, _ in run_in_process(ex, {"double": lambda x: 2 * x})]
[('twice', 1.0)]
"""

from __future__ import annotations

import contextlib
import json
import math
import signal
import threading
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from grading_sandbox import formula
from grading_sandbox.errors import exception_text, missing_function, not_plain
from grading_sandbox.wire import NotPlainData, as_child_receives, plain_data

from ..engine.feedback import safe_text
from ..engine.mistakes import mistakes_of
from ..engine.results import format_score
from ..engine.run import catalogue_of
from ..engine.seeds import public_seed, student_seed
from ..engine.spec import Call, Exercise, Outcome

__all__ = ["call_all", "run_in_process"]


class _Timeout(BaseException):  # BaseException: a student's `except Exception` cannot swallow it
    pass


@contextlib.contextmanager
def _alarm(seconds: float):
    usable = hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if not usable or not seconds or seconds <= 0:
        yield
        return

    def handler(signum, frame):
        raise _Timeout()

    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)


def call_all(namespace: Mapping[str, Any], calls: Sequence[Call], timeout: float) -> list[Outcome]:
    """Make ``calls`` of the functions in ``namespace`` in this process, as the sandboxed child does
    (arguments rebuilt from plain data, results converted to plain data, a formula read by
    :mod:`grading_sandbox.formula`, errors told by the child's own formatter,
    :func:`grading_sandbox.errors.exception_text`), all of them within ``timeout`` seconds; one
    outcome per call."""
    outcomes: list[Outcome] = []
    try:
        with _alarm(timeout), warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            for call in calls:
                fn = namespace.get(call.function)
                if fn is None:
                    outcomes.append(Outcome(False, error=missing_function(call.function)))
                    continue
                if not callable(fn):
                    error = exception_text(TypeError(f"{call.function!r} is not a function"))
                    outcomes.append(Outcome(False, error=error))
                    continue
                args = [as_child_receives(a) for a in call.args]
                kwargs = {k: as_child_receives(v) for k, v in call.kwargs.items()}
                try:
                    value = fn(*args, **kwargs)
                    if call.post is not None:  # as the sandboxed child does (see grading_sandbox.formula)
                        value = formula.apply(json.loads(json.dumps(dict(call.post))), value)
                    value = plain_data(value)
                    value = json.loads(json.dumps(value, allow_nan=True))
                except NotPlainData as exc:
                    outcomes.append(Outcome(False, error=not_plain(str(exc))))
                except (_Timeout, KeyboardInterrupt):
                    raise
                except BaseException as exc:  # SystemExit included: an answer that exits fails
                    outcomes.append(Outcome(False, error=exception_text(exc)))
                else:
                    outcomes.append(Outcome(True, value=value))
    except _Timeout:
        pass
    while len(outcomes) < len(calls):
        outcomes.append(Outcome(False, error=f"timed out after {timeout:g} s"))
    return outcomes


def _clip_fraction(fraction: Any) -> float:
    """A scorer's fraction as ``flowtrack grade`` counts it: clipped to [0, 1], NaN and inf give 0.

    (``min(max(nan, 0.0), 1.0)`` is NaN: Python's ``max``/``min`` keep their first argument when a
    comparison with NaN is false.)
    """
    fraction = float(fraction)
    if not math.isfinite(fraction):
        return 0.0
    return min(1.0, max(0.0, fraction))


def run_in_process(
    exercise: Exercise | str,
    namespace: Mapping[str, Any],
    student: str = "public",
    *,
    cell: str | None = None,
    hidden: bool | None = None,
    verbose: bool = False,
) -> list[tuple[str, float, float, str]]:
    """Run an exercise's tests on the functions in ``namespace`` in this process (insecure).

    Parameters
    ----------
    exercise : Exercise or str
        The exercise or its id / notebook name (looked up in the course, see the module docstring).
    namespace : mapping
        Where the student's functions live (a notebook's ``globals()``).
    student : str
        Seeds the hidden tests' inputs (:func:`~flowtrack_course.grading.engine.seeds.student_seed`,
        without a secret). Public tests always use
        :func:`~flowtrack_course.grading.engine.seeds.public_seed`, the seed ``flowtrack grade`` and
        ``flowtrack check`` give them.
    cell : str, optional
        Only the tests of this notebook test cell (``grade_id``).
    hidden : bool, optional
        Only hidden (True) or only public (False) tests.
    verbose : bool
        Print one line per test (name and score; messages of public tests only).

    Returns
    -------
    list of (test name, points earned, max points, message)
        ``points x clip(fraction, 0, 1)`` as in ``flowtrack grade`` (a NaN or infinite fraction
        earns 0). Hidden tests' messages are replaced by their score only.
    """
    ex = exercise if isinstance(exercise, Exercise) else _course_exercise(exercise)
    catalogue = catalogue_of(ex)
    results = []
    for test in ex.tests:
        if cell is not None and test.grade_id != cell:
            continue
        if hidden is not None and test.hidden != hidden:
            continue
        if test.hidden:
            seed = student_seed(student, ex.id, test.name)
        else:
            seed = public_seed(ex.id, test.name)
        calls, scorer = test.build(np.random.default_rng(seed))
        outcomes = call_all(namespace, calls, test.timeout)
        fraction, message = scorer(outcomes)
        earned = round(test.points * _clip_fraction(fraction), 6)
        lines = catalogue.lines(mistakes_of(message))
        if test.hidden:
            safe = safe_text(message) if earned < test.points else ""
            head = f"hidden test: {format_score(earned)}/{format_score(test.points)}"
            message = "\n".join([head, *([safe] if safe else []), *lines])
        elif lines:
            message = "\n".join([str(message), *lines])
        results.append((test.name, earned, float(test.points), message))
        if verbose:
            shown = "" if test.hidden else f" - {message}"
            print(f"{test.name}: {format_score(earned)}/{format_score(test.points)}{shown}")
    return results


def _course_exercise(key: str) -> Exercise:
    """The exercise ``key`` of the course folder (see the module docstring)."""
    from pathlib import Path

    from ..sources import course_near

    return course_near(Path.cwd() / key).course.get(key)
