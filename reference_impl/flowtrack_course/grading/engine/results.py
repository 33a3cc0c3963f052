"""What grading produces: :class:`TestResult`, :class:`ExerciseResult`, a student's Gradescope
``results.json`` (:func:`results_json`) and feedback page (:func:`feedback_markdown`).

``results.json`` is Gradescope's format (``score``, ``tests[]`` with ``name``, ``score``,
``max_score``, ``status``, ``output``, ``visibility``) with the grader's own record under
``extra_data.flowtrack`` (:data:`FORMAT`: the exercises' scores, the mistakes recognised, and
what a re-run compares to keep a finished student).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .feedback import feedback_lines, mistake_records
from .mistakes import Catalogue

__all__ = ["FORMAT", "ExerciseResult", "TestResult", "feedback_markdown", "read_results", "results_json",
           "format_score", "round_score", "student_folder", "write_atomic"]

FORMAT = "flowtrack-results/1"


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
    """The grade of one exercise: its tests and the problems found with the submission.

    ``catalogue`` holds the messages of the mistakes its tests may name (the exercise's course's).
    """

    exercise_id: str
    title: str
    notebook: str
    tests: list[TestResult] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    isolation: str = ""
    catalogue: Catalogue = field(default_factory=Catalogue, repr=False, compare=False)

    @property
    def score(self) -> float:
        return float(sum(t.score for t in self.tests))

    @property
    def max_score(self) -> float:
        return float(sum(t.max_score for t in self.tests))


_PLAIN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.@+\-]{0,127}$")


def student_folder(student: str) -> str:
    """The name of a student's output folder (``OUT/<student_folder>/results.json``, feedback).

    A student id is the name of the student's submission folder, whatever its letters; file names
    get a safe form of it: the id itself when it is plain ASCII (letters, digits, ``_.@+-``), else
    its letters without accents, ``_`` for the rest, and 8 hex digits of its hash (two ids never
    share a folder). Every output that names a student (grades.csv, results.json, the feedback,
    the gradebook, the reports, the LMS files) names the id, never this.

    >>> import hashlib
    >>> student_folder("ann_42"), student_folder("李雷")[:8]
    ('ann_42', 'student-')
    >>> digest = hashlib.sha256("José Müller".encode()).hexdigest()[:8]
    >>> student_folder("José Müller") == f"Jose_Muller-{digest}"
    True
    """
    student = str(student)
    if _PLAIN_ID.match(student):
        return student
    folded = unicodedata.normalize("NFKD", student).encode("ascii", "ignore").decode("ascii")
    base = re.sub(r"[^A-Za-z0-9_.@+\-]+", "_", folded).strip("_.-@+")[:64] or "student"
    digest = hashlib.sha256(student.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{base}-{digest}"


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


def round_score(x: float) -> float:
    """A score as the outputs show it (6 decimals)."""
    return round(float(x), 6)


def format_score(x: float) -> str:
    """A score as every output prints it: :func:`round_score`'s value without trailing zeros, so
    that grades.csv, the feedback, results.json and the LMS files show the same digits.

    >>> format_score(139 / 6), format_score(10.0), format_score(0.5), format_score(-1e-9)
    ('23.166667', '10', '0.5', '0')
    """
    text = f"{round_score(x):.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def results_json(
    student: str,
    results: Sequence[ExerciseResult],
    *,
    hidden_visibility: str = "after_published",
    extra: dict | None = None,
    notes: Sequence[str] = (),
) -> dict:
    """Gradescope ``results.json`` for one student.

    Public tests are ``"visible"`` with the grader's message; hidden tests carry
    ``hidden_visibility`` and, as output, their name and score only. ``notes`` (what of the
    submission was not graded, and why) open the output.

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
    lines = [f"note: {n}" for n in notes]
    for r in results:
        lines.append(f"{r.exercise_id} ({r.title}): {format_score(r.score)} / {format_score(r.max_score)}")
        lines += [f"  problem: {p}" for p in r.problems]
        for t in r.tests:
            if t.hidden:
                output = f"hidden test {t.name}: {format_score(t.score)} / {format_score(t.max_score)}"
                shown = feedback_lines(t, hidden=True, catalogue=r.catalogue)
                output += "".join(f"\n{line}" for line in shown)
                visibility = hidden_visibility
            else:
                output = t.message
                output += "".join(f"\nproblem: {p}" for p in r.problems if p != t.message)
                shown = feedback_lines(t, hidden=False, with_message=False, catalogue=r.catalogue)
                output += "".join(f"\n{line}" for line in shown)
                visibility = "visible"
            tests.append(
                {
                    "name": f"{r.exercise_id}: {t.name}",
                    "score": round_score(t.score),
                    "max_score": round_score(t.max_score),
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
            r.exercise_id: {"score": round_score(r.score), "max_score": round_score(r.max_score)}
            for r in results
        },
        "max_score": round_score(sum(r.max_score for r in results)),
        "mistakes": mistake_records(results),
    }
    info.update(extra or {})
    return {
        "score": round_score(sum(r.score for r in results)),
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


def feedback_markdown(student: str, r: ExerciseResult, notes: Sequence[str] = ()) -> str:
    """What a student may see of one exercise: public test details, hidden tests by name and score;
    ``notes`` on the whole submission (what was not graded) first."""
    out = [
        f"# {r.exercise_id}: {r.title}",
        "",
        f"Student: `{student}`. Notebook: `{r.notebook}`.",
        "",
        f"**Score: {format_score(r.score)} / {format_score(r.max_score)}**",
        "",
    ]
    if notes:  # the grader's words around file names a student chose: fenced like the problems
        out += ["## Notes on your submission", "", "```text", *(_fence_safe(n) for n in notes), "```", ""]
    if r.problems:  # fenced like the public tests' messages: student text never renders as Markdown
        out += ["## Problems with the submission", ""]
        for p in r.problems:
            out += ["```text", _fence_safe(p), "```", ""]
    out += ["## Tests", "", "| test | kind | score | result |", "|---|---|---|---|"]
    for t in r.tests:
        kind = "hidden" if t.hidden else "public"
        mark = "passed" if t.passed else "failed"
        score = f"{format_score(t.score)} / {format_score(t.max_score)}"
        out.append(f"| {t.name} | {kind} | {score} | {mark} |")
    ids: list[str] = []
    for t in r.tests:
        ids += [m for m in t.mistakes if m not in ids]
    if ids:
        out += ["", "## Mistakes recognised", "", "```text", *r.catalogue.lines(ids), "```"]
    public = [t for t in r.tests if not t.hidden]
    if public:
        out += ["", "## Public tests in detail", ""]
        for t in public:
            out += [f"### {t.name}", "", "```text", _fence_safe(t.message), "```", ""]
    failed_hidden = [t for t in r.tests if t.hidden and not t.passed]
    if failed_hidden:
        out += ["", "## Hidden tests that failed", ""]
        for t in failed_hidden:
            text = _fence_safe("\n".join(feedback_lines(t, hidden=True, catalogue=r.catalogue)))
            out += [f"### {t.name}", "", "```text", text, "```", ""]
    out += [
        "",
        "Hidden tests use other inputs: they say which check failed and why, never their inputs or "
        "expected values.",
        "",
    ]
    return "\n".join(out)


def read_results(path: Path) -> dict | None:
    """A student's ``results.json`` made by this grader (:data:`FORMAT`), else None."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    info = data.get("extra_data", {}).get("flowtrack") if isinstance(data, dict) else None
    if not isinstance(info, dict) or info.get("format") != FORMAT or not isinstance(data.get("tests"), list):
        return None
    return data
