"""Grading one student's folder (:func:`grade_student`): where the notebooks are, whether earlier
results still stand, each exercise in the sandbox, and the student's outputs::

    out/<student>/results.json                Gradescope format; written last and atomically
    out/<student>/feedback/<exercise>.md      what the student may see

(``<student>`` is :func:`~.results.student_folder` of the student's id: the id itself when it is
plain ASCII.)

A student whose ``results.json`` is complete and was made from the same exercises, the same
submitted files and the same key is kept (unless ``force``): a run killed halfway and restarted
loses no finished student, and a second run changes nothing.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from grading_sandbox import SandboxConfigError

from .jobs import StudentJob
from .results import (
    ExerciseResult,
    TestResult,
    feedback_markdown,
    read_results,
    results_json,
    round_score,
    student_folder,
    write_atomic,
)
from .run import preload_modules, run_exercise
from .spec import CannotGradeHere, Exercise

__all__ = [
    "exercises_hash",
    "failure_signature",
    "grade_student",
    "locate_notebook",
    "locate_notebooks",
    "submission_hash",
]


def locate_notebook(student_dir: Path, exercise: Exercise) -> Path:
    """Where ``exercise``'s file is in a student's folder.

    ``student_dir/<exercise.notebook>`` (the bundle's layout), else
    ``student_dir/<exercise id>/<file name>`` (the course's layout, one folder per exercise), else
    the only file of that name below ``student_dir`` (Gradescope uploads are often flat). Returns the
    expected path when nothing is found. A file reached through a symlink that leads outside
    ``student_dir`` (another student's work, a file of the grading machine) does not count as
    submitted.
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
    in_folder = Path(student_dir) / exercise.id / name
    if inside(in_folder):
        return in_folder
    found = sorted(
        p for p in Path(student_dir).rglob(name) if "__MACOSX" not in p.parts and inside(p)
    )
    if found:
        return found[0]
    if os.path.lexists(expected):  # a link leading outside: report it, never read it
        return expected.with_name(f"{expected.name} (a link leading outside the submission)")
    return expected


def locate_notebooks(
    student_dir: str | os.PathLike,
    exercises: Sequence[Exercise],
    renamed: Mapping[str, str] | None = None,
    ignored: Mapping[str, Sequence[str]] | None = None,
) -> tuple[dict[str, Path], dict[str, list[str]]]:
    """``({exercise id: path}, {exercise id: notes})`` of a student's files.

    ``renamed`` (``{exercise id: path relative to the folder}``, the instructor's
    ``--accept-renamed``) stands in for an exercise's notebook when it is a file inside the folder:
    a renamed copy of a missing notebook, or a resubmission newer than the file under the expected
    name. ``ignored`` (``{exercise id: [paths]}``) are the other files that stand for it. The notes
    (that exercise's feedback) name the file graded and the files ignored.
    """
    folder = Path(student_dir)
    notebooks = {ex.id: locate_notebook(folder, ex) for ex in exercises}
    notes: dict[str, list[str]] = {}
    root = folder.resolve()
    by_id = {ex.id: ex for ex in exercises}
    for ex_id, rel in (renamed or {}).items():
        path = folder / rel
        try:
            ok = path.is_file() and path.resolve().is_relative_to(root)
        except (OSError, RuntimeError):
            ok = False
        if not ok or ex_id not in notebooks:
            continue
        notebooks[ex_id] = path
        shown = path.relative_to(folder).as_posix()
        notes[ex_id] = [
            f"graded `{shown}` in place of the expected `{by_id[ex_id].notebook}` (the newest copy: the "
            "highest copy number, then the newest file; renamed copies accepted by the instructor, "
            "--accept-renamed); please submit under the expected name next time"
        ]
    for ex_id, files in (ignored or {}).items():
        if ex_id not in notebooks or not files:
            continue
        graded = notebooks[ex_id]
        shown = graded.relative_to(folder).as_posix() if graded.is_relative_to(folder) else graded.name
        names = ", ".join(f"`{f}`" for f in files)
        if ex_id in notes:
            lead = ""
        elif graded.is_file():
            lead = f"graded `{shown}`; "
        else:
            lead = f"`{by_id[ex_id].notebook}` was not submitted under its expected name; "
        notes.setdefault(ex_id, []).append(
            f"{lead}ignored {names}: one file per exercise is graded (the one under the expected name "
            "unless the instructor accepts renamed copies, --accept-renamed; then the highest copy "
            "number, then the newest file)"
        )
    return notebooks, notes


def exercises_hash(exercises: Sequence[Exercise]) -> str:
    """sha256 of the exercises' definitions and of the source files their tests are built in.

    A change of any test, point value, notebook path or of the module defining the tests changes it,
    so finished students are re-graded after the tests change. An exercise may name more files its
    grading depends on (:meth:`~.spec.Exercise.source_files`).
    """
    from grading_sandbox import formula

    from . import authoring, symbolic

    h = hashlib.sha256()
    files: set[str] = set()
    for ex in exercises:
        desc = [ex.id, ex.notebook, list(ex.answer_cells), list(ex.blocked)]
        desc += [list(ex.allowed)] if ex.allowed else []
        desc += [[t.name, t.grade_id, float(t.points), bool(t.hidden), float(t.timeout)] for t in ex.tests]
        h.update(json.dumps(desc).encode())
        files.update(str(p) for p in ex.source_files())
        for t in ex.tests:
            for fn in (t.build, inspect.unwrap(t.build)):  # the scoring helpers and the test's module
                try:
                    src = inspect.getsourcefile(fn)
                except TypeError:
                    src = None
                if src:
                    files.add(src)
    # the formula reader the sandbox runs for symbolic answers, and the grader's side of it
    files.update(str(Path(m.__file__)) for m in (formula, symbolic, authoring))
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


def failure_signature(result: ExerciseResult) -> str:
    """How an exercise failed, in words that do not depend on the student's hidden inputs when the
    cause is not the student's answer: "" when a test earned points or the answer is the released
    stub (``NotImplementedError``), else the sorted distinct problems and hidden-safe messages.

    Every student of a class failing an exercise with the same signature points at the grader's
    environment (a sandbox that cannot start, a library it cannot load), not at their work.
    """
    if result.score > 0 or not result.tests:
        return ""
    texts = [*result.problems, *(t.safe_message or t.message for t in result.tests)]
    sig = " | ".join(sorted(set(texts)))
    return "" if "NotImplementedError" in sig else sig[:500]


def grade_student(job: StudentJob, sandbox_pool: Any = None) -> dict:
    """Grade one student's folder; write ``out/<student>/feedback/*`` then ``results.json``.

    An earlier ``results.json`` that is not kept is removed before grading starts, so a student
    whose grading fails halfway has none (never a stale one). Results made with another key (or
    none) are not kept on a re-run. With ``job.options.reuse_sandboxes`` (default, with the real
    sandbox) the exercises run in the sandboxes of a :class:`grading_sandbox.SandboxPool` (one
    sandboxed process per kind of exercise that forks a clean child per exercise): ``sandbox_pool``
    when given (a class run shares one per worker process between students), else one for this
    student; it scores the same as a fresh sandbox per exercise and saves most of the start-up time.

    Returns
    -------
    dict
        ``{"student", "skipped", "score", "max_score", "exercises": {id: score}, "isolation",
        "failures": {id: signature}}`` (``failures``: the exercises the student submitted, with
        :func:`failure_signature`, "" where it earned points).

    Raises
    ------
    grading_sandbox.SandboxConfigError
        The sandbox cannot import what an exercise allows: the grader's environment (nothing is
        written for this student).
    """
    from .seeds import secret_id

    options = job.options
    exercises = tuple(job.exercises)
    dest = Path(job.out) / student_folder(job.student)
    ex_hash = job.exercises_hash or exercises_hash(exercises)
    notebooks, notes = locate_notebooks(job.folder, exercises, job.renamed, job.ignored)
    sub_hash = submission_hash(notebooks)
    key_id = secret_id(options.secret)
    results_path = dest / "results.json"
    if not options.force:
        old = read_results(results_path)
        if old is not None:
            info = old["extra_data"]["flowtrack"]
            if (
                info.get("exercises_hash") == ex_hash
                and info.get("submission_hash") == sub_hash
                and info.get("secret_id", "") == key_id
            ):
                return {
                    "student": job.student,
                    "skipped": True,
                    "score": float(old["score"]),
                    "max_score": float(info["max_score"]),
                    "exercises": {k: v["score"] for k, v in info["exercises"].items()},
                    "isolation": info.get("isolation", ""),
                    "failures": dict(info.get("failures") or {}),
                }
    results_path.unlink(missing_ok=True)
    results = []
    pool = None
    factory = options.sandbox_factory
    if factory is None and options.reuse_sandboxes:
        if sandbox_pool is not None:
            factory = sandbox_pool
        else:
            from grading_sandbox import SandboxPool

            pool = factory = SandboxPool(preload_modules(exercises))
    try:
        for ex in exercises:
            try:
                r = run_exercise(ex, notebooks[ex.id], job.student, options=options, sandbox_factory=factory)
            except (SandboxConfigError, CannotGradeHere):  # the grader's environment: no results
                raise
            except Exception as exc:  # one broken exercise must not lose the others
                r = ExerciseResult(ex.id, ex.title, ex.notebook)
                r.problems.append(f"internal grader error: {type(exc).__name__}: {exc}")
                r.tests = [TestResult(t.name, t.grade_id, 0.0, float(t.points), t.hidden, r.problems[0])
                           for t in ex.tests]
            r.problems[:0] = notes.get(ex.id, [])
            results.append(r)
    finally:
        if pool is not None:
            pool.close()
    isolation = next((r.isolation for r in results if r.isolation.startswith("fallback")), "")
    isolation = isolation or next((r.isolation for r in results if r.isolation), "")
    failures = {r.exercise_id: failure_signature(r) for r in results if notebooks[r.exercise_id].is_file()}
    data = results_json(
        job.student,
        results,
        hidden_visibility=options.hidden_visibility,
        extra={
            "exercises_hash": ex_hash,
            "submission_hash": sub_hash,
            "secret_id": key_id,
            "isolation": isolation,
            "failures": failures,
        },
        notes=job.notes,
    )
    for r in results:
        write_atomic(dest / "feedback" / f"{r.exercise_id}.md", feedback_markdown(job.student, r, job.notes))
    write_atomic(results_path, json.dumps(data, indent=1))
    return {
        "student": job.student,
        "skipped": False,
        "score": data["score"],
        "max_score": data["extra_data"]["flowtrack"]["max_score"],
        "exercises": {r.exercise_id: round_score(r.score) for r in results},
        "isolation": isolation,
        "failures": failures,
    }
