"""The exercise notebooks and their trusted tests, discovered in their folders.

Every notebook is valid nbformat with valid nbgrader metadata that matches its grading module; every
solution scores full marks, every stub (nbgrader's own ClearSolutions) scores 0 and a typical wrong
answer (its folder's ``cases.py``) scores strictly in between - through the in-process runner
(nbgrader compatibility) and through the sandbox the grader uses; answers that call the blocked
reference score 0 in the sandbox. The expected values of exercise 9 (from the trusted tracker) are
checked against an independent bookkeeping oracle written here.
"""

from __future__ import annotations

import ast
import copy
import dataclasses
import itertools
import json
import math
import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

from flowtrack_course.grading.check import run_in_process
from flowtrack_course.grading.engine.seeds import student_seed
from flowtrack_course.grading.engine.spec import Call, Exercise, GradedTest, Outcome
from grading_helpers import (
    COURSE,
    EXERCISES,
    RecordingSandbox,
    answer,
    answer_sources,
    cases,
    exercise_module,
    get_exercise,
    replace_solution,
    source_notebook,
)
from grading_sandbox.wire import plain_data

ROOT = COURSE
EXDIR = ROOT / "exercises"
IDS = [ex.id for ex in EXERCISES]


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------
def _read(ex) -> nbformat.NotebookNode:
    return nbformat.read(source_notebook(ex), as_version=4)


def _nbg(cell) -> dict:
    return cell.metadata.get("nbgrader", {})


def _answer_sources(nb, ex) -> dict[str, str]:
    return answer_sources(nb, ex)


def _stub_notebook(ex) -> nbformat.NotebookNode:
    """The student version of the answer cells, made by nbgrader's own ClearSolutions."""
    from nbgrader.preprocessors import ClearSolutions

    nb, _ = ClearSolutions().preprocess(copy.deepcopy(_read(ex)), {})
    return nb


def _namespace(sources: dict[str, str]) -> dict:
    ns: dict = {"__name__": "student"}
    for src in sources.values():
        exec(compile(src, "<answer cell>", "exec"), ns)
    return ns


def _score(results) -> float:
    return sum(r[1] for r in results)


def _replace_solution(source: str, body: str) -> str:
    """Put ``body`` (unindented) between the solution markers of an answer cell."""
    return replace_solution(source, body)


def _wrong_sources(ex) -> dict[str, str]:
    """The exercise's typical wrong answer (its ``cases.py``'s ``WRONG``)."""
    return answer(_answer_sources(_read(ex), ex), cases(ex.id).WRONG)


def _cheat_sources(ex) -> dict[str, str]:
    """Answers that call the blocked reference (its ``cases.py``'s ``CHEAT``)."""
    return answer(_answer_sources(_read(ex), ex), cases(ex.id).CHEAT)


# --------------------------------------------------------------------------------------------------
# notebooks and registry
# --------------------------------------------------------------------------------------------------
def test_exercises_are_discovered_from_their_folders():
    # every folder of exercises/ with a grading module is an exercise, and nothing else is
    folders = sorted(p.parent.name for p in EXDIR.glob("*/grading.py"))
    assert IDS == folders and len(folders) >= 12
    assert len(set(IDS)) == len(IDS)
    for ex in EXERCISES:
        assert ex.notebook == f"{ex.id}.ipynb"  # the bundle's and the submissions' file name
        assert (EXDIR / ex.id / ex.notebook).is_file() and (EXDIR / ex.id / "cases.py").is_file()
        assert (EXDIR / ex.id / "solution.md").is_file()
        assert get_exercise(ex.id) is ex
        assert get_exercise(EXDIR / ex.id / ex.notebook) is ex
        assert get_exercise(ex.notebook) is ex
        assert ex.max_score == 10.0
        assert ex.blocked, ex.id
        assert {t.hidden for t in ex.tests} == {True, False}, "public and hidden tests"
        assert len({t.name for t in ex.tests}) == len(ex.tests)
    with pytest.raises(KeyError, match="no exercise"):
        get_exercise("ex99_nothing")
    with pytest.raises(TypeError, match="looked up by id or notebook path"):
        get_exercise(3)


@pytest.mark.parametrize("ex", EXERCISES, ids=IDS)
def test_notebook_is_valid_nbgrader_source(ex):
    from nbgrader.nbgraderformat import MetadataValidator

    nb = _read(ex)
    nbformat.validate(nb)
    MetadataValidator().validate_nb(nb)  # nbgrader's own schema check (v3), raises on bad metadata
    assert nb.metadata["kernelspec"]["name"] == "python3"
    ids = [_nbg(c)["grade_id"] for c in nb.cells if "nbgrader" in c.metadata]
    assert len(ids) == len(set(ids)), f"duplicate grade_ids in {ex.notebook}"
    for c in nb.cells:
        if c.cell_type == "code":
            assert c.outputs == [] and c.execution_count is None, "no outputs are committed"
    answers = [c for c in nb.cells if _nbg(c).get("solution")]
    tests = [c for c in nb.cells if _nbg(c).get("grade")]
    assert tuple(_nbg(c)["grade_id"] for c in answers) == ex.answer_cells
    for c in answers:
        meta = _nbg(c)
        assert c.cell_type == "code" and meta["grade"] is False and meta["locked"] is False
        assert meta["schema_version"] == 3
        src = c.source
        assert src.count("### BEGIN SOLUTION") == 1 and src.count("### END SOLUTION") == 1
        head = src.split("### BEGIN SOLUTION")[0]
        # the signature and a numpy-style docstring with shapes stay visible to the student
        assert re.search(r"^def \w+\(", head, flags=re.M) and "Returns\n" in head
        assert "shape" in head or "length" in head
    by_cell: dict[str, float] = {}
    for t in ex.tests:
        by_cell[t.grade_id] = by_cell.get(t.grade_id, 0.0) + t.points
    assert {_nbg(c)["grade_id"] for c in tests} == set(by_cell)
    for c in tests:
        meta = _nbg(c)
        assert c.cell_type == "code" and meta["locked"] is True and meta["solution"] is False
        assert meta["points"] == pytest.approx(by_cell[meta["grade_id"]])
        assert c.source.count("### BEGIN HIDDEN TESTS") == 1 and c.source.rstrip().endswith(
            "### END HIDDEN TESTS"
        )
        hidden = c.source.split("### BEGIN HIDDEN TESTS")[1]
        assert f'run_in_process("{ex.id}", globals(), cell="{meta["grade_id"]}"' in hidden
        public = c.source.split("### BEGIN HIDDEN TESTS")[0]
        assert public.strip(), "visible public checks"
        ast.parse(c.source)
    text = "\n".join(c.source for c in nb.cells if c.cell_type == "markdown")
    assert "You may import" in text and "Not:" in text
    for mod in ex.blocked:
        if mod.startswith("flowtrack.") and mod != "flowtrack_course.grading":
            assert f"`{mod}`" in text, f"{mod} is blocked but the notebook does not say so"


def test_student_version_by_nbgrader_has_no_solution_or_hidden_test():
    from nbgrader.preprocessors import ClearHiddenTests, ClearSolutions

    for ex in EXERCISES:
        nb = copy.deepcopy(_read(ex))
        nb, _ = ClearSolutions().preprocess(nb, {})
        nb, _ = ClearHiddenTests().preprocess(nb, {})
        text = json.dumps(nb)
        for marker in ("BEGIN SOLUTION", "END SOLUTION", "HIDDEN TESTS", "run_in_process"):
            assert marker not in text, (ex.id, marker)
        code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
        assert code.count("raise NotImplementedError()") == len(ex.answer_cells)


# --------------------------------------------------------------------------------------------------
# scores through the in-process runner (the nbgrader path)
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ex", EXERCISES, ids=IDS)
def test_solution_scores_full_marks(ex):
    ns = _namespace(_answer_sources(_read(ex), ex))
    for student in ("alice", "bob"):
        results = run_in_process(ex, ns, student=student)
        assert _score(results) == pytest.approx(ex.max_score), results
    # hidden inputs depend on the student, public ones do not
    for t in ex.tests:
        a = t.build(np.random.default_rng(student_seed("alice", ex.id, t.name)))[0]
        b = t.build(np.random.default_rng(student_seed("bob", ex.id, t.name)))[0]
        same = json.dumps([plain_data(list(c.args)) for c in a]) == json.dumps(
            [plain_data(list(c.args)) for c in b]
        )
        assert same == (not t.hidden), t.name


@pytest.mark.parametrize("ex", EXERCISES, ids=IDS)
def test_stub_scores_zero(ex):
    nb = _stub_notebook(ex)
    src = _answer_sources(nb, ex)
    assert all("raise NotImplementedError()" in s for s in src.values())
    results = run_in_process(ex, _namespace(src), student="carol")
    assert _score(results) == 0.0
    assert any(("not implemented" in r[3] or "NotImplementedError" in r[3])
               for r in results if not r[0].startswith("hidden"))


@pytest.mark.parametrize("ex", EXERCISES, ids=IDS)
def test_wrong_answer_scores_in_between(ex):
    results = run_in_process(ex, _namespace(_wrong_sources(ex)), student="dave")
    assert 0.0 < _score(results) < ex.max_score, results


def test_blkdiag_Q_loses_the_hidden_Q_points():
    ex = get_exercise("ex05_cv_model")
    results = {r[0]: r[1] for r in run_in_process(ex, _namespace(_wrong_sources(ex)), student="erin")}
    assert results["Q: the full matrix for random dt and q"] == 0.0
    assert results["F: random dt"] == 2.0


def test_hungarian_brute_force_runs_out_of_time():
    ex = get_exercise("ex08_hungarian")
    src = _answer_sources(_read(ex), ex)
    src["hungarian"] = (
        "import itertools\nimport numpy as np\n"
        "def hungarian(cost):\n"
        "    C = np.asarray(cost, dtype=float)\n"
        "    T = C.shape[0] > C.shape[1]\n"
        "    C = C.T if T else C\n"
        "    n, m = C.shape\n"
        "    total = lambda s: sum(C[i, s[i]] for i in range(n))\n"
        "    best = min(itertools.permutations(range(m), n), key=total)\n"
        "    pairs = [(i, j) for i, j in enumerate(best)]\n"
        "    return np.array([(j, i) for i, j in pairs] if T else pairs)\n"
    )
    # a shorter time limit than the grader's 10 s keeps this test fast; 12x12 and 30x30 are out of
    # reach of brute force at any limit (12! = 4.8e8 permutations)
    fast = dataclasses.replace(ex, tests=tuple(dataclasses.replace(t, timeout=1.0) for t in ex.tests))
    results = {r[0]: r for r in run_in_process(fast, _namespace(src), student="frank")}
    assert results["small matrices: two 3x3, 2x4, 4x2, 1x1"][1] == 2.0
    assert results["a medium matrix: 11x11, where greedy is not optimal"][1] == 0.0
    assert results["random matrices 12x12 to 30x30, with ties, rectangular"][1] == 0.0
    medium = results["a medium matrix: 11x11, where greedy is not optimal"]
    assert "mistake brute-force-assignment:" in medium[3]


# --------------------------------------------------------------------------------------------------
# the runner converts results as the sandboxed child does
# --------------------------------------------------------------------------------------------------
def test_in_process_runner_conversions_and_failures():
    class Liar(np.ndarray):
        def __eq__(self, other):
            return True

        def tolist(self):
            return [[1.0, 0.0, 0.5, 0.0], [0.0, 1.0, 0.0, 0.5], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]

    class AlwaysEqual:
        def __eq__(self, other):
            return True

    ex = get_exercise("ex05_cv_model")
    for fn in (
        lambda dt: np.zeros((4, 4)).view(Liar),
        lambda dt: AlwaysEqual(),
        lambda dt: (_ for _ in ()).throw(SystemExit(0)),
        lambda dt: "F",
    ):
        results = run_in_process(ex, {"cv_transition": fn}, cell="test_F")
        assert _score(results) == 0.0
    assert plain_data((np.float64(1.5), np.arange(2), [True, None, "s"])) == [1.5, [0, 1], [True, None, "s"]]
    with pytest.raises(TypeError):
        plain_data({1: 2})
    with pytest.raises(TypeError):
        plain_data(np.array(["a"]))


def test_in_process_runner_times_out_an_infinite_loop():
    ex = get_exercise("ex05_cv_model")

    def spin(dt):
        while True:
            pass

    fast = dataclasses.replace(ex, tests=tuple(dataclasses.replace(t, timeout=0.2) for t in ex.tests))
    results = run_in_process(
        fast, {"cv_transition": spin, "cv_process_noise": lambda dt, q: np.eye(4)}, cell="test_F"
    )
    assert _score(results) == 0.0
    assert "timed out after 0.2 s" in results[0][3]


def test_scorer_messages_for_public_tests():
    ex = get_exercise("ex01_projection_jacobian")
    ns = {"project": lambda X, fx, fy, cx, cy: np.zeros((2, 2))}
    (res,) = run_in_process(ex, ns, cell="test_project", hidden=False)
    assert res[1] == 0.0 and "shape (3, 2)" in res[3]
    (res,) = run_in_process(ex, ns, cell="test_project", hidden=True)
    assert res[3].startswith("hidden test")  # hidden tests report the score only


# --------------------------------------------------------------------------------------------------
# the in-process runner seeds and clips exactly as `flowtrack grade` / `flowtrack check` do
# --------------------------------------------------------------------------------------------------
def _drawing_exercise(fraction: float | None = None) -> Exercise:
    """A synthetic exercise whose public and hidden tests both draw their inputs from ``rng`` (the
    registry's public tests use fixed inputs, so they cannot tell two seeds apart). Its scorer
    returns ``fraction`` when given, else the share of calls that returned something."""

    def build(rng):
        calls = [Call("echo", (rng.normal(size=3),)), Call("echo", (float(rng.uniform()),))]

        def scorer(outcomes):
            if fraction is not None:
                return fraction, "fixed"
            return sum(o.ok for o in outcomes) / len(outcomes), "share answered"

        return calls, scorer

    tests = (
        GradedTest("public draw", "test_echo", 2.0, hidden=False, build=build),
        GradedTest("hidden draw", "test_echo", 3.0, hidden=True, build=build),
    )
    return Exercise("exx_draw", "draws", "exx_draw.ipynb", ("echo",), (), tests)


def _echo_notebook(ex, tmp_path) -> Path:
    cell = {"cell_type": "code", "execution_count": None, "outputs": [],
            "source": "def echo(x):\n    return x\n",
            "metadata": {"nbgrader": {"grade_id": "echo", "solution": True}}}
    nb = tmp_path / ex.notebook
    nb.write_text(json.dumps({"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": [cell]}))
    return nb


def _grader_inputs(ex, tmp_path, student, public_only=False) -> list[tuple[str, list]]:
    """What `flowtrack grade` (``student``) or `flowtrack check` (None, public only) sends, in order."""
    from flowtrack_course.grading.engine.run import run_exercise

    nb = _echo_notebook(ex, tmp_path)
    RecordingSandbox.sent = []
    result = run_exercise(ex, nb, student, public_only=public_only, sandbox_factory=RecordingSandbox)
    assert not result.problems, result.problems
    return list(RecordingSandbox.sent)


def _in_process_inputs(ex, student=None, **kwargs) -> list[tuple[str, list]]:
    got = []

    def echo(x):
        got.append(("echo", plain_data([x])))
        return x

    if student is not None:
        kwargs["student"] = student
    results = run_in_process(ex, {"echo": echo}, **kwargs)
    assert results and all(earned == points for _, earned, points, _ in results), results
    return got


def test_in_process_public_inputs_are_those_of_grade_and_check(tmp_path):
    from flowtrack_course.grading.engine.seeds import public_seed

    ex = _drawing_exercise()
    public = ex.tests[0]
    assert not public.hidden and ex.tests[1].hidden
    n = 2  # calls per test

    check = _grader_inputs(ex, tmp_path, None, public_only=True)
    graded = _grader_inputs(ex, tmp_path, "alice")  # public tests run first, then hidden ones
    assert len(check) == n and len(graded) == 2 * n
    # the notebook's default student and a named one see the public inputs of check and grade
    assert _in_process_inputs(ex, hidden=False) == check == graded[:n]
    assert _in_process_inputs(ex, "alice", hidden=False) == check
    # those are the calls built from public_seed, which differ from the student-seeded ones (so this
    # test tells the two seeds apart)
    built = [(c.function, plain_data(list(c.args)))
             for c in public.build(np.random.default_rng(public_seed(ex.id, public.name)))[0]]
    assert check == built
    for student in ("public", "alice"):
        other = public.build(np.random.default_rng(student_seed(student, ex.id, public.name)))[0]
        assert [(c.function, plain_data(list(c.args))) for c in other] != built
    # hidden tests keep the student's seed (no secret in the notebook path)
    assert _in_process_inputs(ex, "alice", hidden=True) == graded[n:]
    assert _in_process_inputs(ex, "bob", hidden=True) != graded[n:]


@pytest.mark.parametrize(
    "fraction, share",
    [(math.nan, 0.0), (math.inf, 0.0), (-math.inf, 0.0), (-0.5, 0.0), (0.25, 0.25), (1.5, 1.0)],
)
def test_in_process_clips_a_scorer_fraction_as_grade_does(tmp_path, fraction, share):
    from flowtrack_course.grading.engine.run import run_exercise

    ex = _drawing_exercise(fraction)
    results = run_in_process(ex, {"echo": lambda x: x}, student="alice")
    earned = {name: pts for name, pts, _, _ in results}
    assert earned == {t.name: t.points * share for t in ex.tests}
    assert not any(math.isnan(v) for v in earned.values())
    graded = run_exercise(ex, _echo_notebook(ex, tmp_path), "alice", sandbox_factory=RecordingSandbox)
    assert {t.name: t.score for t in graded.tests} == earned


# --------------------------------------------------------------------------------------------------
# independent oracle for exercise 9's expected values (the trusted tracker)
# --------------------------------------------------------------------------------------------------
def _bookkeeping_oracle(frames, min_hits, max_misses):
    """The rule of the exercise, written as plainly as possible (lists, no dicts of tracks)."""
    live = []  # [id, label, hits, misses, confirmed]
    nid = 0
    out = []
    for labels in frames:
        for t in live:
            if t[1] in labels:
                t[2], t[3] = t[2] + 1, 0
            else:
                t[3] += 1
            if t[2] >= min_hits:
                t[4] = True
        live = [t for t in live if not (t[3] > 0 and not t[4]) and t[3] <= max_misses]
        for lab in labels:
            if all(t[1] != lab for t in live):
                live.append([nid, lab, 1, 0, min_hits <= 1])
                nid += 1
        status = lambda t: "tentative" if not t[4] else ("coasting" if t[3] else "confirmed")  # noqa: E731
        out.append([[t[0], status(t)] for t in sorted(live)])
    return out


def test_ex09_tracker_follows_the_stated_rule():
    rng = np.random.default_rng(9)
    for trial in range(60):
        n_obj = int(rng.integers(1, 7))
        frames = [
            [int(v) for v in rng.permutation(n_obj)[: int(rng.integers(0, n_obj + 1))]]
            for _ in range(int(rng.integers(1, 30)))
        ]
        min_hits, max_misses = int(rng.integers(1, 4)), int(rng.integers(0, 5))
        expected_frames = exercise_module("ex09_track_management").expected_frames
        assert expected_frames(frames, min_hits, max_misses) == _bookkeeping_oracle(
            frames, min_hits, max_misses
        ), trial


def test_ex12_expected_values_match_the_sympy_data_term():
    """The rows and normal equations ex12 grades against equal sympy's derivation from the projection."""
    import sympy as sp

    from flowtrack.symbolic.rgbd import pixel_data_term

    ex12 = exercise_module("ex12_rgbd_data_term")

    d = pixel_data_term()
    X, Y, Z, fx, fy, Ix, Iy, Dx, Dy, cI, cD = d["symbols"]
    rI, rD = sp.symbols("r_I r_D", real=True)
    b_sym = -(cI * rI * d["a_I"] + cD * rD * d["a_D"])
    rng = np.random.default_rng(12)
    Xs, gi, ri, gd, rd, f_x, f_y = ex12._random_pixels(rng, 4)
    wi, wd = rng.uniform(0.0, 3000.0, 4), rng.uniform(0.0, 1e5, 4)
    a_i, a_d = ex12._rows(Xs, gi, gd, f_x, f_y)
    N, b = ex12._reference(Xs, gi, ri, gd, rd, f_x, f_y, wi, wd)
    for k in range(4):
        sub = {X: Xs[k, 0], Y: Xs[k, 1], Z: Xs[k, 2], fx: f_x, fy: f_y, Ix: gi[k, 0], Iy: gi[k, 1],
               Dx: gd[k, 0], Dy: gd[k, 1], cI: wi[k], cD: wd[k], rI: ri[k], rD: rd[k]}
        np.testing.assert_allclose(a_i[k], np.array(d["a_I"].subs(sub), dtype=float).ravel(), rtol=1e-10)
        np.testing.assert_allclose(a_d[k], np.array(d["a_D"].subs(sub), dtype=float).ravel(), rtol=1e-10)
        np.testing.assert_allclose(N[k], np.array(d["N"].subs(sub), dtype=float), rtol=1e-10, atol=1e-9)
        b_k = np.array(b_sym.subs(sub), dtype=float).ravel()
        np.testing.assert_allclose(b[k], b_k, rtol=1e-10, atol=1e-9)


def _markdown(ex_id: str) -> str:
    return "\n".join(c.source for c in _read(get_exercise(ex_id)).cells if c.cell_type == "markdown")


def test_ex12_says_n_is_half_the_hessian_and_b_minus_half_the_gradient():
    """N = 1/2 Hessian and b = -1/2 gradient of E_p at 0 (finite differences of the weighted energy,
    against the reference), and the notebook says so, in its text and in its test cell."""
    ex12 = exercise_module("ex12_rgbd_data_term")
    rng = np.random.default_rng(29)
    X, gi, ri, gd, rd, fx, fy = ex12._random_pixels(rng, 1)
    wi, wd = 2500.0, 62500.0
    N, b = (v[0] for v in ex12._reference(X, gi, ri, gd, rd, fx, fy, wi, wd))
    a_i, a_d = (v[0] for v in ex12._rows(X, gi, gd, fx, fy))

    def E(d):
        return wi * (ri[0] + a_i @ d) ** 2 + wd * (rd[0] + a_d @ d) ** 2

    h, eye = 1e-4, np.eye(3)
    grad = np.array([(E(h * e) - E(-h * e)) / (2 * h) for e in eye])
    hess = np.array([[(E(h * (e + f)) - E(h * (e - f)) - E(h * (f - e)) + E(-h * (e + f))) / (4 * h * h)
                      for f in eye] for e in eye])
    np.testing.assert_allclose(N, hess / 2, rtol=1e-5, atol=1e-6 * np.abs(N).max())
    np.testing.assert_allclose(b, -grad / 2, rtol=1e-6, atol=1e-9 * np.abs(grad).max())
    text = _markdown("ex12_rgbd_data_term")
    assert "half\nthe Hessian" in text or "half the Hessian" in text
    assert "minus half its gradient" in text
    test_cell = next(c.source for c in _read(get_exercise("ex12_rgbd_data_term")).cells
                     if _nbg(c).get("grade_id") == "test_normal_equations")
    assert not re.search(r"N and b are the Hessian and minus the gradient", test_cell)
    assert "half the Hessian" in test_cell


def test_ex12_does_not_claim_that_smoothing_makes_the_system_definite():
    """With stripes on a fronto-parallel plane, diag(N_p) + lam (L kron I3) keeps a null direction for
    every lam (the reference's N_p and grid Laplacian, numpy's eigenvalues): the notebook must not
    say that adding the smoothness term makes the system positive definite."""
    import scipy.sparse as sps

    from flowtrack.variational import grid_laplacian

    ex12 = exercise_module("ex12_rgbd_data_term")
    H, W = 3, 4
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    X = np.stack([(xx - 1.5) / 100.0, (yy - 1.0) / 100.0, np.ones_like(xx)], axis=-1).reshape(-1, 3)
    gi = np.column_stack([np.random.default_rng(1).uniform(0.5, 1.0, H * W), np.zeros(H * W)])
    gd = np.zeros((H * W, 2))
    N, _ = ex12._reference(X, gi, np.zeros(H * W), gd, np.zeros(H * W), 100.0, 100.0, 1.0, 1.0)
    for lam in (0.1, 10.0):
        A = (sps.block_diag(list(N)) + lam * sps.kron(grid_laplacian(H, W), sps.eye(3))).toarray()
        w, V = np.linalg.eigh(A)
        assert w[0] < 1e-12 * w[-1] < w[1]                          # exactly one null direction
        along = np.tile([0.0, 1.0, 0.0], (H * W, 1)) / np.sqrt(H * W)  # uniform motion along the stripes
        np.testing.assert_allclose(np.abs(V[:, 0].reshape(-1, 3)), along, atol=1e-9)
    text = " ".join(_markdown("ex12_rgbd_data_term").split())
    assert not re.search(r"(λ|\\lambda)[^.]*\bmakes\b[^.]*positive definite", text)
    assert "does not make the\nsystem positive definite".replace("\n", " ") in text


def test_ex12_grades_the_motion_a_pixel_cannot_see():
    """The question of the notebook is a graded answer: the unit vector along a_I x a_D, either sign
    per pixel; its length and a row of the data term are wrong."""
    ex = get_exercise("ex12_rgbd_data_term")
    ex12 = exercise_module("ex12_rgbd_data_term")
    assert "unseen_direction" in ex.answer_cells
    tests = [t for t in ex.tests if t.grade_id == "test_unseen"]
    assert {t.hidden for t in tests} == {False, True}
    a_i, a_d = ex12._rows(ex12._X, ex12._GI, ex12._GD, 100.0, 100.0)
    check = ex12.unseen_check(a_i, a_d)
    u = np.cross(a_i, a_d)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    assert check(Outcome(True, (u * [[1.0], [-1.0], [1.0]]).tolist()))[0] == 1.0
    assert check(Outcome(True, np.cross(a_i, a_d).tolist()))[0] == 0.0
    assert check(Outcome(True, (a_d / np.linalg.norm(a_d, axis=1, keepdims=True)).tolist()))[0] == 0.0


def test_ex12_null_dimension_matches_the_lessons_count_and_scipy():
    """The count ex12 grades against: the lesson's reasoning (random texture 0, stripes 1, no texture
    2, one textured pixel 0 for lam > 0; the per-pixel count for lam = 0) and scipy's null_space
    (an SVD with its own cut-off) on the grader's own inputs; the wrong answers differ from it."""
    import scipy.sparse as sps
    from scipy.linalg import null_space

    from flowtrack.variational import grid_laplacian

    ex12 = exercise_module("ex12_rgbd_data_term")
    rng = np.random.default_rng(2929)
    for kind, k in ex12.TEXTURES.items():
        for H, W in ((3, 3), (3, 5), (5, 4)):
            N = ex12._system(rng, kind, H, W)
            per_pixel = (2 if kind.startswith("flat") else 1) * H * W - (kind == "flat but one pixel")
            for lam in (0.0, 0.05, 5.0):
                want = per_pixel if lam == 0.0 else k
                A = (sps.block_diag(list(N)) + lam * sps.kron(grid_laplacian(H, W), sps.eye(3))).toarray()
                assert null_space(A, rcond=1e-11).shape[1] == want, (kind, H, W, lam)
                assert ex12.null_dimension_reference(N, H, W, lam) == want
                check = ex12.null_dimension_check(N, H, W, lam)
                assert check(Outcome(True, want))[0] == 1.0
                if lam > 0:
                    assert check(Outcome(True, per_pixel))[0] == 0.0
                    assert check(Outcome(True, 3 * H * W - want))[0] == 0.0


def test_ex07_gamma_is_the_log_likelihood_ratio_of_scipys_gaussian():
    """The gamma ex07 grades: (C - gamma) / 2 is the negative log-likelihood ratio of clutter against
    a true detection, -ln(P_D N(z; z_hat, S) / ((1 - P_D) lam_c)), with scipy's Gaussian density;
    the decision follows its sign, and the catalogued wrong gammas differ from it."""
    from scipy.stats import multivariate_normal

    ex07 = exercise_module("ex07_mahalanobis_gating")
    rng = np.random.default_rng(729)
    for m in (1, 2, 3):
        z_pred, S, Z = ex07._ex07_random(rng, 3, 4, m)
        P_D, lam_c = 0.85, 0.002
        g = ex07.association_gamma(S, P_D, lam_c)
        for i in range(3):
            for j in range(4):
                d = Z[j] - z_pred[i]
                C = d @ np.linalg.solve(S[i], d)
                pdf = multivariate_normal(z_pred[i], S[i]).pdf(Z[j])
                nllr = -np.log(P_D * pdf / ((1 - P_D) * lam_c))
                np.testing.assert_allclose((C - g[i]) / 2, nllr, rtol=1e-9, atol=1e-9)
        C = np.array([[g[0] - 0.5, g[0] + 0.5], [g[1] + 1.0, g[1] - 1.0], [0.0, g[2] + 3.0]])
        check = ex07._ex07_take_check(C, S, P_D, lam_c)
        take = [[True, False], [False, True], [bool(g[2] > 0), False]]
        assert check(Outcome(True, (g.tolist(), take)))[0] == 1.0
        logdet = np.linalg.slogdet(S)[1]
        wrong = g + m * np.log(2 * np.pi)                     # det(S) for det(2 pi S)
        assert check(Outcome(True, (wrong.tolist(), take)))[0] == 0.5
        wrong = g - (m * np.log(2 * np.pi) + logdet)          # det(2 pi S) not square-rooted
        assert check(Outcome(True, (wrong.tolist(), take)))[0] == 0.5


def test_ex06_velocity_nees_is_chi2_3_when_the_covariance_is_right():
    """The NEES ex06 grades: errors drawn from N(0, C + alpha^2 v v^T) give a mean near 3 (chi2_3,
    Monte Carlo with 20000 draws: its standard error is 0.017); a covariance 10x too confident in
    std gives 100 times that; the catalogued wrong answers differ from it."""
    ex06 = exercise_module("ex06_kalman_predict_update")
    rng = np.random.default_rng(606)
    K = 20000
    v_meas = rng.normal(scale=0.1, size=(K, 3))
    A = rng.normal(scale=0.01, size=(K, 3, 3))
    C = A @ np.swapaxes(A, 1, 2) + 1e-5 * np.eye(3)
    alpha = 0.5
    full = C + alpha**2 * np.einsum("ki,kj->kij", v_meas, v_meas)
    e = np.einsum("kij,kj->ki", np.linalg.cholesky(full), rng.normal(size=(K, 3)))
    eps, mean = ex06.velocity_nees_reference(v_meas, v_meas - e, C, alpha)
    explicit = np.array([e[k] @ np.linalg.inv(full[k]) @ e[k] for k in range(50)])
    np.testing.assert_allclose(eps[:50], explicit, rtol=1e-8)
    assert abs(mean - 3.0) < 0.07
    _, mean_small = ex06.velocity_nees_reference(v_meas, v_meas - 10.0 * e, C, alpha)
    assert 250.0 < mean_small < 350.0
    check = ex06._nees_check(v_meas[:5], v_meas[:5] - e[:5], C[:5], alpha)
    assert check(Outcome(True, (eps[:5].tolist(), float(eps[:5].mean()))))[0] == 1.0
    no_shared, _ = ex06.velocity_nees_reference(v_meas[:5], v_meas[:5] - e[:5], C[:5], 0.0)
    assert check(Outcome(True, (no_shared.tolist(), float(no_shared.mean()))))[0] == 0.0


def test_ex08_expected_optimum_matches_brute_force():
    """The Hungarian check's optimum (scipy) agrees with brute force on small matrices with ties."""
    assignment_check = exercise_module("ex08_hungarian").assignment_check

    rng = np.random.default_rng(8)
    for _ in range(30):
        M, N = (int(v) for v in rng.integers(1, 6, size=2))
        C = rng.integers(0, 3, size=(M, N)).astype(float)
        K = min(M, N)
        best = None
        for rows in itertools.permutations(range(M), K) if M > N else [tuple(range(M))]:
            for cols in itertools.permutations(range(N), K):
                s = sum(C[r, c] for r, c in zip(rows, cols))
                if best is None or s < best[0]:
                    best = (s, [[r, c] for r, c in zip(rows, cols)])
        assert assignment_check(C)(Outcome(True, best[1]))[0] == 1.0
        if K > 0 and np.ptp(C) > 0:
            worst = max(
                (sum(C[r, c] for r, c in zip(range(K), cols)), cols)
                for cols in itertools.permutations(range(N), K)
            )
            if M <= N and worst[0] > best[0]:
                pairs = [[r, c] for r, c in zip(range(K), worst[1])]
                assert assignment_check(C)(Outcome(True, pairs))[0] == 0.0


# --------------------------------------------------------------------------------------------------
# the same, through the grader's sandbox
# --------------------------------------------------------------------------------------------------
def _sandbox_score(ex, sources: dict[str, str], student: str = "sandbox-student") -> tuple[float, dict]:
    from grading_sandbox import Sandbox

    cells = [(gid, sources[gid]) for gid in ex.answer_cells]
    total = 0.0
    with Sandbox(cells, blocked=ex.blocked, packages=ex.packages) as sb:
        for t in ex.tests:
            calls, scorer = t.build(np.random.default_rng(student_seed(student, ex.id, t.name)))
            fraction, _ = scorer(sb.run(calls, timeout=t.timeout))
            total += t.points * fraction
        errors = dict(sb.cell_errors)
    return total, errors


def _sandbox_available() -> bool:
    try:
        import grading_sandbox  # noqa: F401
    except ImportError:
        return False
    return True


needs_sandbox = pytest.mark.skipif(
    not _sandbox_available(), reason="grading_sandbox not importable"
)


@needs_sandbox
@pytest.mark.parametrize("ex", EXERCISES, ids=IDS)
def test_sandbox_scores_solution_stub_wrong_and_cheat(ex):
    from flowtrack_course.grading.engine.notebook import extract_cells

    solution = dict(extract_cells(source_notebook(ex), ex.answer_cells))
    score, errors = _sandbox_score(ex, solution)
    assert score == pytest.approx(ex.max_score) and not errors
    stub = _answer_sources(_stub_notebook(ex), ex)
    assert _sandbox_score(ex, stub)[0] == 0.0
    assert 0.0 < _sandbox_score(ex, _wrong_sources(ex))[0] < ex.max_score
    # calling the blocked reference (which gives full marks in process) scores nothing in the sandbox
    cheat = _cheat_sources(ex)
    assert _score(run_in_process(ex, _namespace(cheat))) == pytest.approx(ex.max_score)
    assert _sandbox_score(ex, cheat)[0] == 0.0


# --------------------------------------------------------------------------------------------------
# nbgrader compatibility: a real kernel runs the source notebook; nbgrader reads partial credit
# --------------------------------------------------------------------------------------------------
def test_nbgrader_executes_notebook_with_partial_credit():
    pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    from nbclient import NotebookClient
    from nbgrader.utils import determine_grade

    ex = get_exercise("ex05_cv_model")
    nb = _read(ex)
    # right for dt < 1 only (the public test uses dt = 0.5): public asserts pass, hidden ones partly
    partial_body = cases(ex.id).WRONG["cv_process_noise"][1].replace(
        "Q = np.zeros((4, 4))", "if dt < 1:\n    return np.kron(q1d, np.eye(2))\nQ = np.zeros((4, 4))"
    )
    partial = copy.deepcopy(nb)
    for c in partial.cells:
        if _nbg(c).get("grade_id") == "cv_process_noise":
            c.source = _replace_solution(c.source, partial_body)
    expected = _score(run_in_process(ex, _namespace(_answer_sources(partial, ex)), cell="test_Q"))
    assert 2.0 < expected < 7.0
    grades = []
    for book in (nb, partial):
        book = copy.deepcopy(book)
        NotebookClient(book, timeout=120, kernel_name="python3", allow_errors=True).execute()
        grades.append(
            {_nbg(c)["grade_id"]: determine_grade(c)[0] for c in book.cells if _nbg(c).get("grade")}
        )
    assert grades[0] == {"test_F": 3.0, "test_Q": 7.0}
    assert grades[1] == {"test_F": 3.0, "test_Q": pytest.approx(expected)}
