"""Benchmark: the hardened grader against the grader before the hardening, same class, same run.

Target: grading costs at most 10 % more CPU per student than before the hardening (seccomp filters,
per-child folders rebuilt for every child, hidden feedback in the grader's words). "Before" is the
tree of ``--old-rev`` (default ``82cb30c^``, the parent of the commit that started the hardening);
"now" is this checkout.

This script runs inside a git checkout of the course: the old tree is extracted with
``git archive <old-rev> | tar -x -C <tmp>/old``, and the old grader runs from it
(``PYTHONPATH=<tmp>/old/reference_impl python -m flowtrack_course.cli grade ... --course <tmp>/old``),
the new one from this checkout (``PYTHONPATH=<checkout>/reference_impl``, the same command). A
subprocess with each environment prints where ``flowtrack_course``, ``flowtrack`` and
``grading_sandbox`` are loaded from, and the run stops unless each comes from its own tree: the
venv's editable install of this checkout must not shadow the old code.

The class: students made by ``bench_grading.make_class`` (a third solutions, a third released stubs,
a third partial), restricted to the exercises whose exercise notebooks are byte for byte the same
in both trees (an exercise whose notebook changed may have gained graded questions, so the two
graders would not grade the same work). Each version grades a course folder that holds only those
exercises (the old tree and a copy of this checkout's ``exercises/``, each without the others), so
both grade exactly the same notebooks and neither spends time on absent ones.

Each version grades the same student folders with the same ``--jobs``, each run into a fresh output
folder, interleaved old, new, new, old, old, new, ... (``--reps`` runs each), after one untimed
warm-up run each (both trees' byte-code and both versions' sandbox cache copies are made there;
``PYTHONDONTWRITEBYTECODE`` is unset for the graders, so neither compiles its sources on every run).
Measured per run: wall-clock seconds and CPU seconds of the grader and everything it started
(``bench_grading.CpuMeter``: a cpuacct cgroup where the machine has one), and the 1-min load
average before and after. Both versions' ``grades.csv`` are compared per student and exercise.

Usage::

    .venv/bin/python benchmarks/bench_grading_versions.py [--quick] [--students N] [--reps R]
        [--jobs J] [--old-rev REV] [--check]

Prints its table and, unless ``--quick``, writes it to ``benchmarks/results/grading_versions.md``
(``grading_versions_jobs<J>.md`` for another ``--jobs``).
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import publish
from bench_grading import CATALOG, EXERCISES, ROOT, CpuMeter, make_class

BAR = 1.10  # new CPU per student <= 1.10 x old
_MODULES = ("flowtrack_course", "flowtrack", "grading_sandbox")


def select_exercises(new_root: Path, old_root: Path,
                     notebooks: dict[str, Path]) -> tuple[list[str], dict[str, str]]:
    """Which exercises both trees grade alike: ``(used ids, {left-out id: why})``.

    ``notebooks`` maps an exercise id to its notebook's path relative to a tree; an exercise is used
    when that file exists in both trees with the same bytes.
    """
    used, left_out = [], {}
    for ex_id, rel in notebooks.items():
        new, old = new_root / rel, old_root / rel
        if not old.is_file():
            left_out[ex_id] = f"no {rel} in the old tree"
        elif not new.is_file():
            left_out[ex_id] = f"no {rel} in this checkout"
        elif new.read_bytes() != old.read_bytes():
            left_out[ex_id] = "exercise notebook changed since the old tree"
        else:
            used.append(ex_id)
    return used, left_out


def extract_tree(rev: str, dest: Path) -> str:
    """Extract ``rev`` of this checkout into ``dest``; return its full commit id."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", f"{rev}^{{commit}}"],
                            check=True, capture_output=True, text=True).stdout.strip()
    dest.mkdir(parents=True)
    archive = subprocess.Popen(["git", "-C", str(ROOT), "archive", commit], stdout=subprocess.PIPE)
    subprocess.run(["tar", "-x", "-C", str(dest)], stdin=archive.stdout, check=True)
    archive.stdout.close()
    if archive.wait() != 0:
        raise RuntimeError(f"git archive {commit} failed")
    return commit


def course_copy(tree: Path, dest: Path, keep: set[str]) -> Path:
    """``dest`` with a copy of ``tree/exercises`` holding only the exercise folders of ``keep``
    (folders not named ``exNN_...``, such as ``languages/``, are copied too)."""
    def ignore(folder, names):
        if Path(folder) != tree / "exercises":
            return []
        return [n for n in names if n[:2] == "ex" and n[2:4].isdigit() and n not in keep]

    shutil.copytree(tree / "exercises", dest / "exercises", ignore=ignore)
    return dest


def restricted_class(dest: Path, n: int, used: list[str]) -> list[tuple[str, str]]:
    """``bench_grading.make_class``'s class with the notebooks of the exercises of ``used`` only."""
    students = make_class(dest, n)
    for name, _ in students:
        for ex in EXERCISES:
            if ex.id not in used:
                (dest / name / ex.notebook).unlink()
    return students


def grader_env(tree: Path) -> dict[str, str]:
    """The environment of a grader run from ``tree``. Byte-code is written and reused (an installed
    package has it): where ``PYTHONDONTWRITEBYTECODE`` is set, every run would compile the grader's
    sources again, and the larger of the two versions would pay more for it."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("FLOWTRACK_COURSE", "PYTHONPATH", "PYTHONDONTWRITEBYTECODE")}
    env["PYTHONPATH"] = str(tree / "reference_impl")
    return env


def check_origin(tree: Path, cwd: Path) -> dict[str, str]:
    """Where a Python started with ``grader_env(tree)`` loads the grader's packages from; raises
    unless every one is under ``tree/reference_impl``."""
    code = f"import importlib\nfor m in {_MODULES!r}: print(m, importlib.import_module(m).__file__)"
    out = subprocess.run([sys.executable, "-c", code], env=grader_env(tree), cwd=cwd, check=True,
                         capture_output=True, text=True).stdout
    files = dict(line.split(" ", 1) for line in out.splitlines())
    base = (tree / "reference_impl").resolve()
    wrong = {m: f for m, f in files.items() if not Path(f).resolve().is_relative_to(base)}
    if wrong or set(files) != set(_MODULES):
        raise RuntimeError(f"PYTHONPATH={base} does not load the grader from there: {files}")
    return files


def grade(tree: Path, course: Path, subs: Path, out: Path, jobs: int, log: Path) -> tuple[float, float, str]:
    """One ``flowtrack grade`` run of the code of ``tree``: ``(wall s, CPU s, how CPU was counted)``."""
    cmd = [sys.executable, "-m", "flowtrack_course.cli", "grade", str(subs), "--out", str(out),
           "--jobs", str(jobs), "--no-progress", "--course", str(course)]
    with CpuMeter() as meter, open(log, "w") as err:
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, env=grader_env(tree), cwd=out.parent, stdout=err, stderr=subprocess.STDOUT)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {proc.returncode}:\n{log.read_text()[-3000:]}")
    return wall, meter.seconds, meter.how


# A class run of the new grader starts, before its first student, one sandbox per distinct sandbox
# configuration of the exercises (``check_environment``), to refuse a broken environment once instead
# of scoring every student 0. It is timed alone here, since it is a fixed cost of every run.
_PREFLIGHT = """\
import json, sys, time
from flowtrack_course.course import use_course
from flowtrack_course.grading.engine import run
from flowtrack_course.grading.sources import course_catalog
check = getattr(run, "check_environment", None)
if check is None:
    print("null")
    raise SystemExit
exercises = course_catalog(use_course(sys.argv[1], need=("exercises",))).default()
walls, sandboxes = [], 0
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    sandboxes = check(exercises)
    walls.append(time.perf_counter() - t0)
print(json.dumps({"sandboxes": sandboxes, "walls": walls}))
"""


def preflight(tree: Path, course: Path, cwd: Path, calls: int = 3) -> dict | None:
    """The grader's check before its first student, where the version of ``tree`` has one: ``None``
    or ``{"sandboxes": n, "wall": median s, "cpu": CPU s per call}``. CPU per call is the difference
    between a process making ``calls`` checks and one making none (the imports cancel out)."""
    import json

    cpu, out = {}, {}
    for k in (0, calls):
        with CpuMeter() as meter:
            out[k] = json.loads(subprocess.run([sys.executable, "-c", _PREFLIGHT, str(course), str(k)],
                                               env=grader_env(tree), cwd=cwd, check=True,
                                               capture_output=True, text=True).stdout)
        cpu[k] = meter.seconds
        if out[k] is None:
            return None
    return {"sandboxes": out[calls]["sandboxes"], "wall": statistics.median(out[calls]["walls"]),
            "cpu": (cpu[calls] - cpu[0]) / calls}


def read_grades(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "grades.csv") as fh:
        return {r["student"]: r for r in csv.DictReader(fh)}


def compare_grades(old: dict, new: dict, ids: list[str]) -> list[str]:
    """Every student and column (exercise or total) whose score differs, as text."""
    diffs = []
    for s in sorted(set(old) | set(new)):
        if s not in old or s not in new:
            diffs.append(f"{s}: only in {'new' if s in new else 'old'}")
            continue
        for col in (*ids, "total", "max"):
            a, b = old[s].get(col), new[s].get(col)
            if a != b and not (a and b and abs(float(a) - float(b)) <= 1e-9):
                diffs.append(f"{s} {col}: old {a}, new {b}")
    return diffs


def _median(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def timed_runs(order, trees, courses, classes, tmp: Path, jobs: int) -> tuple[dict, str]:
    """Grade each class (``{size: folder}``) once per entry of ``order`` with that version; returns
    ``{(version, size): [run, ...]}`` (``run``: wall, cpu, load before and after, out) and how CPU
    was counted."""
    runs, how = {}, ""
    for i, v in enumerate(order):
        for size, subs in classes.items():
            run_dir = tmp / f"run{i:02d}-{v}-{size}"
            run_dir.mkdir()
            before = os.getloadavg()[0]
            wall, cpu, how = grade(trees[v], courses[v], subs, run_dir / "out", jobs, run_dir / "log.txt")
            after = os.getloadavg()[0]
            runs.setdefault((v, size), []).append({"i": i + 1, "wall": wall, "cpu": cpu, "before": before,
                                                   "after": after, "out": run_dir / "out"})
            print(f"run {i + 1}/{len(order)} {v}, {size} students: wall {wall:.1f} s, CPU {cpu:.1f} s "
                  f"({cpu / size:.3f} s / student), load {before:.1f} -> {after:.1f}", flush=True)
    return runs, how


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 students, 2 runs each (smoke run)")
    ap.add_argument("--students", type=int, default=None, help="class size (default 30; quick: 3)")
    ap.add_argument("--small", type=int, default=3,
                    help="a second, small class (its first students) graded after each run, to split a "
                    "run's CPU into a fixed part and a part per student (default 3; 0: none)")
    ap.add_argument("--reps", type=int, default=None, help="timed runs per version (default 3; quick: 2)")
    ap.add_argument("--jobs", type=int, default=2, help="flowtrack grade --jobs (default 2)")
    ap.add_argument("--old-rev", default="82cb30c^", help="the old grader's commit (default 82cb30c^)")
    ap.add_argument("--check", action="store_true", help="exit 1 when the bar is missed")
    args = ap.parse_args(argv)
    n = args.students or (3 if args.quick else 30)
    k = args.small if 0 < args.small < n else 0
    reps = args.reps or (2 if args.quick else 3)

    with tempfile.TemporaryDirectory(prefix="bench-grading-versions-") as tmp:
        tmp = Path(tmp)
        old_commit = extract_tree(args.old_rev, tmp / "old")
        new_commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], check=True,
                                    capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "reference_impl",
                                "exercises"], check=True, capture_output=True, text=True).stdout.strip()
        rel = {ex.id: CATALOG.course.source_notebook(ex).relative_to(ROOT) for ex in EXERCISES}
        used, left_out = select_exercises(ROOT, tmp / "old", rel)
        print(f"old: {args.old_rev} = {old_commit[:10]}; new: this checkout, {new_commit[:10]}"
              f"{' + uncommitted changes' if dirty else ''}")
        print("exercises used (notebook identical in both trees):", ", ".join(used))
        for ex_id, why in left_out.items():
            print(f"left out {ex_id}: {why}")
        if not used:
            raise SystemExit("no exercise notebook is the same in both trees")
        folders = {rel[ex_id].parts[1] for ex_id in used}
        trees = {"old": tmp / "old", "new": ROOT}
        # the old course is the old tree itself, pruned; this checkout is left alone (a copy)
        for d in (tmp / "old" / "exercises").iterdir():
            if d.is_dir() and d.name[:2] == "ex" and d.name[2:4].isdigit() and d.name not in folders:
                shutil.rmtree(d)
        courses = {"old": tmp / "old", "new": course_copy(ROOT, tmp / "new-course", folders)}
        for v, tree in trees.items():
            for m, f in check_origin(tree, tmp).items():
                print(f"{v}: {m} from {f}")

        students = restricted_class(tmp / "subs", n, used)
        # the small class: the first students of the big one (same notebooks), also the warm-up's
        restricted_class(tmp / "small-subs", k or 3, used)
        for v in ("old", "new"):  # untimed: byte-code of both trees, sandbox cache copies
            (tmp / f"warm-{v}").mkdir()
            grade(trees[v], courses[v], tmp / "small-subs", tmp / f"warm-{v}" / "out", args.jobs,
                  tmp / f"warm-{v}" / "log.txt")

        order = [v for r in range(reps) for v in (("old", "new") if r % 2 == 0 else ("new", "old"))]
        classes = {n: tmp / "subs", **({k: tmp / "small-subs"} if k else {})}
        load_start = os.getloadavg()[0]
        runs, how = timed_runs(order, trees, courses, classes, tmp, args.jobs)
        load_end = os.getloadavg()[0]
        checks = {v: preflight(trees[v], courses[v], tmp) for v in trees}

        grades = {v: [read_grades(r["out"]) for r in runs[(v, n)]] for v in trees}
        # each version must agree with itself (hidden inputs are seeded from student and test names)
        unstable = [v for v in grades if any(g != grades[v][0] for g in grades[v][1:])]
        ids = [ex.id for ex in EXERCISES if ex.id in used]
        diffs = compare_grades(grades["old"][0], grades["new"][0], ids)
        totals = {kind: sorted({float(grades["new"][0][s]["total"]) for s, kk in students if kk == kind})
                  for kind in ("solution", "stub", "partial")}

    med = {v: (_median(runs[(v, n)], "wall"), _median(runs[(v, n)], "cpu")) for v in trees}
    cpu_ratio = med["new"][1] / med["old"][1]
    wall_ratio = med["new"][0] / med["old"][0]
    # the i-th old and new runs are neighbours in the interleaved order: their ratios show the spread
    pairs = list(zip(runs[("old", n)], runs[("new", n)]))
    pair_cpu = [b["cpu"] / a["cpu"] for a, b in pairs]
    pair_wall = [b["wall"] / a["wall"] for a, b in pairs]
    met = cpu_ratio <= BAR
    check_cpu = {v: c["cpu"] if c else 0.0 for v, c in checks.items()}
    bare_ratio = (med["new"][1] - check_cpu["new"]) / (med["old"][1] - check_cpu["old"])
    max_total = sum(ex.max_score for ex in EXERCISES if ex.id in used)
    fmt = ", ".join
    rows = [
        "## Grading speed before and after the grader's hardening (`flowtrack grade --jobs "
        f"{args.jobs}`, issue 28)",
        "",
        f"Old: the grader of `{args.old_rev}` ({old_commit[:10]}, extracted with `git archive`); new: this "
        f"checkout ({new_commit[:10]}{', with uncommitted changes' if dirty else ''}). One class of {n} "
        f"synthetic students (a third solutions, a third stubs, a third partial) x {len(used)} exercises "
        f"({max_total:g} points): the exercises whose notebooks are byte for byte the same in both trees "
        f"({fmt(used)}); left out: " + "; ".join(f"{e} ({why})" for e, why in left_out.items())
        + ". Each version grades the same student folders with a course folder holding only those "
        f"exercises, `--jobs {args.jobs}`, a fresh output folder per run, after one untimed warm-up run "
        f"each; runs interleaved {fmt(order)}"
        + (f", each followed by the same version on the class's first {k} students" if k else "")
        + f". CPU: the grader and every process it started ({how}).",
        "",
        "| run | version | students | wall s | CPU s | CPU s / student | 1-min load before -> after |",
        "|---:|---|---:|---:|---:|---:|---|",
    ]
    # in the order they ran: each run's class, then its small class
    for r, _, v, size in sorted((r["i"], size != n, v, size) for (v, size), rs in runs.items() for r in rs):
        x = next(q for q in runs[(v, size)] if q["i"] == r)
        rows.append(f"| {r} | {v} | {size} | {x['wall']:.1f} | {x['cpu']:.1f} | {x['cpu'] / size:.3f} | "
                    f"{x['before']:.1f} -> {x['after']:.1f} |")
    rows += [
        "",
        f"Medians ({reps} runs each){'; fixed and per-student CPU from the two class sizes' if k else ''}:",
        "",
        "| version | wall s | CPU s | CPU s / student |"
        + (" CPU s, fixed | CPU s per added student |" if k else ""),
        "|---|---:|---:|---:|" + ("---:|---:|" if k else ""),
    ]
    split = {}
    for v in trees:
        line = f"| {v} | {med[v][0]:.1f} | {med[v][1]:.1f} | {med[v][1] / n:.3f} |"
        if k:
            small = _median(runs[(v, k)], "cpu")
            slope = (med[v][1] - small) / (n - k)
            split[v] = (small - slope * k, slope)
            line += f" {split[v][0]:.2f} | {slope:.3f} |"
        rows.append(line)
    rows += [
        "",
        f"Ratio new / old of the medians: CPU {cpu_ratio:.3f}, wall {wall_ratio:.3f}"
        + (f"; fixed CPU {split['new'][0] / split['old'][0]:.3f}, CPU per added student "
           f"{split['new'][1] / split['old'][1]:.3f}" if k else "")
        + f". Ratios of neighbouring old and new runs of the {n} students: CPU "
        f"{fmt(f'{q:.3f}' for q in pair_cpu)} (min {min(pair_cpu):.3f}, max {max(pair_cpu):.3f}); wall "
        f"{fmt(f'{q:.3f}' for q in pair_wall)}. 1-min load average {load_start:.1f} before the first "
        f"timed run, {load_end:.1f} after the last.",
        "",
        "The check before the first student (a sandbox per distinct sandbox configuration of the "
        "exercises, importing what they allow; timed alone after the runs, 3 calls): "
        + "; ".join(f"{v}: none" if c is None else
                    f"{v}: {c['sandboxes']} sandboxes, {c['cpu']:.2f} CPU s, {c['wall']:.2f} s wall"
                    for v, c in checks.items()) + "."
        + ("" if not any(checks.values()) else
           f" Without it (its CPU taken off the medians): CPU ratio new / old {bare_ratio:.3f}."
           if args.jobs > 1 else
           # in one process the check runs in the pool that grades next, which reuses its zygotes
           f" (With `--jobs 1` the check runs in the pool that then grades the students, so most of what "
           f"it starts is reused: taking its stand-alone cost off the medians, {bare_ratio:.3f}, "
           "undercounts the new grader.)"),
        "",
        "Scores (`grades.csv`, per student and exercise, total and max): "
        + ("the same in both versions" if not diffs
           else f"{len(diffs)} differences: " + "; ".join(diffs[:20]))
        + "; each version the same in all its runs: " + (f"NO ({fmt(unstable)})" if unstable else "yes")
        + f". Totals by kind (of {max_total:g}): " + "; ".join(f"{a} {b}" for a, b in totals.items()) + ".",
        "",
        "| target | measured | met |",
        "|---|---:|:---:|",
        f"| new CPU per student <= {BAR:.2f} x old (medians, {n} students) | {cpu_ratio:.3f}x | "
        f"{'yes' if met else '**no**'} |",
        "",
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs; the load average "
        "counts every process of the machine: above the number of jobs the cores were shared and the "
        "wall-clock times say more about the load than about the grader; CPU seconds do not depend on it "
        f"as much. {'quick' if args.quick else 'full'} run.",
    ]
    # one section per --jobs: the default of `flowtrack grade` (1) and the benchmark's (2) side by side
    name = "grading_versions" if args.jobs == 2 else f"grading_versions_jobs{args.jobs}"
    publish(name, "\n".join(rows) + "\n", args.quick)
    return 1 if (args.check and (not met or diffs)) else 0


if __name__ == "__main__":
    raise SystemExit(main())
