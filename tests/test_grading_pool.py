"""The fast path of ``flowtrack grade``: zygote sandboxes shared by the students of a worker.

``reuse_sandboxes=True`` (a :class:`SandboxPool`: one sandboxed process per kind of exercise, a
forked child per exercise) must score exactly like a fresh sandbox per student and exercise, on the
course's solutions, the released stubs, partial answers and wrong variants; it must start far fewer
sandboxes; and one student must find nothing of the previous one (files, processes).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

from flowtrack_course.grading.assign.release import release_notebook
from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.engine.seeds import public_seed, student_seed
from flowtrack_course.grading.engine.spec import Call, Exercise, GradedTest, Outcome
from flowtrack_course.grading.grade import grade_class
from grading_helpers import EXERCISES, StandInSandbox, class_job, source_notebook, use_sandbox_mode
from grading_sandbox import Limits, Sandbox, SandboxPool
from grading_sandbox import sandbox as sandbox_mod

pytestmark = pytest.mark.xdist_group("sandbox")

ROOT = Path(__file__).resolve().parents[1]

# Appended to every answer cell of the "wrong" student: each function defined so far returns a
# slightly different value (what a plausible bug does), or something the grader cannot use.
WRONG = """
import numpy as _np
for _n, _f in list(globals().items()):
    if callable(_f) and getattr(_f, "__module__", None) == "__main__" and not _n.startswith("_"):
        def _wrap(f):
            def g(*a, **k):
                r = f(*a, **k)
                try:
                    return _np.asarray(r, dtype=float) * 1.01 + 0.01
                except Exception:
                    return r
            return g
        globals()[_n] = _wrap(_f)
"""


def _answer_cells(nb, ids):
    return [c for c in nb.cells if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") in ids]


def _make_class(sub: Path) -> None:
    for ex in EXERCISES:
        source = nbformat.read(source_notebook(ex), as_version=4)
        stub = release_notebook(source)
        nbformat.write(source, _mk(sub / "solution" / ex.notebook))
        nbformat.write(stub, _mk(sub / "stub" / ex.notebook))
        partial = nbformat.from_dict(stub)  # only the first answer cell solved
        first = _answer_cells(source, ex.answer_cells[:1])[0].source
        _answer_cells(partial, ex.answer_cells[:1])[0].source = first
        nbformat.write(partial, _mk(sub / "partial" / ex.notebook))
        wrong = nbformat.from_dict(source)
        for c in _answer_cells(wrong, ex.answer_cells):
            c.source = "".join(c.source) + WRONG
        nbformat.write(wrong, _mk(sub / "wrong" / ex.notebook))
        crash = nbformat.from_dict(source)  # a crash in one exercise, then the others (same zygote)
        if ex is EXERCISES[0]:
            for c in _answer_cells(crash, ex.answer_cells):
                c.source = "import os\nos._exit(3)\n" + "".join(c.source)
        nbformat.write(crash, _mk(sub / "crash_first" / ex.notebook))


def _mk(p: Path) -> Path:
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def _tests(out: Path, student: str) -> dict[str, float]:
    data = json.loads((out / student / "results.json").read_text())
    return {t["name"]: t["score"] for t in data["tests"]}


@pytest.fixture(scope="module")
def class_dir(tmp_path_factory):
    sub = tmp_path_factory.mktemp("pool") / "subs"
    _make_class(sub)
    return sub


def test_pooled_grading_scores_exactly_like_a_sandbox_per_exercise(class_dir, tmp_path, monkeypatch):
    launches = {True: 0, False: 0}
    real = sandbox_mod.Sandbox._launch
    current = {}

    def counting(self, *a, **k):
        launches[current["reuse"]] += 1
        return real(self, *a, **k)

    monkeypatch.setattr(sandbox_mod.Sandbox, "_launch", counting)
    rows = {}
    for reuse in (False, True):
        current["reuse"] = reuse
        rows[reuse] = grade_class(class_job(class_dir, tmp_path / f"out-{reuse}", jobs=1, progress=False,
                                  reuse_sandboxes=reuse))
    students = ["crash_first", "partial", "solution", "stub", "wrong"]
    for reuse in (False, True):
        assert [r["student"] for r in rows[reuse]] == students and all("error" not in r for r in rows[reuse])
    for s in students:
        old, new = _tests(tmp_path / "out-False", s), _tests(tmp_path / "out-True", s)
        assert old.keys() == new.keys()
        for name in old:
            assert new[name] == pytest.approx(old[name], abs=1e-9), (s, name)
    # independent facts: stubs earn nothing, the wrong variant earns less than the solution, the crash
    # costs only its own exercise
    total = {s: sum(_tests(tmp_path / "out-True", s).values()) for s in students}
    assert total["stub"] == 0.0
    assert total["wrong"] < total["solution"] and total["partial"] < total["solution"]
    first = EXERCISES[0].id
    crash = _tests(tmp_path / "out-True", "crash_first")
    sol = _tests(tmp_path / "out-True", "solution")
    assert all(v == 0 for k, v in crash.items() if k.startswith(first + ":"))
    assert {k: v for k, v in crash.items() if not k.startswith(first)} == {
        k: v for k, v in sol.items() if not k.startswith(first)}
    # the point of the pool: a handful of sandboxes for the class instead of one per exercise
    n_tasks = len(students) * len(EXERCISES)
    assert launches[False] >= n_tasks - len(students)  # (missing notebooks start none)
    assert launches[True] <= launches[False] // 4, launches  # restarts only after a crash or a limit


LEAVER = """
import os, tempfile, time
def leave():
    open("left.txt", "w").write("A's answer")
    d = os.path.join(tempfile.gettempdir(), "a-dir")
    os.makedirs(d + "/deeper", exist_ok=True)
    open(d + "/deeper/x", "w").write("A")
    os.chmod(d, 0o000)
    try:
        if os.fork() == 0:
            os.setsid()
            time.sleep(1000)
    except OSError:
        pass
    return 1
"""

PROBE = """
import os, tempfile
def probe():
    me, parent = os.getpid(), os.getppid()
    uid = os.getuid()
    others = []
    for name in os.listdir("/proc"):
        if name.isdigit() and int(name) not in (me, parent, 1):
            try:
                if os.stat("/proc/" + name).st_uid == uid:
                    others.append(int(name))
            except OSError:
                pass
    return [sorted(os.listdir(".")), sorted(os.listdir(tempfile.gettempdir())), len(others)]
"""


@pytest.mark.parametrize("mode", ["bwrap", "setpriv", "fallback"])
def test_the_next_student_finds_nothing_of_the_previous_one(mode, monkeypatch, tmp_path_factory):
    use_sandbox_mode(mode, monkeypatch, tmp_path_factory)
    limits = Limits(cpu_seconds=5, wall_seconds=10, memory_bytes=1 << 30, processes=16)
    with SandboxPool() as pool:
        with pool([("a", LEAVER)], allowed=("numpy",), limits=limits) as a:
            (out,) = a.run([Call("leave")], timeout=10)
            assert out.ok, out
        with pool([("b", PROBE)], allowed=("numpy",), limits=limits) as b:
            (seen,) = b.run([Call("probe")], timeout=10)
        launched = len(pool._boxes)
    assert seen.ok and seen.value == [[], [], 0], seen
    if mode != "fallback" or pool_shares():
        assert launched == 1  # the same zygote served both


def pool_shares() -> bool:
    import os

    return os.geteuid() == 0


def test_a_pool_refuses_to_reuse_across_different_views():
    pool = SandboxPool()
    try:
        with pool([("a", "def f():\n    return 1\n")], allowed=("numpy",)) as a:
            assert a.run([Call("f")], timeout=30)[0].value == 1
        with pool([("b", "def f():\n    import scipy\n    return 2\n")], allowed=("numpy", "scipy")) as b:
            assert b.run([Call("f")], timeout=30)[0].value == 2
        with pool([("c", "def f():\n    import scipy\n    return 3\n")], allowed=("numpy",)) as c:
            out = c.run([Call("f")], timeout=30)[0]
        assert not out.ok and re.search(r"scipy is not available", out.error), out
        assert len(pool._boxes) == 2
    finally:
        pool.close()


# -- what a zygote preloads ------------------------------------------------------------------------

PRELOAD_PROBE = """
import sys
def probe():
    seen = sorted(m for m in ("sympy", "scipy", "scipy.stats", "scipy.optimize") if m in sys.modules)
    try:
        import scipy.stats  # noqa: F401  (it imports scipy.optimize, which is blocked)
        stats = "imported"
    except ImportError:
        stats = "refused"
    return [seen, stats]
"""


@pytest.mark.parametrize("mode", ["bwrap", "setpriv", "fallback"])
def test_a_zygote_preloads_only_what_its_children_may_import(mode, monkeypatch, tmp_path_factory):
    """A view with a blocked module (scipy.optimize) still gets its allowlist preloaded, under the
    children's import rule: scipy.stats, which needs scipy.optimize, is not preloaded (without the
    rule the setpriv and fallback zygotes, whose file system shows the real scipy.optimize, would
    hold it), and the child finds what a fresh sandbox finds."""
    use_sandbox_mode(mode, monkeypatch, tmp_path_factory)
    limits = Limits(cpu_seconds=10, wall_seconds=30, memory_bytes=1 << 30, processes=16)
    spec = {"blocked": ("scipy.optimize",), "allowed": ("numpy", "scipy", "sympy"), "limits": limits}
    with Sandbox([("p", PRELOAD_PROBE)], **spec) as fresh:
        (alone,) = fresh.run([Call("probe")], timeout=60)
    with SandboxPool(("scipy", "scipy.stats", "sympy")) as pool:
        with pool([("p", PRELOAD_PROBE)], **spec) as box:
            (pooled,) = box.run([Call("probe")], timeout=60)
        zygote = bool(pool._boxes)
    # a fresh child imports its allowlist before any student code (the grader's configuration
    # check), under the same rule: scipy.stats, which needs the blocked scipy.optimize, is not loaded
    assert alone.ok and alone.value == [["scipy", "sympy"], "refused"], alone
    assert pooled.ok and pooled.value[1] == "refused", pooled
    if zygote:  # (the fallback as an ordinary user has none)
        assert pooled.value[0] == ["scipy", "sympy"], pooled


# -- public tests built once, each distinct answer scored once ---------------------------------------


def _memo_exercise(counts: dict, scored: list) -> Exercise:
    def make(kind):
        def build(rng):
            counts[kind] += 1
            x = float(rng.uniform())  # the test's input, from its seed

            def scorer(outcomes):
                scored.append(kind)
                got = outcomes[0].value
                return (1.0 if got == round(x, 3) else 0.0), f"{kind}: got {got!r}"

            return [Call("f", (x,))], scorer

        return build

    tests = (GradedTest("pub", "t_pub", 1.0, False, make("public")),
             GradedTest("hid", "t_hid", 2.0, True, make("hidden")))
    return Exercise("memo_ex", "memo", "memo.ipynb", ("answer",), (), tests)


class _Rounding(StandInSandbox):
    """Sandbox stand-in: a student's answer cell ``DIGITS = n`` answers ``f(x)`` with ``round(x, n)``."""

    def run(self, calls, timeout):
        digits = int(self.cells[0][1].split("=")[1])
        return [Outcome(True, round(c.args[0], digits)) for c in calls]


def test_public_tests_are_built_once_and_each_distinct_answer_scored_once(tmp_path):
    counts, scored = {"public": 0, "hidden": 0}, []
    ex = _memo_exercise(counts, scored)
    digits = {"ann": 3, "bob": 3, "cyd": 2, "dan": 3, "eve": 1}
    results = {}
    for s, d in digits.items():
        nb = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": [
            {"cell_type": "code", "execution_count": None, "outputs": [], "source": f"DIGITS = {d}\n",
             "metadata": {"nbgrader": {"grade_id": "answer", "solution": True}}}]}
        path = tmp_path / s / "memo.ipynb"
        path.parent.mkdir()
        path.write_text(json.dumps(nb))
        results[s] = run_exercise(ex, path, s, sandbox_factory=_Rounding)
    assert counts == {"public": 1, "hidden": len(digits)}
    assert scored.count("public") == 3 and scored.count("hidden") == len(digits)  # 3, 2 and 1 digits
    # each student's public result is what scoring them alone gives (the input drawn here, the oracle)
    x = float(np.random.default_rng(public_seed("memo_ex", "pub")).uniform())
    for s, d in digits.items():
        pub, hid = results[s].tests
        assert (pub.score, pub.message) == ((1.0 if d == 3 else 0.0), f"public: got {round(x, d)!r}"), s
        xs = float(np.random.default_rng(student_seed(s, "memo_ex", "hid")).uniform())
        assert hid.score == (2.0 if round(xs, d) == round(xs, 3) else 0.0), s
