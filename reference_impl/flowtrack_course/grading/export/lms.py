"""Gradebook files an LMS imports (Canvas, Moodle) from ``grades.csv`` and a class roster.

The roster (``--roster FILE``) is a CSV with a header; column names are matched case-insensitively,
ignoring spaces, ``_`` and ``-``:

=====================  ================================================================
``student``            the student id = the folder name in SUBMISSIONS (also ``id``,
                       ``student_id``, ``login``, ``username``)
``name``               full name (or ``first_name`` + ``last_name``)
``email``              e-mail address (``e_mail``, ``mail``, ``email_address``)
``section``            optional (Canvas ``Section``)
``sis_user_id``        optional (Canvas ``SIS User ID``; also ``idnumber``, Moodle's "ID number")
``sis_login_id``       optional (Canvas ``SIS Login ID``)
``canvas_id``          optional (Canvas' numeric user ``ID``; also ``lms_id``, ``lms_user_id``)
=====================  ================================================================

Formats written:

- **Canvas** ("Import" in the Gradebook): columns ``Student, ID, SIS User ID, SIS Login ID, Section``
  then one column per assignment, named ``<assignment> (<assignment id>)`` when the Canvas id is
  known (``--canvas-assignment-id``), else ``<assignment>`` (Canvas then creates the assignment);
  the second row is ``Points Possible`` with the maximum of each column. ``Student`` is
  ``Last, First``. Canvas matches a row by ``ID``, then ``SIS User ID``, then ``SIS Login ID``.
- **Moodle** ("Import > CSV file" in the gradebook): ``First name, Last name, ID number, Email
  address`` then one column per grade item; map "Email address" (or "ID number") to the user
  field of the same name and each grade column to its grade item when importing.

``mode="exercises"`` writes one column per exercise (``<assignment>: <exercise id>``),
``mode="total"`` one column with the total.

Every text cell (roster names, e-mails, ids, sections, column names) that a spreadsheet would read
as a formula, i.e. one starting with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return, is
written with a leading ``'`` (:func:`text_cell`): a roster name ``=HYPERLINK(...)`` stays text in
whatever program opens the file.
"""

from __future__ import annotations

import csv
import io
import os
import re
import unicodedata
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from ..engine.results import format_score

__all__ = [
    "RosterEntry",
    "canvas_csv",
    "export_lms",
    "moodle_csv",
    "read_grades_csv",
    "read_roster",
    "roster_entry",
    "roster_key",
    "text_cell",
]

_ALIASES = {
    "student": ("student", "id", "studentid", "login", "username", "user"),
    "name": ("name", "fullname", "studentname"),
    "first_name": ("firstname", "givenname"),
    "last_name": ("lastname", "surname", "familyname"),
    "email": ("email", "mail", "emailaddress"),
    "section": ("section",),
    "sis_user_id": ("sisuserid", "idnumber", "sisid"),
    "sis_login_id": ("sisloginid",),
    "lms_id": ("canvasid", "lmsid", "lmsuserid", "canvasuserid"),
}
_EMAIL = re.compile(r"^[^@\s]+@[^@\s]+$")


@dataclass(frozen=True)
class RosterEntry:
    """One student of the roster (empty strings for unknown fields)."""

    student: str
    first_name: str = ""
    last_name: str = ""
    email: str = ""
    section: str = ""
    sis_user_id: str = ""
    sis_login_id: str = ""
    lms_id: str = ""

    @property
    def name(self) -> str:
        return " ".join(p for p in (self.first_name, self.last_name) if p)

    @property
    def sortable_name(self) -> str:
        """``Last, First`` (Canvas' Student column)."""
        if self.last_name and self.first_name:
            return f"{self.last_name}, {self.first_name}"
        return self.last_name or self.first_name or self.student

    def nbgrader_fields(self) -> dict:
        """Keyword arguments of nbgrader's ``Gradebook.add_student``."""
        out = {"first_name": self.first_name, "last_name": self.last_name, "email": self.email}
        if self.lms_id:
            out["lms_user_id"] = self.lms_id
        return {k: v for k, v in out.items() if v}


def roster_key(student: str) -> str:
    """How a student id is compared with the roster's: Unicode NFC (an accent typed as one character
    or as a letter and a combining mark, as macOS writes file names), outer spaces ignored.

    >>> roster_key("Jose\u0301 ") == roster_key("Jos\u00e9")
    True
    """
    return unicodedata.normalize("NFC", str(student)).strip()


def roster_entry(roster: Mapping[str, RosterEntry], student: str) -> RosterEntry | None:
    """The roster's entry of ``student`` (a grades.csv id, a folder name), compared by
    :func:`roster_key`; None when the roster has no such student."""
    entry = roster.get(student)
    if entry is not None:
        return entry
    key = roster_key(student)
    return next((e for sid, e in roster.items() if roster_key(sid) == key), None)


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def text_cell(text: str) -> str:
    """``text`` as a CSV cell no spreadsheet evaluates: a leading ``'`` when it starts like a formula.

    >>> text_cell('=HYPERLINK("http://x", "y")'), text_cell("Doe, Jane"), text_cell("")
    ('\\'=HYPERLINK("http://x", "y")', 'Doe, Jane', '')
    """
    text = str(text)
    return "'" + text if text.startswith(_FORMULA_START) else text


def _norm(col: str) -> str:
    return re.sub(r"[\s_\-]+", "", str(col).strip().lower())


def _split_name(name: str) -> tuple[str, str]:
    """``"Jane Doe"`` -> (Jane, Doe); ``"Doe, Jane"`` -> (Jane, Doe)."""
    name = " ".join(name.split())
    if "," in name:
        last, first = (p.strip() for p in name.split(",", 1))
        return first, last
    parts = name.rsplit(" ", 1)
    return (parts[0], parts[1]) if len(parts) == 2 else (name, "")


def read_roster(path: str | os.PathLike) -> dict[str, RosterEntry]:
    """``{student id: RosterEntry}`` from a roster CSV (see the module docstring).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        No student-id column, an empty or duplicate student id, or a malformed e-mail (the row
        number is in the message).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"roster: no such file: {path}")
    text = path.read_text(encoding="utf-8-sig")
    try:
        dialect = csv.Sniffer().sniff(text[:4096], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    reader = csv.reader(io.StringIO(text), dialect)
    header = next(reader, None)
    if not header:
        raise ValueError(f"roster {path}: empty file (expected a header such as student,name,email)")
    cols: dict[str, int] = {}
    for i, h in enumerate(header):
        n = _norm(h)
        for field_name, names in _ALIASES.items():
            if n in names and field_name not in cols:
                cols[field_name] = i
    if "student" not in cols:
        raise ValueError(
            f"roster {path}: no student id column in {header} (expected one of "
            "student, id, student_id, login, username)"
        )
    out: dict[str, RosterEntry] = {}
    for rowno, row in enumerate(reader, start=2):
        if not any(c.strip() for c in row):
            continue

        def get(name: str, row=row) -> str:
            i = cols.get(name)
            return row[i].strip() if i is not None and i < len(row) else ""

        student = get("student")
        if not student:
            raise ValueError(f"roster {path}, row {rowno}: empty student id")
        if student in out:
            raise ValueError(f"roster {path}, row {rowno}: duplicate student id {student!r}")
        first, last = get("first_name"), get("last_name")
        if not (first or last) and get("name"):
            first, last = _split_name(get("name"))
        email = get("email")
        if email and not _EMAIL.match(email):
            raise ValueError(f"roster {path}, row {rowno}: email must look like user@host, got {email!r}")
        out[student] = RosterEntry(
            student,
            first,
            last,
            email,
            get("section"),
            get("sis_user_id"),
            get("sis_login_id"),
            get("lms_id"),
        )
    return out


def read_grades_csv(path: str | os.PathLike) -> tuple[list[str], list[dict]]:
    """``(exercise ids, rows)`` of a ``flowtrack grade`` grades.csv.

    Each row: ``{"student", "exercises": {id: float}, "score": float, "max": float}``; a blank cell
    (an exercise not assigned to that student) is left out of ``exercises``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"grades: no such file: {path}")
    reader = csv.reader(io.StringIO(path.read_text(encoding="utf-8")))
    header = next(reader, None)
    if not header or header[0] != "student" or header[-2:] != ["total", "max"]:
        raise ValueError(
            f"grades {path}: expected the columns student,<exercise ids>,total,max; got {header}"
        )
    ids = header[1:-2]
    rows = []
    for rowno, row in enumerate(reader, start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise ValueError(f"grades {path}, row {rowno}: {len(row)} fields, expected {len(header)}")
        try:
            nums = [None if x.strip() == "" and i < len(ids) else float(x) for i, x in enumerate(row[1:])]
        except ValueError as exc:
            raise ValueError(f"grades {path}, row {rowno}: {exc}") from None
        scores = {i: v for i, v in zip(ids, nums[:-2]) if v is not None}
        rows.append({"student": row[0], "exercises": scores, "score": nums[-2], "max": nums[-1]})
    return ids, rows


def _fmt(x: float | None) -> str:
    return "" if x is None else format_score(x)


def _columns(
    ids: Sequence[str], points: Mapping[str, float], mode: str, assignment: str, total_max: float | None
) -> list[tuple[str, str | None, float | None]]:
    """``(header, exercise id or None for the total, max points)`` of each grade column."""
    if mode == "exercises":
        return [(f"{assignment}: {i}", i, points.get(i)) for i in ids]
    if mode == "total":
        return [(assignment, None, total_max)]
    raise ValueError(f"mode must be 'exercises' or 'total', got {mode!r}")


def _class_rows(rows: Sequence[dict], roster: Mapping[str, RosterEntry] | None) -> tuple[list, list[str]]:
    """``[(RosterEntry, grade row or None)]`` in roster order then the rest, and warnings."""
    roster = dict(roster or {})
    graded = {roster_key(r["student"]): r for r in rows}  # the folder names, joined as ids
    out, warnings = [], []
    for sid, entry in roster.items():
        out.append((entry, graded.get(roster_key(sid))))
    in_roster = {roster_key(sid) for sid in roster}
    missing_roster = [r["student"] for r in rows if roster_key(r["student"]) not in in_roster]
    for s in sorted(missing_roster):
        out.append((RosterEntry(s), graded[roster_key(s)]))
    if roster and missing_roster:
        warnings.append(
            f"{len(missing_roster)} graded student(s) not in the roster (exported with the folder name as "
            f"the login id only): {', '.join(sorted(missing_roster)[:10])}"
        )
    absent = [sid for sid in roster if roster_key(sid) not in graded]
    if absent:
        warnings.append(
            f"{len(absent)} roster student(s) without a graded submission (left blank): "
            f"{', '.join(absent[:10])}"
        )
    return out, warnings


def canvas_csv(
    rows: Sequence[dict],
    ids: Sequence[str],
    *,
    points: Mapping[str, float] | None = None,
    roster: Mapping[str, RosterEntry] | None = None,
    mode: str = "total",
    assignment: str = "flowtrack",
    assignment_id: str | None = None,
) -> tuple[str, list[str]]:
    """Canvas gradebook import CSV (text, warnings); see the module docstring.

    ``rows`` as from :func:`read_grades_csv`; ``points`` the maximum of each exercise (the Points
    Possible row; blank when unknown).
    """
    points = dict(points or {})
    total_max = max((r["max"] for r in rows), default=None) if rows else None
    if total_max is None and points:
        total_max = sum(points.values())
    cols = _columns(ids, points, mode, assignment, total_max)
    if assignment_id:
        if mode != "total":
            raise ValueError("assignment_id: a Canvas assignment id goes with mode='total' only")
        cols = [(f"{assignment} ({assignment_id})", None, total_max)]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["Student", "ID", "SIS User ID", "SIS Login ID", "Section", *[text_cell(c[0]) for c in cols]])
    w.writerow(["    Points Possible", "", "", "", "", *[_fmt(c[2]) for c in cols]])
    body, warnings = _class_rows(rows, roster)
    for entry, row in body:
        login = entry.sis_login_id or (entry.student if not (entry.lms_id or entry.sis_user_id) else "")
        values = []
        for _, ex_id, _ in cols:
            if row is None:
                values.append("")
            else:
                values.append(_fmt(row["score"] if ex_id is None else row["exercises"].get(ex_id)))
        texts = [entry.sortable_name, entry.lms_id, entry.sis_user_id, login, entry.section]
        w.writerow([*map(text_cell, texts), *values])
    return buf.getvalue(), warnings


def moodle_csv(
    rows: Sequence[dict],
    ids: Sequence[str],
    *,
    roster: Mapping[str, RosterEntry] | None = None,
    mode: str = "total",
    assignment: str = "flowtrack",
    points: Mapping[str, float] | None = None,
) -> tuple[str, list[str]]:
    """Moodle gradebook import CSV (text, warnings); see the module docstring.

    A row needs an e-mail or an ID number for Moodle to find the user: rows with neither are
    written with the student id as ID number and reported in the warnings.
    """
    cols = _columns(ids, dict(points or {}), mode, assignment, None)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["First name", "Last name", "ID number", "Email address", *[text_cell(c[0]) for c in cols]])
    body, warnings = _class_rows(rows, roster)
    no_id = []
    for entry, row in body:
        idnumber = entry.sis_user_id
        if not (entry.email or idnumber):
            idnumber = entry.student
            no_id.append(entry.student)
        values = [
            "" if row is None else _fmt(row["score"] if ex_id is None else row["exercises"].get(ex_id))
            for _, ex_id, _ in cols
        ]
        texts = [entry.first_name or entry.student, entry.last_name, idnumber, entry.email]
        w.writerow([*map(text_cell, texts), *values])
    if no_id:
        warnings.append(
            f"{len(no_id)} student(s) without e-mail or ID number in the roster (their folder name is used "
            f"as ID number): {', '.join(no_id[:10])}"
        )
    return buf.getvalue(), warnings


def export_lms(
    lms: str,
    grades: str | os.PathLike,
    out: str | os.PathLike,
    *,
    roster: str | os.PathLike | Mapping[str, RosterEntry] | None = None,
    mode: str = "total",
    assignment: str = "flowtrack",
    assignment_id: str | None = None,
    points: Mapping[str, float] | None = None,
) -> tuple[Path, list[str]]:
    """Write the ``lms`` (``"canvas"`` or ``"moodle"``) import file for ``grades`` (a grades.csv) to ``out``.

    ``points`` default to the registry's exercise maxima for the ids in grades.csv. Returns
    ``(out, warnings)``.
    """
    from ..engine.results import write_atomic

    if lms not in ("canvas", "moodle"):
        raise ValueError(f"lms must be 'canvas' or 'moodle', got {lms!r}")
    ids, rows = read_grades_csv(grades)
    if roster is not None and not isinstance(roster, Mapping):
        roster = read_roster(roster)
    if points is None:
        points = {}
        try:
            from .exercises import get_exercise

            for i in ids:
                points[i] = get_exercise(i).max_score
        except (KeyError, ValueError, ImportError):
            points = {}
    if lms == "canvas":
        text, warnings = canvas_csv(
            rows,
            ids,
            points=points,
            roster=roster,
            mode=mode,
            assignment=assignment,
            assignment_id=assignment_id,
        )
    else:
        if assignment_id:
            raise ValueError("assignment_id is for Canvas only")
        text, warnings = moodle_csv(rows, ids, roster=roster, mode=mode, assignment=assignment, points=points)
    out = Path(out)
    write_atomic(out, text)
    return out, warnings


def roster_as_dict(roster: Mapping[str, RosterEntry]) -> dict[str, dict]:
    """Plain-data form of a roster (for JSON reports)."""
    return {k: asdict(v) for k, v in roster.items()}
