"""What an exercise's grading module is written with: its definitions and the scoring helpers.

An exercise folder's ``grading.py`` (:mod:`.discovery`) defines ``EXERCISE``, an
:class:`~.spec.Exercise`, from what this module exports: the definitions (:class:`~.spec.Exercise`,
:class:`~.spec.GradedTest`, :class:`~.spec.Dependency`, :class:`~.mistakes.Mistake`,
:class:`~.mistakes.Variant`, :class:`~grading_sandbox.Call`, :class:`~grading_sandbox.Outcome`) and
the helpers. A test writes ``build(rng)`` as a function returning ``(function, args, kwargs, check)``
entries and decorates it with :func:`graded_test`; each ``check(outcome) -> (fraction, message)``
scores one call, and :func:`per_call` averages them into the test's scorer (partial credit: the
fraction of calls, or checks, that pass).

Examples
--------
>>> import numpy as np
>>> check = array_check(np.array([1.0, 2.0]))
>>> check(Outcome(True, [1.0, 2.0])), check(Outcome(True, [1.0]))[0]
((1.0, 'ok'), 0.0)
>>> print(check(Outcome(True, [1.0, -2.0]))[1])
values differ at 1 of 2 entries; worst at [1]: expected 2, got -2 (rtol=1e-06, atol=1e-09)
    expected [1., 2.]
    got      [ 1., -2.]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .compare import as_float_array, compare_arrays
from .feedback import Report, compare, safe_error, safe_text
from .mistakes import Mistake, Variant, checked_of, consistent_mistakes, relations_of
from .spec import Call, Dependency, Exercise, GradedTest, Outcome, Scorer

__all__ = [
    "Call",
    "Check",
    "Dependency",
    "Exercise",
    "GradedTest",
    "Mistake",
    "Outcome",
    "Report",
    "Variant",
    "array_check",
    "as_float_array",
    "call_label",
    "compare",
    "compare_arrays",
    "graded_test",
    "per_call",
    "safe_error",
    "tuple_check",
]

Check = Callable[[Outcome], tuple[float, str]]


def per_call(
    labels: Sequence[str], checks: Sequence[Check], functions: Sequence[str] | None = None
) -> Scorer:
    """A scorer awarding the mean over calls of each call's check fraction (in [0, 1]).

    Its message is a :class:`~.feedback.Report`: the public text names
    each failing call with its arguments (``labels``), the hidden-safe text only the functions that
    failed and why (a hidden call's arguments are hidden inputs; which of the calls failed is the
    student code's choice too, so each reason is said once, in a fixed order), and the mistakes
    recognised in any call.
    """
    labels = list(labels)
    checks = list(checks)
    functions = list(functions) if functions is not None else [lab.split("(")[0] for lab in labels]

    def scorer(outcomes: Sequence[Outcome]) -> tuple[float, str]:
        if len(outcomes) != len(checks):
            msg = f"expected {len(checks)} results, got {len(outcomes)}"
            return 0.0, Report(msg, "the sandbox failed (not your code: tell your instructor)")
        fractions = []
        problems = []
        safe_problems: list[str] = []
        messages = []
        for label, fn, check, outcome in zip(labels, functions, checks, outcomes):
            try:
                f, msg = check(outcome)
            except Exception as exc:  # a trusted check must never crash the grader on odd data
                f, msg = 0.0, f"could not check the result ({type(exc).__name__})"
            f = float(min(max(f, 0.0), 1.0)) if math.isfinite(f) else 0.0
            fractions.append(f)
            messages.append(msg)
            if f < 1.0:
                problems.append(f"{label}: {msg}")
                reason = f"{fn}: {safe_text(msg)}"
                if reason not in safe_problems:
                    safe_problems.append(reason)
        score = sum(fractions) / len(fractions) if fractions else 0.0
        if score >= 1.0:
            done = f"all {len(checks)} checks passed"
            return 1.0, Report(done, done)
        mistakes = consistent_mistakes(messages, [f >= 1.0 for f in fractions])
        n_ok = sum(f >= 1.0 for f in fractions)
        more = " ..." if len(problems) > 3 else ""
        head = f"{n_ok}/{len(checks)} checks passed. "
        public = head + "; ".join(problems[:3]) + more
        safe = head + "; ".join(sorted(safe_problems))
        return score, Report(public, safe, mistakes, relations=_agreed(messages, mistakes))

    return scorer


def _agreed(messages: Sequence[Any], mistakes: Sequence[str]) -> dict[str, Any]:
    """The relation of each generic id of ``mistakes`` (the one every message naming it agrees on)."""
    out = {}
    for m in mistakes:
        rel = next((relations_of(msg)[m] for msg in messages if m in relations_of(msg)), None)
        if rel is not None:
            out[m] = rel
    return out


def array_check(
    expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9, variants: Sequence[Variant] = ()
) -> Check:
    """All or nothing: the result equals ``expected`` within the tolerances.

    ``variants`` are the catalogued wrong answers on the same inputs (see
    :mod:`.mistakes`); the message names the one the result equals.
    """

    def check(outcome: Outcome) -> tuple[float, str]:
        d = compare(outcome, expected, rtol=rtol, atol=atol, variants=variants)
        return (1.0 if d.ok else 0.0), d.report()

    return check


def tuple_check(parts: Sequence[Check], names: Sequence[str]) -> Check:
    """A result that is a tuple of ``len(parts)`` items, each checked separately (equal weights)."""

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            return 0.0, Report(err, safe_error(err))
        value = outcome.value
        if type(value) not in (list, tuple) or len(value) != len(parts):
            msg = f"expected a tuple ({', '.join(names)}) of {len(parts)} items"
            return 0.0, Report(msg, msg)  # the grader's words only
        total = 0.0
        msgs = []
        safe = []
        messages = []
        oks = []
        for name, part, item in zip(names, parts, value):
            f, msg = part(Outcome(True, item))
            total += f
            messages.append(msg)
            oks.append(f >= 1.0)
            if f < 1.0:
                msgs.append(f"{name}: {msg}")
                safe.append(f"{name}: {safe_text(msg)}")
        checked = frozenset().union(*(checked_of(m) for m in messages))
        # the parts of one result are one call's evidence: a generic id needs them to agree, and
        # other calls (per_call) to confirm it
        mistakes = consistent_mistakes(messages, oks, least_evidence=1)
        return total / len(parts), Report("; ".join(msgs) or "ok", "; ".join(safe) or "ok", mistakes, checked,
                                          _agreed(messages, mistakes))

    return check


def _describe(x: Any) -> str:
    if isinstance(x, np.ndarray):
        return f"array{x.shape}"
    if isinstance(x, float):
        return f"{x:.4g}"
    if isinstance(x, list):
        return f"list of {len(x)}"
    return repr(x)


def call_label(function: str, args: Sequence[Any], kwargs: Mapping[str, Any] | None = None) -> str:
    """How a call is shown in feedback: ``function(arg, ..., key=value)`` with every argument
    described briefly (arrays by shape, floats to 4 digits, lists by length).

    Examples
    --------
    >>> call_label("f", (1,), {"k": 2}).startswith("f(")
    True
    """
    parts = [_describe(a) for a in args] + [f"{k}={_describe(v)}" for k, v in (kwargs or {}).items()]
    return f"{function}({', '.join(parts)})"


def _calls_and_checks(
    entries: Sequence[tuple],
) -> tuple[list[Call], Scorer]:
    """Entries ``(function, args, kwargs, check)``, or ``(..., check, post)`` for a call whose result
    the sandbox turns into data first (:attr:`grading_sandbox.Call.post`)."""
    calls = [Call(e[0], e[1], e[2], e[4] if len(e) > 4 else None) for e in entries]
    labels = [call_label(e[0], e[1], e[2]) for e in entries]
    return calls, per_call(labels, [e[3] for e in entries], [e[0] for e in entries])


def graded_test(name: str, grade_id: str, points: float, hidden: bool, timeout: float = 10.0):
    """Decorator turning ``build(rng) -> entries`` into a :class:`GradedTest`."""

    def wrap(fn: Callable[[np.random.Generator], Sequence[tuple]]) -> GradedTest:
        def build(rng: np.random.Generator) -> tuple[Sequence[Call], Scorer]:
            return _calls_and_checks(fn(rng))

        build.__doc__ = fn.__doc__
        build.__wrapped__ = fn  # where the test is defined (the exercises' hash covers that file too)
        return GradedTest(
            name=name, grade_id=grade_id, points=points, hidden=hidden, build=build, timeout=timeout
        )

    return wrap
