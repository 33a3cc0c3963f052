"""flowtrack exercise harness (Mathematica on Mathics3): reads a vectors file, calls your function.

It prints the outputs (and, with --check, compares them):

    python ft_mathics.py PROBLEM CASES.json SOURCE.wl          prints  OUTPUT <case id> <json>  per case
    python ft_mathics.py --check PROBLEM PUBLIC.json SOURCE.wl  also compares with each case's "expected"
                                                               and prints CASE <problem> <id> PASS|FAIL ...

The file is in the course's shared vectors format. Each case's inputs are written as Wolfram Language
machine reals, your function is evaluated with ``N[...]`` in one Mathics3 session (``pip install
mathics3``) and its ``InputForm`` is read back. Do not edit (the grader uses its own copy, calling
``grade()`` inside its sandbox's own process).
"""

import json
import math
import os
import re
import sys


def to_wl(value):
    """A number or nested list as a Wolfram Language expression of machine reals (``repr`` digits,
    ``*^`` exponents): the course's one writer, used by the ports too."""
    if isinstance(value, (list, tuple)):
        return "{" + ", ".join(to_wl(v) for v in value) + "}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"value: expected numbers or nested lists of numbers, got {type(value).__name__}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"value: non-finite number {x!r}")
    r = repr(x)
    if "e" in r:
        mant, exp = r.split("e")
        return (mant if "." in mant else mant + ".") + f"*^{int(exp)}"
    return r if "." in r else r + "."


def parse_input_form(text):
    """A Mathics ``InputForm`` of (nested lists of) reals as Python floats and lists (the course's one
    reader, used by the ports too)."""
    s = re.sub(r"`[0-9.]*", "", text.strip())
    s = s.replace("*^", "e").replace("{", "[").replace("}", "]")
    s = re.sub(r"(\d)\.(?![0-9])", r"\1.0", s)
    return json.loads(s)


CALLS = {
    "cv_model": ("cvModel", ("dt", "q"), ("F", "Q")),
    "kalman_step": ("kalmanStep", ("x", "P", "F", "Q", "H", "R", "z"), ("x", "P")),
    "projection_jacobian": ("projectionJacobian", ("X", "fx", "fy", "cx", "cy"), ("J",)),
    "mahalanobis_gating": ("mahalanobisGating", ("z_pred", "S", "Z", "gate"), ("d2", "inside")),
}


def compare(got, exp, rtol, atol):
    if isinstance(exp, list):
        if not isinstance(got, list) or len(got) != len(exp):
            return math.inf
        return max([compare(g, e, rtol, atol) for g, e in zip(got, exp)] or [0.0])
    try:
        err = abs(float(got) - float(exp))
    except (TypeError, ValueError):
        return math.inf
    return err if err <= atol + rtol * abs(float(exp)) else math.inf if math.isnan(err) else -err - 1.0


MAX_PRINTS = 1000  # Print[] results kept per evaluation (a loop of prints must not fill the memory)


class _CappedOut(list):
    """``Evaluation.out`` keeping the first :data:`MAX_PRINTS` messages and prints."""

    def append(self, item):
        if len(self) < MAX_PRINTS:
            super().append(item)


def new_session():
    """A fresh Mathics3 session. The grader's sandbox may have loaded the builtins and built one
    pristine set of definitions before any student code existed (``mathics.profile_mathics``, imported
    by a zygote that then forks a child per exercise): that one is used when present."""
    extra = os.environ.get("FT_PYTHONPATH")
    if extra:
        sys.path[:0] = [p for p in extra.split(os.pathsep) if p and p not in sys.path]
    from mathics.core import load_builtin

    if not load_builtin.mathics3_builtins_modules:
        load_builtin.import_and_load_builtins()
    from mathics.core.evaluation import Evaluation
    from mathics.session import MathicsSession

    warm = sys.modules.get("mathics.profile_mathics")
    definitions = getattr(warm, "definitions", None)
    if definitions is None:
        session = MathicsSession()
    else:  # a MathicsSession around the pre-built definitions (its __init__ would build new ones)
        session = MathicsSession.__new__(MathicsSession)
        session.form, session.last_result, session.shell = "InputForm", None, None
        session.definitions = definitions
        session.evaluation = Evaluation(definitions=definitions, catch_interrupt=False)
    session.evaluation.out = _CappedOut()
    return session


def run_doc(problem, doc, source, check=False, session=None):
    """Evaluate ``source`` (a .wl file) in ``session`` (a new one when None), call the problem's
    function on every case of the vectors document ``doc``; return ``(lines, all_ok, session)``."""
    if session is None:
        session = new_session()
        session.evaluate('Get["' + os.path.abspath(source).replace("\\", "\\\\").replace('"', '\\"') + '"]')
    function, args, outputs = CALLS[problem]
    all_ok = True
    lines = []
    for case in doc["cases"]:
        cid = case["id"]
        try:
            expr = function + "[" + ", ".join(to_wl(case["input"][a]) for a in args) + "]"
            res = session.evaluate(f"ToString[InputForm[N[{expr}]]]")
            got = parse_input_form(str(getattr(res, "value", res)))
            if len(outputs) == 1:
                got = [got]
            if not isinstance(got, list) or len(got) != len(outputs):
                raise ValueError(f"{function} must return {{{', '.join(outputs)}}}")
            out = dict(zip(outputs, got))
        except Exception as exc:  # this case's error, reported like the other harnesses do
            lines.append(f"ERROR {cid} {type(exc).__name__}: {' '.join(str(exc).split())[:300]}")
            all_ok = False
            continue
        lines.append(f"OUTPUT {cid} {json.dumps(out)}")
        if check:
            worst, msg = 0.0, "ok"
            for name, exp in case["expected"].items():
                e = compare(out.get(name), exp, case["rtol"], case["atol"])
                if e < 0 or math.isinf(e):
                    msg = f"{name} differs" if msg == "ok" else msg
                worst = max(worst, abs(e + 1.0) if e < 0 else e)
            all_ok = all_ok and msg == "ok"
            verdict = "PASS" if msg == "ok" else "FAIL"
            lines.append(f"CASE {problem} {cid} {verdict} {worst:.3g} {msg}")
    return lines, all_ok, session


_GRADER = {}


def grade(problem, source, doc):
    """The grader's entry point (run inside its sandbox, in-process): the output lines for ``doc``.
    The public and the hidden test of one exercise share the session (the student's file is read once)."""
    lines, _, _GRADER["session"] = run_doc(problem, doc, source, session=_GRADER.get("session"))
    return "\n".join(lines) + "\n"


def main(argv):
    check = argv[:1] == ["--check"]
    if check:
        argv = argv[1:]
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    problem, cases_path, source = argv
    with open(cases_path, encoding="utf-8") as fh:
        doc = json.load(fh)
    lines, all_ok, _ = run_doc(problem, doc, source, check)
    for line in lines:
        print(line, flush=True)
    return 1 if check and not all_ok else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
