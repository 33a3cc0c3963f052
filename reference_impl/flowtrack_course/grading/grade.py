"""``flowtrack grade``: batch autograding of a class, each student's exercise in a sandboxed child.

The grading process never imports or executes student code. For each student and exercise it
extracts the answer cells of the student's notebook by their nbgrader ``grade_id``, starts a
:class:`~flowtrack_course.grading.sandbox.Sandbox` with them (by default a child forked by a zygote of a
:class:`~flowtrack_course.grading.sandbox.SandboxPool` shared by the worker's students), and for each
:class:`GradedTest` builds the calls from a seeded generator, runs them in the child, and scores the
plain-data outcomes with the test's trusted scorer. A test earns ``points x fraction`` with
``fraction`` from the scorer alone, so the score of a test is

.. math:: s_t = p_t \\, \\mathrm{clip}(f_t, 0, 1), \\qquad S = \\sum_t s_t \\le \\sum_t p_t .

Hidden tests draw their inputs from ``student_seed(student, exercise.id, test.name, secret)``, keyed
by the instructor's secret when one is given (``flowtrack grade --secret-file``; without it the
hidden inputs are predictable from the student's name); public tests from a fixed seed
(:func:`~flowtrack_course.grading.spec.public_seed`), the same one ``flowtrack check`` uses, so a student's
own check and the instructor's grade agree on the public tests.

Outputs of :func:`grade_class` (``out`` is the ``--out`` folder)::

    out/grades.csv                 student, one column per exercise id, total, max
    out/<student>/results.json     Gradescope format (tests[]: name, score, max_score, status,
                                   output, visibility); written last and atomically
    out/<student>/feedback/<exercise>.md   what the student may see
    out/gradebook.db               nbgrader gradebook (``nbgrader export`` works on it)

A student whose ``results.json`` is complete and was made from the same exercises and the same
submitted files is skipped on a re-run (unless ``force``): a run killed halfway and restarted loses
no finished student, and a second run changes nothing.
"""

from __future__ import annotations

import csv
import hashlib
import inspect
import io
import json
import math
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flowtrack._validation import positive_int

from .exercises.feedback import (
    apply_dependencies,
    cell_problems,
    explain_cascade,
    feedback_lines,
    mistake_records,
    mistakes_of,
    safe_text,
)
from .spec import Exercise, GradedTest, Outcome, public_seed, secret_id, student_seed

__all__ = [
    "ExerciseResult",
    "FORMAT",
    "RESERVED_NAMES",
    "UnsafeSandbox",
    "TestResult",
    "exercises_hash",
    "grade_class",
    "grade_student",
    "list_students",
    "locate_notebook",
    "public_seed",
    "warm_public_tests",
    "results_json",
    "run_exercise",
    "write_atomic",
]

FORMAT = "flowtrack-results/1"
# What grade_class writes into its output folder beside the student folders: a student folder of one
# of these names is refused (it would turn the grader's own output into a folder).
RESERVED_NAMES = frozenset(
    {"grades.csv", "gradebook.db", "gradebook.db-journal", "gradebook.db-wal", "gradebook.db-shm",
     "misconceptions.csv"}
)


class UnsafeSandbox(RuntimeError):
    """``flowtrack grade`` without bubblewrap, and the fallback was not allowed explicitly."""
MAX_MESSAGE = 2000
_STUDENT_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.@+\-]{0,127}$")


# --------------------------------------------------------------------------------------------------
# results of one exercise


@dataclass
class TestResult:
    """The grade of one test: ``score`` of ``max_score`` points and the grader's message."""

    name: str
    grade_id: str
    score: float
    max_score: float
    hidden: bool
    message: str
    safe_message: str = ""
    mistakes: tuple[str, ...] = ()

    @property
    def passed(self) -> bool:
        return self.score >= self.max_score - 1e-9


@dataclass
class ExerciseResult:
    """The grade of one exercise: its tests and the problems found with the submission."""

    exercise_id: str
    title: str
    notebook: str
    tests: list[TestResult] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    isolation: str = ""

    @property
    def score(self) -> float:
        return float(sum(t.score for t in self.tests))

    @property
    def max_score(self) -> float:
        return float(sum(t.max_score for t in self.tests))


def _clip_message(text: str) -> str:
    text = str(text)
    return text if len(text) <= MAX_MESSAGE else text[: MAX_MESSAGE - 15] + " ... (truncated)"


def _zero(test: GradedTest, why: str) -> TestResult:
    """``test`` scored 0 for a reason that is not the student's answer to it (``why``)."""
    return TestResult(test.name, test.grade_id, 0.0, float(test.points), test.hidden, why)


def _score_test(test: GradedTest, outcomes: Sequence[Outcome], scorer) -> tuple[float, str]:
    """Apply the trusted scorer; a scorer bug or a bad fraction gives 0, never a crash.

    The message is returned as the scorer made it (a
    :class:`~flowtrack_course.grading.exercises.feedback.Report` carries the hidden-safe text and the
    mistakes recognised).
    """
    try:
        fraction, message = scorer(outcomes)
        fraction = float(fraction)
    except Exception as exc:  # a scorer must never stop the run
        return 0.0, f"internal error in the grader's scorer: {type(exc).__name__}: {exc}"
    if not math.isfinite(fraction):
        fraction = 0.0
    fraction = min(1.0, max(0.0, fraction))
    return float(test.points) * fraction, message if isinstance(message, str) else str(message)


# Public tests (and every test of ``flowtrack check``) draw their inputs from a fixed seed: their
# calls and reference values are the same for every student, and a scorer is a deterministic
# function of the outcomes (the contract that makes a student's check and the grade agree). A
# grading process therefore builds each public test once and scores each distinct set of outcomes
# once (e.g. the class's correct answers); hidden tests, seeded per student, are never shared.
_SHARED_MAX = 4096
_shared_builds: dict[tuple, tuple[list, Any]] = {}
_shared_scores: dict[tuple, tuple[float, str]] = {}


def _built(test: GradedTest, seed: int) -> tuple[list, Any]:
    """``test.build`` with the public ``seed``, made once per process (a build that raises is not kept)."""
    key = (test, seed)
    hit = _shared_builds.get(key)
    if hit is None:
        calls, scorer = test.build(np.random.default_rng(seed))
        hit = (list(calls), scorer)
        if len(_shared_builds) >= _SHARED_MAX:
            _shared_builds.clear()
        _shared_builds[key] = hit
    return hit


def warm_public_tests(exercises: Sequence[Exercise]) -> int:
    """Build the public tests of ``exercises`` once in this process (what :func:`run_exercise` would
    build for the first student), so that processes forked from this one share them.

    A test whose build raises is skipped (the worker reports it when it grades it). Returns the
    number of tests built. Nothing here touches student data.
    """
    n = 0
    for ex in exercises:
        for t in ex.tests:
            if not t.hidden:
                try:
                    _built(t, public_seed(ex.id, t.name))
                except Exception:  # reported when graded
                    continue
                n += 1
    return n


def _scored(test: GradedTest, seed: int, outcomes: Sequence[Outcome], scorer) -> tuple[float, str]:
    """:func:`_score_test` of a shared test, once per distinct ``outcomes`` (compared as exact JSON)."""
    from .wire import is_plain

    rows = [[o.ok, o.value, o.error] for o in outcomes]
    if not is_plain(rows):  # e.g. tuples from a test's fake sandbox: JSON would not tell them apart
        return _score_test(test, outcomes, scorer)
    data = json.dumps(rows, allow_nan=True)  # exact for plain data (1 and 1.0 and True differ)
    key = (test, seed, data)
    hit = _shared_scores.get(key)
    if hit is None:
        hit = _score_test(test, outcomes, scorer)
        if len(_shared_scores) >= _SHARED_MAX:
            _shared_scores.clear()
        _shared_scores[key] = hit
    return hit


def _extract(notebook: Path, grade_ids: Sequence[str]) -> tuple[list[tuple[str, str]], list[str]]:
    """The answer cells that can be extracted and a message for each that cannot.

    A notebook that is missing or not JSON breaks every cell; a single missing cell breaks only the
    functions it defines (the others are still graded).
    """
    from .notebook import read_notebook, select_cells

    if not notebook.is_file():
        return [], [f"notebook not submitted: {notebook.name}"]
    try:
        raw = read_notebook(notebook)  # size-capped, parsed once
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        return [], [_clip_message(f"{type(exc).__name__}: {exc}")]
    try:
        return list(select_cells(raw, list(grade_ids), notebook.name)), []
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        first = _clip_message(f"{type(exc).__name__}: {exc}")
    cells: list[tuple[str, str]] = []
    problems: list[str] = []
    for gid in grade_ids:
        try:
            cells += list(select_cells(raw, [gid], notebook.name))
        except (ValueError, OSError, UnicodeDecodeError) as exc:
            problems.append(_clip_message(f"cell {gid!r}: {exc}"))
    if not cells:
        problems = [first]  # the whole notebook is unusable: say it once
    return cells, problems


def run_exercise(
    exercise: Exercise,
    notebook: str | os.PathLike,
    student: str | None = None,
    *,
    public_only: bool = False,
    limits: Any = None,
    sandbox_factory: Callable[..., Any] | None = None,
    secret: bytes | None = None,
    hidden_paths: Sequence[str | os.PathLike] = (),
) -> ExerciseResult:
    """Grade one notebook against one exercise.

    Parameters
    ----------
    exercise : Exercise
        The trusted test definitions.
    notebook : path
        The submitted notebook (may be missing or malformed: that scores 0 with a message).
    student : str or None
        Seeds the hidden tests' inputs (``student_seed``); ``None`` runs public tests only seeds.
    public_only : bool
        Run only the tests with ``hidden=False`` (``flowtrack check``).
    limits : Limits or None
        Resource limits for the sandbox (its defaults when ``None``).
    sandbox_factory : callable or None
        ``Sandbox``-like class (tests inject fakes); default
        :class:`flowtrack_course.grading.sandbox.Sandbox`.
    secret : bytes or None
        The instructor's seed key for the hidden tests (:func:`~flowtrack_course.grading.spec.read_secret`).
    hidden_paths : sequence of path
        What the sandbox's fallback must refuse to open (the class's submissions, the output folder,
        the key file); bubblewrap shows none of them anyway.

    Returns
    -------
    ExerciseResult
        One :class:`TestResult` per test run; never raises because of the submission.
    """
    if not isinstance(exercise, Exercise):
        raise TypeError(f"exercise must be an Exercise, got {type(exercise).__name__}")
    tests = [t for t in exercise.tests if not (public_only and t.hidden)]
    result = ExerciseResult(exercise.id, exercise.title, exercise.notebook)
    # hook (issue 19): a language exercise (flowtrack_course.grading.languages) makes its own driver cell
    extract = getattr(exercise, "extract_cells", None)
    cells, problems = extract(Path(notebook)) if extract else _extract(Path(notebook), exercise.answer_cells)
    result.problems += problems
    if not cells:
        why = problems[0] if problems else "no answer cells"
        result.tests += [_zero(t, why) for t in tests]
        return result
    if sandbox_factory is None:
        from .sandbox import Sandbox as sandbox_factory
    kwargs: dict[str, Any] = {"blocked": tuple(exercise.blocked)}
    if exercise.allowed:
        kwargs["allowed"] = tuple(exercise.allowed)
    if hidden_paths:
        kwargs["hidden_paths"] = tuple(hidden_paths)
    if limits is not None:
        kwargs["limits"] = limits
    if getattr(exercise, "spawns", False):  # issue 19: an answer in another language is built and run
        kwargs["spawn"] = True
    # Every public test runs before any hidden one: the child keeps state between tests, so a
    # public test run after a hidden one could carry the hidden inputs into its (shown) message.
    # Results are reported in the exercise's order.
    order = sorted(range(len(tests)), key=lambda i: tests[i].hidden)
    done: dict[int, TestResult] = {}
    with sandbox_factory(cells, **kwargs) as box:
        result.isolation = str(getattr(box, "isolation", ""))
        for i in order:
            t = tests[i]
            shared = not (t.hidden and student is not None)  # the same inputs for every student
            if shared:
                seed = public_seed(exercise.id, t.name)
            else:
                seed = student_seed(student, exercise.id, t.name, secret)
            try:
                calls, scorer = _built(t, seed) if shared else t.build(np.random.default_rng(seed))
            except Exception as exc:  # a broken test definition scores 0, run goes on
                done[i] = _zero(t, f"internal error building the test: {type(exc).__name__}: {exc}")
                continue
            try:
                outcomes = list(box.run(list(calls), t.timeout))
            except Exception as exc:  # the sandbox reports, never stops the run
                outcomes = [Outcome(False, None, f"sandbox error: {exc}") for _ in calls]
            if len(outcomes) != len(calls):
                outcomes = [Outcome(False, None, "no result from the sandbox") for _ in calls]
            outcomes = explain_cascade(outcomes, dict(getattr(box, "cell_errors", {}) or {}))
            if shared:
                score, message = _scored(t, seed, outcomes, scorer)
            else:
                score, message = _score_test(t, outcomes, scorer)
            done[i] = TestResult(
                t.name, t.grade_id, score, float(t.points), t.hidden, _clip_message(message),
                _clip_message(safe_text(message)), mistakes_of(message),
            )
        result.tests += apply_dependencies(exercise.id, [done[i] for i in range(len(tests))])
        # known once the child has started (the sandbox starts it lazily on the first run)
        errors = dict(getattr(box, "cell_errors", {}) or {})
        result.problems += [_clip_message(p) for p in cell_problems(errors, exercise.answer_cells)]
    return result


# --------------------------------------------------------------------------------------------------
# one student


def locate_notebook(student_dir: Path, exercise: Exercise) -> Path:
    """``student_dir/<exercise.notebook>``, else the only file of that name below ``student_dir``.

    (Gradescope uploads are often flat.) Returns the expected path when nothing is found. A
    notebook reached through a symlink that leads outside ``student_dir`` (another student's work,
    a file of the grading machine) does not count as submitted.
    """
    root = Path(student_dir).resolve()

    def inside(p: Path) -> bool:
        try:
            return p.is_file() and p.resolve().is_relative_to(root)
        except (OSError, RuntimeError):  # a symlink loop
            return False

    expected = Path(student_dir) / exercise.notebook
    if inside(expected):
        return expected
    name = Path(exercise.notebook).name
    found = sorted(
        p for p in Path(student_dir).rglob(name) if "__MACOSX" not in p.parts and inside(p)
    )
    if found:
        return found[0]
    if os.path.lexists(expected):  # a link leading outside: report it, never read it
        return expected.with_name(f"{expected.name} (a link leading outside the submission)")
    return expected


def exercises_hash(exercises: Sequence[Exercise]) -> str:
    """sha256 of the exercises' definitions and of the source files their tests are built in.

    A change of any test, point value, notebook path or of the module defining the tests changes it,
    so finished students are re-graded after the tests change. An exercise may name more files its
    grading depends on (``source_files()``: a language item's driver and harness files, issue 19).
    """
    h = hashlib.sha256()
    files: set[str] = set()
    for ex in exercises:
        desc = [ex.id, ex.notebook, list(ex.answer_cells), list(ex.blocked)]
        desc += [list(ex.allowed)] if ex.allowed else []
        desc += [[t.name, t.grade_id, float(t.points), bool(t.hidden), float(t.timeout)] for t in ex.tests]
        h.update(json.dumps(desc).encode())
        extra = getattr(ex, "source_files", None)  # issue 19: a language item's harness and driver files
        if callable(extra):
            files.update(str(p) for p in extra())
        for t in ex.tests:
            for fn in (t.build, inspect.unwrap(t.build)):  # the scoring helpers and the test's module
                try:
                    src = inspect.getsourcefile(fn)
                except TypeError:
                    src = None
                if src:
                    files.add(src)
    # the formula reader the sandbox runs for symbolic answers, and the grader's side of it
    files.add(str(Path(__file__).with_name("_formula.py")))
    files.add(str(Path(__file__).with_name("exercises") / "symbolic_answers.py"))
    for src in sorted(files):
        h.update(Path(src).read_bytes())
    return h.hexdigest()


def submission_hash(notebooks: dict[str, Path]) -> str:
    """sha256 of the located notebooks (``exercise id -> path``), a missing one included."""
    h = hashlib.sha256()
    for ex_id, p in notebooks.items():
        h.update(ex_id.encode() + b"\0")
        if p.is_file():
            with open(p, "rb") as fh:
                h.update(hashlib.file_digest(fh, "sha256").digest())  # streamed: any size
        else:
            h.update(b"<missing>")
    return h.hexdigest()


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and ``os.replace`` (all or nothing).

    UTF-8 with ``errors="backslashreplace"``: a lone surrogate in a student's error message is
    written as ``\\ud800`` instead of failing the write.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", errors="backslashreplace") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _round(x: float) -> float:
    return round(float(x), 6)


def results_json(
    student: str,
    results: Sequence[ExerciseResult],
    *,
    hidden_visibility: str = "after_published",
    extra: dict | None = None,
) -> dict:
    """Gradescope ``results.json`` for one student.

    Public tests are ``"visible"`` with the grader's message; hidden tests carry
    ``hidden_visibility`` and, as output, their name and score only.

    Examples
    --------
    >>> r = ExerciseResult("ex", "Title", "ex.ipynb", [
    ...     TestResult("a", "test_a", 1.0, 1.0, False, "ok"),
    ...     TestResult("b", "test_a", 0.5, 2.0, True, "expected [1.0, 2.0]")])
    >>> data = results_json("s1", [r])
    >>> data["score"], [(t["status"], t["visibility"], t["output"]) for t in data["tests"]]
    (1.5, [('passed', 'visible', 'ok'), ('failed', 'after_published', 'hidden test b: 0.5 / 2')])
    """
    if hidden_visibility not in ("hidden", "after_due_date", "after_published", "visible"):
        raise ValueError(f"hidden_visibility must be a Gradescope visibility, got {hidden_visibility!r}")
    tests = []
    lines = []
    for r in results:
        lines.append(f"{r.exercise_id} ({r.title}): {_round(r.score):g} / {_round(r.max_score):g}")
        lines += [f"  problem: {p}" for p in r.problems]
        for t in r.tests:
            if t.hidden:
                output = f"hidden test {t.name}: {_round(t.score):g} / {_round(t.max_score):g}"
                output += "".join(f"\n{line}" for line in feedback_lines(t, hidden=True))
                visibility = hidden_visibility
            else:
                output = t.message
                output += "".join(f"\nproblem: {p}" for p in r.problems if p != t.message)
                output += "".join(f"\n{line}" for line in feedback_lines(t, hidden=False, with_message=False))
                visibility = "visible"
            tests.append(
                {
                    "name": f"{r.exercise_id}: {t.name}",
                    "score": _round(t.score),
                    "max_score": _round(t.max_score),
                    "status": "passed" if t.passed else "failed",
                    "output": output,
                    "visibility": visibility,
                    "extra_data": {
                        "exercise": r.exercise_id, "grade_id": t.grade_id, "hidden": t.hidden,
                        "mistakes": list(t.mistakes),
                    },
                }
            )
    info = {
        "format": FORMAT,
        "student": student,
        "exercises": {
            r.exercise_id: {"score": _round(r.score), "max_score": _round(r.max_score)} for r in results
        },
        "max_score": _round(sum(r.max_score for r in results)),
        "mistakes": mistake_records(results),
    }
    info.update(extra or {})
    return {
        "score": _round(sum(r.score for r in results)),
        "output": "\n".join(lines),
        "visibility": "visible",
        "stdout_visibility": "hidden",
        # outputs hold student text (error messages): shown as plain text, never as Markdown or HTML
        "output_format": "text",
        "test_output_format": "text",
        "tests": tests,
        "extra_data": {"flowtrack": info},
    }


def _fence_safe(text: str) -> str:
    """``text`` for a fenced ``text`` block: a run of backticks cannot close the fence."""
    return str(text).replace("```", "'''")


def feedback_markdown(student: str, r: ExerciseResult) -> str:
    """What a student may see of one exercise: public test details, hidden tests by name and score."""
    out = [
        f"# {r.exercise_id}: {r.title}",
        "",
        f"Student: `{student}`. Notebook: `{r.notebook}`.",
        "",
        f"**Score: {_round(r.score):g} / {_round(r.max_score):g}**",
        "",
    ]
    if r.problems:  # fenced like the public tests' messages: student text never renders as Markdown
        out += ["## Problems with the submission", ""]
        for p in r.problems:
            out += ["```text", _fence_safe(p), "```", ""]
    out += ["## Tests", "", "| test | kind | score | result |", "|---|---|---|---|"]
    for t in r.tests:
        kind = "hidden" if t.hidden else "public"
        mark = "passed" if t.passed else "failed"
        out.append(f"| {t.name} | {kind} | {_round(t.score):g} / {_round(t.max_score):g} | {mark} |")
    ids: list[str] = []
    for t in r.tests:
        ids += [m for m in t.mistakes if m not in ids]
    if ids:
        from .exercises.catalogue import mistake_line

        out += ["", "## Mistakes recognised", "", "```text", *[mistake_line(m) for m in ids], "```"]
    public = [t for t in r.tests if not t.hidden]
    if public:
        out += ["", "## Public tests in detail", ""]
        for t in public:
            out += [f"### {t.name}", "", "```text", _fence_safe(t.message), "```", ""]
    failed_hidden = [t for t in r.tests if t.hidden and not t.passed]
    if failed_hidden:
        out += ["", "## Hidden tests that failed", ""]
        for t in failed_hidden:
            text = _fence_safe("\n".join(feedback_lines(t, hidden=True)))
            out += [f"### {t.name}", "", "```text", text, "```", ""]
    out += [
        "",
        "Hidden tests use other inputs: they say which check failed and why, never their inputs or "
        "expected values.",
        "",
    ]
    return "\n".join(out)


def _read_results(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    info = data.get("extra_data", {}).get("flowtrack") if isinstance(data, dict) else None
    if not isinstance(info, dict) or info.get("format") != FORMAT or not isinstance(data.get("tests"), list):
        return None
    return data


def grade_student(
    student: str,
    student_dir: str | os.PathLike,
    exercises: Sequence[Exercise],
    out: str | os.PathLike,
    *,
    force: bool = False,
    hidden_visibility: str = "after_published",
    limits: Any = None,
    sandbox_factory: Callable[..., Any] | None = None,
    ex_hash: str | None = None,
    secret: bytes | None = None,
    hidden_paths: Sequence[str | os.PathLike] = (),
    renamed: dict[str, str] | None = None,
    reuse_sandboxes: bool = True,
    sandbox_pool: Any = None,
) -> dict:
    """Grade one student's folder; write ``out/<student>/feedback/*`` then ``results.json``.

    An earlier ``results.json`` that is not kept is removed before grading starts, so a student
    whose grading fails halfway has none (never a stale one); ``hidden_paths`` go to
    :func:`run_exercise`.

    ``secret`` keys the hidden tests' seeds (see :func:`run_exercise`); results made with another
    key (or none) are not kept on a re-run. ``renamed`` (``{exercise id: path in the folder}``, from
    :mod:`.layout`, ``flowtrack grade --accept-renamed``) grades renamed copies of missing notebooks.
    ``reuse_sandboxes`` (default, with the real sandbox): exercises run in the sandboxes of a
    :class:`~flowtrack_course.grading.sandbox.SandboxPool` (one sandboxed process per kind of exercise that
    forks a clean child per exercise), ``sandbox_pool`` when given (:func:`grade_class` shares one
    per worker process between students), else one for this student; it scores the same as a fresh
    sandbox per exercise and saves most of the start-up time. ``False``: a fresh sandbox per exercise.
    Returns ``{"student", "skipped", "score", "max_score", "exercises": {id: score}, "isolation"}``.
    """
    student_dir = Path(student_dir)
    dest = Path(out) / student
    ex_hash = ex_hash or exercises_hash(exercises)
    notebooks = {ex.id: locate_notebook(student_dir, ex) for ex in exercises}
    # issue 18 hook: --accept-renamed grades an LMS-renamed copy (layout.py) and says so in the feedback
    from .layout import rename_notes

    notes = rename_notes(student_dir, exercises, notebooks, renamed)
    sub_hash = submission_hash(notebooks)
    key_id = secret_id(secret)
    results_path = dest / "results.json"
    if not force:
        old = _read_results(results_path)
        if old is not None:
            info = old["extra_data"]["flowtrack"]
            if (
                info.get("exercises_hash") == ex_hash
                and info.get("submission_hash") == sub_hash
                and info.get("secret_id", "") == key_id
            ):
                return {
                    "student": student,
                    "skipped": True,
                    "score": float(old["score"]),
                    "max_score": float(info["max_score"]),
                    "exercises": {k: v["score"] for k, v in info["exercises"].items()},
                    "isolation": info.get("isolation", ""),
                }
    results_path.unlink(missing_ok=True)
    results = []
    pool = None
    if sandbox_factory is None and reuse_sandboxes:
        if sandbox_pool is not None:
            sandbox_factory = sandbox_pool
        else:
            from .sandbox import SandboxPool

            pool = sandbox_factory = SandboxPool(_preload(exercises))
    try:
        for ex in exercises:
            try:
                r = run_exercise(
                    ex, notebooks[ex.id], student, limits=limits, sandbox_factory=sandbox_factory,
                    secret=secret, hidden_paths=hidden_paths,
                )
            except Exception as exc:  # one broken exercise must not lose the others
                r = ExerciseResult(ex.id, ex.title, ex.notebook)
                r.problems.append(f"internal grader error: {type(exc).__name__}: {exc}")
                r.tests = [_zero(t, r.problems[0]) for t in ex.tests]
            r.problems[:0] = notes.get(ex.id, [])  # issue 18 hook (--accept-renamed)
            results.append(r)
    finally:
        if pool is not None:
            pool.close()
    isolation = next((r.isolation for r in results if r.isolation.startswith("fallback")), "")
    isolation = isolation or next((r.isolation for r in results if r.isolation), "")
    data = results_json(
        student,
        results,
        hidden_visibility=hidden_visibility,
        extra={
            "exercises_hash": ex_hash,
            "submission_hash": sub_hash,
            "secret_id": key_id,
            "isolation": isolation,
        },
    )
    for r in results:
        write_atomic(dest / "feedback" / f"{r.exercise_id}.md", feedback_markdown(student, r))
    write_atomic(results_path, json.dumps(data, indent=1))
    return {
        "student": student,
        "skipped": False,
        "score": data["score"],
        "max_score": data["extra_data"]["flowtrack"]["max_score"],
        "exercises": {r.exercise_id: _round(r.score) for r in results},
        "isolation": isolation,
    }


# --------------------------------------------------------------------------------------------------
# a class


def list_students(submissions: str | os.PathLike) -> list[str]:
    """The student folders of ``submissions`` (sorted; hidden folders ignored).

    Raises
    ------
    FileNotFoundError
        ``submissions`` is not a folder.
    ValueError
        A folder name is not a safe student id (letters, digits, ``_.@+-``).
    """
    root = Path(submissions)
    if not root.is_dir():
        raise FileNotFoundError(f"submissions: no such folder: {root}")
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    bad = [n for n in names if not _STUDENT_NAME.match(n)]
    if bad:
        raise ValueError(f"submissions: student folder names must match {_STUDENT_NAME.pattern}, got {bad}")
    return names


def _preload(exercises: Sequence[Exercise]) -> tuple[str, ...]:
    """What a zygote may import before forking: the modules the exercises' allowlists name."""
    return tuple(dict.fromkeys(a for ex in exercises for a in (ex.allowed or ())))


_POOLS: dict[tuple, Any] = {}


def _shared_pool(preload: tuple[str, ...]) -> Any:
    """This process's :class:`~flowtrack_course.grading.sandbox.SandboxPool` (a grading worker's): its
    zygotes serve one student after the other; closed when the process exits."""
    pool = _POOLS.get(preload)
    if pool is None:
        from multiprocessing import util

        from .sandbox import SandboxPool

        pool = _POOLS[preload] = SandboxPool(preload)
        util.Finalize(None, pool.close, exitpriority=10)  # run at a worker's exit (atexit is not)
    return pool


def close_shared_pools() -> None:
    """Kill the sandboxes of this process's shared pools."""
    pools = list(_POOLS.values())
    _POOLS.clear()
    for pool in pools:
        pool.close()


def _worker(args: tuple, exercises: Sequence[Exercise] | None = None, sandbox_factory=None) -> dict:
    """Grade one task of :func:`grade_class`; ``exercises`` default to the registry's by id."""
    (student, student_dir, out, force, hidden_visibility, ex_hash, exercise_ids, secret, hidden,
     renamed, reuse) = args
    try:
        if exercises is None:
            from .exercises import get_exercise
            from .languages import find_language_exercise  # hook (issue 19)

            exercises = [find_language_exercise(i) or get_exercise(i) for i in exercise_ids]
        return grade_student(
            student, student_dir, exercises, out, force=force, hidden_visibility=hidden_visibility,
            ex_hash=ex_hash, sandbox_factory=sandbox_factory, secret=secret, hidden_paths=hidden,
            renamed=renamed, reuse_sandboxes=reuse,
            sandbox_pool=_shared_pool(_preload(exercises)) if reuse and sandbox_factory is None else None,
        )
    except Exception as exc:  # reported in the summary, the class goes on
        try:  # no results.json of an earlier run may stand for this one
            (Path(out) / student / "results.json").unlink(missing_ok=True)
        except OSError:
            pass
        return {"student": student, "error": f"{type(exc).__name__}: {exc}"}


def _write_grades_csv(path: Path, rows: Iterable[dict], exercises: Sequence[Exercise]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["student", *[ex.id for ex in exercises], "total", "max"])
    max_total = _round(sum(ex.max_score for ex in exercises))
    for row in rows:
        scores = row.get("exercises", {})
        w.writerow(
            [row["student"], *[f"{scores.get(ex.id, 0.0):g}" for ex in exercises],
             f"{row.get('score', 0.0):g}", f"{max_total:g}"]
        )
    write_atomic(path, buf.getvalue())


#: disk space the grader keeps for its outputs where students write to the same filesystem
GRADER_RESERVE = 32 << 20


def _check_disk_reserve(out: str | os.PathLike, jobs: int) -> None:
    """Refuse to grade where students could fill the filesystem of the outputs (issue 17).

    Outside bubblewrap the students' files are on the host (the sandbox's work area, the
    world-writable folders), each student's bounded by the meter at ``disk_bytes`` plus what it
    writes between two measurements (counted as ``disk_bytes`` again). See
    :func:`~flowtrack_course.grading.isolation.disk_reserve_problem`.
    """
    from .cache import cache_root
    from .isolation import WORLD_WRITABLE, disk_reserve_problem
    from .sandbox import Limits

    students_max = jobs * 2 * Limits().disk_bytes
    problem = disk_reserve_problem([cache_root() / "work", *WORLD_WRITABLE], [out, tempfile.gettempdir()],
                                   students_max, GRADER_RESERVE)
    if problem:
        raise UnsafeSandbox(problem)


def grade_class(
    submissions: str | os.PathLike,
    out: str | os.PathLike,
    *,
    jobs: int = 1,
    force: bool = False,
    exercises: Sequence[Exercise] | None = None,
    hidden_visibility: str = "after_published",
    assignment: str = "flowtrack",
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    sandbox_factory: Callable[..., Any] | None = None,
    secret: bytes | None = None,
    hidden_paths: Sequence[str | os.PathLike] = (),
    allow_unsafe_sandbox: bool = False,
    renamed: dict[str, dict[str, str]] | None = None,
    roster: dict | None = None,
    reuse_sandboxes: bool = True,
) -> list[dict]:
    """Grade every student folder of ``submissions`` into ``out`` (see the module docstring).

    Student code runs under bubblewrap; where it cannot
    (:func:`~flowtrack_course.grading.isolation.choose_mode`)
    this raises :class:`UnsafeSandbox` unless ``allow_unsafe_sandbox``: the fallback's in-process
    guard can be got around, so a student could read the class's submissions, the output folder or
    the key. The fallback still refuses ``submissions``, ``out`` and ``hidden_paths`` (e.g. the key
    file) to the code it runs. A student folder named like one of the grader's own outputs
    (:data:`RESERVED_NAMES`) is not graded and reported as an error.

    ``secret`` (the instructor's key, :func:`~flowtrack_course.grading.spec.read_secret`) seeds the hidden
    tests; use the same one for every run of a class. ``renamed`` (``{student: {exercise id: path}}``,
    :meth:`.layout.LayoutReport.renamed_map`) grades accepted renamed copies; ``roster``
    (:func:`.lms.read_roster`) fills names and e-mails in the nbgrader gradebook.

    ``jobs`` worker processes grade students in parallel (each runs its own sandboxes); ``jobs=1``
    grades in this process, as do exercises not in the registry and a given ``sandbox_factory``
    (tests' fakes). ``reuse_sandboxes`` goes to :func:`grade_student`. Returns one summary dict per
    student (sorted by student).
    """
    from tqdm.auto import tqdm

    from .gradebook import write_gradebook

    positive_int(jobs, "jobs")
    log = log or (lambda msg: print(msg, file=sys.stderr))
    from .exercises import EXERCISES
    from .languages import LANGUAGE_EXERCISES, submitted_exercises  # hook (issue 19)

    if exercises is None:  # the notebooks, and the language exercises someone in the class answered
        exercises = (*EXERCISES, *submitted_exercises(submissions))
    exercises = tuple(exercises)
    hidden = tuple(str(Path(p).resolve()) for p in (submissions, out, *hidden_paths))
    # Workers look exercises up by id; exercises not in the registry (tests' fakes) grade in-process.
    registry = {ex.id: ex for ex in (*EXERCISES, *LANGUAGE_EXERCISES)}
    custom = sandbox_factory is not None or any(registry.get(ex.id) is not ex for ex in exercises)
    students = list_students(submissions)
    if sandbox_factory is None:
        from .isolation import choose_mode

        mode, why = choose_mode()
        if mode == "setpriv" and not allow_unsafe_sandbox:
            # no namespaces: the student's uid sees what file permissions let any user see
            from .isolation import readable_by_sandbox

            Path(out).mkdir(mode=0o700, parents=True, exist_ok=True)  # a new one: private
            exposed = readable_by_sandbox(hidden)
            if exposed:
                raise UnsafeSandbox(
                    f"bubblewrap cannot isolate student code here ({why}); the setpriv sandbox runs it as an "
                    "unprivileged uid, which can read " + ", ".join(exposed) + ". Make them private to "
                    "the grader (chmod go-rwx " + " ".join(exposed) + "), or pass --allow-unsafe-sandbox."
                )
        elif mode != "bwrap" and not allow_unsafe_sandbox:
            raise UnsafeSandbox(
                f"bubblewrap cannot isolate student code here ({why}). The fallback sandbox runs it as a "
                "plain process behind an in-process audit hook that a determined student can get around "
                "(e.g. with ctypes): they could then read other students' submissions, the output folder "
                "and the seed key, and the machine's other files. Install bubblewrap (apt-get install "
                "bubblewrap) and allow unprivileged user namespaces, or pass --allow-unsafe-sandbox "
                "(allow_unsafe_sandbox=True) to grade anyway."
            )
        if mode != "bwrap":
            _check_disk_reserve(out, min(jobs, max(1, len(students))))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ex_hash = exercises_hash(exercises)
    reserved = [s for s in students if s.lower() in RESERVED_NAMES]
    tasks = [
        (s, str(Path(submissions) / s), str(out), force, hidden_visibility, ex_hash,
         tuple(ex.id for ex in exercises), secret, hidden, (renamed or {}).get(s), reuse_sandboxes)
        for s in students if s not in reserved
    ]
    summaries: dict[str, dict] = {}
    bar = tqdm(total=len(tasks), desc="grading", unit="student", disable=not progress)
    if jobs == 1 or len(tasks) <= 1 or custom:
        try:
            for task in tasks:
                summaries[task[0]] = _worker(task, exercises, sandbox_factory)
                bar.update(1)
        finally:
            close_shared_pools()
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed
        from concurrent.futures.process import BrokenProcessPool

        pending = list(tasks)
        for _attempt in range(2):
            ctx = mp.get_context("forkserver" if sys.platform.startswith("linux") else "spawn")
            if ctx.get_start_method() == "forkserver":
                # the fork server imports the grader and builds the public tests once, before it
                # forks the workers (ignored when it already runs)
                ctx.set_forkserver_preload(["flowtrack_course.grading._warm"])
            broken = []
            with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
                futures = {pool.submit(_worker, t): t for t in pending}
                for fut in as_completed(futures):
                    task = futures[fut]
                    try:
                        summaries[task[0]] = fut.result()
                        bar.update(1)
                    except BrokenProcessPool:
                        broken.append(task)
            pending = broken
            if not pending:
                break
        for task in pending:
            summaries[task[0]] = {"student": task[0], "error": "a grading worker died"}
            bar.update(1)
    bar.close()
    for s in reserved:
        summaries[s] = {"student": s, "error": f"the folder name {s!r} is reserved for the grader's outputs "
                        "(rename the student's folder)"}
    rows = [summaries[s] for s in students]
    isolations = {r.get("isolation", "") for r in rows}
    for iso in sorted(i for i in isolations if i.startswith("fallback")):
        log(f"warning: sandbox isolation is {iso!r}: student code ran without the full bubblewrap sandbox")
    for r in rows:
        if "error" in r:
            log(f"error: student {r['student']}: {r['error']} (scored 0; re-run grade to retry)")
    _write_grades_csv(out / "grades.csv", rows, exercises)
    write_gradebook(out / "gradebook.db", exercises, out, students, assignment=assignment, roster=roster)
    return rows
