"""Symbolic answers, the grader's side: formulas compared through their values, never parsed here.

A conceptual item's answer function returns a formula as text. The grader does not read that text:
the call carries a ``post`` request (:func:`formula_request`) and the sandboxed child parses the
text with the :mod:`ast` whitelist and evaluates it with sympy at the grader's points
(:mod:`grading_sandbox.formula`), sending back only numbers. The grader evaluates its own,
trusted, expressions (the right answer and the catalogued wrong ones) at the same points and
compares (:func:`FormulaValues`): sympy equivalence by identity testing at random points (two
rational functions that agree at random real points within 1e-9 are equal, with probability 1).

Nothing here calls ``eval``, ``sympify`` or ``parse_expr`` on student text; student data arrives as
JSON and is read with :func:`values_of` (shapes and types checked) into numpy arrays.

Examples
--------
>>> import numpy as np, sympy as sp
>>> points = sample_points(["dt", "q"], np.random.default_rng(0))
>>> dt, q = sp.symbols("dt q", positive=True)
>>> right = expected_values(sp.Matrix([[q * dt**4 / 4, q * dt**3 / 2]]), ["dt", "q"], points)
>>> from grading_sandbox.formula import apply
>>> got = values_of(apply(formula_request(["dt", "q"], points), "Matrix([[dt**4/4*q, q*dt**3/2]])"))
>>> got.equivalent(right), got.equivalent(right.scaled(-1))
(True, False)
>>> print(values_of(apply(formula_request(["dt"], points[:, :1]), "__import__('os')")).error)
only the names dt and Matrix, sqrt, exp, log, sin, cos, Rational, pi may be used, not __import__
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["FormulaValues", "expected_values", "formula_request", "sample_points", "values_of"]

N_POINTS = 6


def sample_points(names: Sequence[str], rng: np.random.Generator, n: int = N_POINTS) -> np.ndarray:
    """``n`` random points, one positive value in [0.3, 2] per symbol (shape ``(n, len(names))``)."""
    return rng.uniform(0.3, 2.0, size=(n, len(names)))


def formula_request(names: Sequence[str], points: np.ndarray) -> dict:
    """The ``post`` request of a call whose result is a formula in ``names``
    (:mod:`grading_sandbox.formula`)."""
    return {"op": "formula", "symbols": list(names), "points": np.asarray(points, float).tolist()}


@dataclass(frozen=True)
class FormulaValues:
    """A formula's values at the points: ``values`` of shape ``(n_points, *shape)``, complex;
    ``error`` when the sandbox could not read the formula (then ``values`` is None)."""

    shape: tuple[int, ...]
    values: np.ndarray | None
    error: str = ""

    def _close(self, a: np.ndarray, b: np.ndarray, rtol: float) -> np.ndarray:
        scale = 1e-12 * (1.0 + float(np.nanmax(np.abs(b), initial=0.0)))
        return np.isfinite(a) & np.isfinite(b) & (np.abs(a - b) <= rtol * np.abs(b) + scale)

    def equivalent(self, other: FormulaValues, rtol: float = 1e-9) -> bool:
        """Equal at every point (same shape)."""
        if self.values is None or other.values is None or self.shape != other.shape:
            return False
        return bool(np.all(self._close(self.values, other.values, rtol)))

    def differing_entries(self, other: FormulaValues, rtol: float = 1e-9) -> list[tuple[int, ...]]:
        """Indices of the entries that differ from ``other``'s at some point (same shape)."""
        ok = self._close(self.values, other.values, rtol).all(axis=0)
        return [tuple(int(i) for i in ix) for ix in np.argwhere(~ok)]

    def scaled(self, c: complex) -> FormulaValues:
        return FormulaValues(self.shape, None if self.values is None else self.values * c)

    def proportional(self, other: FormulaValues, rtol: float = 1e-9) -> complex | None:
        """The constant ``c`` with ``self = c * other`` at every point (nonzero), else None."""
        if self.values is None or other.values is None or self.shape != other.shape:
            return None
        a, b = self.values.ravel(), other.values.ravel()
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            return None
        big = np.abs(b) > 1e-12 * (1.0 + np.abs(b).max())
        if not big.any():
            return None
        c = complex(np.median((a[big] / b[big]).real) + 1j * np.median((a[big] / b[big]).imag))
        if abs(c) < 1e-12 or not self.equivalent(other.scaled(c), rtol):
            return None
        return c


def values_of(data: Any) -> FormulaValues:
    """Read what the sandbox sent for a formula (plain JSON data, untrusted) into a
    :class:`FormulaValues`; anything malformed becomes an ``error``."""
    if type(data) is dict and type(data.get("error")) is str:
        return FormulaValues((), None, data["error"][:500])
    bad = FormulaValues((), None, "the sandbox did not return the formula's values")
    if type(data) is not dict or type(data.get("shape")) is not list or type(data.get("values")) is not list:
        return bad
    shape = data["shape"]
    if len(shape) > 2 or not all(type(s) is int and 0 < s <= 64 for s in shape):
        return bad
    size = int(np.prod(shape)) if shape else 1
    rows = data["values"]
    if not rows or len(rows) > 64:
        return bad
    out = np.empty((len(rows), size), dtype=complex)
    for i, row in enumerate(rows):
        if type(row) is not list or len(row) != size:
            return bad
        for j, pair in enumerate(row):
            if type(pair) is not list or len(pair) != 2 or not all(type(x) in (int, float) for x in pair):
                return bad
            out[i, j] = complex(float(pair[0]), float(pair[1]))
    return FormulaValues(tuple(shape), out.reshape((len(rows), *shape)))


def expected_values(expr: Any, names: Sequence[str], points: np.ndarray) -> FormulaValues:
    """The values of a trusted sympy expression or Matrix (in symbols named ``names``) at ``points``."""
    from grading_sandbox.formula import evaluate, symbols_named

    symbols = symbols_named(names)
    by_name = {s.name: s for s in getattr(expr, "free_symbols", set())}
    expr = expr.xreplace({by_name[n]: symbols[n] for n in names if n in by_name})
    return values_of(evaluate(expr, symbols, np.asarray(points, float).tolist()))
