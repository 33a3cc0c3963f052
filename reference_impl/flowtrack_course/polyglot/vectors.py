r"""The shared vectors format: one JSON dump for the ports' files and the students' ``public.json``.

A problem document is ``{"problem": name, "cases": [{"id", "input", "expected", "rtol", "atol"},
...]}`` (the grader sends cases without ``expected``/``rtol``/``atol`` into a sandbox). Matrices are
nested lists, row by row. :func:`dumps` writes it canonically: sorted keys, floats as Python's
shortest round-trip ``repr``, one case per line (readable diffs).

A port passes a case iff every expected number ``e`` and its own ``g`` satisfy
:math:`|g - e| \le atol + rtol\,|e|`. Every port harness (C++, Java, Octave, Mathics, block
diagram) reads every case of the files of the problems it implements, compares with the case's
tolerance itself and prints one line per case on stdout::

    CASE <problem> <case_id> PASS|FAIL <max_abs_error> <free text message>

(``max_abs_error`` as a float, ``nan`` when the case could not be computed), which
:func:`parse_case_lines` turns into :class:`CaseResult`\ s (:func:`harness_results` adds a failed
result when a harness printed no line at all). Ports run in Python (Mathics, block diagram) compare
with :func:`compare_outputs` instead.
"""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import dataclass

__all__ = [
    "CaseResult",
    "compare_outputs",
    "dumps",
    "failure",
    "harness_results",
    "parse_case_lines",
    "plain",
]


def plain(obj):
    """``obj`` with numpy arrays and scalars turned into Python lists, floats, ints and bools.

    Floats must be finite; a negative zero becomes ``0.0`` (the files hold no ``-0.0``).

    Examples
    --------
    >>> import numpy as np
    >>> plain({"a": np.arange(2), "b": np.float64(-0.0), "c": (1.5, np.bool_(True))})
    {'a': [0, 1], 'b': 0.0, 'c': [1.5, True]}
    """
    if hasattr(obj, "tolist") and not isinstance(obj, (bool, int, float, str)):  # numpy arrays, scalars
        return plain(obj.tolist())
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, bool):
        return bool(obj)
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        value = float(obj)
        if not math.isfinite(value):
            raise ValueError(f"vector values must be finite, got {value}")
        return value + 0.0  # no negative zero in the files
    return obj


def dumps(doc: dict) -> str:
    """Serialise a problem document: sorted keys, ``repr``-exact floats, one case per line.

    Parameters
    ----------
    doc : dict
        ``{"problem": str, "cases": [dict, ...]}``.

    Returns
    -------
    str
        JSON text ending in a newline; ``json.loads`` gives ``doc`` back exactly.

    Examples
    --------
    >>> print(dumps({"problem": "p", "cases": [{"id": "a", "input": {"x": 0.1}}]}), end="")
    {"cases": [
    {"id": "a", "input": {"x": 0.1}}
    ], "problem": "p"}
    """
    if not isinstance(doc, dict) or "problem" not in doc or "cases" not in doc:
        raise ValueError("doc must be a dict with keys 'problem' and 'cases'")
    cases = [json.dumps(plain(c), sort_keys=True, allow_nan=False) for c in doc["cases"]]
    rest = {k: v for k, v in doc.items() if k != "cases"}
    head = json.dumps(plain(rest), sort_keys=True, allow_nan=False)
    # keys sort as "cases" < "problem": put the case list first, one per line for readable diffs
    return '{"cases": [\n' + ",\n".join(cases) + "\n], " + head[1:] + "\n"


@dataclass(frozen=True)
class CaseResult:
    """One port's verdict on one vector case (``language`` is the port: ``cpp-eigen``, ``java-ejml``, ...)."""

    language: str
    problem: str
    case_id: str
    passed: bool
    max_error: float
    message: str = ""


def parse_case_lines(language: str, text: str) -> list[CaseResult]:
    """Parse ``CASE problem id PASS|FAIL err message`` lines; other lines are ignored."""
    results = []
    for line in text.splitlines():
        parts = line.strip().split(maxsplit=5)
        if len(parts) < 5 or parts[0] != "CASE" or parts[3] not in ("PASS", "FAIL"):
            continue
        try:
            err = float(parts[4])
        except ValueError:
            err = math.nan
        results.append(
            CaseResult(
                language, parts[1], parts[2], parts[3] == "PASS", err, parts[5] if len(parts) > 5 else ""
            )
        )
    return results


def failure(language: str, problem: str, message: str, case_id: str = "-") -> CaseResult:
    """A failed :class:`CaseResult` without an error value (``max_error`` is ``nan``)."""
    return CaseResult(language, problem, case_id, False, math.nan, message)


def harness_results(language: str, proc: subprocess.CompletedProcess) -> list[CaseResult]:
    """The ``CASE`` lines of a finished harness, or one failed result (problem ``harness``) if none.

    The failed result's message is the exit code and the last line of the harness' stderr.
    """
    results = parse_case_lines(language, proc.stdout)
    if not results:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        results = [failure(language, "harness", f"exit {proc.returncode}: {tail}")]
    return results


def compare_outputs(got: dict, expected: dict, rtol: float, atol: float) -> tuple[bool, float, str]:
    r"""Compare a port's outputs with a vector case's expected values.

    A case passes iff every expected key the port produces has the expected shape and every entry
    satisfies :math:`|g - e| \le atol + rtol\,|e|` (``nan`` never does). Expected keys missing from
    ``got`` are informational outputs the port does not compute and are skipped.

    Parameters
    ----------
    got, expected : dict
        Output name -> number or array_like of numbers.
    rtol, atol : float
        The case's tolerances.

    Returns
    -------
    passed : bool
    worst : float
        Largest absolute error (``inf`` if a value is ``nan``, ``nan`` on a shape mismatch).
    message : str
        ``"ok"``, or the first offending entry with plain-number values.

    Examples
    --------
    >>> compare_outputs({"Q": [[1.0, 2.5]]}, {"Q": [[1.0, 2.0]], "T_true": 0.0}, 0.0, 0.1)
    (False, 0.5, 'Q[0, 1]: got 2.5, expected 2.0')
    """
    import numpy as np  # not at module level: ``flowtrack --help`` imports the ports' runner

    ok, worst, msg = True, 0.0, "ok"
    for key, exp in expected.items():
        if key not in got:
            continue
        e = np.atleast_1d(np.asarray(exp, dtype=float))
        g = np.atleast_1d(np.asarray(got[key], dtype=float))
        if g.shape != e.shape:
            return False, math.nan, f"{key}: shape {g.shape}, expected {e.shape}"
        err = np.abs(g - e)
        worst = max(worst, math.inf if np.isnan(err).any() else float(err.max(initial=0.0)))
        bad = np.argwhere(~(err <= atol + rtol * np.abs(e)))
        if len(bad) and ok:
            i = tuple(bad[0])
            where = ", ".join(str(int(j)) for j in i)
            ok, msg = False, f"{key}[{where}]: got {float(g[i])!r}, expected {float(e[i])!r}"
    return ok, worst, msg
