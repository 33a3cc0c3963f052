"""A problem of the polyglot stack: its inputs, the reference's outputs, its cases, its mistakes.

A :class:`Problem` turns inputs (a dict in the vectors format's ``"input"`` form: numbers and nested
lists, row-major) into named outputs (``"expected"``), computed by the Python reference. Its cases
are defined once, here, and feed both consumers through :meth:`Problem.document`:

- the ports' test vectors ``cpp_java_matlab_ports/vectors/<name>.json`` (:meth:`Problem.vectors`:
  the named cases of ``vector_cases``, fixed seeds);
- the language grader's tests (problems with ``public``): the public cases (fixed inputs, also the
  students' ``public.json``) and the hidden ones, drawn by ``hidden(rng)`` from the student's keyed
  seed. Expected values never enter a sandbox.

A problem served to both (``projection_jacobian``) draws its random inputs with one function, so
the ports' seeded cases and the grader's hidden cases for the same seed are the same inputs.

``mistakes`` are catalogued wrong answers: an id of the course's mistake catalogue (the Python
notebooks' ids; the message lives there) and a function computing what the mistaken code returns.
``generic`` lists the generic explanations (``generic-sign`` ...) that make sense for the problem's
outputs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..vectors import plain

__all__ = ["GENERIC", "Case", "Problem", "as_inputs", "spd"]

Inputs = dict
Outputs = dict

#: The generic explanations the language grader tries on a wrong output. ``generic-permutation`` is
#: left out: a wrong assignment is always a permutation of the right one and a wrong 0/1 gate vector
#: nearly always is, so it would name a mistake that is not there.
GENERIC = ("generic-sign", "generic-transpose", "generic-scale")


@dataclass(frozen=True)
class Case:
    """One named case: its inputs and, when the reference cannot compute them from the inputs (a
    ground truth known only when the inputs were made), outputs added to the reference's."""

    id: str
    input: Inputs
    expected: Outputs | None = None


@dataclass(frozen=True)
class Problem:
    """One problem (see the module docstring).

    ``rtol``/``atol`` are the tolerances of the grader and, unless ``vector_tolerance`` says
    otherwise, of the vector file. ``languages`` are the languages the problem is set in (None:
    every graded language).
    """

    name: str
    title: str
    outputs: tuple[str, ...]
    reference: Callable[[Inputs], Outputs] | None
    rtol: float = 1e-7
    atol: float = 1e-9
    public: Callable[[], list[Inputs]] | None = None
    hidden: Callable[[np.random.Generator], list[Inputs]] | None = None
    vector_cases: Callable[[], list[Case]] | None = None
    vector_tolerance: tuple[float, float] | None = None
    mistakes: tuple[tuple[str, Callable[[Inputs], Outputs]], ...] = ()
    generic: tuple[str, ...] = GENERIC
    languages: tuple[str, ...] | None = None

    @property
    def graded(self) -> bool:
        """Whether students answer it (the language grader sets it)."""
        return self.public is not None

    def expected(self, case: Case) -> Outputs:
        """The outputs of ``case``: the reference's on its inputs, and the case's own."""
        out = dict(self.reference(case.input)) if self.reference is not None else {}
        out.update(case.expected or {})
        return out

    def public_cases(self) -> list[Case]:
        """The grader's public cases (``public-0``, ...)."""
        return [Case(f"public-{i}", inp) for i, inp in enumerate(self.public())]

    def hidden_cases(self, rng: np.random.Generator) -> list[Case]:
        """The grader's hidden cases (``hidden-0``, ...) drawn from ``rng``."""
        return [Case(f"hidden-{i}", inp) for i, inp in enumerate(self.hidden(rng))]

    def document(
        self, cases: Sequence[Case], *, expected: bool = True, tolerance: tuple[float, float] | None = None
    ) -> dict:
        """The vectors-format document of ``cases``: with ``expected=False`` their inputs only (what
        a sandbox gets), else with the expected outputs and the tolerance (default the problem's)."""
        rtol, atol = tolerance or (self.rtol, self.atol)
        out = []
        for c in cases:
            if expected:
                out.append({"id": c.id, "input": plain(c.input), "expected": plain(self.expected(c)),
                            "rtol": rtol, "atol": atol})
            else:
                out.append({"id": c.id, "input": plain(c.input)})
        return {"problem": self.name, "cases": out}

    def vectors(self) -> dict:
        """The ports' vector document of this problem (``flowtrack ports --regenerate``)."""
        if self.vector_cases is None:
            raise ValueError(f"problem {self.name!r} has no vector file")
        return self.document(self.vector_cases(), tolerance=self.vector_tolerance)


def as_inputs(d: dict) -> Inputs:
    """Inputs as plain floats and nested lists of floats (the form cases are written in)."""
    return {k: float(v) if np.isscalar(v) else np.asarray(v, dtype=float).tolist() for k, v in d.items()}


def spd(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    """A random symmetric positive definite ``(n, n)`` matrix (eigenvalues at least ``0.3 scale``)."""
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T / n + 0.3 * np.eye(n))
