"""Running one exercise: a submission's answer cells in a sandboxed child, each test's calls, and
the trusted scorers on the plain-data outcomes (:func:`run_exercise`).

The grading process never imports or executes student code. For each test it builds the calls from
a seeded generator, runs them in the child, and scores the outcomes with the test's trusted scorer.
A test earns ``points x fraction`` with ``fraction`` from the scorer alone, so the score of a test is

.. math:: s_t = p_t \\, \\mathrm{clip}(f_t, 0, 1), \\qquad S = \\sum_t s_t \\le \\sum_t p_t .

Hidden tests draw their inputs from ``student_seed(student, exercise.id, test.name, secret)``, keyed
by the instructor's secret when one is given (without it the hidden inputs are predictable from the
student's name); public tests from a fixed seed (:func:`~.seeds.public_seed`), the same in a
student's own check and in the class run, so the two agree on the public tests.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from grading_sandbox import Outcome, SandboxConfigError
from grading_sandbox.wire import is_plain

from .feedback import apply_dependencies, cell_problems, explain_cascade, safe_text
from .jobs import GradingOptions
from .mistakes import Catalogue, mistakes_of
from .results import ExerciseResult, TestResult
from .seeds import public_seed, student_seed
from .spec import CannotGradeHere, Exercise, GradedTest
from .text import clip_message

__all__ = ["PRIVATE_PACKAGES", "catalogue_of", "check_environment", "preload_modules", "run_exercise",
           "sandbox_options", "warm_public_tests"]

#: What student code may never import nor read, whatever the exercise: the grader's own package.
PRIVATE_PACKAGES = (__name__.partition(".")[0],)


def _zero(test: GradedTest, why: str) -> TestResult:
    """``test`` scored 0 for a reason that is not the student's answer to it (``why``)."""
    return TestResult(test.name, test.grade_id, 0.0, float(test.points), test.hidden, why)


def _score_test(test: GradedTest, outcomes: Sequence[Outcome], scorer) -> tuple[float, str]:
    """Apply the trusted scorer; a scorer bug or a bad fraction gives 0, never a crash.

    The message is returned as the scorer made it (a :class:`~.feedback.Report` carries the
    hidden-safe text and the mistakes recognised).
    """
    try:
        fraction, message = scorer(outcomes)
        fraction = float(fraction)
    except Exception as exc:  # a scorer must never stop the run
        return 0.0, f"internal error in the grader's scorer: {type(exc).__name__}: {exc}"
    if not math.isfinite(fraction):
        fraction = 0.0
    fraction = min(1.0, max(0.0, fraction))
    return float(test.points) * fraction, message if isinstance(message, str) else str(message)


# Public tests (and every test of a student's own check) draw their inputs from a fixed seed: their
# calls and reference values are the same for every student, and a scorer is a deterministic
# function of the outcomes (the contract that makes a student's check and the grade agree). A
# grading process therefore builds each public test once and scores each distinct set of outcomes
# once (e.g. the class's correct answers); hidden tests, seeded per student, are never shared.
_SHARED_MAX = 4096
_shared_builds: dict[tuple, tuple[list, Any]] = {}
_shared_scores: dict[tuple, tuple[float, str]] = {}


def _built(test: GradedTest, seed: int) -> tuple[list, Any]:
    """``test.build`` with the public ``seed``, made once per process (a build that raises is not kept)."""
    key = (test, seed)
    hit = _shared_builds.get(key)
    if hit is None:
        calls, scorer = test.build(np.random.default_rng(seed))
        hit = (list(calls), scorer)
        if len(_shared_builds) >= _SHARED_MAX:
            _shared_builds.clear()
        _shared_builds[key] = hit
    return hit


def warm_public_tests(exercises: Sequence[Exercise]) -> int:
    """Build the public tests of ``exercises`` once in this process (what :func:`run_exercise` would
    build for the first student), so that processes forked from this one share them.

    A test whose build raises is skipped (the worker reports it when it grades it). Returns the
    number of tests built. Nothing here touches student data.
    """
    n = 0
    for ex in exercises:
        for t in ex.tests:
            if not t.hidden:
                try:
                    _built(t, public_seed(ex.id, t.name))
                except Exception:  # reported when graded
                    continue
                n += 1
    return n


def _scored(test: GradedTest, seed: int, outcomes: Sequence[Outcome], scorer) -> tuple[float, str]:
    """:func:`_score_test` of a shared test, once per distinct ``outcomes`` (compared as exact JSON)."""
    rows = [[o.ok, o.value, o.error] for o in outcomes]
    if not is_plain(rows):  # e.g. tuples from a test's fake sandbox: JSON would not tell them apart
        return _score_test(test, outcomes, scorer)
    data = json.dumps(rows, allow_nan=True)  # exact for plain data (1 and 1.0 and True differ)
    key = (test, seed, data)
    hit = _shared_scores.get(key)
    if hit is None:
        hit = _score_test(test, outcomes, scorer)
        if len(_shared_scores) >= _SHARED_MAX:
            _shared_scores.clear()
        _shared_scores[key] = hit
    return hit


def catalogue_of(exercise: Exercise) -> Catalogue:
    """The messages of the mistakes ``exercise`` may name: its course's when it was discovered in
    one, else its own and the generic ones."""
    return exercise.catalogue if exercise.catalogue is not None else Catalogue(exercise.mistakes)


def preload_modules(exercises: Sequence[Exercise]) -> tuple[str, ...]:
    """What a zygote may import before forking: the modules the exercises' allowlists name."""
    return tuple(dict.fromkeys(a for ex in exercises for a in (ex.allowed or ())))


def sandbox_options(exercise: Exercise, options: GradingOptions | None = None) -> dict[str, Any]:
    """The keyword arguments of the :class:`grading_sandbox.Sandbox` that runs ``exercise``'s cells."""
    options = options if options is not None else GradingOptions()
    kwargs: dict[str, Any] = {"blocked": tuple(exercise.blocked)}
    if exercise.allowed:
        kwargs["allowed"] = tuple(exercise.allowed)
    if exercise.packages:
        kwargs["packages"] = tuple(exercise.packages)
    kwargs["private"] = PRIVATE_PACKAGES
    if options.hidden_paths:
        kwargs["hidden_paths"] = tuple(options.hidden_paths)
    if options.limits is not None:
        kwargs["limits"] = options.limits
    if exercise.spawns:  # the exercise's own code builds and runs the answer (another language)
        kwargs["spawn"] = True
    return kwargs


def _check_here(exercise: Exercise) -> None:
    """Raise :class:`~.spec.CannotGradeHere` when this machine lacks what ``exercise`` needs."""
    why = exercise.environment_problem()
    if why:
        raise CannotGradeHere(
            f"cannot grade {exercise.id} on this machine: {why}. This is the installation, not the "
            "student's work: install it and run again"
        )


def check_environment(exercises: Sequence[Exercise], options: GradingOptions | None = None, *,
                      pool: Any = None) -> int:
    """Start, once per distinct sandbox the ``exercises`` need (their allowlists, blocked modules
    and exposed packages), a child without student code: it imports numpy and every module the
    allowlist names, as a student's would. Returns the number of sandboxes started. ``pool``: the
    :class:`grading_sandbox.SandboxPool` that grades next in this process (its zygotes, started
    here, then serve the first student); default a pool of its own, closed on return.

    Raises
    ------
    grading_sandbox.SandboxConfigError
        A child cannot import one of them: the grader's environment is broken for that exercise (the
        message has the fix), and grading it would give every student a 0 that is not theirs.
    CannotGradeHere
        An exercise needs a toolchain this machine lacks (:meth:`~.spec.Exercise.environment_problem`).
    """
    from grading_sandbox import SandboxPool

    options = options if options is not None else GradingOptions()
    for ex in exercises:
        _check_here(ex)
    seen: set[tuple] = set()
    # the same pool of zygotes a grading worker uses: sandboxes with one file system view share a
    # process that imported numpy and the allowlists once, and each configuration is checked in a
    # child it forks (what a student's exercise runs in), which costs a fraction of a fresh start
    own = pool is None
    pool = SandboxPool(preload=preload_modules(exercises)) if own else pool
    try:
        for ex in exercises:
            kwargs = sandbox_options(ex, options)
            key = (kwargs.get("allowed"), kwargs["blocked"], kwargs.get("packages"),
                   kwargs.get("spawn", False))
            if key in seen:
                continue
            seen.add(key)
            with pool([], **kwargs) as box:
                box.start()
    finally:
        if own:
            pool.close()
    return len(seen)


def run_exercise(
    exercise: Exercise,
    notebook: str | os.PathLike,
    student: str | None = None,
    *,
    public_only: bool = False,
    options: GradingOptions | None = None,
    sandbox_factory: Any = None,
) -> ExerciseResult:
    """Grade one student's file against one exercise.

    Parameters
    ----------
    exercise : Exercise
        The trusted test definitions.
    notebook : path
        The submitted file (may be missing or malformed: that scores 0 with a message).
    student : str or None
        Seeds the hidden tests' inputs (``student_seed``); ``None`` runs public tests only seeds.
    public_only : bool
        Run only the tests with ``hidden=False`` (a student's own check).
    options : GradingOptions or None
        The seed key, the paths the fallback hides, the limits and the sandbox (defaults: none, the
        sandbox's own).
    sandbox_factory : callable or None
        Where the sandboxes come from when not ``options.sandbox_factory`` (a class run passes the
        :class:`grading_sandbox.SandboxPool` of its worker); default :class:`grading_sandbox.Sandbox`.

    Returns
    -------
    ExerciseResult
        One :class:`TestResult` per test run; never raises because of the submission.

    Raises
    ------
    grading_sandbox.SandboxConfigError
        The sandbox's Python cannot import what the exercise allows (before any student code ran):
        the grader's configuration, which must not become the student's score.
    CannotGradeHere
        This machine lacks the exercise's toolchain (a compiler, Mathics3): the same.
    """
    if not isinstance(exercise, Exercise):
        raise TypeError(f"exercise must be an Exercise, got {type(exercise).__name__}")
    _check_here(exercise)
    options = options if options is not None else GradingOptions()
    tests = [t for t in exercise.tests if not (public_only and t.hidden)]
    result = ExerciseResult(exercise.id, exercise.title, exercise.notebook, catalogue=catalogue_of(exercise))
    cells, problems = exercise.extract_cells(Path(notebook))
    result.problems += problems
    if not cells:
        why = problems[0] if problems else "no answer cells"
        result.tests += [_zero(t, why) for t in tests]
        return result
    factory = options.sandbox_factory or sandbox_factory
    if factory is None:
        from grading_sandbox import Sandbox as factory
    kwargs = sandbox_options(exercise, options)
    # Every public test runs before any hidden one: the child keeps state between tests, so a
    # public test run after a hidden one could carry the hidden inputs into its (shown) message.
    # Results are reported in the exercise's order.
    order = sorted(range(len(tests)), key=lambda i: tests[i].hidden)
    done: dict[int, TestResult] = {}
    with factory(cells, **kwargs) as box:
        result.isolation = str(getattr(box, "isolation", ""))
        for i in order:
            t = tests[i]
            shared = not (t.hidden and student is not None)  # the same inputs for every student
            if shared:
                seed = public_seed(exercise.id, t.name)
            else:
                seed = student_seed(student, exercise.id, t.name, options.secret)
            try:
                calls, scorer = _built(t, seed) if shared else t.build(np.random.default_rng(seed))
            except Exception as exc:  # a broken test definition scores 0, run goes on
                done[i] = _zero(t, f"internal error building the test: {type(exc).__name__}: {exc}")
                continue
            try:
                outcomes = list(box.run(list(calls), t.timeout))
            except SandboxConfigError:  # the grader's environment, not the student: never a score
                raise
            except Exception as exc:  # the sandbox reports, never stops the run
                outcomes = [Outcome(False, None, f"sandbox error: {exc}") for _ in calls]
            if len(outcomes) != len(calls):
                outcomes = [Outcome(False, None, "no result from the sandbox") for _ in calls]
            outcomes = explain_cascade(outcomes, dict(getattr(box, "cell_errors", {}) or {}))
            if shared:
                score, message = _scored(t, seed, outcomes, scorer)
            else:
                score, message = _score_test(t, outcomes, scorer)
            done[i] = TestResult(
                t.name, t.grade_id, score, float(t.points), t.hidden, clip_message(message),
                clip_message(safe_text(message)), mistakes_of(message),
            )
        result.tests += apply_dependencies(exercise.depends, [done[i] for i in range(len(tests))])
        # known once the child has started (the sandbox starts it lazily on the first run)
        errors = dict(getattr(box, "cell_errors", {}) or {})
        result.problems += [clip_message(p) for p in cell_problems(errors, exercise.answer_cells)]
    return result
