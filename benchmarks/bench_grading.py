"""Benchmark: ``flowtrack grade --jobs 2``, 100 students x all exercises, vs ``nbgrader autograde``.

The class: 100 students, a third with every solution (the exercises' source notebooks), a third
with the released stubs, a third partial (every other exercise solved; in exercises with two answer
cells only the first one). flowtrack grades the whole class with ``--jobs 2`` (one sandbox per
student and exercise). The peer is ``nbgrader autograde`` on the same notebooks in a throwaway
nbgrader course made in a temporary folder (``generate_assignment`` first, not timed); nbgrader
runs one kernel per notebook, one student after the other, so it is measured on a few students
(one of each kind, the same mix) and compared per student. Both are measured in the same run, on
the same machine.

Targets: the whole class in < 5 minutes and >= 3x faster per student than nbgrader.

Section "answers in other languages" (``--languages``): 20 students x C++, Java, Octave and
Mathematica x 4 problems graded by ``flowtrack grade --jobs 2``; wall-clock, CPU seconds of the grader and
everything it started, and the load average (see ``languages_main``). Target: <= 5 min on 2 idle cores.

Section "sandbox reuse": the same class graded by ``grade_class(jobs=2)`` twice in this
process, with a fresh sandbox per student and exercise (``reuse_sandboxes=False``, the old path)
and with zygote sandboxes shared by each worker's students (the default); the per-test scores of
the two must be identical. Target: the whole class in <= 30 s with the shared zygotes on an idle
2-core machine. Each path is reported with its wall-clock time, its CPU time (this process, its
grading workers and every sandboxed process, from a cgroup made for the measurement:
:class:`CpuMeter`) and the 1-min load average before and after, since the machine may be shared:
CPU seconds / 2 is what 2 idle cores need at best, whatever the load. ``--reuse-only`` runs only
this section, ``--no-old`` skips its old path.

Usage::

    .venv/bin/python benchmarks/bench_grading.py [--quick] [--check]

Prints its table and, unless ``--quick``, writes it to ``benchmarks/results/grading.md``.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nbformat

from _results import publish
from flowtrack_course.grading.assign.release import release_notebook
from flowtrack_course.grading.sources import course_catalog

ROOT = Path(__file__).resolve().parents[1]
CATALOG = course_catalog(ROOT)
EXERCISES = CATALOG.default()


def _source(ex) -> Path:
    """The instructor's notebook of ``ex`` (``exercises/<id>/<notebook>``)."""
    return CATALOG.course.source_notebook(ex)
KINDS = ("solution", "stub", "partial")


def _student_notebook(ex, index: int, kind: str, sources: dict, stubs: dict):
    if kind == "solution":
        return sources[ex.id]
    if kind == "stub":
        return stubs[ex.id]
    if index % 2 == 0:
        return sources[ex.id]
    nb = nbformat.from_dict(stubs[ex.id])
    first = ex.answer_cells[0]
    if len(ex.answer_cells) > 1:
        for cell, src in zip(nb.cells, sources[ex.id].cells):
            if cell.metadata.get("nbgrader", {}).get("grade_id") == first:
                cell.source = src.source
    return nb


def make_class(dest: Path, n_students: int) -> list[tuple[str, str]]:
    sources = {ex.id: nbformat.read(_source(ex), as_version=4) for ex in EXERCISES}
    stubs = {k: release_notebook(v) for k, v in sources.items()}
    students = []
    for s in range(n_students):
        kind = KINDS[s % 3]
        name = f"s{s:03d}_{kind}"
        for i, ex in enumerate(EXERCISES):
            p = dest / name / ex.notebook
            p.parent.mkdir(parents=True, exist_ok=True)
            nbformat.write(_student_notebook(ex, i, kind, sources, stubs), p)
        students.append((name, kind))
    return students


def _descendants(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        try:
            for task in os.listdir(f"/proc/{p}/task"):
                todo += [int(c) for c in Path(f"/proc/{p}/task/{task}/children").read_text().split()]
        except OSError:
            pass
    return out


class CpuMeter:
    """CPU seconds of this process and everything it starts meanwhile, sandboxes included.

    Sandboxed processes are killed, not waited for, by their parents (a zygote and the processes
    of its pid namespace die together), so ``RUSAGE_CHILDREN`` misses most of their time. The meter
    therefore moves this process into a cgroup of its own for the measurement, where the kernel
    counts every descendant: cgroup v1 ``cpuacct`` (``cpuacct.usage``) or v2 (``cpu.stat``), where
    this user may make one (root, or a delegated cgroup); afterwards this process and any left
    (multiprocessing's fork server) go back and the cgroup is removed. Elsewhere ``how`` says
    ``"rusage (lower bound)"``: this process and its waited-for children only. (Under cgroup v2 the
    sandboxes then get no memory cgroup of their own: a cgroup holding a process cannot hand
    controllers down. v1 ``cpuacct`` leaves the other controllers alone.)

    Use: ``with CpuMeter() as m: ...`` then ``m.seconds``, ``m.how``.
    """

    def __init__(self) -> None:
        self.seconds = float("nan")
        self.how = ""
        self._dir: Path | None = None
        self._home: Path | None = None
        self._read = None

    def _cgroup(self) -> bool:
        """Move this process into a new cgroup that counts CPU time; False where none can be made."""
        v1, v2 = Path("/sys/fs/cgroup/cpuacct"), Path("/sys/fs/cgroup")
        home = None
        for line in Path("/proc/self/cgroup").read_text().splitlines():
            num, ctrls, path = line.split(":", 2)
            if v1.is_dir() and "cpuacct" in ctrls.split(","):
                home, self.how = v1 / path.lstrip("/"), "cgroup v1 cpuacct"
                self._read = lambda d: int((d / "cpuacct.usage").read_text()) / 1e9
                break
            if num == "0" and not ctrls and (v2 / "cgroup.controllers").is_file():
                home, self.how = v2 / path.lstrip("/"), "cgroup v2 cpu.stat"
                self._read = lambda d: int(
                    next(x.split()[1] for x in (d / "cpu.stat").read_text().splitlines()
                         if x.startswith("usage_usec"))) / 1e6
        if home is None:
            return False
        d = home / f"bench-grading-{os.getpid()}-{time.monotonic_ns()}"
        try:
            d.mkdir()
        except OSError:
            return False
        try:
            (d / "cgroup.procs").write_text(str(os.getpid()))
        except OSError:
            d.rmdir()
            return False
        # and what this process started before and keeps (multiprocessing's fork server, which
        # forks the grading workers): their new children are then counted too
        for pid in _descendants(os.getpid())[1:]:
            try:
                (d / "cgroup.procs").write_text(str(pid))
            except OSError:
                pass
        self._dir, self._home = d, home
        return True

    def __enter__(self) -> CpuMeter:
        try:
            ok = self._cgroup()
        except (OSError, ValueError, StopIteration):
            ok = False
        if not ok:
            self.how = "rusage (lower bound)"
            self._dir = None
        self._start = self._now()
        return self

    def _now(self) -> float:
        import resource

        if self._dir is not None:
            return self._read(self._dir)
        a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime

    def elapsed(self) -> float:
        """CPU seconds so far (of processes still running: up to their last tick)."""
        return self._now() - self._start

    def __exit__(self, *exc) -> None:
        time.sleep(0.2)  # let processes killed at the end be accounted
        self.seconds = self._now() - self._start
        if self._dir is None:
            return
        for _ in range(50):
            left = (self._dir / "cgroup.procs").read_text().split()
            for pid in left:
                try:
                    (self._home / "cgroup.procs").write_text(pid)
                except OSError:  # gone meanwhile
                    pass
            try:
                self._dir.rmdir()
                return
            except OSError:
                time.sleep(0.1)


def run_flowtrack(subs: Path, out: Path, jobs: int) -> tuple[float, dict[str, float]]:
    exe = Path(sys.executable).parent / "flowtrack"
    t0 = time.perf_counter()
    subprocess.run(
        [str(exe), "grade", str(subs), "--out", str(out), "--jobs", str(jobs), "--no-progress",
         "--course", str(ROOT)],
        check=True, stdout=subprocess.DEVNULL,
    )
    wall = time.perf_counter() - t0
    with open(out / "grades.csv") as fh:
        totals = {r["student"]: float(r["total"]) for r in csv.DictReader(fh)}
    return wall, totals


def run_nbgrader(course: Path, students: list[tuple[str, str]], subs: Path) -> tuple[float, dict[str, float]]:
    bindir = Path(sys.executable).parent
    env = dict(os.environ, PATH=f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}")
    (course / "source" / "ps1").mkdir(parents=True)
    for ex in EXERCISES:
        shutil.copy(_source(ex), course / "source" / "ps1" / ex.notebook)
    (course / "nbgrader_config.py").write_text(
        "c = get_config()\n"
        f"c.CourseDirectory.root = {str(course)!r}\n"
        "c.CourseDirectory.course_id = 'bench'\n"
        "c.ExecutePreprocessor.timeout = 120\n"
    )
    nbg = [str(bindir / "nbgrader")]
    subprocess.run([*nbg, "generate_assignment", "ps1", "--force"], cwd=course, env=env, check=True,
                   capture_output=True)
    for name, _ in students:
        shutil.copytree(subs / name, course / "submitted" / name / "ps1")
    t0 = time.perf_counter()
    subprocess.run([*nbg, "autograde", "ps1", "--force"], cwd=course, env=env, check=True,
                   capture_output=True)
    wall = time.perf_counter() - t0
    subprocess.run([*nbg, "export", "--to", str(course / "export.csv")], cwd=course, env=env, check=True,
                   capture_output=True)
    with open(course / "export.csv") as fh:
        totals = {r["student_id"]: float(r["raw_score"]) for r in csv.DictReader(fh)}
    return wall, totals


# --------------------------------------------------------------------------------------------------
# Section: answers in other languages. A class of N students x every language exercise
# (C++, Java, Octave, Mathematica x 4 problems; a third solutions, a third stubs, a third partial: every
# other problem solved) graded by `flowtrack grade --jobs 2` with the toolchain caches warm (the C++
# and Java harnesses are built once, before timing). Measured: wall-clock, CPU seconds of the grader
# and everything it started (sandboxes, compilers, VMs: a cpuacct cgroup of its own where the machine
# has one, else the rusage of reaped children, which misses what a sandbox's pid namespace kills),
# and the load average; the machine may be shared, so the CPU seconds say whether 2 idle cores
# could do it in the time. Then each language alone on 3 students (solution, stub, partial) with
# `--jobs 1`: CPU seconds per item. Peer, in the same run: the same toolchain work without any
# sandbox (compile the student's file, link the cached harness, run it on the public cases), one item
# after the other, for the first (solution) student; compared per item.

_CPUACCT = Path("/sys/fs/cgroup/cpuacct")


def run_accounted(cmd: list[str], **kwargs) -> tuple[float, float, str]:
    """Run ``cmd``; ``(wall s, CPU s of it and all its descendants, how the CPU was measured)``."""
    import resource

    group = None
    if (_CPUACCT / "cpuacct.usage").is_file() and os.access(_CPUACCT, os.W_OK):
        group = _CPUACCT / f"flowtrack-bench-{os.getpid()}-{time.monotonic_ns()}"
        try:
            group.mkdir()
        except OSError:
            group = None

    def enter() -> None:
        (group / "cgroup.procs").write_text(str(os.getpid()))

    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        subprocess.run(cmd, check=True, preexec_fn=enter if group is not None else None, **kwargs)
        wall = time.perf_counter() - t0
        if group is not None:
            return wall, int((group / "cpuacct.usage").read_text()) / 1e9, "cgroup cpuacct"
    finally:
        for _ in range(50 if group is not None else 0):
            try:
                group.rmdir()
                break
            except OSError:
                time.sleep(0.1)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return wall, cpu, "rusage of reaped children (undercounts sandboxes)"


def _languages():
    """The course's answers in other languages (this checkout's), as the grader discovers them."""
    from flowtrack_course.grading.engine.discovery import discover
    from flowtrack_course.grading.languages import LanguageSource

    return LanguageSource(discover(ROOT))


def bench_items(languages=None) -> list:
    """The language items of the bar: the four problems every language has (not the C++ assignment)."""
    return [ex for ex in _languages().exercises()
            if ex.problem in PROBLEM_ORDER and (languages is None or ex.language in languages)]


def make_language_class(dest: Path, n_students: int, languages=None) -> list[tuple[str, str]]:
    from flowtrack_course.grading.languages import strip_solutions

    source = _languages()
    students = []
    for s in range(n_students):
        kind = KINDS[s % 3]
        name = f"s{s:03d}_{kind}"
        for ex in bench_items(languages):
            text = source.instructor_source(ex).read_text()
            if kind == "stub" or (kind == "partial" and PROBLEM_ORDER.index(ex.problem) % 2):
                text = strip_solutions(text, ex.language)
            p = dest / name / "exercises" / ex.notebook
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(text)
        students.append((name, kind))
    return students


PROBLEM_ORDER = ("cv_model", "kalman_step", "projection_jacobian", "mahalanobis_gating")


def run_direct(subs: Path, students: list[tuple[str, str]], work: Path) -> tuple[float, int]:
    """The peer: build and run every language item of ``students`` without a sandbox."""
    import json

    from flowtrack_course.grading.languages import PROBLEMS, public_vectors

    items = 0
    t0 = time.perf_counter()
    for name, _ in students:
        for ex in bench_items():
            tc = ex.toolchain
            d = work / name / ex.id
            d.mkdir(parents=True)
            src = tc.source_name(ex.problem)
            shutil.copy(subs / name / "exercises" / ex.notebook, d / src)
            for rel, text in tc.support_files(ex.problem).items():
                (d / rel).write_text(text)
            for rel, data in ex.harness_blobs().items():
                (d / rel).write_bytes(data)
            doc = public_vectors(PROBLEMS[ex.problem])
            (d / "cases.json").write_text(json.dumps(doc))
            for cmd in tc.build_commands(ex.problem):
                subprocess.run(cmd, cwd=d, capture_output=True, timeout=300)
            run = [sys.executable if c == "@PYTHON@" else c for c in tc.run_command(ex.problem)]
            subprocess.run(run, cwd=d, capture_output=True, timeout=300)
            items += 1
    return time.perf_counter() - t0, items


def _grade_cmd(subs: Path, out: Path, jobs: int) -> list[str]:
    exe = Path(sys.executable).parent / "flowtrack"
    return [str(exe), "grade", str(subs), "--out", str(out), "--jobs", str(jobs), "--no-progress",
            "--course", str(ROOT)]


def languages_main(args) -> int:
    from flowtrack_course.grading.languages import TOOLCHAINS

    bench = bench_items()
    n = args.students or (3 if args.quick else 20)
    jobs = 2
    for ex in bench:  # warm the per-language caches (grader-made artefacts only)
        ex.harness_blobs()
    langs = [lang for lang, tc in TOOLCHAINS.items() if tc.graded]
    per_lang = {}
    with tempfile.TemporaryDirectory(prefix="bench-grading-lang-") as tmp:
        tmp = Path(tmp)
        students = make_language_class(tmp / "subs", n)
        load0 = os.getloadavg()
        ft_wall, ft_cpu, how = run_accounted(_grade_cmd(tmp / "subs", tmp / "out", jobs),
                                             stdout=subprocess.DEVNULL)
        load1 = os.getloadavg()
        print(f"flowtrack grade --jobs {jobs}: {ft_wall:.1f} s wall, {ft_cpu:.1f} CPU s for {n} students "
              f"(load {load0[0]:.1f} -> {load1[0]:.1f})", flush=True)
        with open(tmp / "out" / "grades.csv") as fh:
            ft_totals = {r["student"]: float(r["total"]) for r in csv.DictReader(fh)}
        header = (tmp / "out" / "grades.csv").read_text().splitlines()[0].split(",")
        for lang in langs:  # each language alone: CPU seconds per item
            k = 3
            make_language_class(tmp / f"subs-{lang}", k, {lang})
            w, c, _ = run_accounted(_grade_cmd(tmp / f"subs-{lang}", tmp / f"out-{lang}", 1),
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            per_lang[lang] = (k * 4, w, c, os.getloadavg()[0])
            print(f"{lang}: {c / (k * 4):.2f} CPU s / item", flush=True)
        peer_wall, peer_items = run_direct(tmp / "subs", students[:1], tmp / "direct")
    items = n * len(bench)
    per_item, peer_per_item = ft_wall / items, peer_wall / peer_items
    max_total = sum(ex.max_score for ex in bench)
    by_kind = {k: sorted({ft_totals[s] for s, kk in students if kk == k}) for k in KINDS}
    budget = 300 * n / 20
    rows = [
        "## Autograder, answers in other languages (`flowtrack grade`, issue 19)",
        "",
        f"{n} synthetic students x {len(bench)} language exercises ({', '.join(langs)} x "
        f"{len(bench) // len(langs)} problems, {max_total:g} points; a third solutions, a "
        "third stubs, a third partial). `flowtrack grade --jobs 2`: a sandbox per student and exercise "
        "(children of each worker's zygotes), compiling (C++, Java) and running the student's file "
        "against public and hidden inputs; Mathics3 runs in the sandbox's child, forked from a zygote "
        "that loaded the interpreter once; the C++ and Java harnesses (grader sources only) cached "
        "beforehand. CPU s: the grader and everything it started (" + how + "). Peer: the same builds "
        "and runs on the public inputs without any sandbox, one after the other, for 1 student; per item.",
        "",
        "| grader | items | wall s | CPU s | s / item (wall) | 1-min load before -> after |",
        "|---|---:|---:|---:|---:|---|",
        f"| `flowtrack grade --jobs 2` | {items} | {ft_wall:.1f} | {ft_cpu:.1f} | {per_item:.2f} | "
        f"{load0[0]:.1f} -> {load1[0]:.1f} |",
        f"| direct build + run, no sandbox, 1 process | {peer_items} | {peer_wall:.1f} | | "
        f"{peer_per_item:.2f} | |",
        "",
        "Each language alone, 3 students (solution, stub, partial) x 4 problems, `--jobs 1` (CPU s include "
        "the grader's own start-up, about 2-3 s per run):",
        "",
        "| language | items | wall s | CPU s | CPU s / item | 1-min load after |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for lang, (k, w, c, ld) in per_lang.items():
        rows.append(f"| {lang} | {k} | {w:.1f} | {c:.1f} | {c / k:.2f} | {ld:.1f} |")
    rows += [
        "",
        f"Totals by kind (of {max_total:g}): " + "; ".join(f"{k} {v}" for k, v in by_kind.items()),
        f"grades.csv columns: {', '.join(c for c in header if '_' in c)}",
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| {n} students x {len(bench)} items <= {budget:.0f} s wall | {ft_wall:.1f} s | "
        f"{'yes' if ft_wall <= budget else 'no'} |",
        f"| the same work fits 2 idle cores in {budget:.0f} s (CPU s <= {2 * budget:.0f}) | "
        f"{ft_cpu:.1f} CPU s | {'yes' if ft_cpu <= 2 * budget else 'no'} |",
        f"| sandboxed, 2 jobs, per item vs direct, 1 process | {per_item / peer_per_item:.2f}x | info |",
        "",
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs; the load average "
        "counts every process of the machine (other jobs included): above 2 the 2 cores were shared and "
        f"the wall-clock is inflated; {'quick' if args.quick else 'full'} run.",
    ]
    publish("grading_languages", "\n".join(rows) + "\n", args.quick)
    return 1 if (args.check and ft_wall > budget) else 0


def breakdown(subs: Path, out: Path, n: int) -> tuple[list[str], str]:
    """CPU per student of each exercise, split into the grader's process (notebook reading, the
    reference computations, sending, scoring, writing) and the sandboxes (forks of the zygotes,
    the student's code, the clean-ups): the first ``n`` students graded one exercise at a time in
    this process, with one shared pool whose zygotes are started (and the public tests built)
    by a first student beforehand."""
    from flowtrack_course.grading.engine.jobs import GradingOptions, StudentJob
    from flowtrack_course.grading.engine.run import preload_modules
    from flowtrack_course.grading.engine.student import grade_student
    from grading_sandbox import SandboxPool

    students = sorted(p.name for p in subs.iterdir())[:n]
    rows = []
    with CpuMeter() as meter:
        pool = SandboxPool(preload_modules(EXERCISES))
        grade_student(StudentJob(students[0], subs / students[0], out / "warm", EXERCISES), sandbox_pool=pool)
        forced = GradingOptions(force=True)
        for ex in EXERCISES:
            c0, p0 = meter.elapsed(), time.process_time()
            for s in students:
                grade_student(StudentJob(s, subs / s, out / ex.id, (ex,), forced), sandbox_pool=pool)
            grader = (time.process_time() - p0) / len(students)
            rows.append((ex.id, grader, (meter.elapsed() - c0) / len(students) - grader))
        pool.close()
    table = ["| exercise | grader ms | sandboxes ms | total ms |", "|---|---:|---:|---:|"]
    table += [f"| {e} | {1000 * g:.0f} | {1000 * c:.0f} | {1000 * (g + c):.0f} |" for e, g, c in rows]
    g, c = sum(r[1] for r in rows), sum(r[2] for r in rows)
    table.append(f"| all ({len(students)} students) | {1000 * g:.0f} | {1000 * c:.0f} | {1000 * (g + c):.0f} "
                 "|")
    return table, meter.how


def _test_scores(out: Path) -> dict[tuple[str, str], float]:
    import json

    scores = {}
    for res in sorted(out.glob("*/results.json")):
        for t in json.loads(res.read_text())["tests"]:
            scores[(res.parent.name, t["name"])] = t["score"]
    return scores


def reuse_section(n: int, old: bool = True) -> tuple[list[str], bool]:
    """Old path (a sandbox per student and exercise) vs shared zygotes, same class, same run."""
    from flowtrack_course.grading.engine.jobs import ClassJob, GradingOptions
    from flowtrack_course.grading.grade import grade_class

    walls, cpus, scores, loads, how = {}, {}, {}, {}, ""
    with tempfile.TemporaryDirectory(prefix="bench-grading-reuse-") as tmp:
        tmp = Path(tmp)
        make_class(tmp / "subs", n)
        for reuse in (False, True) if old else (True,):
            out = tmp / f"out-{reuse}"
            before = os.getloadavg()[0]
            with CpuMeter() as meter:
                t0 = time.perf_counter()
                job = ClassJob(tmp / "subs", out, catalog=CATALOG, jobs=2, progress=False,
                               options=GradingOptions(reuse_sandboxes=reuse))
                rows = grade_class(job)
                walls[reuse] = time.perf_counter() - t0
            cpus[reuse], how = meter.seconds, meter.how
            loads[reuse] = (before, os.getloadavg()[0])
            assert not [r for r in rows if "error" in r], [r for r in rows if "error" in r][:3]
            scores[reuse] = _test_scores(out)
        n_detail = min(n, 12)
        detail, detail_how = breakdown(tmp / "subs", tmp / "detail", n_detail)
    same = scores[False] == scores[True] and len(scores[True]) > 0 if old else None
    met = walls[True] <= 30 * n / 100 and same is not False
    cpu_met = cpus[True] <= 60 * n / 100
    paths = {False: "fresh sandbox per exercise", True: "shared zygotes"}
    rows = [
        "## Sandbox reuse (`flowtrack grade --jobs 2`, issue 18)",
        "",
        f"{n} synthetic students x {len(EXERCISES)} exercises, `grade_class(jobs=2)` in one process: "
        + ("a fresh sandbox per student and exercise (old) vs " if old else "")
        + "zygote sandboxes shared by each worker's students, a forked child per exercise (new). "
        + ("Same class, same run; per-test scores compared. " if old else "")
        + f"CPU = this process, its 2 grading workers and every sandboxed process ({how}); CPU / 2 is "
        "the least wall-clock time 2 idle cores need.",
        "",
        "| path | wall s | CPU s | CPU s / student | CPU / 2 s | 1-min load before, after |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for reuse in walls:
        rows.append(
            f"| {paths[reuse]} | {walls[reuse]:.1f} | {cpus[reuse]:.1f} | {cpus[reuse] / n:.3f} | "
            f"{cpus[reuse] / 2:.1f} | {loads[reuse][0]:.1f}, {loads[reuse][1]:.1f} |"
        )
    rows.append("")
    if old:
        rows += [
            f"Speed-up {walls[False] / walls[True]:.2f}x wall, {cpus[False] / cpus[True]:.2f}x CPU; per-test "
            f"scores identical: {'yes' if same else 'NO'} ({len(scores[True])} test results).",
            "",
        ]
    rows += [
        f"Where a student's CPU goes with shared zygotes, per exercise ({detail_how}; the first {n_detail} "
        "students graded one exercise at a time in one process, after a first student started the "
        "zygotes; grader = the grading process: notebook, reference computations, sending, scoring, "
        "writing; sandboxes = zygote forks, the student's code, clean-ups). The class total adds, once "
        "per worker, its zygotes' start (numpy, scipy, sympy) and, once, the fork server's imports, "
        "the gradebook and the CSVs.",
        "",
        *detail,
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| whole class <= {30 * n / 100:g} s wall (2 idle cores) | {walls[True]:.1f} s | "
        f"{'yes' if met else 'no (see the load)'} |",
        f"| whole class <= {60 * n / 100:g} CPU s (what 2 cores give in {30 * n / 100:g} s) | "
        f"{cpus[True]:.1f} s | {'yes' if cpu_met else 'no'} |",
        "",
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs; the load "
        "average counts every process of the machine (other jobs included): above 2 the 2 cores were "
        "shared, and the wall-clock time says more about the load than about the grader.",
    ]
    return rows, met and cpu_met


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="6 students, 1 for nbgrader (smoke run)")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    ap.add_argument("--languages", action="store_true",
                    help="only the section on answers in other languages (20 students x 4 languages x 4 "
                    "problems; quick: 3 students)")
    ap.add_argument("--students", type=int, default=None, help="class size (default 100; quick: 6)")
    ap.add_argument("--nbgrader-students", type=int, default=None, help="students for nbgrader (default 3)")
    ap.add_argument("--reuse-only", action="store_true", help="only the sandbox-reuse section")
    ap.add_argument("--no-old", action="store_true",
                    help="sandbox-reuse section: skip the old path (a fresh sandbox per exercise)")
    args = ap.parse_args(argv)
    if args.languages:
        return languages_main(args)

    if args.reuse_only:
        n = args.students or (6 if args.quick else 100)
        rows, met = reuse_section(n, old=not args.no_old)
        publish("grading_reuse", "\n".join(rows) + "\n", args.quick)
        return 1 if (args.check and not met) else 0
    n = args.students or (6 if args.quick else 100)
    n_nb = args.nbgrader_students or (1 if args.quick else 3)
    jobs = 2
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as tmp:
        tmp = Path(tmp)
        students = make_class(tmp / "subs", n)
        load_before = os.getloadavg()[0]
        with CpuMeter() as meter:
            ft_wall, ft_totals = run_flowtrack(tmp / "subs", tmp / "out", jobs)
        load_after = os.getloadavg()[0]
        rerun_t0 = time.perf_counter()
        run_flowtrack(tmp / "subs", tmp / "out", jobs)  # idempotent re-run: every student is kept
        rerun_wall = time.perf_counter() - rerun_t0
        nb_students = students[:n_nb]
        nb_wall, nb_totals = run_nbgrader(tmp / "course", nb_students, tmp / "subs")
    max_total = sum(ex.max_score for ex in EXERCISES)
    ft_per, nb_per = ft_wall / n, nb_wall / n_nb
    ratio = nb_per / ft_per
    rows = [
        "## Autograder (`flowtrack grade`)",
        "",
        f"{n} synthetic students x {len(EXERCISES)} exercises ({max_total:g} points; a third solutions, "
        "a third stubs, a third partial). flowtrack: `flowtrack grade --jobs 2`, the whole class (zygote "
        "sandboxes shared by each worker's students, a forked child per student and exercise; CPU: the "
        f"command and every process it started, {meter.how}; 1-min load {load_before:.1f} before, "
        f"{load_after:.1f} after). Peer: `nbgrader autograde` (one kernel per notebook, "
        f"students one after the other) on the first {n_nb} students of the same class (one of each "
        "kind), in a throwaway nbgrader course; compared per student. Same run, same machine.",
        "",
        "| grader | students | wall s | s / student | CPU s |",
        "|---|---:|---:|---:|---:|",
        f"| `flowtrack grade --jobs 2` | {n} | {ft_wall:.1f} | {ft_per:.2f} | {meter.seconds:.1f} |",
        f"| `flowtrack grade --jobs 2`, re-run (all kept) | {n} | {rerun_wall:.1f} | {rerun_wall / n:.3f} "
        "| |",
        f"| `nbgrader autograde` | {n_nb} | {nb_wall:.1f} | {nb_per:.2f} | |",
        "",
        "| student | kind | flowtrack | nbgrader |",
        "|---|---|---:|---:|",
    ]
    for name, kind in nb_students:
        theirs = nb_totals.get(name, float("nan"))
        rows.append(f"| {name} | {kind} | {ft_totals.get(name, 0):g} | {theirs:g} |")
    rows += [
        "",
        "(nbgrader's hidden-test cells call the same scorers in the student's kernel; their hidden inputs "
        "are not seeded per student, so partial scores may differ.)",
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| whole class < 300 s | {ft_wall:.1f} s | {'yes' if ft_wall < 300 else 'no'} |",
        f"| per student >= 3x faster than nbgrader | {ratio:.1f}x | {'yes' if ratio >= 3 else 'no'} |",
        "",
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs, 1-min load "
        f"average {os.getloadavg()[0]:.1f} at the end; {'quick' if args.quick else 'full'} run.",
    ]
    publish("grading", "\n".join(rows) + "\n", args.quick)
    reuse_rows, reuse_met = reuse_section(n, old=not args.no_old)
    publish("grading_reuse", "\n".join(reuse_rows) + "\n", args.quick)
    met = ft_wall < 300 * n / 100 and ratio >= 3 and reuse_met
    return 1 if (args.check and not met) else 0


if __name__ == "__main__":
    raise SystemExit(main())
