"""Shared types of the port harnesses.

Every language harness (C++, Java, Octave, Mathics, block diagram) reads every case of the vector
files of the problems it implements, compares with the case's tolerance itself, and prints one line
per case on stdout::

    CASE <problem> <case_id> PASS|FAIL <max_abs_error> <free text message>

(``max_abs_error`` as a float, ``nan`` when the case could not be computed). A ``lang_*`` module runs
the harness and turns those lines into :class:`CaseResult` objects with :func:`parse_case_lines`
(:func:`harness_results` adds a failed result when a harness printed no line at all). Ports run in
Python (Mathics, block diagram) compare with :func:`compare_outputs` instead.
"""

from __future__ import annotations

import math
import subprocess
from dataclasses import dataclass
from pathlib import Path

from ..course import ports_dir, vectors_dir

__all__ = [
    "CaseResult",
    "ToolchainMissing",
    "compare_outputs",
    "failure",
    "harness_results",
    "parse_case_lines",
]



def __getattr__(name: str) -> Path:
    """``PORTS_DIR`` (the course's ports folder: sources, ``vectors/``, the build cache ``build/``)
    and ``VECTORS_DIR``, looked up when read (``--course``/``$FLOWTRACK_COURSE``/the current folder,
    see :mod:`flowtrack_course.course`)."""
    if name == "PORTS_DIR":
        return ports_dir()
    if name == "VECTORS_DIR":
        return vectors_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class ToolchainMissing(RuntimeError):
    """A compiler/interpreter a port needs is not installed (never a silent skip).

    The port harnesses' error; the grader has its own,
    :class:`flowtrack_course.grading.languages.toolchains.ToolchainMissing`.
    """


@dataclass(frozen=True)
class CaseResult:
    language: str  # e.g. "cpp-eigen", "cpp-pcl", "java", "java-ejml", "java-opencv", "octave", ...
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
    import numpy as np  # not at module level: ``flowtrack --help`` imports this module

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
