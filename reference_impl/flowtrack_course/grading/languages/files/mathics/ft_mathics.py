"""flowtrack exercise harness (Mathematica on Mathics3): reads a vectors file, calls your function.

It prints the outputs (and, with --check, compares them):

    python ft_mathics.py PROBLEM CASES.json SOURCE.wl          prints  OUTPUT <case id> <json>  per case
    python ft_mathics.py --check PROBLEM PUBLIC.json SOURCE.wl  also compares with each case's "expected"
                                                               and prints CASE <problem> <id> PASS|FAIL ...

The file is in the course's shared vectors format. Each case's inputs are written as Wolfram Language
machine reals, your function is evaluated with ``N[...]`` in one Mathics3 session (``pip install
mathics3``) and its ``InputForm`` is read back. Do not edit (the grader uses its own copy).
"""

import json
import math
import os
import re
import sys


def to_wl(value):
    if isinstance(value, (list, tuple)):
        return "{" + ", ".join(to_wl(v) for v in value) + "}"
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"non-finite input {x!r}")
    r = repr(x)
    if "e" in r:
        mant, exp = r.split("e")
        return (mant if "." in mant else mant + ".") + f"*^{int(exp)}"
    return r if "." in r else r + "."


def parse_input_form(text):
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


def main(argv):
    check = argv[:1] == ["--check"]
    if check:
        argv = argv[1:]
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    problem, cases_path, source = argv
    extra = os.environ.get("FT_PYTHONPATH")
    if extra:
        sys.path[:0] = [p for p in extra.split(os.pathsep) if p]
    from mathics.core.load_builtin import import_and_load_builtins

    import_and_load_builtins()
    from mathics.session import MathicsSession

    with open(cases_path, encoding="utf-8") as fh:
        doc = json.load(fh)
    session = MathicsSession()
    session.evaluate('Get["' + os.path.abspath(source).replace("\\", "\\\\").replace('"', '\\"') + '"]')
    function, args, outputs = CALLS[problem]
    all_ok = True
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
            print(f"ERROR {cid} {type(exc).__name__}: {' '.join(str(exc).split())[:300]}", flush=True)
            all_ok = False
            continue
        print(f"OUTPUT {cid} {json.dumps(out)}", flush=True)
        if check:
            worst, msg = 0.0, "ok"
            for name, exp in case["expected"].items():
                e = compare(out.get(name), exp, case["rtol"], case["atol"])
                if e < 0 or math.isinf(e):
                    msg = f"{name} differs" if msg == "ok" else msg
                worst = max(worst, abs(e + 1.0) if e < 0 else e)
            all_ok = all_ok and msg == "ok"
            verdict = "PASS" if msg == "ok" else "FAIL"
            print(f"CASE {problem} {cid} {verdict} {worst:.3g} {msg}", flush=True)
    return 1 if check and not all_ok else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
