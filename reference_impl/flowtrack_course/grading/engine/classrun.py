"""Grading a class (:func:`run_class`): every student folder of SUBMISSIONS, in worker processes.

Outputs (``out`` is the ``--out`` folder)::

    out/grades.csv                 student, one column per exercise id, total, max
    out/<student>/...              see :mod:`.student`

(The nbgrader gradebook and the reports are the exports', written by the command that runs this.)
Student code runs under bubblewrap; where it cannot (:func:`grading_sandbox.choose_mode`) the run
stops with :class:`UnsafeSandbox` unless the job allows the fallback. Each worker process grades one
student after the other with :func:`~.student.grade_student`; a worker receives a
:class:`~.jobs.StudentJob` whose exercises it looks up by id in the job's catalog (picklable: it
discovers the course again, once per process).
"""

from __future__ import annotations

import csv
import io
import os
import sys
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from flowtrack.validation import positive_int

from .jobs import ClassJob, StudentJob
from .layout import student_id_problem
from .results import format_score, round_score, student_folder, write_atomic
from .run import check_environment, preload_modules
from .spec import CannotGradeHere, Exercise
from .student import exercises_hash, grade_student

__all__ = [
    "GRADER_RESERVE",
    "OUTPUT_FILES",
    "RESERVED_NAMES",
    "UnsafeSandbox",
    "close_shared_pools",
    "list_students",
    "run_class",
    "uniform_failures",
    "unusable_students",
]

#: Every file a class run (``flowtrack grade``) writes into its output folder beside the student
#: folders, by role: the commands and exports take the names from here.
OUTPUT_FILES = {
    "grades": "grades.csv",
    "gradebook": "gradebook.db",
    "misconceptions": "misconceptions.csv",
    "class_report": "class_report.md",
    "canvas": "canvas.csv",
    "moodle": "moodle.csv",
}
# A student folder named like one of them (or SQLite's files beside the gradebook) is refused: it
# would turn the grader's own output into a folder.
RESERVED_NAMES = frozenset(
    {*OUTPUT_FILES.values(), "gradebook.db-journal", "gradebook.db-wal", "gradebook.db-shm"}
)
#: disk space the grader keeps for its outputs where students write to the same filesystem
GRADER_RESERVE = 32 << 20


class UnsafeSandbox(RuntimeError):
    """A class run where bubblewrap cannot isolate student code, and the fallback was not allowed."""


def list_students(submissions: str | os.PathLike) -> list[str]:
    """The student ids of ``submissions``: its folders' names, as they are (spaces, accents and any
    script included), sorted; hidden folders and names that cannot be ids
    (:func:`~.layout.student_id_problem`, reported by :func:`unusable_students`) are left out.

    Raises
    ------
    FileNotFoundError
        ``submissions`` is not a folder.
    """
    root = Path(submissions)
    if not root.is_dir():
        raise FileNotFoundError(f"submissions: no such folder: {root}")
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    return [n for n in names if not student_id_problem(n)]


def unusable_students(submissions: str | os.PathLike) -> dict[str, str]:
    """``{folder name: why}`` of the folders of ``submissions`` that cannot be student ids."""
    root = Path(submissions)
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    return {n: why for n in names if (why := student_id_problem(n))}


_POOLS: dict[tuple, Any] = {}


def _shared_pool(preload: tuple[str, ...]) -> Any:
    """This process's :class:`grading_sandbox.SandboxPool` (a grading worker's): its zygotes serve
    one student after the other; closed when the process exits."""
    pool = _POOLS.get(preload)
    if pool is None:
        from multiprocessing import util

        from grading_sandbox import SandboxPool

        pool = _POOLS[preload] = SandboxPool(preload)
        util.Finalize(None, pool.close, exitpriority=10)  # run at a worker's exit (atexit is not)
    return pool


def close_shared_pools() -> None:
    """Kill the sandboxes of this process's shared pools."""
    pools = list(_POOLS.values())
    _POOLS.clear()
    for pool in pools:
        pool.close()


@dataclass(frozen=True)
class _Task:
    """What a worker process receives: a student's job whose exercises are given by id, and where
    to look them up."""

    job: StudentJob
    exercise_ids: tuple[str, ...]
    catalog: Any


def _grade(job: StudentJob) -> dict:
    """Grade one student; an error is reported in the summary (the class goes on) and leaves no
    results.json of an earlier run standing for this one."""
    from grading_sandbox import SandboxConfigError

    try:
        pool = None
        if job.options.reuse_sandboxes and job.options.sandbox_factory is None:
            pool = _shared_pool(preload_modules(job.exercises))
        return grade_student(job, sandbox_pool=pool)
    except (SandboxConfigError, CannotGradeHere) as exc:  # the grader's environment: said once
        return {"student": job.student, "error": str(exc), "config_error": True}
    except Exception as exc:
        try:
            (Path(job.out) / student_folder(job.student) / "results.json").unlink(missing_ok=True)
        except OSError:
            pass
        return {"student": job.student, "error": f"{type(exc).__name__}: {exc}"}


def _worker(task: _Task) -> dict:
    """A worker process's task: the exercises looked up by id in the catalog, then :func:`_grade`."""
    try:
        exercises = tuple(task.catalog.get(i) for i in task.exercise_ids)
    except Exception as exc:
        return {"student": task.job.student, "error": f"{type(exc).__name__}: {exc}"}
    return _grade(replace(task.job, exercises=exercises))


def _write_grades_csv(path: Path, rows: Iterable[dict], exercises: Sequence[Exercise],
                      assigned: dict[str, Sequence[Exercise]] | None = None) -> None:
    """``grades.csv``: a column per exercise of the run; a student's cell is blank for an exercise not
    assigned to them (another language than the one they chose), and their ``max`` counts only the
    exercises assigned to them (``assigned``: ``{student: exercises}``; default: all)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["student", *[ex.id for ex in exercises], "total", "max"])
    for row in rows:
        scores = row.get("exercises", {})
        mine = (assigned or {}).get(row["student"], exercises)
        ids = {ex.id for ex in mine}
        cells = [format_score(scores.get(ex.id, 0.0)) if ex.id in ids else "" for ex in exercises]
        top = round_score(sum(ex.max_score for ex in mine))
        w.writerow([row["student"], *cells, format_score(row.get('score', 0.0)), format_score(top)])
    write_atomic(path, buf.getvalue())


def _check_disk_reserve(out: str | os.PathLike, jobs: int) -> None:
    """Refuse to grade where students could fill the filesystem of the outputs.

    Outside bubblewrap the students' files are on the host (the sandbox's work area, the
    world-writable folders), each student's bounded by the meter at ``disk_bytes`` plus what it
    writes between two measurements (counted as ``disk_bytes`` again). See
    :func:`grading_sandbox.isolation.disk_reserve_problem`.
    """
    from grading_sandbox import Limits
    from grading_sandbox.cache import cache_root
    from grading_sandbox.isolation import WORLD_WRITABLE, disk_reserve_problem

    students_max = jobs * 2 * Limits().disk_bytes
    problem = disk_reserve_problem([cache_root() / "work", *WORLD_WRITABLE], [out, tempfile.gettempdir()],
                                   students_max, GRADER_RESERVE)
    if problem:
        raise UnsafeSandbox(problem)


def _check_isolation(job: ClassJob, hidden: Sequence[str], n_students: int) -> None:
    """Raise :class:`UnsafeSandbox` where student code would not be isolated from the grader."""
    from grading_sandbox import choose_mode, readable_by_sandbox

    mode, why = choose_mode()
    if mode == "setpriv" and not job.allow_unsafe_sandbox:
        # no namespaces: the student's uid sees what file permissions let any user see
        job.out.mkdir(mode=0o700, parents=True, exist_ok=True)  # a new one: private
        exposed = readable_by_sandbox(hidden)
        if exposed:
            raise UnsafeSandbox(
                f"bubblewrap cannot isolate student code here ({why}); the setpriv sandbox runs it as an "
                "unprivileged uid, which can read " + ", ".join(exposed) + ". Make them private to "
                "the grader (chmod go-rwx " + " ".join(exposed) + "), or pass --allow-unsafe-sandbox."
            )
    elif mode != "bwrap" and not job.allow_unsafe_sandbox:
        raise UnsafeSandbox(
            f"bubblewrap cannot isolate student code here ({why}). The fallback sandbox runs it as a "
            "plain process behind an in-process audit hook that a determined student can get around "
            "(e.g. with ctypes): they could then read other students' submissions, the output folder "
            "and the seed key, and the machine's other files. Install bubblewrap (apt-get install "
            "bubblewrap) and allow unprivileged user namespaces, or pass --allow-unsafe-sandbox "
            "(allow_unsafe_sandbox=True) to grade anyway."
        )
    if mode != "bwrap":
        _check_disk_reserve(job.out, min(job.jobs, max(1, n_students)))


def run_class(job: ClassJob) -> tuple[list[dict], tuple[Exercise, ...], list[str]]:
    """Grade every student folder of ``job.submissions`` into ``job.out`` (see the module docstring).

    The fallback still refuses ``submissions``, ``out``, the course and ``options.hidden_paths``
    (e.g. the key file) to the code it runs. A student folder named like one of the grader's own
    outputs (:data:`RESERVED_NAMES`) is not graded and reported as an error. ``job.jobs`` worker
    processes grade students in parallel (each runs its own sandboxes); one job grades in this
    process, as do exercises not in the catalog and a sandbox stand-in (tests' fakes).

    Returns
    -------
    rows : list of dict
        One summary per student (sorted by student; :func:`~.student.grade_student`).
    exercises : tuple of Exercise
        The exercises graded (the columns of ``grades.csv``).
    students : list of str
        The student folders found (those refused included).
    """
    from tqdm.auto import tqdm

    positive_int(job.jobs, "jobs")
    log = job.log or (lambda msg: print(msg, file=sys.stderr))
    exercises = job.resolved()
    catalog = job.catalog
    # what the setpriv mode must find unreadable by the sandbox's uid, and what the fallback hides
    # (the course too: its exercise folders hold the grading modules and the worked solutions)
    private = job.options.hiding(job.submissions, job.out).hidden_paths
    options = job.options.hiding(job.submissions, job.out, *([catalog.root] if catalog is not None else []))
    # Workers look exercises up by id; exercises not in the catalog (tests' fakes) grade in-process.
    known = {ex.id: ex for ex in catalog.everything()} if catalog is not None else {}
    custom = options.sandbox_factory is not None or any(known.get(ex.id) is not ex for ex in exercises)
    students = list_students(job.submissions)
    if options.sandbox_factory is None:
        _check_isolation(job, private, len(students))
    job.out.mkdir(parents=True, exist_ok=True)
    ex_hash = exercises_hash(exercises)
    reserved = [s for s in students if student_folder(s).lower() in RESERVED_NAMES]
    assigned = {s: _assigned(catalog, exercises, job.submissions / s) for s in students}
    jobs = [
        StudentJob(s, job.submissions / s, job.out, assigned[s][0], options, ex_hash,
                   job.renamed.get(s) or {}, ignored=job.ignored.get(s) or {}, notes=assigned[s][1])
        for s in students if s not in reserved
    ]
    in_process = job.jobs == 1 or len(jobs) <= 1 or custom
    try:
        if options.sandbox_factory is None and jobs:
            # before any student: a sandbox that cannot import what an exercise allows would score
            # every student 0 on it (grading_sandbox.SandboxConfigError, raised with the fix); graded
            # in this process, the students' own pool runs the check and keeps its zygotes
            pool = None
            if in_process and options.reuse_sandboxes:
                pool = _shared_pool(preload_modules(exercises))
            check_environment(exercises, options, pool=pool)
    except BaseException:
        close_shared_pools()
        raise
    summaries: dict[str, dict] = {}
    bar = tqdm(total=len(jobs), desc="grading", unit="student", disable=not job.progress)
    if in_process:
        try:
            for sj in jobs:
                summaries[sj.student] = _grade(sj)
                bar.update(1)
        finally:
            close_shared_pools()
    else:
        summaries.update(_in_workers(jobs, catalog, job.jobs, bar))
    bar.close()
    for s in reserved:
        summaries[s] = {"student": s, "error": f"the folder name {s!r} is reserved for the grader's outputs "
                        "(rename the student's folder)"}
    rows = [summaries[s] for s in students]
    isolations = {r.get("isolation", "") for r in rows}
    for iso in sorted(i for i in isolations if i.startswith("fallback")):
        log(f"warning: sandbox isolation is {iso!r}: student code ran without the full bubblewrap sandbox")
    config = [r for r in rows if r.get("config_error")]
    if config:  # the same for everyone: said once, loudly
        who = ", ".join(r["student"] for r in config[:5]) + (" ..." if len(config) > 5 else "")
        log(f"error: {config[0]['error']}\n(not graded: {len(config)} student(s): {who}; fix the grader's "
            "environment and re-run grade)")
    for r in rows:
        if "error" in r and not r.get("config_error"):
            log(f"error: student {r['student']}: {r['error']} (scored 0; re-run grade to retry)")
    mine = {s: a[0] for s, a in assigned.items()}
    _write_grades_csv(job.out / OUTPUT_FILES["grades"], rows, exercises, mine)
    return rows, exercises, students


def uniform_failures(rows: Sequence[dict], exercises: Sequence[Exercise], least: int = 2) -> list[str]:
    """One line per exercise that every student who submitted it (at least ``least`` of them)
    failed in exactly the same way (:func:`~.student.failure_signature`): students' own mistakes
    differ, so this is the grader's environment or the exercise's definition, not their work."""
    out = []
    for ex in exercises:
        sigs = [r["failures"][ex.id] for r in rows if ex.id in (r.get("failures") or {})]
        if len(sigs) >= least and sigs[0] and all(s == sigs[0] for s in sigs):
            out.append(
                f"every one of the {len(sigs)} students who submitted {ex.id} failed it the same way "
                f"(0 points each): {sigs[0][:300]}. Students' own mistakes differ: check the grader's "
                "environment (run `flowtrack check` on the exercise's solution) before publishing these "
                "grades"
            )
    return out


def _assigned(catalog: Any, exercises: Sequence[Exercise],
              folder: Path) -> tuple[tuple[Exercise, ...], tuple[str, ...]]:
    """The exercises of a class run one student is graded on, and the notes on what of their folder is
    not graded: those the catalog assigns the student (exercises it does not know, tests' fakes, are
    everyone's), and its notes."""
    if catalog is None:
        return tuple(exercises), ()
    known = {ex.id for ex in catalog.everything()}
    mine = {ex.id for ex in catalog.for_student(folder)}
    return (tuple(ex for ex in exercises if ex.id not in known or ex.id in mine),
            tuple(catalog.ignored(folder)))


def _in_workers(jobs: list[StudentJob], catalog: Any, n_workers: int, bar) -> dict[str, dict]:
    """Grade ``jobs`` in ``n_workers`` processes (a worker that dies gets its students retried once)."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    summaries: dict[str, dict] = {}
    pending = [_Task(replace(sj, exercises=()), tuple(ex.id for ex in sj.exercises), catalog) for sj in jobs]
    for _attempt in range(2):
        ctx = mp.get_context("forkserver" if sys.platform.startswith("linux") else "spawn")
        if ctx.get_start_method() == "forkserver":
            # the fork server imports the grader and builds the public tests once, before it
            # forks the workers (ignored when it already runs)
            ctx.set_forkserver_preload([f"{__package__}._warm"])
        broken = []
        with ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx) as pool:
            futures = {pool.submit(_worker, t): t for t in pending}
            for fut in as_completed(futures):
                task = futures[fut]
                try:
                    summaries[task.job.student] = fut.result()
                    bar.update(1)
                except BrokenProcessPool:
                    broken.append(task)
        pending = broken
        if not pending:
            break
    for task in pending:
        summaries[task.job.student] = {"student": task.job.student, "error": "a grading worker died"}
        bar.update(1)
    return summaries
