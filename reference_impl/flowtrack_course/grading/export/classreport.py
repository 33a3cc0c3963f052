"""``misconceptions.csv`` and the class report of a ``flowtrack grade`` run.

Both are built from a small interface: *mistakes* are ``{student: [(exercise id, mistake id),
...]}``, read from the students' ``results.json`` by :func:`collect_mistakes`: the grader's own
records of what its mistake matcher recognised (``extra_data.flowtrack.mistakes``: records with
``exercise`` and ``id``, or pairs), only ids of the course's catalogue when one is given. The
``mistake <id>: <message>`` lines of a test's ``output`` are never parsed: that output also holds
the student's own text (an exception's message in a public test), which could forge them.

``misconceptions.csv`` columns: ``exercise,mistake_id,count,students`` (students separated by
``;``, sorted), rows by decreasing ``count``. The class report (Markdown) has the score
distribution of each exercise (n, mean, median, min, max, full marks, zero, a histogram over
tenths of the maximum) and the most frequent mistakes.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

from ..engine.classrun import OUTPUT_FILES
from ..engine.mistakes import GENERIC
from ..engine.results import student_folder

__all__ = [
    "MISCONCEPTIONS_HEADER",
    "class_report_markdown",
    "collect_mistakes",
    "misconception_rows",
    "score_distribution",
    "write_class_outputs",
    "write_misconceptions_csv",
]

MISCONCEPTIONS_HEADER = ("exercise", "mistake_id", "count", "students")

Mistakes = Mapping[str, Sequence[tuple[str, str]]]


def collect_mistakes(
    out: str | os.PathLike, students: Sequence[str], known: Collection[str] | None = None
) -> dict[str, list[tuple[str, str]]]:
    """``{student: sorted unique [(exercise, mistake id)]}`` from ``out/<student>/results.json``.

    Only the grader's records count (see the module docstring); ``known`` (the catalogue's ids)
    keeps only those. Unreadable results give no mistakes (the grade run reports those students
    separately).
    """
    found: dict[str, list[tuple[str, str]]] = {}
    for s in students:
        try:
            data = json.loads((Path(out) / student_folder(s) / "results.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        pairs: set[tuple[str, str]] = set()
        info = (data.get("extra_data") or {}).get("flowtrack", {}) if isinstance(data, dict) else {}
        for item in info.get("mistakes", []) if isinstance(info, dict) else []:
            if isinstance(item, dict) and "exercise" in item and "id" in item:  # the grader's records
                pairs.add((str(item["exercise"]), str(item["id"])))
            elif isinstance(item, (list, tuple)) and len(item) == 2:
                pairs.add((str(item[0]), str(item[1])))
        found[s] = sorted(p for p in pairs if known is None or p[1] in known)
    return found


def misconception_rows(mistakes: Mistakes) -> list[tuple[str, str, int, list[str]]]:
    """``[(exercise, mistake id, n students, sorted students)]``, most frequent first.

    >>> misconception_rows({"ann": [("ex1", "sign")], "bob": [("ex1", "sign"), ("ex2", "scale")]})
    [('ex1', 'sign', 2, ['ann', 'bob']), ('ex2', 'scale', 1, ['bob'])]
    """
    who: dict[tuple[str, str], set[str]] = {}
    for student, pairs in mistakes.items():
        for ex, mid in pairs:
            who.setdefault((str(ex), str(mid)), set()).add(student)
    rows = [(ex, mid, len(s), sorted(s)) for (ex, mid), s in who.items()]
    rows.sort(key=lambda r: (-r[2], r[0], r[1]))
    return rows


def write_misconceptions_csv(path: str | os.PathLike, mistakes: Mistakes) -> Path:
    """Write ``misconceptions.csv`` (header always, one row per (exercise, mistake))."""
    from ..engine.results import write_atomic

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(MISCONCEPTIONS_HEADER)
    for ex, mid, n, students in misconception_rows(mistakes):
        w.writerow([ex, mid, n, ";".join(students)])
    write_atomic(Path(path), buf.getvalue())
    return Path(path)


def score_distribution(scores: Sequence[float], max_score: float, bins: int = 10) -> dict:
    """Summary of one exercise's scores: n, mean, median, min, max, full, zero and a histogram.

    The histogram counts scores in ``bins`` equal intervals of ``[0, max_score]``, the last closed.

    >>> d = score_distribution([0, 5, 10, 10], 10, bins=2)
    >>> d["mean"], d["median"], d["full"], d["zero"], d["histogram"]
    (6.25, 7.5, 2, 1, [1, 3])
    """
    xs = sorted(float(x) for x in scores)
    n = len(xs)
    hist = [0] * bins
    for x in xs:
        k = math.floor(x / max_score * bins) if max_score > 0 else 0
        hist[min(max(k, 0), bins - 1)] += 1
    if n:
        mid = n // 2
        median = xs[mid] if n % 2 else 0.5 * (xs[mid - 1] + xs[mid])
        mean = sum(xs) / n
    else:
        median = mean = float("nan")
    return {
        "n": n,
        "mean": mean,
        "median": median,
        "min": xs[0] if n else float("nan"),
        "max": xs[-1] if n else float("nan"),
        "full": sum(1 for x in xs if x >= max_score - 1e-9),
        "zero": sum(1 for x in xs if x <= 1e-9),
        "histogram": hist,
        "max_score": float(max_score),
    }


def _g(x: float) -> str:
    return "–" if isinstance(x, float) and math.isnan(x) else f"{round(float(x), 3):g}"


def class_report_markdown(
    rows: Sequence[dict],
    exercises: Sequence,
    mistakes: Mistakes,
    *,
    title: str = "Class report",
    top: int = 10,
) -> str:
    """The class report: score distribution per exercise and the most frequent mistakes (Markdown).

    ``rows`` are ``flowtrack grade`` summaries (``{"student", "exercises": {id: score}}``; rows with
    ``"error"`` are left out and counted); ``exercises`` have ``id``, ``title`` and ``max_score``.
    """
    ok = [r for r in rows if "error" not in r]
    lines = [
        f"# {title}",
        "",
        f"{len(ok)} students graded"
        + (
            f", {len(rows) - len(ok)} could not be graded (see the run's errors)"
            if len(rows) > len(ok)
            else ""
        )
        + ".",
        "",
        "## Score distribution per exercise",
        "",
    ]
    lines += [
        "| exercise | max | n | mean | median | min | max scored | full marks | zero | histogram (0 → max) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    bars = " ▁▂▃▄▅▆▇█"

    def graded(ex) -> list[dict]:
        """The rows of the students graded on ``ex`` (not those who chose another language)."""
        return [r for r in ok if ex.id in r.get("exercises", {})]

    for ex in exercises:
        d = score_distribution([float(r["exercises"][ex.id]) for r in graded(ex)], ex.max_score)
        peak = max(d["histogram"]) or 1
        spark = "".join(bars[math.ceil(8 * h / peak)] for h in d["histogram"])
        lines.append(
            f"| {ex.id} | {_g(ex.max_score)} | {d['n']} | {_g(d['mean'])} | {_g(d['median'])} "
            f"| {_g(d['min'])} | {_g(d['max'])} | {d['full']} | {d['zero']} | `{spark}` {d['histogram']} |"
        )
    lines += ["", "## Most frequent mistakes", ""]
    mrows = misconception_rows(mistakes)
    if not mrows:
        lines.append(
            "No mistakes were recognised in this run (the mistake catalogue reports them as "
            "`mistake <id>: ...` feedback lines)."
        )
    else:
        lines += ["| exercise | mistake | students | share |", "|---|---|---|---|"]
        for ex, mid, n, _ in mrows[:top]:
            lines.append(f"| {ex} | `{mid}` | {n} | {100.0 * n / max(len(ok), 1):.0f} % |")
        lines += ["", "Every (exercise, mistake) pair with its students is in `misconceptions.csv`."]

    def fraction(ex) -> float:
        rows = graded(ex)
        return sum(float(r["exercises"][ex.id]) for r in rows) / max(len(rows), 1) / max(ex.max_score, 1e-12)

    def submitted(ex) -> bool:
        """Someone handed ``ex`` in (rows without the ``failures`` record, from older runs, count)."""
        return any(ex.id in r["failures"] if "failures" in r else True for r in graded(ex))

    # an exercise nobody handed in scores 0 for everyone: nothing to reteach from that
    weakest = sorted((ex for ex in exercises if graded(ex) and submitted(ex)), key=fraction)
    if ok and weakest:
        lines += ["", "## What to reteach first", ""]
        for ex in weakest[:3]:
            rows = graded(ex)
            mean = sum(float(r["exercises"][ex.id]) for r in rows) / len(rows)
            share = 100.0 * mean / ex.max_score if ex.max_score else 0.0
            lines.append(f"- {ex.id} ({ex.title}): mean {share:.0f} % of the points")
    lines.append("")
    return "\n".join(lines)


def write_class_outputs(
    out: str | os.PathLike, rows: Sequence[dict], exercises: Sequence, mistakes: Mistakes | None = None
) -> tuple[Path, Path]:
    """Write ``out/misconceptions.csv`` and ``out/class_report.md``; mistakes default to
    :func:`collect_mistakes` of the rows' students (the ids of the exercises' catalogues and the
    generic ones). Returns both paths."""
    from ..engine.results import write_atomic

    out = Path(out)
    if mistakes is None:
        known: set[str] | None = set()
        for ex in exercises:
            catalogue = getattr(ex, "catalogue", None)
            ids = set(catalogue) if catalogue is not None else {m.id for m in getattr(ex, "mistakes", ())}
            if not ids and not hasattr(ex, "mistakes"):
                known = None  # exercises that do not say which mistakes they name: keep every record
                break
            known |= ids
        if known is not None:
            known |= {m.id for m in GENERIC}
        mistakes = collect_mistakes(out, [r["student"] for r in rows if "error" not in r], known)
    csv_path = write_misconceptions_csv(out / OUTPUT_FILES["misconceptions"], mistakes)
    report = out / OUTPUT_FILES["class_report"]
    write_atomic(report, class_report_markdown(rows, exercises, mistakes))
    return csv_path, report
