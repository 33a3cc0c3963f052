r"""Feedback that shows the difference without leaking hidden data, and the mistake catalogue.

A check's message is a :class:`Report`: a ``str`` (what a student sees of a *public* test: expected
against got, the worst entry and its index) that also carries ``safe``, the text a student may see of
a *hidden* test (which check failed and why: a shape, the share of wrong entries, the worst relative
error and its index, a timeout with its limit, an exception's type and line, never an input or an
expected value), and ``mistakes``, the catalogued mistakes recognised from the student's outputs.

A mistake is recognised by running the trusted *wrong* answer (a :class:`Variant`: the mistake id and
the array the mistaken code returns on the same inputs, computed on the grader's side) and finding the
student's output equal to it (within the test's tolerance) while different from the right answer.
When no catalogued variant fits, :func:`diagnose` tries the generic explanations
``generic-sign``, ``generic-scale``, ``generic-transpose``, ``generic-permutation``. Each recognised
mistake becomes one line ``mistake <id>: <message>`` (:func:`mistake_line`; the format is a contract,
see ``/work/shared/API.md``); a correct answer gets none.

Examples
--------
>>> import numpy as np
>>> from flowtrack_course.grading.spec import Outcome
>>> r = compare(Outcome(True, [[-1.0, -2.0]]), np.array([[1.0, 2.0]]))
>>> r.ok, list(r.mistakes)
(False, ['generic-sign'])
>>> "expected" in r.public and "expected" not in r.safe
True
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..spec import Outcome, as_float_array
from .catalogue import CATALOGUE, mistake_line

__all__ = [
    "Diff",
    "Report",
    "Variant",
    "compare",
    "diagnose",
    "mistake_line",
    "safe_error",
]


class Report(str):
    """A check's message: the public text (``str`` value), the hidden-safe text and the mistakes.

    ``mistakes`` is a tuple of catalogue ids, in the order recognised, without repeats; ``checked``
    the catalogued ids that were visible on these inputs (their wrong answer differs from the right
    one). A test names a mistake only when every call where it was visible matched it
    (:func:`consistent_mistakes`): one coincidence among several calls names nothing.
    """

    safe: str
    mistakes: tuple[str, ...]
    checked: frozenset[str]

    def __new__(
        cls, public: str, safe: str | None = None, mistakes: Iterable[str] = (), checked: Iterable[str] = ()
    ):
        obj = super().__new__(cls, public)
        obj.safe = str(public) if safe is None else str(safe)
        seen: list[str] = []
        for m in mistakes:
            if m not in seen:
                seen.append(m)
        obj.mistakes = tuple(seen)
        obj.checked = frozenset(checked) | frozenset(m for m in seen if not m.startswith("generic-"))
        return obj


def safe_text(message: Any) -> str:
    """The hidden-safe text of a message (a plain ``str`` has none: only a generic sentence)."""
    safe = getattr(message, "safe", None)
    return str(safe) if safe is not None else "the results differ from the expected ones"


def mistakes_of(message: Any) -> tuple[str, ...]:
    return tuple(getattr(message, "mistakes", ()) or ())


def checked_of(message: Any) -> frozenset[str]:
    return frozenset(getattr(message, "checked", ()) or ())


def consistent_mistakes(messages: Sequence[Any], passed: Sequence[bool] = ()) -> list[str]:
    """The mistakes of several checks (calls, or parts of a result) that every check agrees with.

    A catalogued mistake counts when at least one check matched it and every failing check where it
    was visible (in ``checked``) matched it too (a passing check does not count against it: one
    member of a family, such as a gate with 2 degrees of freedom, is right for 2-D measurements);
    generic diagnoses count when any check made them.
    """
    named: list[str] = []
    for msg in messages:
        named += [m for m in mistakes_of(msg) if m not in named]
    out = []
    for m in named:
        if m.startswith("generic-"):
            out.append(m)
            continue
        failing = [msg for k, msg in enumerate(messages) if not (k < len(passed) and passed[k])]
        if all(m in mistakes_of(msg) for msg in failing if m in checked_of(msg)):
            out.append(m)
    return out


@dataclass(frozen=True)
class Variant:
    """A catalogued wrong answer: ``value`` is what the mistaken code returns on this call's inputs."""

    mistake: str
    value: Any


_LOCATION = re.compile(r'File "(<cell [^>]*>)", line (\d+)')
_LAST = re.compile(r"^([A-Za-z_][A-Za-z0-9_.]*(?:Error|Exception|Warning|Interrupt|Exit))\b")


def safe_error(error: str) -> str:
    """An error of a hidden call without anything the student's code could have put in it.

    The exception's type and the cell line where it was raised are kept, its text is not (a
    student's code sees the hidden inputs and could print them into an exception); the grader's own
    reasons (time limit, output limit, memory) are kept whole.

    >>> safe_error('Traceback ...\\n  File "<cell f>", line 3, in f\\nValueError: x = [0.123, 4.5]')
    'ValueError (raised at <cell f> line 3)'
    >>> safe_error("timed out")
    'timed out (the time limit of this test was exceeded)'
    """
    text = str(error or "the call failed").strip()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    last = lines[-1].strip() if lines else text
    if "Traceback" not in text and not _LAST.match(last):
        if text == "timed out":
            return "timed out (the time limit of this test was exceeded)"
        # the grader's own messages (limits, missing functions, a cell that failed) hold no data
        return text[:300]
    m = _LAST.match(last)
    kind = m.group(1) if m else "an exception"
    where = _LOCATION.findall(text)
    at = f" (raised at {where[-1][0]} line {where[-1][1]})" if where else ""
    if kind.endswith("NotImplementedError"):
        return "NotImplementedError: the function is not implemented yet"
    return f"{kind}{at}"


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _fmt_array(a: np.ndarray) -> str:
    return np.array2string(np.asarray(a), precision=6, separator=", ", threshold=40, max_line_width=100)


def _index(idx: tuple[int, ...]) -> str:
    return "[" + ", ".join(str(int(i)) for i in idx) + "]"


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
    """Mistake ids explaining ``got`` (wrong) against ``expected``: catalogued first, else generic.

    A variant counts only where it differs from the right answer (on these inputs the mistake is
    visible) and the student's output equals it. Generic diagnoses need a finite, nonzero result.
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
    if not (np.all(np.isfinite(got)) and np.all(np.isfinite(expected))) or not np.any(expected):
        return []
    tol = dict(rtol=max(rtol, 1e-6), atol=max(atol, 1e-9) * 10)
    if got.shape == expected.shape:
        if np.allclose(got, -expected, **tol):
            return ["generic-sign"]
        e = expected.ravel()
        c = float(np.dot(e, got.ravel()) / np.dot(e, e))
        if abs(c) > 1e-12 and not np.isclose(c, 1.0) and np.allclose(got, c * expected, **tol):
            return ["generic-scale"]
    if expected.ndim >= 2 and got.shape == np.swapaxes(expected, -1, -2).shape:
        if np.allclose(got, np.swapaxes(expected, -1, -2), **tol) and not np.allclose(
            expected, np.swapaxes(expected, -1, -2), **tol
        ):
            return ["generic-transpose"]
    if got.shape == expected.shape and expected.ndim >= 1 and expected.shape[0] > 1:
        for axis in range(min(expected.ndim, 2)):
            a = np.moveaxis(got, axis, 0).reshape(got.shape[axis], -1)
            b = np.moveaxis(expected, axis, 0).reshape(expected.shape[axis], -1)
            cost = np.abs(a[:, None, :] - b[None, :, :]).max(axis=2)
            scale = tol["atol"] + tol["rtol"] * np.abs(b).max()
            from scipy.optimize import linear_sum_assignment

            r, c = linear_sum_assignment(cost)
            if np.all(cost[r, c] <= scale) and np.any(r != c):
                return ["generic-permutation"]
    return []


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


@dataclass(frozen=True)
class Diff:
    """The result of :func:`compare`: ``ok``, the public and the hidden-safe texts, the mistakes."""

    ok: bool
    public: str
    safe: str
    mistakes: tuple[str, ...] = ()
    checked: tuple[str, ...] = ()

    def report(self) -> Report:
        return Report(self.public, self.safe, self.mistakes, self.checked)


def compare(
    outcome: Outcome,
    expected: np.ndarray,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    variants: Sequence[Variant] = (),
) -> Diff:
    """Compare one outcome with the expected array and say how they differ.

    The public text shows expected against got (whole arrays when small) and the worst entry with
    its index; the safe text only the shape, the share of wrong entries, the worst relative error and
    its index.
    """
    expected = np.asarray(expected, dtype=np.float64)
    checked = tuple(visible_variants(expected, variants, rtol, atol))
    if not outcome.ok:
        err = outcome.error or "the call failed"
        return Diff(False, err, safe_error(err), (), checked)
    got = as_float_array(outcome.value, expected.shape)
    if got is None:
        got_any = as_float_array(outcome.value)
        if got_any is None:
            msg = "the result is not an array of numbers"
            return Diff(False, msg, msg)
        msg = f"expected an array of shape {expected.shape}, got shape {got_any.shape}"
        mistakes = tuple(diagnose(got_any, expected, variants, rtol, atol))
        return Diff(False, msg, msg, mistakes, checked)
    n = expected.size
    fin_e = np.isfinite(expected)
    fin_g = np.isfinite(got)
    bad_nonfinite = (fin_e != fin_g) | (
        ~fin_e & ~fin_g & ~((got == expected) | (np.isnan(got) & np.isnan(expected)))
    )
    err = np.zeros_like(expected)
    both = fin_e & fin_g
    err[both] = np.abs(got[both] - expected[both])
    bound = atol + rtol * np.abs(np.where(fin_e, expected, 0.0))
    bad = bad_nonfinite | (both & (err > bound))
    if not bad.any():
        return Diff(True, "ok", "ok", (), checked)
    mistakes = tuple(diagnose(got, expected, variants, rtol, atol))
    k = int(bad.sum())
    tolerance = f"rtol={rtol:g}, atol={atol:g}"
    if bad_nonfinite.any():
        idx = tuple(int(i) for i in np.argwhere(bad_nonfinite)[0])
        public = (
            f"{int(bad_nonfinite.sum())} of {n} entries are non-finite where the expected value is finite "
            f"or the other way round (+inf, -inf and NaN are different); first at {_index(idx)}: "
            f"expected {_fmt(expected[idx])}, got {_fmt(got[idx])}"
        )
        safe = (
            f"{int(bad_nonfinite.sum())} of {n} entries are inf/NaN where a finite value is expected, or "
            f"the other way round (first at entry {_index(idx)})"
        )
    else:
        rel = np.where(bad, err / np.maximum(np.abs(expected), atol if atol > 0 else 1e-300), 0.0)
        excess = np.where(bad, err - bound, -np.inf)
        idx = tuple(int(i) for i in np.unravel_index(int(np.argmax(excess)), expected.shape))
        public = (
            f"values differ at {k} of {n} entries; worst at {_index(idx)}: expected {_fmt(expected[idx])}, "
            f"got {_fmt(got[idx])} ({tolerance})"
        )
        worst_rel = float(rel[idx])
        rel_text = (
            f"relative error {worst_rel:.2g}"
            if np.isfinite(worst_rel) and expected[idx] != 0
            else ("a nonzero value where zero is expected")
        )
        # the absolute tolerance may be scaled by the expected values: only the relative one is shown
        safe = (
            f"values differ at {k} of {n} entries; the worst, at entry {_index(idx)}: {rel_text} "
            f"(rtol={rtol:g})"
        )
    if n <= 24:
        public += f"\n    expected {_fmt_array(expected)}\n    got      {_fmt_array(got)}"
    return Diff(False, public, safe, mistakes, checked)


def describe_mistakes(ids: Sequence[str]) -> list[str]:
    """One ``mistake <id>: <message>`` line per id (unknown ids are skipped)."""
    return [mistake_line(i) for i in ids if i in CATALOGUE]


# --------------------------------------------------------------------------------------------------
# test-level feedback: one line per cause, dependencies, the lines a student sees

#: Per exercise: a test cell's ``grade_id`` -> (the test cell it builds on, that function, this one).
#: When both fail, the dependent test's message starts by saying which function to fix first.
DEPENDS: dict[str, dict[str, tuple[str, str, str]]] = {
    "ex03_gauss_seidel": {
        "test_solver": ("test_sweep", "red_black_sweep", "solve_gauss_seidel"),
        "test_iterates": ("test_sweep", "red_black_sweep", "solve_gauss_seidel"),
    },
    "ex04_graph_scene_flow": {
        "test_graph_flow": ("test_laplacian", "knn_laplacian", "graph_scene_flow"),
    },
    "ex07_mahalanobis_gating": {
        "test_gating": ("test_cost", "mahalanobis_cost", "gated_cost"),
    },
}

_NO_FUNCTION = re.compile(
    r"there is no function named '([^']+)'|no function named '([^']+)' was defined"
    r"|NameError: name '([^']+)' is not defined"
)


def _one_line(text: str) -> str:
    """``text`` on one line: newlines, other control characters and lone surrogates escaped."""
    out = []
    for ch in str(text):
        if ch == "\n":
            out.append("\\n")
        elif ch == "\\" or ch.isprintable() or ch == " ":
            out.append(ch)
        else:  # control characters, lone surrogates (unwritable as UTF-8), other unprintables
            out.append(ch.encode("unicode_escape").decode("ascii"))
    return "".join(out)


def _cause(text: str) -> str:
    """The exception of a traceback (``ImportError: ...``) on one line, with where it was raised.

    The exception's whole message is kept (a multi-line message is not cut to its last line) and
    escaped onto one line: its newlines as ``\\n``, a lone surrogate as ``\\ud800``.

    >>> _cause('Traceback (most recent call last):\\n  File "<cell f>", line 2, in <module>\\n'
    ...        'ValueError: \\ud800 bad\\n<!--')
    'ValueError: \\\\ud800 bad\\\\n<!-- (at <cell f> line 2)'
    """
    text = str(text)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    # the exception starts after the last "  File ..." line and its indented source lines
    start = 0
    for i, ln in enumerate(lines):
        if ln.startswith('  File "'):
            start = i + 1
    while start and start < len(lines) and lines[start].startswith("    "):
        start += 1
    if start == 0 and lines and lines[0].startswith("Traceback"):
        start = 1
    exc = "\n".join(lines[start:]).strip() or text.strip()
    where = _LOCATION.findall(text)
    return _one_line(exc)[:300] + (f" (at {where[-1][0]} line {where[-1][1]})" if where else "")


def explain_cascade(outcomes: Sequence[Outcome], cell_errors: dict[str, str]) -> list[Outcome]:
    """Replace "no function named f" by the cause when an answer cell failed to run.

    A cell that fails (an ImportError of a blocked module, a syntax error) leaves its functions
    undefined; every call of them would otherwise report a NameError of its own.
    """
    if not cell_errors:
        return list(outcomes)
    out = []
    for o in outcomes:
        m = _NO_FUNCTION.search(o.error or "") if not o.ok else None
        if m is None:
            out.append(o)
            continue
        name = m.group(1) or m.group(2) or m.group(3)
        gid = name if name in cell_errors else next(iter(cell_errors))
        out.append(
            Outcome(False, None, f"not run: answer cell {gid!r} failed to run: {_cause(cell_errors[gid])}")
        )
    return out


def cell_problems(cell_errors: dict[str, str], order: Sequence[str]) -> list[str]:
    """One problem line per failed answer cell; a NameError after an earlier failure says so."""
    lines = []
    failed: list[str] = []
    for gid in [g for g in order if g in cell_errors] + [g for g in cell_errors if g not in order]:
        cause = _cause(cell_errors[gid])
        if failed and cause.startswith("NameError"):
            cause += f" (probably because cell {failed[0]!r} failed above: fix that first)"
        lines.append(f"cell {gid!r} failed to run: {cause}")
        failed.append(gid)
    return lines


def apply_dependencies(exercise_id: str, tests: list) -> list:
    """Tests (``TestResult``) of a function built on another that fails too: say which to fix first."""
    import dataclasses

    deps = DEPENDS.get(exercise_id, {})
    failed = {t.grade_id for t in tests if not t.passed}
    out = []
    for t in tests:
        dep = deps.get(t.grade_id)
        if dep is not None and not t.passed and dep[0] in failed:
            lead = (
                f"fix `{dep[1]}` first: `{dep[2]}` builds on it and its tests fail too (this test "
                "may pass once it is right). "
            )
            t = dataclasses.replace(t, message=lead + t.message, safe_message=lead + (t.safe_message or ""))
        out.append(t)
    return out


def feedback_lines(test, *, hidden: bool, with_message: bool = True) -> list[str]:
    """What a student sees of one test beyond its score: the (safe) message and the mistake lines."""
    lines = []
    if with_message and not test.passed:
        text = test.safe_message if hidden else test.message
        if text:
            lines.append(text)
    lines += describe_mistakes(getattr(test, "mistakes", ()))
    return lines


def mistake_records(results: Sequence) -> list[dict]:
    """``[{"exercise", "id", "tests"}]`` of the mistakes recognised in ``ExerciseResult``\\ s."""
    records: dict[tuple[str, str], dict] = {}
    for r in results:
        for t in r.tests:
            for m in t.mistakes:
                rec = records.setdefault(
                    (r.exercise_id, m), {"exercise": r.exercise_id, "id": m, "tests": []}
                )
                rec["tests"].append(t.name)
    return list(records.values())
