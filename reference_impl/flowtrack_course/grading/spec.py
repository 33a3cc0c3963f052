"""What an exercise is, for the grader: trusted test definitions and trusted comparisons.

An :class:`Exercise` names its notebook, the nbgrader ``grade_id`` of the answer cells whose code
the sandboxed child executes, the modules the child may not import, and its :class:`GradedTest`\\ s.
A test's ``build(rng)`` returns the :class:`Call`\\ s to make in the child and a scorer; the scorer
receives one :class:`Outcome` per call (plain data only, converted by the grader) and returns the
fraction of the points earned and a message. Expected values are computed here, by the trusted
reference, and never sent to the child.
"""

from __future__ import annotations

import hashlib
import hmac
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "Call",
    "Exercise",
    "GradedTest",
    "Outcome",
    "Scorer",
    "as_float_array",
    "compare_arrays",
    "public_seed",
    "read_secret",
    "secret_id",
    "student_seed",
]


@dataclass(frozen=True)
class Call:
    """One call of a student function: ``function(*args, **kwargs)`` inside the child.

    ``args``/``kwargs`` hold plain data or numpy arrays (a bool, integer or float array is sent to
    the child as nested lists with its dtype and shape and rebuilt there as a bool, int64 or float64
    array, see the sandbox). ``post`` (plain data) asks the child to turn the result into data
    before it is sent: ``{"op": "formula", "symbols": [...], "points": [[...], ...]}`` parses a
    formula given as text and evaluates it at the points (:mod:`flowtrack_course.grading._formula`),
    so that the grader never parses student text.
    """

    function: str
    args: tuple[Any, ...] = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    post: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class Outcome:
    """What came back from one call: plain data only (never an object made by student code).

    ``ok`` is False when the call raised, timed out, crashed the child, exceeded a limit or returned
    something that is not plain data; ``error`` then says why.
    """

    ok: bool
    value: Any = None
    error: str = ""


Scorer = Callable[[Sequence[Outcome]], tuple[float, str]]


@dataclass(frozen=True)
class GradedTest:
    """A test: ``build(rng) -> (calls, scorer)``; ``scorer(outcomes) -> (fraction in [0, 1], message)``.

    ``hidden`` tests are reported to students by name and score only. ``grade_id`` is the nbgrader id
    of the notebook's test cell this test stands for (the notebook's own test cells are never run by
    the grader: students can edit them).
    """

    name: str
    grade_id: str
    points: float
    hidden: bool
    build: Callable[[np.random.Generator], tuple[Sequence[Call], Scorer]]
    timeout: float = 10.0


@dataclass(frozen=True)
class Exercise:
    """One exercise notebook and its tests.

    ``notebook`` is the path relative to ``exercises/``; ``answer_cells`` the grade_ids of the cells
    (in notebook order) the child executes; ``blocked`` the modules the child cannot import
    (e.g. ``"flowtrack.camera"``, ``"scipy.optimize"``); ``allowed`` what the student may import
    besides the standard library (the notebook's "You may import" line; ``numpy`` always): the
    sandbox then holds only the packages these need and refuses importing any other. Empty: no
    allowlist (everything installed, minus ``blocked``).
    """

    id: str
    title: str
    notebook: str
    answer_cells: tuple[str, ...]
    blocked: tuple[str, ...]
    tests: tuple[GradedTest, ...]
    allowed: tuple[str, ...] = ()

    @property
    def max_score(self) -> float:
        return float(sum(t.points for t in self.tests))


def student_seed(student: str, exercise: str, test: str, secret: bytes | None = None) -> int:
    """A stable 63-bit seed for one student's inputs of one test.

    Without ``secret`` it is sha256 of the names, which anyone holding the course package can
    recompute: a student could then draw their own hidden inputs, run the reference outside the
    sandbox and hard-code the answers. With the instructor's ``secret`` (see :func:`read_secret`)
    it is HMAC-SHA256 keyed by it, unpredictable without the key and still reproducible by the
    instructor.

    >>> student_seed("ana", "ex01", "t") == student_seed("ana", "ex01", "t")
    True
    >>> student_seed("ana", "ex01", "t") != student_seed("ana", "ex01", "t", secret=b"k" * 32)
    True
    """
    message = f"{student}\0{exercise}\0{test}".encode()
    if secret is None:
        digest = hashlib.sha256(message).digest()
    else:
        digest = hmac.new(_check_secret(secret), message, hashlib.sha256).digest()
    return int.from_bytes(digest[:8], "little") >> 1


def public_seed(exercise_id: str, test_name: str) -> int:
    """The fixed seed of a public test (the same for every student, in ``check``, ``grade`` and the
    notebooks' in-process run).

    >>> public_seed("ex01", "t") == student_seed("<public>", "ex01", "t")
    True
    """
    return student_seed("<public>", exercise_id, test_name)


SECRET_BYTES = 32  # what read_secret(create=True) writes; at least MIN_SECRET_BYTES are required
MIN_SECRET_BYTES = 16


def _check_secret(secret: bytes) -> bytes:
    if not isinstance(secret, bytes):
        raise TypeError(f"secret must be bytes, got {type(secret).__name__}")
    if len(secret) < MIN_SECRET_BYTES:
        raise ValueError(f"secret must hold at least {MIN_SECRET_BYTES} bytes, got {len(secret)}")
    return secret


def secret_id(secret: bytes | None) -> str:
    """A fingerprint of ``secret`` (``""`` for none): tells grading runs apart, reveals nothing."""
    if secret is None:
        return ""
    return hashlib.sha256(b"flowtrack seed key\0" + _check_secret(secret)).hexdigest()[:16]


def read_secret(path, *, create: bool = False) -> bytes:
    """The instructor's seed key from the file ``path``; with ``create``, a new random one if missing.

    A created file holds :data:`SECRET_BYTES` random bytes (``secrets.token_bytes``) and is readable
    by its owner only. Keep it next to the course, out of the students' release and out of version
    control shared with students: the same file must be used for every grading run of a class
    (hidden inputs, hence scores, depend on it).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist and ``create`` is false.
    ValueError
        The file holds fewer than :data:`MIN_SECRET_BYTES` bytes.
    """
    import os
    import secrets
    from pathlib import Path

    path = Path(path)
    if create and not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(secrets.token_bytes(SECRET_BYTES))
    if not path.is_file():
        raise FileNotFoundError(f"secret file: no such file: {path}")
    data = path.read_bytes()
    if len(data) < MIN_SECRET_BYTES:
        raise ValueError(
            f"secret file {path} must hold at least {MIN_SECRET_BYTES} bytes, got {len(data)} "
            "(create one with: head -c 32 /dev/urandom > FILE)"
        )
    return data


def as_float_array(value: Any, shape: tuple[int | None, ...] | None = None) -> np.ndarray | None:
    """Plain data -> float64 array, or None when it is not numeric or has the wrong shape.

    Only ``int``, ``float``, ``bool`` and nested ``list``/``tuple`` of them are accepted (what the
    grader's JSON decoding produces); ``None`` entries in ``shape`` match any length.
    """
    if not _plain_numeric(value):
        return None
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            return None
    return arr


def _plain_numeric(value: Any, depth: int = 0) -> bool:
    if depth > 8:
        return False
    if type(value) in (int, float, bool):
        return True
    if type(value) in (list, tuple):
        return all(_plain_numeric(v, depth + 1) for v in value)
    return False


def compare_arrays(
    outcome: Outcome, expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9
) -> tuple[bool, str]:
    """Trusted comparison of one outcome with an expected array (shape must match exactly)."""
    if not outcome.ok:
        return False, outcome.error or "the call failed"
    expected = np.asarray(expected, dtype=np.float64)
    got = as_float_array(outcome.value, expected.shape)
    if got is None:
        got_any = as_float_array(outcome.value)
        if got_any is None:
            return False, "the result is not an array of numbers"
        return False, f"expected an array of shape {expected.shape}, got shape {got_any.shape}"
    if not np.all(np.isfinite(got) == np.isfinite(expected)):
        return False, "NaN/inf where the expected value is finite (or the other way round)"
    finite = np.isfinite(expected)
    # Non-finite entries must be the same non-finite value: +inf (e.g. a gated cost) is not NaN or -inf.
    if not np.array_equal(got[~finite], expected[~finite], equal_nan=True):
        return False, "NaN/inf entries differ from the expected ones (+inf, -inf and NaN are different)"
    err = np.abs(got[finite] - expected[finite])
    bound = atol + rtol * np.abs(expected[finite])
    if np.all(err <= bound):
        return True, "ok"
    worst = float(np.max(err - bound)) if err.size else math.nan
    return False, f"values differ (worst excess over tolerance {worst:.3g}; rtol={rtol:g}, atol={atol:g})"
