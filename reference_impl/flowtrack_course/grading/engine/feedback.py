r"""Feedback that shows the difference without leaking hidden data.

A check's message is a :class:`Report`: a ``str`` (what a student sees of a *public* test: expected
against got, the worst entry and its index) that also carries ``safe``, the text a student may see of
a *hidden* test, and ``mistakes``, the catalogued mistakes recognised from the student's outputs
(:mod:`.mistakes`).

The safe text holds the grader's own words only, never a character the student's code chose: that
code saw the hidden inputs, so anything it controls (an exception's message or type name, an exit
status, the shape it returned, which entries are wrong, how many and by how much) could carry them
out. It says which check failed and why from a fixed vocabulary: the expected shape, "inf/NaN where
a finite value is expected", "wrong values" with the tolerance, a limit or a crash without numbers,
"your code raised" an exception type of a fixed list (:func:`safe_error`,
:func:`grading_sandbox.errors.category`). A :class:`Report` made without a safe text has the
generic one. Test-level feedback: one line per cause (:func:`explain_cascade`,
:func:`cell_problems`), which function to fix first (:func:`apply_dependencies`) and the lines a
student sees of a test (:func:`feedback_lines`).

Examples
--------
>>> import numpy as np
>>> from grading_sandbox import Outcome
>>> r = compare(Outcome(True, [[-1.0, -2.0]]), np.array([[1.0, 2.0]]))
>>> r.ok, list(r.mistakes)
(False, ['generic-sign'])
>>> "expected" in r.public and "expected" not in r.safe
True
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from grading_sandbox import Outcome
from grading_sandbox.errors import category

from .compare import as_float_array
from .mistakes import Catalogue, Variant, diagnose, generic_relation, shape_hint, visible_variants

__all__ = [
    "Diff",
    "Report",
    "apply_dependencies",
    "cell_problems",
    "compare",
    "explain_cascade",
    "feedback_lines",
    "mistake_records",
    "safe_error",
    "safe_text",
]


#: the hidden-safe text of a check that gives none
GENERIC_SAFE = "the results differ from the expected ones"


class Report(str):
    """A check's message: the public text (``str`` value), the hidden-safe text and the mistakes.

    ``safe`` must be made of the grader's own words (see the module docstring); without one a
    hidden test shows :data:`GENERIC_SAFE`.

    ``mistakes`` is a tuple of catalogue ids, in the order recognised, without repeats; ``checked``
    the catalogued ids that were visible on these inputs (their wrong answer differs from the right
    one); ``relations`` the relation of each generic id (the factor of ``generic-scale``, ...);
    ``evidence`` the independent evaluations the message stands for (1 for a call). A test names a
    mistake only when every call where it was visible matched it (:func:`consistent_mistakes`): one
    coincidence among several calls names nothing, and a generic id needs two calls or more.
    """

    safe: str
    mistakes: tuple[str, ...]
    checked: frozenset[str]
    relations: dict[str, Any]
    evidence: int

    def __new__(
        cls, public: str, safe: str | None = None, mistakes: Iterable[str] = (), checked: Iterable[str] = (),
        relations: Mapping[str, Any] | None = None, evidence: int = 1,
    ):
        obj = super().__new__(cls, public)
        obj.safe = GENERIC_SAFE if safe is None else str(safe)
        seen: list[str] = []
        for m in mistakes:
            if m not in seen:
                seen.append(m)
        obj.mistakes = tuple(seen)
        obj.checked = frozenset(checked) | frozenset(m for m in seen if not m.startswith("generic-"))
        obj.relations = dict(relations or {})
        obj.evidence = int(evidence)
        return obj

    def retext(self, public: str, safe: str | None = None) -> Report:
        """This report with other texts (the same mistakes, relations and evidence)."""
        return Report(public, safe, self.mistakes, self.checked, self.relations, self.evidence)


def safe_text(message: Any) -> str:
    """The hidden-safe text of a message (a plain ``str`` has none: only a generic sentence)."""
    safe = getattr(message, "safe", None)
    return str(safe) if safe is not None else GENERIC_SAFE


_LOCATION = re.compile(r'File "(<cell [^>]*>)", line (\d+)')
_ENGINE = (
    ("not run: answer cell", "not run: an answer cell failed to run (see the problems with the submission)"),
    ("sandbox error:", "the sandbox failed (not your code: tell your instructor)"),
    ("no result from the sandbox", "the sandbox failed (not your code: tell your instructor)"),
)


def safe_error(error: str) -> str:
    """What a hidden test may show of a failed call's ``error``: one sentence of a fixed list.

    The error's text is never copied: a student's code sees the hidden inputs and could put them in
    an exception's message, its type's name, an exit status or a signal. The engine's own reasons
    (a cell that failed, a sandbox error) and the sandbox's (limits, crashes, exits) become fixed
    sentences, an exception its type when the type is one of a fixed list
    (:func:`grading_sandbox.errors.category`).

    >>> safe_error('ValueError: \\n0.123456')
    'your code raised ValueError'
    >>> safe_error("Leak: 0.123456"), safe_error("timed out after 10 s")
    ('your code raised an exception', "timed out (the test's time limit was exceeded)")
    """
    text = str(error or "").strip()
    for prefix, sentence in _ENGINE:
        if text.startswith(prefix):
            return sentence
    return category(text)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _fmt_array(a: np.ndarray) -> str:
    return np.array2string(np.asarray(a), precision=6, separator=", ", threshold=40, max_line_width=100)


def _index(idx: tuple[int, ...]) -> str:
    return "[" + ", ".join(str(int(i)) for i in idx) + "]"


@dataclass(frozen=True)
class Diff:
    """The result of :func:`compare`: ``ok``, the public and the hidden-safe texts, the mistakes."""

    ok: bool
    public: str
    safe: str
    mistakes: tuple[str, ...] = ()
    checked: tuple[str, ...] = ()
    relations: tuple[tuple[str, Any], ...] = ()

    def report(self) -> Report:
        return Report(self.public, self.safe, self.mistakes, self.checked, dict(self.relations))


def compare(
    outcome: Outcome,
    expected: np.ndarray,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    variants: Sequence[Variant] = (),
) -> Diff:
    """Compare one outcome with the expected array and say how they differ.

    The public text shows expected against got (whole arrays when small) and the worst entry with
    its index; the safe text only which check failed (the expected shape, non-finite entries, wrong
    values and the relative tolerance, or :func:`safe_error`'s sentence).
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
        msg = (f"wrong shape: expected an array of shape {expected.shape}, got shape {got_any.shape}"
               + shape_hint(got_any.shape, expected.shape))
        mistakes = tuple(diagnose(got_any, expected, variants, rtol, atol))
        safe = f"wrong shape (expected {expected.shape})" + shape_hint(got_any.shape, expected.shape)
        return Diff(False, msg, safe, mistakes, checked, _relations(mistakes, got_any, expected, rtol, atol))
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
    relations = _relations(mistakes, got, expected, rtol, atol)
    k = int(bad.sum())
    tolerance = f"rtol={rtol:g}, atol={atol:g}"
    if bad_nonfinite.any():
        idx = tuple(int(i) for i in np.argwhere(bad_nonfinite)[0])
        public = (
            f"{int(bad_nonfinite.sum())} of {n} entries are non-finite where the expected value is finite "
            f"or the other way round (+inf, -inf and NaN are different); first at {_index(idx)}: "
            f"expected {_fmt(expected[idx])}, got {_fmt(got[idx])}"
        )
        safe = "inf/NaN where a finite value is expected, or the other way round"
    else:
        excess = np.where(bad, err - bound, -np.inf)
        idx = tuple(int(i) for i in np.unravel_index(int(np.argmax(excess)), expected.shape))
        public = (
            f"values differ at {k} of {n} entries; worst at {_index(idx)}: expected {_fmt(expected[idx])}, "
            f"got {_fmt(got[idx])} ({tolerance})"
        )
        # which entries, how many and by how much are the student's choice: not shown (and the
        # absolute tolerance may be scaled by the expected values: only the relative one is named)
        safe = f"wrong values (beyond the relative tolerance rtol={rtol:g})"
    if n <= 24:
        public += f"\n    expected {_fmt_array(expected)}\n    got      {_fmt_array(got)}"
    return Diff(False, public, safe, mistakes, checked, relations)


def _relations(mistakes, got, expected, rtol, atol) -> tuple[tuple[str, Any], ...]:
    """``((generic id, relation),)`` when the diagnosis is generic (:func:`~.mistakes.generic_relation`)."""
    if not mistakes or not mistakes[0].startswith("generic-"):
        return ()
    rel = generic_relation(got, expected, rtol, atol)
    return (rel,) if rel is not None else ()


# --------------------------------------------------------------------------------------------------
# test-level feedback: one line per cause, dependencies, the lines a student sees

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

    A syntax error (Python prints where it is, the offending line and a caret, then the error)
    keeps the offending line, as Python shows it:

    >>> _cause('Traceback (most recent call last):\\n  File "<cell f>", line 2, in <module>\\n'
    ...        'ValueError: \\ud800 bad\\n<!--')
    'ValueError: \\\\ud800 bad\\\\n<!-- (at <cell f> line 2)'
    >>> _cause('File "<cell f>", line 4\\n    def def f(dt):\\n        ^^^\\nSyntaxError: invalid syntax')
    'SyntaxError: invalid syntax (at <cell f> line 4: def def f(dt):)'
    """
    text = str(text)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    # the exception starts after the last "File ..." line and its indented source lines (the
    # child's text may have lost the first line's indentation when it was stripped)
    start = 0
    for i, ln in enumerate(lines):
        if ln.lstrip().startswith('File "'):
            start = i + 1
    source = []
    while start and start < len(lines) and lines[start].startswith("    "):
        source.append(lines[start].strip())
        start += 1
    if start == 0 and lines and lines[0].startswith("Traceback"):
        start = 1
    exc = "\n".join(lines[start:]).strip() or text.strip()
    where = _LOCATION.findall(text)
    code = ""
    if exc.startswith(("SyntaxError", "IndentationError", "TabError")) and source:
        code = ": " + _one_line(source[0])[:120]
    return _one_line(exc)[:300] + (f" (at {where[-1][0]} line {where[-1][1]}{code})" if where else "")


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


def apply_dependencies(depends: Sequence, tests: list) -> list:
    """Tests (``TestResult``) of a function built on another that fails too: say which to fix first.

    ``depends`` are the exercise's :class:`~.spec.Dependency`\\ s (``test``, ``on``, ``function``,
    ``builds``).
    """
    import dataclasses

    deps = {d.test: d for d in depends}
    failed = {t.grade_id for t in tests if not t.passed}
    out = []
    for t in tests:
        dep = deps.get(t.grade_id)
        if dep is not None and not t.passed and dep.on in failed:
            lead = (
                f"fix `{dep.function}` first: `{dep.builds}` builds on it and its tests fail too (this "
                "test may pass once it is right). "
            )
            t = dataclasses.replace(t, message=lead + t.message, safe_message=lead + (t.safe_message or ""))
        out.append(t)
    return out


def feedback_lines(
    test, *, hidden: bool, with_message: bool = True, catalogue: Catalogue | None = None
) -> list[str]:
    """What a student sees of one test beyond its score: the (safe) message and the mistake lines
    (their messages from ``catalogue``, default the generic mistakes only)."""
    lines = []
    if with_message and not test.passed:
        text = test.safe_message if hidden else test.message
        if text:
            lines.append(text)
    lines += (catalogue or Catalogue()).lines(getattr(test, "mistakes", ()))
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
