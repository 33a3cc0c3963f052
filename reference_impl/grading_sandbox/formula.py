"""A student's formula (text) read and evaluated **inside the sandbox**: only numbers come out.

A conceptual item's answer function returns a string such as ``"Matrix([[dt**4/4*q, ...]])"``
(what ``str()`` of a sympy object gives). The grader never parses that text: the call carries a
``post`` request (``{"op": "formula", "symbols": [...], "points": [[...], ...]}``) and the sandboxed
child, right after the student's function returned, hands the text to :func:`apply`, which

1. parses it with :mod:`ast` and builds the sympy object node by node from a whitelist (numbers, the
   item's symbols, ``+ - * / **``, ``Matrix``/lists and a few functions), with limits on length,
   nesting, size, exponents and the size of exact numbers (:func:`parse_answer`; never ``eval``,
   ``sympify`` or ``parse_expr``, which evaluate Python) - a second layer behind the sandbox's
   own time, memory and process limits, which bound whatever sympy does with an answer that passes
   the whitelist;
2. evaluates the result at the grader's points (positive values of the symbols, 20 digits) and
   returns plain data, ``{"shape": [...], "values": [[[re, im], ...], ...]}`` (one flattened list of
   entries per point), or ``{"error": "why the text is not an accepted formula"}``.

The grader compares those numbers with the values of its own (trusted) expressions at the same
points: equal at every point within a relative 1e-9 means equivalent (a polynomial or rational
identity that holds at random points holds everywhere, with probability 1). A student whose code
tampers with this module inside the sandbox can only change the numbers sent for their own answer,
which they could have returned as an answer anyway: to forge the right values they need the right
formula.

This module is copied next to ``_child.py`` (:func:`.runtime.runner_dir`) and loaded by the child
before any student code runs; it imports only the standard library, and sympy when a formula is
evaluated. A grader imports it from the package to evaluate its own expressions the same way
(:func:`evaluate`), and an in-process runner to do what the child does (:func:`apply`).

Examples
--------
>>> import sympy as sp
>>> dt, q = sp.symbols("dt q", positive=True)
>>> parse_answer("Matrix([[dt**4/4*q, q*dt**3/2]])", {"dt": dt, "q": q})
Matrix([[dt**4*q/4, dt**3*q/2]])
>>> apply({"op": "formula", "symbols": ["dt"], "points": [[1.0]]}, "__import__('os')")["error"]
'only the names dt and Matrix, sqrt, exp, log, sin, cos, Rational, pi may be used, not __import__'
>>> apply({"op": "formula", "symbols": ["x"], "points": [[2.0]]}, "x**2/2")
{'shape': [], 'values': [[[2.0, 0.0]]]}
>>> apply({"op": "formula", "symbols": ["x"], "points": [[2.0]]}, "x**999999999")
{'error': 'exponents must be numbers of size at most 24'}
"""

import ast

MAX_CHARS = 4000
MAX_NODES = 3000
MAX_DEPTH = 60
MAX_EXPONENT = 24
MAX_DIGITS = 60  # exact numbers (integers, numerators, denominators) stay below 10**MAX_DIGITS
MAX_POINTS = 16
FUNCTIONS = ("Matrix", "sqrt", "exp", "log", "sin", "cos", "Rational", "pi")


class AnswerError(ValueError):
    """The answer text is not a formula the grader accepts (the message says why)."""


def _depth(tree):
    """The nesting depth of an ast, computed without recursion."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        if deepest > MAX_DEPTH:
            return deepest
        stack.extend((child, d + 1) for child in ast.iter_child_nodes(node))
    return deepest


def parse_answer(text, symbols):
    """Parse ``text`` into a sympy expression or Matrix using only ``symbols`` and the whitelist.

    Raises
    ------
    AnswerError
        ``text`` is not a string, too long, too deep, does not parse or uses anything outside the
        whitelist (the message says which).
    """
    import sympy as sp

    if type(text) is not str:
        raise AnswerError(f"the answer must be a string (a formula), got {type(text).__name__}")
    if len(text) > MAX_CHARS:
        raise AnswerError(f"the answer is longer than {MAX_CHARS} characters")
    if text.count("(") + text.count("[") > MAX_NODES:
        raise AnswerError("the formula is too large")
    try:
        tree = ast.parse(text.strip().replace("^", "**"), mode="eval")
    except (SyntaxError, ValueError) as exc:
        raise AnswerError(f"the formula does not parse: {getattr(exc, 'msg', exc)}") from None
    except (RecursionError, MemoryError):
        raise AnswerError("the formula is nested too deeply") from None
    if sum(1 for _ in ast.walk(tree)) > MAX_NODES:
        raise AnswerError("the formula is too large")
    if _depth(tree) > MAX_DEPTH:
        raise AnswerError(f"the formula is nested more than {MAX_DEPTH} levels deep")
    funcs = {"sqrt": sp.sqrt, "exp": sp.exp, "log": sp.log, "sin": sp.sin, "cos": sp.cos}
    allowed = ", ".join(symbols) + " and " + ", ".join(FUNCTIONS)
    limit = 10**MAX_DIGITS

    def small(v):
        if isinstance(v, sp.Rational) and (abs(v.p) >= limit or abs(v.q) >= limit):
            raise AnswerError("a number in the formula is too large")
        return v

    def conv(node):
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
        arithmetic = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)
        if isinstance(node, ast.BinOp) and isinstance(node.op, arithmetic):
            left, right = conv(node.left), conv(node.right)
            if isinstance(left, list) or isinstance(right, list):
                raise AnswerError("lists cannot be added or multiplied: write Matrix([[...], [...]])")
            if isinstance(node.op, ast.Add):
                return small(left + right)
            if isinstance(node.op, ast.Sub):
                return small(left - right)
            if isinstance(node.op, ast.Mult):
                return small(left * right)
            if isinstance(node.op, ast.Div):
                if right == 0:
                    raise AnswerError("division by zero in the formula")
                return small(left / right)
            if not (isinstance(right, sp.Expr) and right.is_number and abs(float(right)) <= MAX_EXPONENT):
                raise AnswerError(f"exponents must be numbers of size at most {MAX_EXPONENT}")
            if isinstance(left, sp.Rational) and isinstance(right, sp.Rational):
                digits = max(len(str(abs(left.p))), len(str(left.q)))
                if digits * abs(float(right)) > MAX_DIGITS:
                    raise AnswerError("a number in the formula is too large")
            return left**right
        if isinstance(node, (ast.List, ast.Tuple)):
            return [conv(e) for e in node.elts]
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            name = node.func.id
            if name not in FUNCTIONS or name == "pi":
                raise AnswerError(f"only the names {allowed} may be used, not {name}")
            args = [conv(a) for a in node.args]
            if name == "Matrix" and len(args) == 1 and isinstance(args[0], list):
                try:
                    return sp.Matrix(args[0])
                except Exception:
                    raise AnswerError("Matrix(...) needs a list of rows of equal length") from None
            if name == "Rational" and len(args) == 2 and all(isinstance(a, sp.Integer) for a in args):
                if args[1] == 0:
                    raise AnswerError("division by zero in the formula")
                return sp.Rational(args[0], args[1])
            fn = funcs.get(name)
            if fn is not None and len(args) == 1 and isinstance(args[0], sp.Expr):
                return fn(args[0])
            raise AnswerError(f"{name}(...) is not allowed here (or has the wrong arguments)")
        raise AnswerError(f"{type(node).__name__} is not allowed in a formula: use numbers, {allowed}")

    out = conv(tree)
    if isinstance(out, list):
        raise AnswerError("a list is not a formula: write Matrix([[...], [...]]) for a matrix")
    return out


def symbols_named(names):
    """The positive sympy symbols of ``names`` (what every formula item uses), by name."""
    import sympy as sp

    return {n: sp.Symbol(n, positive=True) for n in names}


def evaluate(expr, symbols, points, digits=20):
    """``{"shape", "values"}`` of a sympy expression or Matrix at ``points`` (plain data).

    ``points`` lists one value per symbol (in the order of ``symbols``) per point; each point gives
    the flattened entries as ``[re, im]`` pairs (NaN where a value is not a finite number).
    """
    import sympy as sp

    is_matrix = isinstance(expr, sp.MatrixBase)
    shape = list(expr.shape) if is_matrix else []
    entries = list(expr) if is_matrix else [expr]
    syms = [symbols[n] for n in symbols]
    values = []
    for point in points:
        sub = {s: sp.Float(repr(float(x)), digits + 5) for s, x in zip(syms, point)}
        row = []
        for e in entries:
            try:
                z = complex(e.xreplace(sub).evalf(digits))
                pair = [z.real, z.imag]
            except (TypeError, ValueError, OverflowError, ZeroDivisionError):
                pair = [float("nan"), float("nan")]
            row.append(pair)
        values.append(row)
    return {"shape": shape, "values": values}


def apply(post, value):
    """What the child sends back for a call with a ``post`` request (see the module docstring).

    Raises
    ------
    ValueError
        ``post`` is not a request this module knows (a grader bug; the call then fails).
    """
    if type(post) is not dict or post.get("op") != "formula":
        raise ValueError("unknown post-processing request")
    names = post.get("symbols")
    points = post.get("points")
    if (
        type(names) is not list
        or not all(type(n) is str and n.isidentifier() for n in names)
        or type(points) is not list
        or not 0 < len(points) <= MAX_POINTS
        or not all(type(p) is list and len(p) == len(names) for p in points)
    ):
        raise ValueError("malformed formula request")
    symbols = symbols_named(names)
    try:
        expr = parse_answer(value, symbols)
    except AnswerError as exc:
        return {"error": str(exc)[:500]}
    return evaluate(expr, symbols, points)
