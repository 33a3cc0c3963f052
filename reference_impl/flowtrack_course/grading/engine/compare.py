"""Trusted comparisons of what came back from the sandbox (plain data) with expected arrays.

>>> from grading_sandbox import Outcome
>>> compare_arrays(Outcome(True, [1.0, 2.0]), [1.0, 2.0])
(True, 'ok')
>>> as_float_array([[1, 2]], (1, None)).shape, as_float_array("12") is None
((1, 2), True)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from grading_sandbox import Outcome

__all__ = ["as_float_array", "compare_arrays"]


def as_float_array(value: Any, shape: tuple[int | None, ...] | None = None) -> np.ndarray | None:
    """Plain data -> float64 array, or None when it is not numeric or has the wrong shape.

    Only ``int``, ``float``, ``bool`` and nested ``list``/``tuple`` of them are accepted (what the
    grader's JSON decoding produces); ``None`` entries in ``shape`` match any length.
    """
    if not _plain_numeric(value):
        return None
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            return None
    return arr


def _plain_numeric(value: Any, depth: int = 0) -> bool:
    if depth > 8:
        return False
    if type(value) in (int, float, bool):
        return True
    if type(value) in (list, tuple):
        return all(_plain_numeric(v, depth + 1) for v in value)
    return False


def compare_arrays(
    outcome: Outcome, expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9
) -> tuple[bool, str]:
    """Trusted comparison of one outcome with an expected array (shape must match exactly)."""
    if not outcome.ok:
        return False, outcome.error or "the call failed"
    expected = np.asarray(expected, dtype=np.float64)
    got = as_float_array(outcome.value, expected.shape)
    if got is None:
        got_any = as_float_array(outcome.value)
        if got_any is None:
            return False, "the result is not an array of numbers"
        return False, f"expected an array of shape {expected.shape}, got shape {got_any.shape}"
    if not np.all(np.isfinite(got) == np.isfinite(expected)):
        return False, "NaN/inf where the expected value is finite (or the other way round)"
    finite = np.isfinite(expected)
    # Non-finite entries must be the same non-finite value: +inf (e.g. a gated cost) is not NaN or -inf.
    if not np.array_equal(got[~finite], expected[~finite], equal_nan=True):
        return False, "NaN/inf entries differ from the expected ones (+inf, -inf and NaN are different)"
    err = np.abs(got[finite] - expected[finite])
    bound = atol + rtol * np.abs(expected[finite])
    if np.all(err <= bound):
        return True, "ok"
    worst = float(np.max(err - bound)) if err.size else math.nan
    return False, f"values differ (worst excess over tolerance {worst:.3g}; rtol={rtol:g}, atol={atol:g})"
