"""Helpers shared by the ports' tests (C++, Java, Octave, Mathics, block diagram).

``perturbed_vectors`` makes a temporary copy of the vector files in which one expected value per
problem is moved beyond its case's tolerance; a port's harness run on the copy must then report FAIL
for exactly those cases (and PASS for all others), which proves that the harness can fail.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import pytest

from flowtrack_course.polyglot.base import ToolchainMissing
from flowtrack_course.polyglot.vectors import CaseResult, dumps
from flowtrack_course.ports.runner import DEFAULT_BUILD_DIR as BUILD_DIR
from flowtrack_course.ports.vectors import VECTORS_DIR

__all__ = [
    "BUILD_DIR",
    "assert_every_case_passes",
    "failing_cases",
    "perturbed_vectors",
    "run_port",
    "vector_case_ids",
]


def run_port(run: Callable[..., list[CaseResult]], *args) -> list[CaseResult]:
    """``run(*args)``, with a missing toolchain failing the test (the ports are never skipped)."""
    try:
        return run(*args)
    except ToolchainMissing as exc:
        pytest.fail(f"toolchain missing (the ports are never skipped): {exc}")


def _first_number_path(value, path=()):
    """Path (keys/indices) of the first numeric leaf in a nested list, depth first."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return path
    if isinstance(value, list):
        for i, v in enumerate(value):
            found = _first_number_path(v, (*path, i))
            if found is not None:
                return found
    return None


def perturbed_vectors(
    tmp_path: Path, problems: Iterable[str], keys: dict[str, str] | None = None, source: Path = VECTORS_DIR
) -> tuple[Path, set[tuple[str, str]]]:
    """Copy the vector files to ``tmp_path/vectors`` and spoil one expected value per problem.

    In the first case of each problem the first number of one expected entry (``keys[problem]``, by
    default the first key in sorted order, e.g. ``"T"`` before ``"T_true"``) is moved by ten times
    the case's tolerance ``atol + rtol |e|`` (integers, e.g. match indices, by one), so any port
    within tolerance of the true value is outside it for the spoilt one.

    Parameters
    ----------
    tmp_path : Path
        A temporary folder (pytest's ``tmp_path``).
    problems : iterable of str
        Problems (vector file stems) to spoil; the other files are copied unchanged.
    keys : dict, optional
        Problem -> expected key to spoil.
    source : Path
        The vector folder to copy.

    Returns
    -------
    folder : Path
        The copy.
    spoilt : set of (problem, case_id)
        The cases that must now FAIL.
    """
    out = Path(tmp_path) / "vectors"
    out.mkdir(parents=True, exist_ok=True)
    for f in sorted(Path(source).glob("*.json")):
        shutil.copyfile(f, out / f.name)
    spoilt = set()
    for problem in problems:
        path = out / f"{problem}.json"
        if not path.exists():
            raise FileNotFoundError(f"no vector file for problem {problem!r} in {source}")
        doc = json.loads(path.read_text())
        case = doc["cases"][0]
        key = (keys or {}).get(problem, sorted(case["expected"])[0])
        holder = case["expected"]
        leaf = _first_number_path(holder[key])
        if leaf is None:
            raise ValueError(f"{problem}: expected[{key!r}] has no number to spoil")
        parent, last = holder, key
        for step in leaf:
            parent, last = parent[last], step
        e = parent[last]
        if isinstance(e, int):
            parent[last] = e + 1
        else:
            parent[last] = e + 10.0 * (case["atol"] + case["rtol"] * abs(e)) + 1e-300
        path.write_text(dumps(doc))
        spoilt.add((problem, case["id"]))
    return out, spoilt


def failing_cases(results: Sequence[CaseResult], problems: Iterable[str]) -> set[tuple[str, str]]:
    """``{(problem, case_id)}`` of the failed results among the given problems."""
    wanted = set(problems)
    return {(r.problem, r.case_id) for r in results if r.problem in wanted and not r.passed}


def vector_case_ids(problem: str, vectors_dir: Path = VECTORS_DIR) -> list[str]:
    """Case ids of one vector file, in file order."""
    doc = json.loads((Path(vectors_dir) / f"{problem}.json").read_text())
    return [c["id"] for c in doc["cases"]]


def assert_every_case_passes(
    results: Sequence[CaseResult], problem: str, language: str | None = None
) -> None:
    """Every case of ``problem``'s vector file was run (in file order) and passed.

    A case added to a vector file is picked up without code changes, so the case ids must match the
    file's; ``language`` narrows ``results`` to one port when a runner reports several.
    """
    got = [r for r in results if r.problem == problem and (language is None or r.language == language)]
    assert [r.case_id for r in got] == vector_case_ids(problem)
    failed = [f"{r.case_id}: {r.message} (max error {r.max_error:.3g})" for r in got if not r.passed]
    assert not failed, "\n".join(failed)
