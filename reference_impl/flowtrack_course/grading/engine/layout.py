"""Checks of a SUBMISSIONS folder before ``flowtrack grade`` grades it.

``flowtrack grade SUBMISSIONS`` expects one folder per student holding that student's notebooks
under the exercises' file names::

    SUBMISSIONS/<student>/ex02_other_topic.ipynb
    SUBMISSIONS/<student>/ex07_some_model.ipynb
    ...

LMS downloads rarely look like that. :func:`check_layout` finds, without reading any notebook:

- a *flat* layout: notebooks directly in SUBMISSIONS (Canvas' "Download submissions" zip is flat:
  ``<name>_<user id>_<submission id>_<file>``; Moodle prefixes ``<Full Name>_<id>_assignsubmission_file_``);
  each gets a suggested ``mv`` into ``<student>/<notebook>``;
- *renamed copies* of an expected notebook inside a student folder: ``name (1).ipynb``,
  ``name-2.ipynb``, ``name_2.ipynb``, ``name - Copy.ipynb``, a change of case, an LMS prefix. The
  best match is the highest copy number (the latest resubmission), then the newest file, whether
  the expected file is there too or not (the expected name has copy number 0);
- *unknown files* (anything that is neither an expected notebook nor a renamed copy of one);
- student folders whose names cannot be student ids (:func:`student_id_problem`: control
  characters, bytes that are not UTF-8); any other name is an id as it is, spaces and accents
  included (files are written under :func:`~.results.student_folder`, a safe form of it).

The grader itself (:func:`~.student.locate_notebook`) only accepts the exact file name; with
``flowtrack grade --accept-renamed`` the best copy found here is graded (in place of a missing
notebook, or of an older one under the expected name), and the student's feedback names the file
graded and the files ignored (:func:`~.student.locate_notebooks`).

Matching works on a canonical form of a file name: without ``.ipynb``, lower case, copy suffixes
removed (repeatedly), separators unified:

>>> [canonical(n) for n in ("EX07_model (1).ipynb", "ex07-model - Copy.ipynb", "ex07_model_2.ipynb")]
['ex07_model', 'ex07_model', 'ex07_model']
>>> [copy_number(n) for n in ("ex07_model (3).ipynb", "ex07_model-2.ipynb", "ex07_model.ipynb")]
[3, 2, 0]
"""

from __future__ import annotations

import os
import re
import shlex
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .spec import Exercise
from .student import locate_notebook

__all__ = [
    "LayoutReport",
    "Rename",
    "canonical",
    "check_layout",
    "copy_number",
    "expected_layout",
    "match_exercise",
    "suggest_rename",
    "suggest_student_id",
    "student_id_problem",
]

# one copy marker at the end of a stem: " (1)", "-2", "_2", " 2", " - Copy", "copy 3"
_COPY = re.compile(r"(?:\s*\((\d{1,3})\)|[-_ ](\d{1,3})|\s*-?\s*copy(?:\s*(\d{1,3}))?)$", re.IGNORECASE)
_SEP = re.compile(r"[\s\-_.]+")
_IGNORED_PARTS = ("__MACOSX", ".ipynb_checkpoints", "__pycache__")
# LMS prefixes of a flat download: Canvas "<name>_[LATE_]<user id>_<submission id>_", Moodle
# "<Full Name>_<id>_assignsubmission_file_"
_CANVAS_TAIL = re.compile(r"(?:_late)?(?:_\d+){1,2}$", re.IGNORECASE)
_MOODLE_TAIL = re.compile(r"_\d+_assignsubmission(?:_\w*)?$", re.IGNORECASE)


def _stem(name: str) -> str:
    return name[: -len(".ipynb")] if name.lower().endswith(".ipynb") else name


def canonical(name: str) -> str:
    """A file name reduced for matching: no ``.ipynb``, no copy suffixes, lower case, ``_`` separators."""
    stem = _stem(str(name)).strip()
    while True:
        new = _COPY.sub("", stem).strip()
        if new == stem or not new:
            break
        stem = new
    return _SEP.sub("_", stem.lower()).strip("_")


def copy_number(name: str) -> int:
    """The number of the last copy marker of ``name`` (``name (3)`` -> 3, ``name - Copy`` -> 1), else 0."""
    m = _COPY.search(_stem(str(name)).strip())
    if not m:
        return 0
    num = next((g for g in m.groups() if g), None)
    return int(num) if num else 1


@dataclass(frozen=True)
class Rename:
    """A renamed copy ``found`` (relative to the student folder) standing for ``expected``."""

    student: str
    exercise_id: str
    expected: str
    found: str
    reason: str
    original: str | None = None  # the expected file when it is there too (older than ``found``)

    def __str__(self) -> str:
        return f"{self.student}/{self.found} -> {self.student}/{self.expected} ({self.reason})"


@dataclass
class LayoutReport:
    """What :func:`check_layout` found; ``messages()`` is the text shown before grading."""

    submissions: Path
    students: list[str] = field(default_factory=list)
    flat: dict[str, str] = field(default_factory=dict)  # top-level notebook -> suggested <student>/<nb>
    flat_unmatched: list[str] = field(default_factory=list)  # top-level files matching no exercise
    unusable: dict[str, str] = field(default_factory=dict)  # folder -> why it cannot be an id
    lms_folders: dict[str, str] = field(default_factory=dict)  # LMS download folder -> suggested id
    renamed: list[Rename] = field(default_factory=list)
    ambiguous: dict[tuple[str, str], list[str]] = field(default_factory=dict)  # other candidates
    older_copies: dict[tuple[str, str], list[str]] = field(default_factory=dict)  # behind the expected file
    unknown: dict[str, list[str]] = field(default_factory=dict)  # student -> files
    missing: dict[str, list[str]] = field(default_factory=dict)  # student -> exercise ids
    found: dict[str, int] = field(default_factory=dict)  # student -> notebooks at the expected place

    @property
    def blocking(self) -> bool:
        """True when grading would grade nobody's work: no usable student folder with a notebook."""
        return bool(self.flat or self.unusable) and not any(self.found.values())

    def renamed_for(self, student: str) -> dict[str, str]:
        """``{exercise id: path relative to the student folder}`` of ``student``'s renamed copies."""
        return {r.exercise_id: r.found for r in self.renamed if r.student == student}

    def renamed_map(self) -> dict[str, dict[str, str]]:
        """``{student: renamed_for(student)}`` for every student with a renamed copy."""
        return {s: self.renamed_for(s) for s in sorted({r.student for r in self.renamed})}

    def ignored_for(self, student: str, *, accept_renamed: bool = False) -> dict[str, list[str]]:
        """``{exercise id: [paths relative to the student folder]}``: the files of ``student`` that
        stand for an exercise but are not the one graded (the feedback names them). With
        ``accept_renamed`` the best copy is graded and the others (the expected file included) are
        ignored; without it only the expected file is graded and every renamed copy is ignored."""
        out: dict[str, list[str]] = {}
        for r in self.renamed:
            if r.student != student:
                continue
            others = self.ambiguous.get((student, r.exercise_id), [])
            if accept_renamed:
                out[r.exercise_id] = list(others)
            else:
                out[r.exercise_id] = [r.found, *(o for o in others if o != r.original)]
        for (s, ex_id), older in self.older_copies.items():
            if s == student:
                out[ex_id] = list(older)
        return out

    def ignored_map(self, *, accept_renamed: bool = False) -> dict[str, dict[str, list[str]]]:
        """``{student: ignored_for(student)}`` for every student with ignored files."""
        out = {s: self.ignored_for(s, accept_renamed=accept_renamed) for s in self.students}
        return {s: v for s, v in out.items() if v}

    def messages(self, exercises: Sequence[Exercise], *, accept_renamed: bool = False) -> list[str]:
        """Human-readable warnings (empty when the layout is as expected)."""
        sub = str(self.submissions)
        q = shlex.quote
        out: list[str] = []
        if self.flat or self.flat_unmatched:
            out.append(
                f"layout: {len(self.flat) + len(self.flat_unmatched)} file(s) directly in {sub}: "
                "notebooks must be in one folder per student. Expected layout:\n" + expected_layout(exercises)
            )
            if self.flat:
                out.append("layout: suggested moves (check the student ids; <student> = could not tell):")
                for f, dest in sorted(self.flat.items()):
                    d = Path(sub) / dest
                    out.append(f"  mkdir -p {q(str(d.parent))} && mv {q(str(Path(sub) / f))} {q(str(d))}")
            if self.flat_unmatched:
                out.append("layout: files matching no exercise: " + ", ".join(sorted(self.flat_unmatched)))
        if self.unusable:
            out.append(f"layout: {len(self.unusable)} student folder(s) NOT graded: their names cannot be "
                       "student ids (rename them and grade again):")
            for f, why in sorted(self.unusable.items()):
                out.append(f"  {f!a}: {why}")
        if self.lms_folders:
            out.append(
                f"layout: {len(self.lms_folders)} folder name(s) look like an LMS download's; they are "
                "graded under these names (the id in grades.csv and the roster join); to use the "
                "roster's ids instead, rename them:"
            )
            for f, new in sorted(self.lms_folders.items()):
                out.append(f"  mv {q(str(Path(sub) / f))} {q(str(Path(sub) / new))}")
        if self.renamed:
            verb = (
                "graded in place of the missing notebook (--accept-renamed)"
                if accept_renamed
                else (
                    "NOT graded (the notebook counts as not submitted); rename it, or grade the best match "
                    "with --accept-renamed"
                )
            )
            out.append(f"layout: {len(self.renamed)} renamed copy(ies) of expected notebooks, {verb}:")
            for r in self.renamed:
                line = f"  {r}"
                if r.original is not None:
                    line += f"; newer than the expected {r.original}, which is " + (
                        "ignored" if accept_renamed else "graded instead")
                others = [o for o in self.ambiguous.get((r.student, r.exercise_id), []) if o != r.original]
                if others:
                    line += f"; also found {', '.join(others)} (ignored)"
                out.append(line)
            if not accept_renamed:
                out.append("layout: suggested renames (a resubmission replaces the older expected file):")
                for r in self.renamed:
                    src, dst = Path(sub) / r.student / r.found, Path(sub) / r.student / r.expected
                    out.append(f"  mv {q(str(src))} {q(str(dst))}")
        if self.unknown:
            n = sum(len(v) for v in self.unknown.values())
            shown = [f"{s}/{f}" for s, files in sorted(self.unknown.items()) for f in files]
            more = f" (and {len(shown) - 10} more)" if len(shown) > 10 else ""
            out.append(f"layout: {n} unknown file(s) ignored: {', '.join(shown[:10])}{more}")
        return out


def expected_layout(exercises: Sequence[Exercise]) -> str:
    """The expected tree of SUBMISSIONS as indented text."""
    lines = ["  SUBMISSIONS/", "    <student>/"]
    lines += [f"      {ex.notebook}" for ex in exercises]
    return "\n".join(lines)


def match_exercise(name: str, exercises: Sequence[Exercise]) -> tuple[Exercise, str] | None:
    """The exercise a (possibly renamed or LMS-prefixed) notebook file name stands for.

    Returns ``(exercise, prefix)`` with the canonical text before the exercise's name (an LMS prefix,
    ``""`` for a plain copy), or None. Only ``.ipynb`` files match; the longest exercise name wins.

    >>> from flowtrack_course.grading.engine.spec import Exercise
    >>> ex = Exercise("ex07", "Some model", "ex07_some_model.ipynb", ("a",), (), ())
    >>> match_exercise("doejane_LATE_123_456_ex07_some_model-1.ipynb", [ex])[1]
    'doejane_late_123_456'
    """
    if not str(name).lower().endswith(".ipynb"):
        return None
    c = canonical(name)
    best: tuple[Exercise, str, int] | None = None
    for ex in exercises:
        e = canonical(Path(ex.notebook).name)
        if c == e:
            return ex, ""
        if c.endswith("_" + e) and (best is None or len(e) > best[2]):
            best = (ex, c[: -len(e) - 1], len(e))
    return None if best is None else (best[0], best[1])


def suggest_student_id(prefix: str) -> str:
    """A student id from an LMS file-name prefix or folder name (``<student>`` when none is left):
    the LMS' id and submission numbers removed, letters of every script kept.

    >>> suggest_student_id("doejane_LATE_12345_67890")
    'doejane'
    >>> suggest_student_id("Jane Doe_4242_assignsubmission_file_")
    'Jane Doe'
    >>> suggest_student_id("José Müller_77_assignsubmission_file_")
    'José Müller'
    """
    p = str(prefix).strip(" _-")
    p = _MOODLE_TAIL.sub("", p)
    p = _CANVAS_TAIL.sub("", p)
    p = " ".join(re.sub(r"[^\w.@+\- ]+", "_", p).split()).strip("_.- ")[:128]
    return p if p and not student_id_problem(p) and not p.startswith(".") else "<student>"


def student_id_problem(name: str) -> str:
    """Why a folder name cannot be a student id ("" when it can: any name is an id as it is,
    spaces, accents and other scripts included; only what no CSV, feedback page or LMS could carry
    is refused).

    >>> student_id_problem("José Müller"), student_id_problem("李雷"), student_id_problem("a@b.org")
    ('', '', '')
    >>> student_id_problem("bad\\nname")
    'it holds control characters (a new line, a tab, ...)'
    """
    name = str(name)
    if not name.strip():
        return "it is empty or only spaces"
    if any(0xD800 <= ord(c) <= 0xDFFF for c in name):
        return "it holds bytes that are not UTF-8 text (rename it in UTF-8)"
    joiners = "\u200c\u200d"  # zero-width (non-)joiners: part of how some scripts write names
    if any(unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp", "Cs", "Co", "Cn") and c not in joiners
           for c in name):
        return "it holds control characters (a new line, a tab, ...)"
    if len(name) > 200:
        return "it is longer than 200 characters"
    return ""


def _files(folder: Path) -> list[Path]:
    """Regular files below ``folder`` (relative paths), skipping hidden and OS/Jupyter clutter."""
    out = []
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and d not in _IGNORED_PARTS)
        for f in sorted(filenames):
            if f.startswith(".") or f in ("Thumbs.db", "desktop.ini"):
                continue
            out.append((Path(dirpath) / f).relative_to(folder))
    return out


def _inside(root: Path, rel: Path) -> bool:
    p = root / rel
    try:
        return p.is_file() and p.resolve().is_relative_to(root.resolve())
    except (OSError, RuntimeError):
        return False


def _best(root: Path, cands: list[Path]) -> list[Path]:
    """Candidates best first: highest copy number (latest resubmission), then newest, then name."""

    def key(p: Path):
        try:
            mtime = (root / p).stat().st_mtime
        except OSError:
            mtime = 0.0
        return (-copy_number(p.name), -mtime, str(p))

    return sorted(cands, key=key)


def _check_student(report: LayoutReport, student: str, folder: Path, exercises: Sequence[Exercise]) -> None:
    files = _files(folder)
    used: set[Path] = set()
    report.found[student] = 0
    for ex in exercises:
        located = locate_notebook(folder, ex)
        original = None
        if located.is_file():
            report.found[student] += 1
            original = located.relative_to(folder) if located.is_relative_to(folder) else located
            used.add(original)
        cands = [rel for rel in files
                 if rel != original and match_exercise(rel.name, [ex]) is not None and _inside(folder, rel)]
        if not cands:
            if original is None:
                report.missing.setdefault(student, []).append(ex.id)
            continue
        used.update(cands)
        # the expected name has copy number 0: a numbered resubmission (or a newer same-named copy)
        # is the student's latest work even while the first submission is still there
        ordered = _best(folder, cands + ([original] if original is not None else []))
        best = ordered[0]
        if best == original:
            report.older_copies[(student, ex.id)] = [p.as_posix() for p in ordered[1:]]
            continue
        expected_name = Path(ex.notebook).name
        if best.name.lower() == expected_name.lower() and best.name != expected_name:
            reason = "case differs"
        elif copy_number(best.name):
            reason = f"resubmission copy {copy_number(best.name)}, as Canvas and Moodle name them"
        else:
            reason = "renamed"
        report.renamed.append(Rename(student, ex.id, ex.notebook, best.as_posix(), reason,
                                     original.as_posix() if original is not None else None))
        if len(ordered) > 1:
            report.ambiguous[(student, ex.id)] = [p.as_posix() for p in ordered[1:]]
    unknown = [rel.as_posix() for rel in files if rel not in used]
    if unknown:
        report.unknown[student] = unknown


def check_layout(submissions: str | os.PathLike, exercises: Sequence[Exercise]) -> LayoutReport:
    """Inspect ``submissions`` (names and file metadata only; nothing is opened) before grading.

    Raises
    ------
    FileNotFoundError
        ``submissions`` is not a folder.
    """
    root = Path(submissions)
    if not root.is_dir():
        raise FileNotFoundError(f"submissions: no such folder: {root}")
    report = LayoutReport(root)
    for entry in sorted(root.iterdir()):
        if entry.name.startswith(".") or entry.name in _IGNORED_PARTS:
            continue
        if entry.is_dir():
            why = student_id_problem(entry.name)
            if why:
                report.unusable[entry.name] = why
                continue
            if _MOODLE_TAIL.search(entry.name.rstrip(" _-")):
                suggested = suggest_student_id(entry.name)
                if suggested != "<student>":
                    report.lms_folders[entry.name] = suggested
            report.students.append(entry.name)
            _check_student(report, entry.name, entry, exercises)
        elif entry.is_file():
            m = match_exercise(entry.name, exercises)
            if m is None:
                report.flat_unmatched.append(entry.name)
            else:
                ex, prefix = m
                report.flat[entry.name] = f"{suggest_student_id(prefix)}/{ex.notebook}"
    return report


def suggest_rename(notebook: str | os.PathLike, exercises: Sequence[Exercise]) -> tuple[Exercise, str] | None:
    """``(exercise, note)`` when ``notebook``'s file name is a renamed copy of an exercise notebook.

    The note tells the student the grader will not find the file under this name and gives the
    ``mv`` command (``flowtrack check`` prints it).
    """
    path = Path(notebook)
    m = match_exercise(path.name, exercises)
    if m is None or path.name == Path(m[0].notebook).name:
        return None
    ex = m[0]
    target = path.with_name(Path(ex.notebook).name)
    note = (
        f"NOTE: {path.name!r} looks like a renamed copy of {Path(ex.notebook).name!r} "
        f"(exercise {ex.id}); the grader only finds the notebook under its original name. "
        "Rename it before submitting:\n"
        f"  mv {shlex.quote(str(path))} {shlex.quote(str(target))}"
    )
    return ex, note
