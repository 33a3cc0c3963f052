r"""Mathematica on Mathics3: the port on the shared vectors, and the grader's recipe for an answer.

**One Wolfram-language writer and reader.** Mathics3 has no JSON reader worth relying on, so every
case is written as a Wolfram Language expression (machine reals with ``repr`` precision, ``*^``
exponents) and every answer is read back from its ``InputForm``. Both directions live in the
students' harness ``files/mathics/ft_mathics.py``, which must stand alone (students run it; the
sandbox runs it without flowtrack); :func:`harness` loads that file as a module and the ports use
its :func:`to_wl`, :func:`parse_input_form` and session instead of keeping a second copy.

**Port.** Sources: ``cpp_java_matlab_ports/mathematica/``: ``KalmanCV2D.wl`` (the syllabus'
functional filter with ``Q = KroneckerProduct[Q1d, IdentityMatrix[2]]``), ``SteadyState.wl`` (the
scalar Riccati equation solved with ``Solve``, positive root), ``ProjectionJacobian.wl`` (``D`` via
``Outer``). All cases run in *one* fresh Mathics3 process (``python -m
flowtrack_course.polyglot.mathics JOB``, about 3 s start-up); each result is printed in ``InputForm``
(16 significant digits for machine reals; the steady state with 30 digits) and compared with the
case's tolerance here, in Python. Every case of every problem in :data:`PROBLEMS` is run, including
the 1000-step ``kalman_cv2d`` case: Mathics3 needs about 70 ms per 4×4 filter step (that case alone
takes about 75 s); its ``FoldList`` is quadratic in the list length, hence the port's linear
``kalmanFoldList``, and it counts every symbol rewrite of one top-level evaluation against
``$IterationLimit``, hence the ``Block[{$IterationLimit = Infinity}, ...]`` around the fold (both
explained in ``KalmanCV2D.wl``).

**Answers.** A student writes ``<problem>.wl``; ``ft_mathics.py`` runs inside the sandbox's child
itself (:meth:`MathicsToolchain.inproc`): in ``flowtrack grade`` the child is forked from a zygote
that loaded the interpreter and built one pristine set of definitions before any student code
existed, so an item starts Mathics3 in milliseconds, not in the ~3 s (~10 s on a busy machine) of a
fresh interpreter (~0.6 s of CPU per item, ~7.6 s with a fresh interpreter per run).
"""

from __future__ import annotations

import functools
import hashlib
import json
import subprocess
import sys
import types
from dataclasses import dataclass
from pathlib import Path

from ..course import ports_dir
from .base import FILES, Toolchain, python_module, support_text
from .vectors import CaseResult, compare_outputs, failure

__all__ = [
    "PORTS",
    "PROBLEMS",
    "TOOLCHAIN",
    "case_expression",
    "harness",
    "parse_input_form",
    "run",
    "to_wl",
]

#: The ports this module runs (the names in ``flowtrack ports``' table).
PORTS: tuple[str, ...] = ("mathics",)
#: The vector problems the port implements.
PROBLEMS: tuple[str, ...] = ("kalman_cv2d", "white_noise_q", "projection_jacobian", "steady_state_scalar")
SOURCES = ("KalmanCV2D.wl", "SteadyState.wl", "ProjectionJacobian.wl")


@dataclass(frozen=True)
class MathicsToolchain(Toolchain):
    """An answer in Mathematica, evaluated by ``ft_mathics.py`` in the sandboxed child's own process."""

    def support_files(self, problem: str) -> dict[str, str]:
        return {"ft_mathics.py": support_text("mathics", "ft_mathics.py")}

    def inproc(self, problem: str) -> dict | None:
        return {"file": "ft_mathics.py", "function": "grade", "args": [problem, self.source_name(problem)]}

    def run_command(self, problem: str) -> list[str]:
        # @PYTHON@: the sandbox's own interpreter (see flowtrack_course.grading.languages.driver)
        return ["@PYTHON@", "-I", "-S", "ft_mathics.py", problem, "cases.json", self.source_name(problem)]

    def bundle_files(self, problem: str) -> dict[str, str]:
        return {"ft_mathics.py": support_text("mathics", "ft_mathics.py")}


TOOLCHAIN = MathicsToolchain(
    "mathics",
    "Mathematica (Mathics3)",
    requirements=(python_module("mathics", package='-e ".[ports]" (PyPI mathics3)'),),
    extension=".wl",
    todo="(* YOUR CODE HERE *)",
    compile_seconds=0.0,  # nothing to build; a fresh interpreter's start-up is part of the run
    run_seconds=30.0,
)


@functools.cache
def harness() -> types.ModuleType:
    """The students' harness ``files/mathics/ft_mathics.py``, loaded as a module (see the module
    docstring: the one Wolfram-language writer and reader)."""
    path = FILES / "mathics" / "ft_mathics.py"
    module = types.ModuleType("ft_mathics")
    module.__file__ = str(path)
    exec(compile(path.read_text(encoding="utf-8"), str(path), "exec"), module.__dict__)
    return module


def to_wl(value) -> str:
    """Write a number or nested list as a Wolfram Language expression of machine reals.

    Examples
    --------
    >>> to_wl([[1, -2.5e-07], [3.0, 0.1]])
    '{{1.0, -2.5*^-7}, {3.0, 0.1}}'
    """
    return harness().to_wl(value)


def parse_input_form(text: str):
    """Parse a Mathics ``InputForm`` of (nested lists of) reals into Python floats/lists.

    Examples
    --------
    >>> parse_input_form("{{0., 1.5*^-7}, {2, -3.25`30.}}")
    [[0.0, 1.5e-07], [2, -3.25]]
    """
    return harness().parse_input_form(text)


# -- the port -----------------------------------------------------------------------------------------
def _src_dir() -> Path:
    """The Mathematica sources in the course folder (see :mod:`flowtrack_course.course`)."""
    return ports_dir() / "mathematica"



def case_expression(problem: str, inp: dict) -> str:
    """The Wolfram Language expression whose ``InputForm`` is the port's answer for one case."""
    if problem == "kalman_cv2d":
        x0 = inp.get("x0", [0.0] * 4)
        P0 = inp.get("P0", [[1e3 if i == j else 0.0 for j in range(4)] for i in range(4)])
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
    flowtrack_course.polyglot.base.ToolchainMissing
        The ``mathics3`` Python package is not installed (``pip install -e ".[ports]"``).
    """
    TOOLCHAIN.check(ports=True)
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
    job = json.loads(Path(job_path).read_text())
    session = harness().new_session()
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
