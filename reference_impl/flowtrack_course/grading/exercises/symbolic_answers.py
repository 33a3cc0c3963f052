"""Symbolic answers: a student's formula, as text, turned into sympy without evaluating any code.

A conceptual item's answer function returns a string such as ``"Matrix([[dt**4/4*q, ...]])"`` (what
``str()`` of a sympy object gives). The grader never passes it to ``eval``, ``sympify`` or
``parse_expr`` (which all evaluate Python): :func:`parse_answer` parses it with :mod:`ast` and
builds the sympy object node by node from a whitelist (numbers, the item's symbols, ``+ - * / **``,
``Matrix``/lists and a few functions), with limits on length, size and exponents. Anything else is a
clear :class:`AnswerError` for the student.

:func:`equivalent` decides sympy equivalence: numerically at random positive points first (fast,
catches most differences), then ``sympy.simplify`` of the difference.

Examples
--------
>>> import sympy as sp
>>> dt, q = sp.symbols("dt q", positive=True)
>>> M = parse_answer("Matrix([[dt**4/4*q, q*dt**3/2]])", {"dt": dt, "q": q})
>>> equivalent(M, sp.Matrix([[q * dt**4 / 4, q * dt**3 / 2]]))
True
>>> parse_answer("__import__('os')", {"dt": dt})
Traceback (most recent call last):
...
flowtrack_course.grading.exercises.symbolic_answers.AnswerError: only the names dt and Matrix, sqrt, exp, log, sin, cos, Rational, pi may be used, not __import__
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from typing import Any

__all__ = ["AnswerError", "equivalent", "parse_answer", "proportional"]

MAX_CHARS = 4000
MAX_NODES = 3000
MAX_EXPONENT = 24


class AnswerError(ValueError):
    """The answer text is not a formula the grader accepts (the message says why)."""


def _functions():
    import sympy as sp

    return {
        "Matrix": None,  # handled separately
        "sqrt": sp.sqrt,
        "exp": sp.exp,
        "log": sp.log,
        "sin": sp.sin,
        "cos": sp.cos,
        "Rational": None,  # handled separately
        "pi": sp.pi,
    }


def parse_answer(text: Any, symbols: Mapping[str, Any]) -> Any:
    """Parse ``text`` into a sympy expression or Matrix using only ``symbols`` and the whitelist."""
    import sympy as sp

    if not isinstance(text, str):
        raise AnswerError(f"the answer must be a string (a formula), got {type(text).__name__}")
    if len(text) > MAX_CHARS:
        raise AnswerError(f"the answer is longer than {MAX_CHARS} characters")
    try:
        tree = ast.parse(text.strip().replace("^", "**"), mode="eval")
    except SyntaxError as exc:
        raise AnswerError(f"the formula does not parse: {exc.msg}") from None
    if sum(1 for _ in ast.walk(tree)) > MAX_NODES:
        raise AnswerError("the formula is too large")
    funcs = _functions()
    allowed = ", ".join(symbols) + " and " + ", ".join(funcs)

    def conv(node: ast.AST) -> Any:
        if isinstance(node, ast.Expression):
            return conv(node.body)
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            if type(node.value) is int:
                if abs(node.value) > 10**12:
                    raise AnswerError("a number in the formula is too large")
                return sp.Integer(node.value)
            return sp.Float(node.value)
        if isinstance(node, ast.Name):
            if node.id in symbols:
                return symbols[node.id]
            if node.id == "pi":
                return sp.pi
            raise AnswerError(f"only the names {allowed} may be used, not {node.id}")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = conv(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and isinstance(
            node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)
        ):
            left, right = conv(node.left), conv(node.right)
            if isinstance(node.op, ast.Add):
                return left + right
            if isinstance(node.op, ast.Sub):
                return left - right
            if isinstance(node.op, ast.Mult):
                return left * right
            if isinstance(node.op, ast.Div):
                if right == 0:
                    raise AnswerError("division by zero in the formula")
                return left / right
            if not (isinstance(right, sp.Expr) and right.is_number and abs(float(right)) <= MAX_EXPONENT):
                raise AnswerError(f"exponents must be numbers of size at most {MAX_EXPONENT}")
            return left**right
        if isinstance(node, (ast.List, ast.Tuple)):
            return [conv(e) for e in node.elts]
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            name = node.func.id
            if name not in funcs:
                raise AnswerError(f"only the names {allowed} may be used, not {name}")
            args = [conv(a) for a in node.args]
            if name == "Matrix" and len(args) == 1 and isinstance(args[0], list):
                rows = args[0]
                try:
                    return sp.Matrix(rows)
                except Exception:
                    raise AnswerError("Matrix(...) needs a list of rows of equal length") from None
            if name == "Rational" and len(args) == 2 and all(isinstance(a, sp.Integer) for a in args):
                return sp.Rational(args[0], args[1])
            fn = funcs.get(name)
            if callable(fn) and len(args) == 1 and isinstance(args[0], sp.Expr):
                return fn(args[0])
            raise AnswerError(f"{name}(...) is not allowed here (or has the wrong arguments)")
        raise AnswerError(f"{type(node).__name__} is not allowed in a formula: use numbers, {allowed}")

    out = conv(tree)
    if isinstance(out, list):
        raise AnswerError("a list is not a formula: write Matrix([[...], [...]]) for a matrix")
    return out


def _points(symbols, n: int, seed: int = 0):
    import numpy as np

    rng = np.random.default_rng(seed)
    return [{s: float(rng.uniform(0.3, 2.0)) for s in symbols} for _ in range(n)]


def _numeric(expr, point) -> Any:
    import numpy as np
    import sympy as sp

    val = expr.subs(point).evalf() if hasattr(expr, "subs") else expr
    if isinstance(val, sp.MatrixBase):
        return np.array(val.tolist(), dtype=complex)
    return np.array(complex(val))


def _shape(x):
    import sympy as sp

    return x.shape if isinstance(x, sp.MatrixBase) else ()


def equivalent(a: Any, b: Any, rtol: float = 1e-9) -> bool:
    """``a`` and ``b`` (expressions or matrices of the same shape) are equal as functions."""
    import numpy as np
    import sympy as sp

    if _shape(a) != _shape(b):
        return False
    syms = sorted((getattr(a, "free_symbols", set()) | getattr(b, "free_symbols", set())), key=str)
    try:
        for p in _points(syms, 4):
            x, y = _numeric(a, p), _numeric(b, p)
            if not np.allclose(x, y, rtol=rtol, atol=1e-12 * (1 + np.abs(y).max())):
                return False
        diff = sp.simplify(a - b)
    except Exception:
        return False
    if isinstance(diff, sp.MatrixBase):
        return all(sp.simplify(e) == 0 for e in diff)
    return diff == 0


def proportional(a: Any, b: Any) -> bool:
    """``a = c b`` for a nonzero constant ``c`` (an equation's left side, up to its scale)."""
    import sympy as sp

    if _shape(a) != () or _shape(b) != () or b == 0:
        return False
    try:
        ratio = sp.simplify(a / b)
    except Exception:
        return False
    return bool(ratio != 0 and not ratio.free_symbols and ratio.is_finite)
