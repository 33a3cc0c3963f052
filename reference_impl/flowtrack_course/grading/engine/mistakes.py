"""The one mistake matcher: catalogued wrong answers, how they are recognised, and their lines.

A :class:`Mistake` is a stable id (instructors' reports count them across terms:
``misconceptions.csv``, the class report), what the mistake is, why it is wrong and where the
lessons explain it. An exercise defines its mistakes next to its tests (``Exercise.mistakes``) and
recognises them by running the trusted *wrong* answer (a :class:`Variant`: the id and the array the
mistaken code returns on the same inputs, computed on the grader's side) and finding the student's
output equal to it (:func:`diagnose`) while different from the right one; when no catalogued
variant fits, the generic explanations :data:`GENERIC` may. A :class:`Catalogue` holds the
messages of a course's mistakes; each recognised mistake becomes one line
``mistake <id>: <message>`` (:meth:`Catalogue.line`; the format is a contract). An id is never
reused for another mistake.

>>> Catalogue().line("generic-sign").startswith("mistake generic-sign: ")
True
>>> diagnose([[-1.0, -2.0]], [[1.0, 2.0]])
['generic-sign']

A generic diagnosis of one call is only a hint: a test names it when two calls or more make it
with the same relation (:func:`consistent_mistakes`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .compare import as_float_array

__all__ = [
    "GENERIC",
    "Catalogue",
    "Mistake",
    "Variant",
    "checked_of",
    "consistent_mistakes",
    "diagnose",
    "evidence_of",
    "generic_relation",
    "mistakes_of",
    "relations_of",
    "shape_hint",
    "visible_variants",
]


@dataclass(frozen=True)
class Mistake:
    """A catalogued mistake: ``id``, ``message`` (what, why, where in the lessons) and the exercise
    that defines it (``"*"`` for the generic ones; set when a course's exercises are discovered)."""

    id: str
    message: str
    exercise: str = ""

    def of(self, exercise: str) -> Mistake:
        """This mistake, defined by ``exercise``."""
        return replace(self, exercise=exercise)


GENERIC = tuple(m.of("*") for m in [
    Mistake(
        "generic-sign",
        "your result is the expected one with the sign flipped: look for a subtraction done "
        "the wrong way round or a minus sign lost in a derivative",
    ),
    Mistake(
        "generic-scale",
        "your result is the expected one times a constant factor: look for a missing or extra "
        "factor (a time step, a 2 or 1/2, a gain or a variance)",
    ),
    Mistake(
        "generic-transpose",
        "your result is the transpose of the expected one: check which index is the row (the "
        "docstring gives the shape and the meaning of each axis)",
    ),
    Mistake(
        "generic-permutation",
        "your result has the expected rows or columns in another order: check the order the "
        "docstring asks for (state order, sorting, indices)",
    ),
])


class Catalogue(Mapping[str, Mistake]):
    """The mistakes of a course by id (the generic ones always included): a read-only mapping.

    Raises
    ------
    ValueError
        Two mistakes share an id but not their message (an id names one mistake only).
    """

    def __init__(self, mistakes: Iterable[Mistake] = ()) -> None:
        self._by_id: dict[str, Mistake] = {}
        for m in (*GENERIC, *mistakes):
            old = self._by_id.get(m.id)
            if old is not None and old.message != m.message:
                raise ValueError(
                    f"mistake {m.id!r} is defined twice with different messages "
                    f"({old.exercise or '?'} and {m.exercise or '?'}): an id names one mistake"
                )
            if old is None:
                self._by_id[m.id] = m

    def __iter__(self) -> Iterator[str]:
        return iter(self._by_id)

    def __len__(self) -> int:
        return len(self._by_id)

    def __getitem__(self, mistake_id: str) -> Mistake:
        return self._by_id[mistake_id]

    def line(self, mistake_id: str) -> str:
        """The feedback line of a catalogued mistake: ``mistake <id>: <message>``."""
        return f"mistake {mistake_id}: {self._by_id[mistake_id].message}"

    def lines(self, ids: Iterable[str]) -> list[str]:
        """One :meth:`line` per id (unknown ids are skipped)."""
        return [self.line(i) for i in ids if i in self._by_id]


def mistakes_of(message: Any) -> tuple[str, ...]:
    """The ids of the mistakes a check's message (a :class:`~.feedback.Report`) recognised."""
    return tuple(getattr(message, "mistakes", ()) or ())


def checked_of(message: Any) -> frozenset[str]:
    """The ids of the catalogued mistakes that were visible on the inputs of a check's message."""
    return frozenset(getattr(message, "checked", ()) or ())


def relations_of(message: Any) -> Mapping[str, Any]:
    """``{generic id: relation}`` of a check's message: the factor of ``generic-scale`` (-1 for
    ``generic-sign``), ``"transpose"``, the permuted axis of ``generic-permutation``."""
    return getattr(message, "relations", None) or {}


def evidence_of(message: Any) -> int:
    """How many independent evaluations a check's message stands for (a call: 1; a formula
    evaluated at k random points: k)."""
    n = getattr(message, "evidence", 1)
    return n if isinstance(n, int) and n > 0 else 1


def _same_relation(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return bool(np.isclose(a, b, rtol=1e-6, atol=0.0))
    return a is not None and a == b


def consistent_mistakes(
    messages: Sequence[Any], passed: Sequence[bool] = (), least_evidence: int = 2
) -> list[str]:
    """The mistakes of several checks (calls, or parts of a result) that every check agrees with.

    A catalogued mistake counts when at least one check matched it and every failing check where it
    was visible (in ``checked``) matched it too (a passing check does not count against it: one
    member of a family, such as a gate with 2 degrees of freedom, is right for 2-D measurements).
    A generic diagnosis says less (any wrong number is some multiple of the right one), so it
    counts only when every failing check made it with the same relation (the same factor, the
    same transposition) and together they stand for at least ``least_evidence`` independent
    evaluations (:func:`evidence_of`; the parts of one result are one: ``least_evidence=1``).
    """
    named: list[str] = []
    for msg in messages:
        named += [m for m in mistakes_of(msg) if m not in named]
    failing = [msg for k, msg in enumerate(messages) if not (k < len(passed) and passed[k])]
    out = []
    for m in named:
        if m.startswith("generic-"):
            if not failing or not all(m in mistakes_of(msg) for msg in failing):
                continue
            rels = [relations_of(msg).get(m) for msg in failing]
            same = all(_same_relation(r, rels[0]) for r in rels)
            if same and sum(map(evidence_of, failing)) >= least_evidence:
                out.append(m)
            continue
        if all(m in mistakes_of(msg) for msg in failing if m in checked_of(msg)):
            out.append(m)
    return out


@dataclass(frozen=True)
class Variant:
    """A catalogued wrong answer: ``value`` is what the mistaken code returns on this call's inputs."""

    mistake: str
    value: Any


def _close(got: np.ndarray, ref: np.ndarray, rtol: float, atol: float) -> bool:
    if got.shape != ref.shape:
        return False
    fin = np.isfinite(ref)
    if not np.array_equal(np.isfinite(got), fin):
        return False
    if not np.array_equal(got[~fin], ref[~fin], equal_nan=True):
        return False
    return bool(np.all(np.abs(got[fin] - ref[fin]) <= atol + rtol * np.abs(ref[fin])))


def diagnose(
    got: np.ndarray,
    expected: np.ndarray,
    variants: Sequence[Variant] = (),
    rtol: float = 1e-6,
    atol: float = 1e-9,
) -> list[str]:
    """Mistake ids explaining ``got`` (wrong) against ``expected``: catalogued first, else generic
    (:func:`generic_relation`).

    A variant counts only where it differs from the right answer (on these inputs the mistake is
    visible) and the student's output equals it.
    """
    got = np.asarray(got, dtype=np.float64)
    expected = np.asarray(expected, dtype=np.float64)
    found: list[str] = []
    for v in variants:
        wrong = as_float_array(v.value) if not isinstance(v.value, np.ndarray) else v.value
        if wrong is None:
            continue
        wrong = np.asarray(wrong, dtype=np.float64)
        if _close(wrong, expected, rtol, atol):
            continue
        if _close(got, wrong, max(rtol, 1e-6), max(atol, 1e-9)) and v.mistake not in found:
            found.append(v.mistake)
    if found:
        return found
    generic = generic_relation(got, expected, rtol, atol)
    return [generic[0]] if generic is not None else []


def generic_relation(
    got: np.ndarray, expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9
) -> tuple[str, Any] | None:
    """The generic mistake relating ``got`` to ``expected`` and the relation, or None.

    ``("generic-sign", -1.0)``, ``("generic-scale", c)`` (``got = c expected``, ``c`` not 0, 1 or
    -1; only for results with two nonzero entries or more: a single number is a multiple of any
    other), ``("generic-transpose", "transpose")`` (the last two axes swapped; also for a result of
    the swapped shape) and ``("generic-permutation", axis)`` (the same rows, or columns, in another
    order). Needs finite results and a nonzero expected one.

    >>> generic_relation(np.array([2.0, 4.0]), np.array([1.0, 2.0]))
    ('generic-scale', 2.0)
    >>> generic_relation(np.array([3.0]), np.array([1.0])) is None
    True
    >>> generic_relation(np.ones((5, 3, 2)), np.ones((5, 2, 3)))
    ('generic-transpose', 'transpose')
    """
    got = np.asarray(got, dtype=np.float64)
    expected = np.asarray(expected, dtype=np.float64)
    if not (np.all(np.isfinite(got)) and np.all(np.isfinite(expected))) or not np.any(expected):
        return None
    tol = dict(rtol=max(rtol, 1e-6), atol=max(atol, 1e-9) * 10)
    if got.shape == expected.shape:
        if np.allclose(got, -expected, **tol):
            return ("generic-sign", -1.0)
        e = expected.ravel()
        c = float(np.dot(e, got.ravel()) / np.dot(e, e))
        if (np.count_nonzero(np.abs(e) > tol["atol"]) >= 2 and abs(c) > 1e-12 and not np.isclose(c, 1.0)
                and np.allclose(got, c * expected, **tol)):
            return ("generic-scale", c)
    if expected.ndim >= 2:
        swapped = np.swapaxes(expected, -1, -2)
        symmetric = swapped.shape == expected.shape and np.allclose(expected, swapped, **tol)
        if got.shape == swapped.shape and not symmetric and np.allclose(got, swapped, **tol):
            return ("generic-transpose", "transpose")
    if got.shape == expected.shape and expected.ndim >= 1 and expected.shape[0] > 1:
        from scipy.optimize import linear_sum_assignment

        for axis in range(min(expected.ndim, 2)):
            a = np.moveaxis(got, axis, 0).reshape(got.shape[axis], -1)
            b = np.moveaxis(expected, axis, 0).reshape(expected.shape[axis], -1)
            cost = np.abs(a[:, None, :] - b[None, :, :]).max(axis=2)
            scale = tol["atol"] + tol["rtol"] * np.abs(b).max()
            r, c = linear_sum_assignment(cost)
            if np.all(cost[r, c] <= scale) and np.any(r != c):
                return ("generic-permutation", axis)
    return None


def shape_hint(got_shape: tuple[int, ...], expected_shape: tuple[int, ...]) -> str:
    """What a wrong shape suggests: the last two axes swapped, or nothing.

    >>> shape_hint((7, 3, 2), (7, 2, 3))
    ' (the last two axes swapped: transposed?)'
    """
    got_shape, expected_shape = tuple(got_shape), tuple(expected_shape)
    if len(got_shape) >= 2 and got_shape != expected_shape and (
            (*got_shape[:-2], got_shape[-1], got_shape[-2]) == expected_shape):
        return " (the last two axes swapped: transposed?)"
    return ""


def visible_variants(
    expected: np.ndarray, variants: Sequence[Variant], rtol: float, atol: float
) -> list[str]:
    """The ids of the variants whose wrong answer differs from ``expected`` on these inputs."""
    out = []
    for v in variants:
        wrong = v.value if isinstance(v.value, np.ndarray) else as_float_array(v.value)
        if wrong is None or v.mistake in out:
            continue
        if not _close(np.asarray(wrong, dtype=np.float64), expected, rtol, atol):
            out.append(v.mistake)
    return out
