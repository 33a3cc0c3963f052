"""Attacks through ex11's formula answers: the text is parsed inside the sandbox.

A formula answer (``q_order()`` returns ``"Matrix([[...]])"``) is parsed by an :mod:`ast` whitelist
and evaluated with sympy in the sandboxed child (:mod:`grading_sandbox.formula`); only
numbers come back. Each attack below - a huge exponent, deep nesting, ``__import__``, attribute
walks, very long strings, exact numbers that explode, a formula that passes the whitelist but
keeps sympy busy for ever, forged replies - scores 0 as a wrong answer (or a time-out) and leaves
the grader whole: the grader process never parses the text (checked by making every parser of the
grader process fail while the real sandbox grades).
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtrack_course.grading.engine.seeds import public_seed
from flowtrack_course.grading.engine.symbolic import formula_request, values_of
from grading_helpers import exercise_module, get_exercise
from grading_sandbox import Call, Limits, Outcome, Sandbox

pytestmark = pytest.mark.xdist_group("sandbox")

EX = get_exercise("ex11_concepts")
_ex11_q = exercise_module("ex11_concepts")._ex11_q
LIMITS = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30, processes=16)
RIGHT = (
    "Matrix([[dt**4*q/4, dt**3*q/2, 0, 0], [dt**3*q/2, dt**2*q, 0, 0], "
    "[0, 0, dt**4*q/4, dt**3*q/2], [0, 0, dt**3*q/2, dt**2*q]])"
)

ATTACKS = {
    "huge_exponent": "return 'dt**999999999'",
    "huge_exponent_caret": "return 'q^999999999 * dt'",
    "deep_parentheses": "return '(' * 3000 + 'dt' + ')' * 3000",
    "deep_unary": "return '-' * 3900 + 'dt'",
    "deep_matrix": "return 'Matrix(' + '[' * 1000 + 'dt' + ']' * 1000 + ')'",
    "dunder_import": "return \"__import__('os').system('touch /tmp/pwned')\"",
    "attribute_walk": "return '().__class__.__base__.__subclasses__()'",
    "lambda_call": "return '(lambda: dt)()'",
    "very_long": "return 'dt+' * 500000 + 'dt'",
    "huge_string": "return 'd' * (200 * 1024 * 1024)",
    "exploding_integer": "return '((((10**12)**24)**24)**24)**24'",
    "not_a_string": "return {'shape': [4, 4], 'values': [[[0.0, 0.0]] * 16] * 6}",
    "bytes": "return b'dt'",
    # passes the whitelist: the sandbox's time limit ends it
    "busy_sympy": "return 'exp(exp(exp(exp(24))))*dt'",
}
CELL = "\n".join(f"def {name}():\n    {body}\n" for name, body in ATTACKS.items()) + (
    f"def q_order():\n    return {RIGHT!r}\n"
)


def _q_test():
    calls, scorer = _ex11_q.build(np.random.default_rng(public_seed(EX.id, _ex11_q.name)))
    return calls, scorer


@pytest.fixture(scope="module")
def box():
    with Sandbox([("q_order", CELL)], blocked=EX.blocked, allowed=EX.allowed, packages=EX.packages,
                 limits=LIMITS) as sb:
        yield sb


def test_the_right_answer_scores_through_the_sandbox(box):
    calls, scorer = _q_test()
    assert calls[0].post is not None and calls[0].post["op"] == "formula"
    fraction, _ = scorer(box.run(calls, timeout=20))
    assert fraction == 1.0
    assert not box.cell_errors


@pytest.mark.parametrize("name", list(ATTACKS))
def test_formula_attack_scores_zero(box, name):
    calls, scorer = _q_test()
    attack = [Call(name, (), {}, calls[0].post)]
    timeout = 6.0 if name == "busy_sympy" else 20.0
    outcomes = box.run(attack, timeout=timeout)
    fraction, message = scorer(outcomes)
    assert fraction == 0.0, (name, outcomes)
    if name == "busy_sympy":
        assert not outcomes[0].ok  # killed by the sandbox's limits, not answered
    else:
        assert outcomes[0].ok, outcomes  # refused by the whitelist: an honest wrong answer
        assert "could not be read" in str(message), message
        assert set(outcomes[0].value) == {"error"} and len(outcomes[0].value["error"]) <= 500
    # the sandbox answers the next call normally (a killed child is replaced)
    assert scorer(box.run(calls, timeout=20))[0] == 1.0
    assert not (name == "dunder_import" and __import__("os").path.exists("/tmp/pwned"))


def test_the_grader_process_never_parses_formula_text(box, monkeypatch):
    """Every parser of the grader process fails: grading through the sandbox still works."""
    import sympy
    import sympy.parsing.sympy_parser as sympy_parser

    from grading_sandbox import formula as _formula

    def refuse(*args, **kwargs):
        raise AssertionError("the grader process parsed formula text")

    monkeypatch.setattr(sympy, "sympify", refuse)
    monkeypatch.setattr(sympy, "parse_expr", refuse)
    monkeypatch.setattr(sympy_parser, "parse_expr", refuse)
    monkeypatch.setattr(_formula, "parse_answer", refuse)
    calls, scorer = _q_test()
    assert scorer(box.run(calls, timeout=20))[0] == 1.0
    # text that reached the grader unevaluated (no sandbox in between) is not read either
    fraction, message = scorer([Outcome(True, RIGHT)])
    assert fraction == 0.0 and "did not return the formula's values" in str(message)


def test_forged_values_need_the_right_formula():
    """Values the sandbox sends are data: malformed ones are refused, made-up ones are wrong."""
    calls, scorer = _q_test()
    for forged in (
        {"shape": [4, 4], "values": "x"},
        {"shape": [10**9], "values": [[[0.0, 0.0]]]},
        {"shape": [4, 4], "values": [[[0.0, 0.0]] * 16] * 6},
        {"shape": [4, 4], "values": [[[float("nan"), 0.0]] * 16] * 6},
        {"error": "x" * 10_000},
    ):
        fraction, message = scorer([Outcome(True, forged)])
        assert fraction == 0.0, forged
        assert len(str(message)) < 2000
    points = np.array(calls[0].post["points"])
    assert values_of({"shape": [], "values": [[[1.0, 0.0]]] * len(points)}).values.shape == (len(points),)
    assert formula_request(["dt", "q"], points)["points"] == calls[0].post["points"]
