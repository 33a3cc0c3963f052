"""Shared types of the port harnesses.

Every language harness (C++, Java, Octave, Mathics, block diagram) reads every case of the vector
files of the problems it implements, compares with the case's tolerance itself, and prints one line
per case on stdout::

    CASE <problem> <case_id> PASS|FAIL <max_abs_error> <free text message>

(``max_abs_error`` as a float, ``nan`` when the case could not be computed). A ``lang_*`` module runs
the harness and turns those lines into :class:`CaseResult` objects with :func:`parse_case_lines`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

__all__ = ["CaseResult", "ToolchainMissing", "parse_case_lines", "PORTS_DIR", "VECTORS_DIR"]

#: The repository's ports folder (sources of the ports, vectors/ and the build cache build/).
PORTS_DIR = Path(__file__).resolve().parents[3] / "cpp_java_matlab_ports"
VECTORS_DIR = PORTS_DIR / "vectors"


class ToolchainMissing(RuntimeError):
    """A compiler/interpreter a port needs is not installed (never a silent skip)."""


@dataclass(frozen=True)
class CaseResult:
    language: str  # e.g. "cpp-eigen", "cpp-pcl", "java", "java-ejml", "java-opencv", "octave", ...
    problem: str
    case_id: str
    passed: bool
    max_error: float
    message: str = ""


def parse_case_lines(language: str, text: str) -> list[CaseResult]:
    """Parse ``CASE problem id PASS|FAIL err message`` lines; other lines are ignored."""
    results = []
    for line in text.splitlines():
        parts = line.strip().split(maxsplit=5)
        if len(parts) < 5 or parts[0] != "CASE" or parts[3] not in ("PASS", "FAIL"):
            continue
        try:
            err = float(parts[4])
        except ValueError:
            err = math.nan
        results.append(
            CaseResult(
                language, parts[1], parts[2], parts[3] == "PASS", err, parts[5] if len(parts) > 5 else ""
            )
        )
    return results
