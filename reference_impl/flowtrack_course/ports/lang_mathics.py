r"""Run the Mathematica port on Mathics3 against the shared test vectors.

Sources: ``cpp_java_matlab_ports/mathematica/`` — ``KalmanCV2D.wl`` (the syllabus' functional filter
with ``Q = KroneckerProduct[Q1d, IdentityMatrix[2]]``), ``SteadyState.wl`` (the scalar Riccati
equation solved with ``Solve``, positive root), ``ProjectionJacobian.wl`` (``D`` via ``Outer``).

Mathics3 has no JSON reader worth relying on, so this module turns each vector case into a Wolfram
Language expression (inputs written as machine reals with ``repr`` precision, ``*^`` exponents),
runs all of them in *one* fresh Mathics3 process (``python -m flowtrack_course.ports.lang_mathics JOB``,
about 3 s start-up), reads each result printed in ``InputForm`` (16 significant digits for machine
reals; the steady state is printed with 30 digits) and compares it with the case's tolerance here,
in Python: pass iff every ``|got - exp| <= atol + rtol |exp|``.

Every case of every problem in :data:`PROBLEMS` is run, including the 1000-step ``kalman_cv2d``
case. Speed: Mathics3 needs about 70 ms per 4×4 filter step (the 1000-step case alone takes about
75 s); Mathics3's ``FoldList`` is quadratic in the list length, hence the port's linear
``kalmanFoldList`` (same result), and Mathics3 counts every symbol rewrite of one top-level
evaluation against ``$IterationLimit``, hence the ``Block[{$IterationLimit = Infinity}, ...]``
around the fold (both explained in ``KalmanCV2D.wl``).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from ..course import ports_dir
from .base import CaseResult, ToolchainMissing, compare_outputs, failure

__all__ = [
    "LANGUAGES",
    "PROBLEMS",
    "run",
    "to_wl",
    "parse_input_form",
    "case_expression",
]

LANGUAGES: tuple[str, ...] = ("mathics",)
PROBLEMS: tuple[str, ...] = ("kalman_cv2d", "white_noise_q", "projection_jacobian", "steady_state_scalar")

def _src_dir() -> Path:
    """The Mathematica sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "mathematica"


def __getattr__(name: str) -> Path:
    if name == "SRC_DIR":  # read lazily: the course folder is chosen at run time
        return _src_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
SOURCES = ("KalmanCV2D.wl", "SteadyState.wl", "ProjectionJacobian.wl")


def to_wl(value) -> str:
    """Write a number or nested list as a Wolfram Language expression of machine reals.

    Examples
    --------
    >>> to_wl([[1, -2.5e-07], [3.0, 0.1]])
    '{{1.0, -2.5*^-7}, {3.0, 0.1}}'
    """
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


_BACKTICK = re.compile(r"`[0-9.]*")
_BARE_POINT = re.compile(r"(\d)\.(?![0-9])")


def parse_input_form(text: str):
    """Parse a Mathics ``InputForm`` of (nested lists of) reals into Python floats/lists.

    Examples
    --------
    >>> parse_input_form("{{0., 1.5*^-7}, {2, -3.25`30.}}")
    [[0.0, 1.5e-07], [2, -3.25]]
    """
    s = _BACKTICK.sub("", text.strip())
    s = s.replace("*^", "e").replace("{", "[").replace("}", "]")
    s = _BARE_POINT.sub(r"\1.0", s)
    return json.loads(s)


def case_expression(problem: str, inp: dict) -> str:
    """The Wolfram Language expression whose ``InputForm`` is the port's answer for one case."""
    if problem == "kalman_cv2d":
        x0 = inp.get("x0", [0.0] * 4)
        P0 = inp.get("P0", (1e3 * np.eye(4)).tolist())
        args = [inp["dt"], inp["process_var"], inp["meas_var"], x0, P0, inp["measurements"]]
        return "N[kalmanCV2D[" + ", ".join(to_wl(a) for a in args) + "]]"
    if problem == "white_noise_q":
        return f"N[whiteNoiseQ[{to_wl(inp['dt'])}, {to_wl(inp['q'])}, {int(inp['dim'])}]]"
    if problem == "projection_jacobian":
        args = [inp["X"], inp["fx"], inp["fy"], inp["cx"], inp["cy"]]
        return "N[projectionJacobian[" + ", ".join(to_wl(a) for a in args) + "]]"
    if problem == "steady_state_scalar":
        args = [inp.get("f", 1.0), inp.get("h", 1.0), inp["q"], inp["r"]]
        return "steadyStateP[" + ", ".join(to_wl(a) for a in args) + "]"
    raise ValueError(f"problem: {problem!r} is not implemented by the Mathematica port")


def _unpack(problem: str, got) -> dict:
    if problem == "kalman_cv2d":
        return {"positions": got[0], "P_final": got[1]}
    if problem == "white_noise_q":
        return {"Q": got}
    if problem == "projection_jacobian":
        return {"J": got}
    return {"P": got[0], "P_post": got[1]}


def run(vectors_dir: Path, build_dir: Path, *, reuse: bool = False) -> list[CaseResult]:
    """Evaluate every case of :data:`PROBLEMS` in one Mathics3 session and compare.

    Parameters
    ----------
    vectors_dir : Path
        Directory with the ``<problem>.json`` vector files.
    build_dir : Path
        The ports' build root; the job file goes to ``build_dir/mathics/job.json``, the answers to
        ``build_dir/mathics/answers.json``.
    reuse : bool
        Take the answer of an expression from ``answers.json`` when the Mathematica sources are
        unchanged (the key is a hash of the sources and the expression); only the missing ones are
        evaluated. The comparison with the expected values is always redone. Used by the test that
        spoils expected values (the inputs, hence the expressions, are the same).

    Returns
    -------
    list of CaseResult

    Raises
    ------
    flowtrack_course.ports.base.ToolchainMissing
        The ``mathics3`` Python package is not installed (``pip install -e ".[ports]"``).
    """
    if importlib.util.find_spec("mathics") is None:
        raise ToolchainMissing('Mathics3 not installed: pip install -e ".[ports]" (PyPI mathics3)')
    vectors_dir = Path(vectors_dir)
    results: list[CaseResult] = []
    jobs, meta = [], []
    for problem in PROBLEMS:
        path = vectors_dir / f"{problem}.json"
        if not path.exists():
            results.append(failure("mathics", problem, f"vector file {path.name} missing"))
            continue
        for case in json.loads(path.read_text())["cases"]:
            try:
                jobs.append(case_expression(problem, case["input"]))
                meta.append((problem, case))
            except (KeyError, TypeError, ValueError) as exc:
                results.append(failure("mathics", problem, f"bad input: {exc}", case["id"]))
    out = Path(build_dir) / "mathics"
    out.mkdir(parents=True, exist_ok=True)
    src_hash = hashlib.sha256(b"".join((_src_dir() / s).read_bytes() for s in SOURCES)).hexdigest()
    keys = [hashlib.sha256((src_hash + e).encode()).hexdigest() for e in jobs]
    store = out / "answers.json"
    cache = json.loads(store.read_text()) if reuse and store.exists() else {}
    answers: dict[int, str] = {i: cache[k] for i, k in enumerate(keys) if k in cache}
    todo = [i for i in range(len(jobs)) if i not in answers]
    errors: dict[int, str] = {}
    tail, returncode = "", 0
    if todo:
        job = out / "job.json"
        sources = [str(_src_dir() / s) for s in SOURCES]
        job.write_text(json.dumps({"sources": sources, "expressions": [jobs[i] for i in todo]}))
        proc = subprocess.run([sys.executable, "-m", __name__, str(job)], capture_output=True, text=True)
        returncode = proc.returncode
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        for line in proc.stdout.splitlines():
            parts = line.split(" ", 2)
            if len(parts) == 3 and parts[0] in ("RESULT", "ERROR") and parts[1].isdigit():
                i = todo[int(parts[1])]
                (answers if parts[0] == "RESULT" else errors)[i] = parts[2]
        fresh = json.loads(store.read_text()) if store.exists() else {}
        fresh.update({keys[i]: answers[i] for i in todo if i in answers})
        store.write_text(json.dumps(fresh))
    for i, (problem, case) in enumerate(meta):
        cid = case["id"]
        if i not in answers:
            why = errors.get(i, f"no result (exit {returncode}: {tail})")
            results.append(failure("mathics", problem, why, cid))
            continue
        try:
            got = _unpack(problem, parse_input_form(answers[i]))
        except (ValueError, IndexError, TypeError) as exc:
            results.append(failure("mathics", problem, f"unparsable output: {exc}", cid))
            continue
        ok, err, msg = compare_outputs(got, case["expected"], float(case["rtol"]), float(case["atol"]))
        results.append(CaseResult("mathics", problem, cid, ok, err, msg))
    return results


def _main(job_path: str) -> int:  # pragma: no cover - runs in the Mathics subprocess
    """Evaluate the job's sources and expressions; print ``RESULT i <InputForm>`` per expression."""
    from mathics.core.load_builtin import import_and_load_builtins

    import_and_load_builtins()
    from mathics.session import MathicsSession

    job = json.loads(Path(job_path).read_text())
    session = MathicsSession()
    for src in job["sources"]:
        session.evaluate(f'Get["{src}"]')
    for i, expr in enumerate(job["expressions"]):
        try:
            res = session.evaluate(f"ToString[InputForm[{expr}]]")
            text = res.value if hasattr(res, "value") else str(res)
        except Exception as exc:  # any Mathics failure is this case's error
            print(f"ERROR {i} {type(exc).__name__}: {exc}", flush=True)
            continue
        print(f"RESULT {i} {' '.join(str(text).split())}", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(_main(sys.argv[1]))
