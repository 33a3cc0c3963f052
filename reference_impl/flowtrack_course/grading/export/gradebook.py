"""The nbgrader gradebook of a ``flowtrack grade`` run (``out/gradebook.db``).

The database is written through nbgrader's own :class:`nbgrader.api.Gradebook`, so every nbgrader tool
reads it: ``nbgrader export --db sqlite:///out/gradebook.db`` (CSV of the class) or the formgrader.
Layout: one assignment (``"flowtrack"`` unless told otherwise); one notebook per exercise, named
after the notebook's file name without ``.ipynb`` (nbgrader's convention); one code grade cell per
``grade_id`` of the exercise's tests with ``max_score`` = the sum of those tests' points (the points
an nbgrader author writes into the cell's metadata); one student and one submission per student with
the grader's scores as ``auto_score``. The whole database is rebuilt from the students'
``results.json`` on every run (written to a temporary file, then moved into place), so it always
matches ``grades.csv``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

from ..engine.results import student_folder
from ..engine.spec import Exercise

__all__ = ["grade_cells", "notebook_name", "write_gradebook"]


def notebook_name(exercise: Exercise) -> str:
    """nbgrader's notebook name: the notebook's file name without ``.ipynb``.

    An exercise answered in another file (a source file in another language: ``cv_model.cpp`` and
    ``cv_model.m`` share a stem) uses its id.
    """
    if not exercise.notebook.endswith(".ipynb"):
        return exercise.id
    return Path(exercise.notebook).stem


def grade_cells(exercise: Exercise) -> dict[str, float]:
    """``{grade_id: max_score}`` in test order: the points of the tests standing for each cell."""
    cells: dict[str, float] = {}
    for t in exercise.tests:
        cells[t.grade_id] = cells.get(t.grade_id, 0.0) + float(t.points)
    return cells


def _roster_fields(roster: dict | None, student: str) -> dict:
    """nbgrader Student fields (first_name, last_name, email, lms_user_id) from a roster entry."""
    from .lms import roster_entry

    entry = roster_entry(roster or {}, student)
    return entry.nbgrader_fields() if entry is not None else {}


def _cell_scores(results_path: Path) -> dict[tuple[str, str], float] | None:
    """``{(exercise_id, grade_id): score}`` from a student's results.json (None when unreadable)."""
    try:
        data = json.loads(results_path.read_text(encoding="utf-8"))
        scores: dict[tuple[str, str], float] = {}
        for t in data["tests"]:
            key = (t["extra_data"]["exercise"], t["extra_data"]["grade_id"])
            scores[key] = scores.get(key, 0.0) + float(t["score"])
        return scores
    except (OSError, ValueError, KeyError, TypeError):
        return None


_REVISION = re.compile(r"^(down_revision|revision)\s*=\s*(?:'([0-9a-f]+)'|\"([0-9a-f]+)\"|None)", re.M)


def _alembic_head() -> str | None:
    """The head of nbgrader's alembic migrations, read from its version files (None if unclear).

    nbgrader stamps a new gradebook with this revision by running the ``alembic heads`` command in a
    subprocess (seconds on a loaded machine); reading the files gives the same answer at once.
    """
    import nbgrader

    revisions, parents = set(), set()
    for f in (Path(nbgrader.__file__).parent / "alembic" / "versions").glob("*.py"):
        for kind, a, b in _REVISION.findall(f.read_text(encoding="utf-8")):
            if a or b:
                (revisions if kind == "revision" else parents).add(a or b)
    heads = revisions - parents
    return heads.pop() if len(heads) == 1 else None


@contextlib.contextmanager
def _alembic_on_path() -> Iterator[None]:
    """Let nbgrader find its alembic revision: read from its files, else the ``alembic`` command
    beside this interpreter (its folder is put on PATH)."""
    import nbgrader.api

    old = os.environ.get("PATH", "")
    bindir = str(Path(sys.executable).parent)
    os.environ["PATH"] = bindir + os.pathsep + old if old else bindir
    original = nbgrader.api.get_alembic_version
    head = _alembic_head()
    if head is not None:
        nbgrader.api.get_alembic_version = lambda: head
    try:
        with warnings.catch_warnings():
            # nbgrader's add_submission builds objects in a way SQLAlchemy 2 warns about (harmless)
            warnings.filterwarnings("ignore", message=".*not in session.*")
            yield
    finally:
        nbgrader.api.get_alembic_version = original
        os.environ["PATH"] = old


def _nbgrader_api():
    """``nbgrader.api``, imported without jsonschema's IRI format checker when jsonschema is not
    imported yet: its ``rfc3987_syntax`` compiles grammars at import (about 1 s of CPU, half the
    import), and nothing here validates an IRI."""
    if "nbgrader.api" in sys.modules or "jsonschema" in sys.modules or "rfc3987_syntax" in sys.modules:
        import nbgrader.api

        return nbgrader.api
    sys.modules["rfc3987_syntax"] = None  # type: ignore[assignment]  # an ImportError, which jsonschema skips
    try:
        import nbgrader.api
    finally:
        if sys.modules.get("rfc3987_syntax", 0) is None:
            del sys.modules["rfc3987_syntax"]
    return nbgrader.api


def write_gradebook(
    path: str | os.PathLike,
    exercises: Sequence[Exercise],
    out: str | os.PathLike,
    students: Sequence[str],
    *,
    assignment: str = "flowtrack",
    roster: dict | None = None,
) -> Path:
    """(Re)build the nbgrader gradebook at ``path`` from ``out/<student>/results.json``.

    Students without a readable results.json get a student entry and no submission (nbgrader then
    exports 0 for them). ``roster`` (``{student: RosterEntry}``, :func:`.lms.read_roster`) fills the
    students' names and e-mails, so ``nbgrader export`` has them. Returns ``path``.
    """
    Gradebook = _nbgrader_api().Gradebook
    from sqlalchemy import text

    if not assignment or not isinstance(assignment, str):
        raise ValueError(f"assignment must be a non-empty string, got {assignment!r}")
    path = Path(path)
    names = [notebook_name(ex) for ex in exercises]
    if len(set(names)) != len(names):
        raise ValueError(f"exercises: notebook file names must be unique for nbgrader, got {names}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".gradebook.", suffix=".db", dir=path.parent)
    os.close(fd)
    os.unlink(tmp)
    try:
        with _alembic_on_path(), Gradebook(f"sqlite:///{tmp}") as gb:
            # a temporary file moved into place at the end: no need to sync every commit
            gb.db.execute(text("PRAGMA synchronous=OFF"))
            # the only writer of a new file: objects need not be re-read after each commit (without
            # this add_submission re-loads the assignment's notebooks and cells for every student)
            gb.db.registry().expire_on_commit = False
            gb.add_assignment(assignment)
            for ex in exercises:
                nb = notebook_name(ex)
                gb.add_notebook(nb, assignment)
                for gid, points in grade_cells(ex).items():
                    gb.add_grade_cell(gid, nb, assignment, max_score=points, cell_type="code")
            ex_of = {notebook_name(ex): ex.id for ex in exercises}
            for student in students:
                gb.add_student(student, **_roster_fields(roster, student))
                scores = _cell_scores(Path(out) / student_folder(student) / "results.json")
                if scores is None:
                    continue
                # the submission's grades as add_submission made them (one per grade cell of each
                # notebook), filled in place: no query per grade (find_grade)
                for nb in gb.add_submission(assignment, student).notebooks:
                    for grade in nb.grades:
                        grade.auto_score = scores.get((ex_of[nb.name], grade.name), 0.0)
            gb.db.commit()
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
