"""Students answer in C++ (Eigen) and Octave, graded by the same grader.

Oracles: the problems' expected values (the Python reference) are checked against independent
formulas (finite differences, explicit inverses, the textbook matrices); the grader's scoring of
wrong answers is checked on outputs of the catalogued mistaken formulas; the instructor solutions
must earn full marks in the sandbox, their stubs 0, a wrong variant partial credit with its mistake
named, and a compile error becomes feedback with the compiler's message.
"""

from __future__ import annotations

import itertools
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from flowtrack_course.grading.assignment import Assignment
from flowtrack_course.grading.engine.discovery import discover
from flowtrack_course.grading.engine.mistakes import mistakes_of
from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.engine.spec import Outcome
from flowtrack_course.grading.grade import grade_class
from flowtrack_course.grading.languages import (
    PROBLEMS,
    TOOLCHAINS,
    LanguageSource,
    materialise,
    strip_solutions,
)
from flowtrack_course.grading.languages.exercises import _score_cases
from flowtrack_course.grading.sources import course_catalog
from grading_helpers import (
    COURSE_SET,
    LANGUAGE_EXERCISES,
    LANGUAGES,
    class_job,
    find_language_exercise,
    get_exercise,
    instructor_source,
    run_grade_with,
    source_notebook,
    student_job,
)
from grading_sandbox import bwrap_status

pytestmark = pytest.mark.xdist_group("sandbox")

REPO = Path(__file__).resolve().parents[1]
SOURCES = REPO / "exercises"
CATALOGUE = LANGUAGES.catalogue


def _ex(language: str, problem: str):
    ex = find_language_exercise(f"{language}_{problem}")
    assert ex is not None
    return ex


@pytest.fixture
def toolchain(request, monkeypatch):
    ok, why = bwrap_status()
    assert ok, f"bubblewrap must work for the language tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    TOOLCHAINS[request.param].check()  # a missing toolchain fails, it is never skipped silently
    return request.param


# -- the problems' expected values against independent oracles ------------------------------------
def test_cv_model_reference_is_the_textbook_matrix():
    for inp in [*PROBLEMS["cv_model"].public(), *PROBLEMS["cv_model"].hidden(np.random.default_rng(1))]:
        dt, q = inp["dt"], inp["q"]
        out = PROBLEMS["cv_model"].reference(inp)
        F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]])
        Q = q * np.array(
            [
                [dt**4 / 4, 0, dt**3 / 2, 0],
                [0, dt**4 / 4, 0, dt**3 / 2],
                [dt**3 / 2, 0, dt**2, 0],
                [0, dt**3 / 2, 0, dt**2],
            ]
        )
        np.testing.assert_allclose(out["F"], F, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(out["Q"], Q, rtol=1e-12, atol=1e-15)


def test_kalman_step_reference_matches_the_explicit_inverse_form():
    p = PROBLEMS["kalman_step"]
    for inp in [*p.public(), *p.hidden(np.random.default_rng(2))]:
        x, P, F, Q, H, R, z = (np.asarray(inp[k], float) for k in "x P F Q H R z".split())
        xp, Pp = F @ x, F @ P @ F.T + Q
        K = Pp @ H.T @ np.linalg.inv(H @ Pp @ H.T + R)
        out = p.reference(inp)
        np.testing.assert_allclose(out["x"], xp + K @ (z - H @ xp), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(out["P"], (np.eye(len(x)) - K @ H) @ Pp, rtol=1e-7, atol=1e-10)


def test_projection_jacobian_reference_matches_finite_differences():
    p = PROBLEMS["projection_jacobian"]
    for inp in [*p.public(), *p.hidden(np.random.default_rng(3))]:
        X = np.asarray(inp["X"], float)

        def proj(Y, inp=inp):
            return np.array([inp["fx"] * Y[0] / Y[2] + inp["cx"], inp["fy"] * Y[1] / Y[2] + inp["cy"]])

        h = 1e-6
        J = np.stack([(proj(X + h * e) - proj(X - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
        np.testing.assert_allclose(p.reference(inp)["J"], J, rtol=1e-6, atol=1e-6)


def test_mahalanobis_reference_matches_solve_and_the_gate():
    p = PROBLEMS["mahalanobis_gating"]
    for inp in [*p.public(), *p.hidden(np.random.default_rng(4))]:
        zp, S, Z = (np.asarray(inp[k], float) for k in ("z_pred", "S", "Z"))
        d2 = np.array([r @ np.linalg.solve(S, r) for r in Z - zp])
        out = p.reference(inp)
        np.testing.assert_allclose(out["d2"], d2, rtol=1e-10)
        # the gate decision, where d2 is not within rounding of the gate (another BLAS may round there)
        clear = np.abs(d2 - inp["gate"]) > 1e-9 * inp["gate"]
        np.testing.assert_array_equal(out["inside"][clear], (d2 <= inp["gate"]).astype(float)[clear])
        assert 0.0 < out["inside"].mean() < 1.0  # a never- or always-gating answer cannot score
    assert p.reference(p.public()[0])["inside"].tolist() == [1.0, 1.0, 0.0]  # 1, 4, 9.25 vs 9.21


def _brute_force_assignment(C: np.ndarray) -> np.ndarray:
    n, m = C.shape
    best = min(itertools.permutations(range(m), n), key=lambda cols: sum(C[i, j] for i, j in enumerate(cols)))
    return np.array(best, dtype=float)


def test_assignment_reference_is_the_brute_force_optimum_and_greedy_fails_where_meant():
    p = PROBLEMS["assignment"]
    from flowtrack_course.polyglot.problems.association import lsa_greedy

    for seed in range(4):
        hidden = p.hidden(np.random.default_rng(seed))
        greedy_right = []
        for inp in [*p.public(), *hidden]:
            C = np.asarray(inp["C"], float)
            assert C.shape[0] <= C.shape[1] <= C.shape[0] + 2
            want = _brute_force_assignment(C)
            np.testing.assert_array_equal(p.reference(inp)["assignment"], want)
            greedy_right.append(np.array_equal(lsa_greedy(inp)["assignment"], want))
        # public: greedy wrong, then right; hidden: right once, wrong twice (partial credit, named)
        assert greedy_right == [False, True, True, False, False], seed


# -- scoring: partial credit and the mistake catalogue, without a sandbox ---------------------------
def _score(*args, **kwargs):
    """The language grader's scoring of one call, its mistakes' messages from the course."""
    return _score_cases(*args, catalogue=CATALOGUE, **kwargs)


def _outcome(cases, outputs):
    return Outcome(
        True,
        {
            c["id"]: {"ok": True, "value": {k: np.asarray(v).tolist() for k, v in o.items()}}
            for c, o in zip(cases, outputs)
        },
    )


@pytest.mark.parametrize("problem", sorted(PROBLEMS))
def test_each_catalogued_mistake_gets_partial_credit_and_is_named(problem):
    p = PROBLEMS[problem]
    cases = [{"id": f"c{i}", "input": inp} for i, inp in enumerate(p.hidden(np.random.default_rng(5)))]
    expected = [{k: np.asarray(v, float) for k, v in p.reference(c["input"]).items()} for c in cases]
    score, msg = _score(p, cases, expected, _outcome(cases, expected), show=True)
    assert score == 1.0 and "mistake" not in msg
    assert p.mistakes
    for mid, wrong in p.mistakes:
        outputs = [{**exp, **wrong(c["input"])} for c, exp in zip(cases, expected)]
        score, msg = _score(p, cases, expected, _outcome(cases, outputs), show=True)
        assert 0.0 <= score < 1.0, (mid, score)
        if len(p.outputs) > 1 and set(wrong(cases[0]["input"])) != set(p.outputs):
            assert score > 0.0, mid  # the other outputs still count
        assert mid in mistakes_of(msg), (mid, msg)  # its line comes from the catalogue


def test_generic_mistakes_and_failures_are_reported():
    p = PROBLEMS["projection_jacobian"]
    cases = [{"id": "a", "input": p.public()[1]}, {"id": "b", "input": p.public()[0]}]
    exp = [{"J": np.asarray(p.reference(c["input"])["J"])} for c in cases]
    score, msg = _score(p, cases, exp, _outcome(cases, [{"J": -e["J"]} for e in exp]), show=True)
    assert score == 0.0 and mistakes_of(msg) == ("generic-sign",)
    score, msg = _score(p, cases, exp, _outcome(cases, [{"J": 2.5 * e["J"]} for e in exp]), show=True)
    assert mistakes_of(msg) == ("generic-scale",)
    # one case is a hint, not evidence; two factors are no constant one
    score, msg = _score(p, cases[:1], exp[:1], _outcome(cases[:1], [{"J": 2.5 * exp[0]["J"]}]), show=True)
    assert not mistakes_of(msg)
    score, msg = _score(p, cases, exp, _outcome(cases, [{"J": 2.5 * exp[0]["J"]}, {"J": 3 * exp[1]["J"]}]),
                        show=True)
    assert not mistakes_of(msg)
    score, msg = _score(p, cases[:1], exp[:1], _outcome(cases[:1], [{"J": [[1.0, 2.0]]}]), show=True)
    assert score == 0.0 and "shape (1, 2)" in msg
    score, msg = _score(p, cases, exp, Outcome(False, None, "build failed: error: x"), show=True)
    assert score == 0.0 and "build failed" in msg
    hidden_msg = _score(p, cases, exp, _outcome(cases, [{"J": -e["J"]} for e in exp]), show=False)[1]
    assert "case a" not in hidden_msg  # hidden tests: no per-case details in the public text


# -- stubs and the bundle ----------------------------------------------------------------------------
def test_strip_solutions_and_unbalanced_markers():
    text = "int f() {\n    // BEGIN SOLUTION\n    return 1;\n    // END SOLUTION\n}\n"
    assert strip_solutions(text, "cpp") == "int f() {\n    // YOUR CODE HERE\n}\n"
    with pytest.raises(ValueError, match="unbalanced"):
        strip_solutions("// BEGIN SOLUTION\nx\n", "cpp")


def test_every_language_exercise_has_an_instructor_source_with_markers():
    assert {ex.language for ex in LANGUAGE_EXERCISES} == {"cpp", "java", "mathics", "octave"}
    assert len(LANGUAGE_EXERCISES) == 19  # 4 problems x 4 languages, and the assignment in 3 of them
    in_assignment = [ex.language for ex in LANGUAGE_EXERCISES if ex.problem == "assignment"]
    assert in_assignment == ["cpp", "octave", "java"]
    for ex in LANGUAGE_EXERCISES:
        text = instructor_source(ex).read_text()
        assert "BEGIN SOLUTION" in text and "END SOLUTION" in text, ex.notebook
        assert LANGUAGES.guide(ex.language) is not None


def test_release_writes_stubs_tests_and_readmes_at_the_same_paths(tmp_path):
    written = LANGUAGES.release(SOURCES, tmp_path)
    assert sorted(written) == sorted(ex.notebook for ex in LANGUAGE_EXERCISES)
    for ex in LANGUAGE_EXERCISES:
        folder = tmp_path / ex.language / ex.problem
        stub = (tmp_path / ex.notebook).read_text()
        assert "SOLUTION" not in stub and "YOUR CODE HERE" in stub
        doc = json.loads((folder / "public.json").read_text())
        assert doc["problem"] == ex.problem and len(doc["cases"]) == len(PROBLEMS[ex.problem].public())
        for case in doc["cases"]:  # the public expected values are the reference's
            ref = PROBLEMS[ex.problem].reference(case["input"])
            for k, v in case["expected"].items():
                np.testing.assert_allclose(v, ref[k], rtol=0, atol=0)
        assert (tmp_path / ex.language / "README.md").is_file()
    assert (tmp_path / "cpp" / "kalman_step" / "CMakeLists.txt").read_text().count("kalman_step") >= 1


def test_sources_live_in_the_folder_of_the_exercise_they_are_a_form_of():
    for ex in LANGUAGE_EXERCISES:
        assert instructor_source(ex) == COURSE_SET.folder(ex.exercise) / ex.language / ex.source_name
    owners = {ex.problem: ex.exercise for ex in LANGUAGE_EXERCISES}
    assert owners == {"projection_jacobian": "ex01_projection_jacobian", "cv_model": "ex05_cv_model",
                      "kalman_step": "ex06_kalman_predict_update",
                      "mahalanobis_gating": "ex07_mahalanobis_gating", "assignment": "ex08_hungarian"}


def test_a_course_in_the_earlier_layout_releases_the_same_stubs(tmp_path):
    """Sources at ``exercises/<lang>/<problem>/<file>`` and guides at ``exercises/<lang>/README.md``
    (the layout before the sources moved into the exercises' folders) are still found."""
    course = tmp_path / "course"
    (course / "exercises" / "ex05_cv_model").mkdir(parents=True)
    shutil.copy(COURSE_SET.folder("ex05_cv_model") / "grading.py", course / "exercises" / "ex05_cv_model")
    for ex in LANGUAGE_EXERCISES:
        if ex.problem == "cv_model":
            legacy = course / "exercises" / ex.notebook
            legacy.parent.mkdir(parents=True)
            shutil.copy(instructor_source(ex), legacy)
            shutil.copy(LANGUAGES.guide(ex.language), legacy.parent.parent / "README.md")
    old = LanguageSource(discover(course))
    cv = [ex.id for ex in LANGUAGE_EXERCISES if ex.problem == "cv_model"]
    assert [ex.id for ex in old.exercises()] == cv
    written = old.release(course / "exercises", tmp_path / "old")
    assert LANGUAGES.release(SOURCES, tmp_path / "new")
    assert len(written) == 4
    for rel in written:
        folder = Path(rel).parent
        for f in sorted((tmp_path / "new" / folder).rglob("*")):
            if f.is_file():
                assert (tmp_path / "old" / folder / f.relative_to(tmp_path / "new" / folder)).read_bytes() \
                    == f.read_bytes(), f
        assert (tmp_path / "old" / folder.parent / "README.md").read_bytes() == \
            (tmp_path / "new" / folder.parent / "README.md").read_bytes()


# -- the sandbox: solutions, stubs, wrong variants, compile errors ---------------------------------
def _write(tmp_path: Path, ex, text: str) -> Path:
    p = tmp_path / "exercises" / ex.notebook
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


@pytest.mark.parametrize("toolchain", ["cpp", "java", "mathics", "octave"], indirect=True)
def test_solutions_get_full_marks(toolchain):
    slow = {"cpp": ["kalman_step", "mahalanobis_gating"], "mathics": ["kalman_step", "projection_jacobian"]}
    answered = [p for p in sorted(PROBLEMS) if find_language_exercise(f"{toolchain}_{p}")]
    problems = slow.get(toolchain, answered)
    for problem in problems:
        ex = _ex(toolchain, problem)
        r = run_exercise(ex, instructor_source(ex), "ana")
        assert r.isolation == "bwrap"
        assert r.score == r.max_score == 3.0, (ex.id, [t.message for t in r.tests], r.problems)


@pytest.mark.parametrize("toolchain", ["cpp", "java", "mathics", "octave"], indirect=True)
def test_stub_scores_zero_and_wrong_variant_gets_partial_credit_named(toolchain, tmp_path):
    ex = _ex(toolchain, "cv_model")
    source = instructor_source(ex).read_text()
    stub = _write(tmp_path / "stub", ex, strip_solutions(source, toolchain))
    r = run_exercise(ex, stub, "ana")
    assert r.score == 0.0, [t.message for t in r.tests]
    if toolchain == "cpp":  # the syllabus' blkdiag(Q1d, Q1d)
        wrong = source.replace(
            "Q.block<2, 2>(2 * i, 2 * k) = q * q1(i, k) * Eigen::Matrix2d::Identity();",
            "Q(2 * i + 0, 0) = 0.0; Q.setZero(); Q.block<2, 2>(0, 0) = q * q1; Q.block<2, 2>(2, 2) = q * q1;",
        )
    elif toolchain == "java":  # the continuous-time powers
        wrong = source.replace(
            "{{Math.pow(dt, 4) / 4, Math.pow(dt, 3) / 2}, {Math.pow(dt, 3) / 2, dt * dt}}",
            "{{Math.pow(dt, 3) / 3, dt * dt / 2}, {dt * dt / 2, dt}}",
        )
    elif toolchain == "mathics":  # transposed F
        wrong = source.replace(
            "F = {{1, 0, dt, 0}, {0, 1, 0, dt}, {0, 0, 1, 0}, {0, 0, 0, 1}};",
            "F = Transpose[{{1, 0, dt, 0}, {0, 1, 0, dt}, {0, 0, 1, 0}, {0, 0, 0, 1}}];",
        )
    else:
        wrong = source.replace(
            "Q = q * kron([dt^4 / 4, dt^3 / 2; dt^3 / 2, dt^2], eye(2));",
            "Q = q * kron([dt^3 / 3, dt^2 / 2; dt^2 / 2, dt], eye(2));",
        )
    assert wrong != source
    r = run_exercise(ex, _write(tmp_path / "wrong", ex, wrong), "ana")
    assert r.score == pytest.approx(1.5), [t.message for t in r.tests]  # one of F, Q right
    mistakes = {"cpp": "q-block-diagonal", "mathics": "generic-transpose"}
    mistake = mistakes.get(toolchain, "q-continuous-white-noise")
    assert all(mistake in t.mistakes for t in r.tests), [(t.message, t.mistakes) for t in r.tests]


@pytest.mark.parametrize("toolchain", ["cpp", "java"], indirect=True)
def test_compile_error_is_feedback_with_the_compilers_message(toolchain, tmp_path):
    ex = _ex(toolchain, "projection_jacobian")
    old = "J(0, 0) = fx * iz;" if toolchain == "cpp" else "J[0][0] = fx * iz;"
    bad = instructor_source(ex).read_text().replace(old, old.replace("iz", "undeclared_thing"))
    assert "undeclared_thing" in bad
    r = run_exercise(ex, _write(tmp_path, ex, bad), "ana")
    assert r.score == 0.0
    public = next(t for t in r.tests if not t.hidden)
    assert "build failed" in public.message and "undeclared_thing" in public.message, public.message


@pytest.mark.parametrize("toolchain", ["octave"], indirect=True)
def test_check_and_grade_commands_cover_the_languages(toolchain, tmp_path, capsys):
    from flowtrack_course.grading.check import check_notebook

    ex = _ex("octave", "projection_jacobian")
    assert check_notebook(instructor_source(ex)) == 0
    assert "public score: 1 / 1" in capsys.readouterr().out
    subs = tmp_path / "subs"
    _write(subs / "ana", ex, instructor_source(ex).read_text())
    _write(subs / "ben", ex, strip_solutions(instructor_source(ex).read_text(), "octave"))
    # answers in Octave count where the assignment says so (assignment.toml: languages = ["octave"])
    catalog = course_catalog(REPO, Assignment(languages=("octave",)))
    rows = {r["student"]: r for r in grade_class(class_job(subs, tmp_path / "out", progress=False,
                                                           catalog=catalog))}
    assert rows["ana"]["exercises"][ex.id] == 3.0 and rows["ben"]["exercises"][ex.id] == 0.0
    header = (tmp_path / "out" / "grades.csv").read_text().splitlines()[0].split(",")
    assert ex.id in header and "total" in header
    assert "cpp_cv_model" not in header  # only the assigned languages get columns
    results = json.loads((tmp_path / "out" / "ana" / "results.json").read_text())
    assert any(t["name"].startswith(ex.id) for t in results["tests"])
    assert (tmp_path / "out" / "ben" / "feedback" / f"{ex.id}.md").is_file()
    # `flowtrack grade` (run_grade: the layout check first) grades a class that answered only in Octave
    run = run_grade_with(subs, tmp_path / "out-cli", progress=False, log=lambda msg: None, catalog=catalog)
    assert run.status == 0, run.reason
    rows = {r["student"]: r for r in run.rows}
    assert rows["ana"]["exercises"][ex.id] == 3.0 and rows["ben"]["exercises"][ex.id] == 0.0


def test_materialise_solution_runs_the_octave_public_tests_locally(tmp_path):
    import shutil
    import subprocess

    octave = shutil.which("octave-cli")
    assert octave, "octave must be installed (make test installs it)"
    ex = _ex("octave", "mahalanobis_gating")
    materialise(ex, instructor_source(ex).parent, tmp_path, stub=False)
    proc = subprocess.run(
        [octave, "--norc", "run_public_tests.m"], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count(" PASS ") == 2


def test_materialise_solution_runs_the_java_public_tests_locally(tmp_path):
    import shutil
    import subprocess

    assert shutil.which("javac"), "a JDK must be installed (make test installs it)"
    ex = _ex("java", "projection_jacobian")
    materialise(ex, instructor_source(ex).parent, tmp_path, stub=False)
    proc = subprocess.run(
        ["sh", "run_public_tests.sh"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count(" PASS ") == 2


def test_mathics_harness_runs_the_public_tests_locally(tmp_path):
    import subprocess
    import sys

    ex = _ex("mathics", "projection_jacobian")
    materialise(ex, instructor_source(ex).parent, tmp_path, stub=False)
    cmd = [sys.executable, "ft_mathics.py", "--check", ex.problem, "public.json", "projection_jacobian.wl"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count(" PASS ") == 2


@pytest.mark.parametrize("toolchain", ["octave"], indirect=True)
def test_gradescope_run_grades_a_flat_language_upload(toolchain, tmp_path):
    from flowtrack_course.grading.export.gradescope import SETUP_SH, grader_requirements
    from flowtrack_course.grading.grade.gradescope import run_submission

    apt = " ".join(ln.rstrip("\\") for ln in SETUP_SH.splitlines() if not ln.lstrip().startswith("#"))
    for pkg in ("g++", "libeigen3-dev", "nlohmann-json3-dev", "octave", "openjdk-17-jdk-headless",
                "libgoogle-gson-java", "libejml-java"):
        assert f" {pkg} " in f" {apt} "  # the bundle's image gets the toolchains from Debian
    # and Mathics3 through the grader requirements the bundle installs (flowtrack itself --no-deps)
    assert 'pip" install -q -r "$ROOT/source/requirements-grader.txt"' in SETUP_SH
    reqs = [re.split(r"[<>=!~;\[ ]", r, maxsplit=1)[0].lower() for r in grader_requirements(REPO).split("\n")]
    assert "mathics3" in reqs
    ex = _ex("octave", "cv_model")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "cv_model.m").write_text(instructor_source(ex).read_text())  # a flat upload
    data = run_submission(tmp_path / "sub", tmp_path / "results.json", student="ana",
                          catalog=course_catalog(REPO, Assignment(languages=("octave",))))
    mine = [t for t in data["tests"] if t["name"].startswith(ex.id)]
    assert len(mine) == 2 and all(t["status"] == "passed" for t in mine), mine
    assert not any(t["name"].startswith("cpp_") for t in data["tests"])


@pytest.mark.parametrize("toolchain", ["octave"], indirect=True)
def test_language_answers_score_the_same_in_the_pool_and_fresh(toolchain, tmp_path):
    # grade_student runs the exercises in a SandboxPool by default: a language answer (a driver
    # that starts a compiler or interpreter inside the sandbox) must score as in a fresh sandbox,
    # right and wrong answers alike, beside a notebook exercise sharing the pool.
    import shutil

    from flowtrack_course.grading.engine.student import grade_student

    right, wrong = _ex("octave", "cv_model"), _ex("octave", "projection_jacobian")
    nb = get_exercise("ex05_cv_model")
    sub = tmp_path / "ana"
    _write(sub, right, instructor_source(right).read_text())
    _write(sub, wrong, strip_solutions(instructor_source(wrong).read_text(), "octave"))
    shutil.copy(source_notebook(nb), sub / nb.notebook)
    scores = {}
    for reuse in (True, False):
        s = grade_student(student_job("ana", sub, [right, nb, wrong], tmp_path / f"out{reuse}", force=True,
                                      reuse_sandboxes=reuse))
        scores[reuse] = s["exercises"]
    assert scores[True] == scores[False]
    assert scores[True][right.id] == right.max_score and scores[True][nb.id] == nb.max_score
    assert scores[True][wrong.id] == 0.0


_GREEDY = {
    "cpp": (
        "    // YOUR CODE HERE\n",
        "    std::vector<bool> taken(m, false);\n"
        "    for (int i = 0; i < n; ++i) {\n"
        "        int best = -1;\n"
        "        for (int j = 0; j < m; ++j)\n"
        "            if (!taken[j] && (best < 0 || C(i, j) < C(i, best))) best = j;\n"
        "        taken[best] = true;\n"
        "        a[i] = best;\n"
        "    }\n",
    ),
    "java": (
        "        // YOUR CODE HERE\n",
        "        boolean[] taken = new boolean[m];\n"
        "        for (int i = 0; i < n; i++) {\n"
        "            int best = -1;\n"
        "            for (int j = 0; j < m; j++)\n"
        "                if (!taken[j] && (best < 0 || C[i][j] < C[i][best])) best = j;\n"
        "            taken[best] = true;\n"
        "            a[i] = best;\n"
        "        }\n",
    ),
    "octave": (
        "  % YOUR CODE HERE\n",
        "  free = true(1, m);\n"
        "  for i = 1:n\n"
        "    c = C(i, :);\n"
        "    c(~free) = inf;\n"
        "    [~, a(i)] = min(c);\n"
        "    free(a(i)) = false;\n"
        "  end\n",
    ),
}


@pytest.mark.parametrize("toolchain", ["cpp", "java", "octave"], indirect=True)
def test_assignment_solution_stub_and_greedy(toolchain, tmp_path):
    ex = _ex(toolchain, "assignment")
    source = instructor_source(ex).read_text()
    r = run_exercise(ex, instructor_source(ex), "ana")
    assert r.score == r.max_score == 3.0, ([t.message for t in r.tests], r.problems)
    stub = strip_solutions(source, toolchain)
    r = run_exercise(ex, _write(tmp_path / "stub", ex, stub), "ana")
    assert r.score == 0.0, [t.message for t in r.tests]
    greedy = stub.replace(*_GREEDY[toolchain])
    assert greedy != stub
    r = run_exercise(ex, _write(tmp_path / "greedy", ex, greedy), "ana")
    # public: 1 of 2 cases (0.5 of 1 point); hidden: 1 of 3 (2/3 of 2 points)
    assert r.score == pytest.approx(0.5 + 2 / 3), [t.message for t in r.tests]
    assert all("greedy-assignment" in t.mistakes for t in r.tests), [(t.message, t.mistakes) for t in r.tests]


# -- what a failed program and a missing toolchain tell ------------------------------------------------


def test_a_failed_build_or_run_reaches_the_hidden_feedback_in_the_graders_words():
    from flowtrack_course.grading.engine.feedback import safe_text

    p = PROBLEMS["projection_jacobian"]
    cases = [{"id": "a", "input": p.public()[1]}]
    exp = [{"J": np.asarray(p.reference(cases[0]["input"])["J"])}]
    build = ("RuntimeError: build failed (g++, exit 1):\nprojection_jacobian.cpp:9:5: error: 0.123456\n"
             "projection_jacobian.cpp:12:1: error: x")
    score, msg = _score(p, cases, exp, Outcome(False, None, build), show=False,
                        source_name="projection_jacobian.cpp")
    assert score == 0.0 and "0.123456" in msg  # the public text: the compiler's own
    safe = safe_text(msg)
    assert safe.startswith("the build failed (g++): 2 compiler errors, the first at line 9"), safe
    assert "0.123456" not in safe
    # a run that printed no result: the category, never the exit status or the program's text
    run = "RuntimeError: the program printed no result (exit 55): 0.55"
    safe = safe_text(_score(p, cases, exp, Outcome(False, None, run), show=False)[1])
    assert safe == "the program printed no result", safe
    # an interpreter in the driver's process could raise the driver's words: no build report then
    safe = safe_text(_score(p, cases, exp, Outcome(False, None, build), show=False, builds=False,
                            source_name="projection_jacobian.cpp")[1])
    assert "line 9" not in safe and "0.123456" not in safe, safe


def test_stubs_state_the_interface_not_the_answer():
    """ex05 asks for Q's layout (kron(Q1d, I2) for the state [px, py, vx, vy]): no stub may say it."""
    header = REPO / "reference_impl/flowtrack_course/polyglot/files/cpp/cv_model.hpp"
    texts = {"cpp header": header.read_text()}
    for language in ("cpp", "java", "octave", "mathics"):
        ex = _ex(language, "cv_model")
        texts[language] = strip_solutions(instructor_source(ex).read_text(), language)
    for where, text in texts.items():
        assert not re.search(r"kron|Kronecker", text), where


def test_a_missing_toolchain_is_the_installation_not_the_students_fail(monkeypatch, tmp_path):
    from flowtrack_course.grading.check import check_notebook
    from flowtrack_course.grading.engine.spec import CannotGradeHere
    from flowtrack_course.polyglot.base import ToolchainMissing

    ex = _ex("mathics", "cv_model")

    def missing(self, ports=False):
        raise ToolchainMissing("Mathics3 is not installed: pip install 'flowtrack[mathics]'")

    monkeypatch.setattr(type(ex.toolchain), "check", missing)
    assert "Mathics3 is not installed" in ex.environment_problem()
    path = _write(tmp_path / "ana", ex, instructor_source(ex).read_text())
    with pytest.raises(CannotGradeHere, match="not the student's work"):
        run_exercise(ex, path, "ana")
    assert check_notebook(path) == 3  # not checked: no FAIL, no score


def test_hidden_feedback_of_wrong_outputs_carries_nothing_the_program_chose():
    """A program sees the hidden inputs: which cases fail, by how much and the shape it returns are
    its choice, so the hidden text is the same whatever wrong values it printed."""
    from flowtrack_course.grading.engine.feedback import safe_text

    p = PROBLEMS["projection_jacobian"]
    cases = [{"id": "a", "input": p.public()[1]}, {"id": "b", "input": p.public()[0]}]
    exp = [{"J": np.asarray(p.reference(c["input"])["J"])} for c in cases]
    texts = {
        safe_text(_score(p, cases, exp, _outcome(cases, [{"J": e["J"] + d} for e in exp]), show=False)[1])
        for d in (0.37, 55.0, 1e-3)
    }
    assert len(texts) == 1, texts
    (text,) = texts
    assert "case a" not in text and "0.37" not in text and "55" not in text, text
