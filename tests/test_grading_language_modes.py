"""Answers in other languages outside bubblewrap, and re-grading when the grader's files change.

* setpriv (a Gradescope container: root, no namespaces): the child that compiles and runs a C++,
  Java or Octave answer (or runs Mathics3 in-process) is a fresh unprivileged uid; a solution earns
  full marks, its stub 0, and a C++
  global constructor that calls ``system()`` to write into the grader's folders scores 0 and writes
  nothing (only the uid's file permissions stop it: the audit hook never sees a C++ program).
* fallback (a student's laptop, ``flowtrack check``): the same solutions earn full marks.
* ``exercises_hash`` covers the language harness, driver and toolchain files: a change of any of them
  re-grades finished students.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.engine.student import exercises_hash
from flowtrack_course.grading.languages import TOOLCHAINS, strip_solutions
from flowtrack_course.grading.languages.exercises import LanguageExercise
from grading_helpers import find_language_exercise, instructor_source, use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

REPO = Path(__file__).resolve().parents[1]


def _grade(tmp_path: Path, ex_id: str, text: str | None = None):
    ex = find_language_exercise(ex_id)
    TOOLCHAINS[ex.language].check()  # a missing toolchain fails, it is never skipped silently
    src = instructor_source(ex)
    path = tmp_path / ex.id / "exercises" / ex.notebook
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(src.read_text() if text is None else text)
    r = run_exercise(ex, path, "mallory")
    return r, [t.message for t in r.tests] + r.problems


@pytest.mark.parametrize(
    "ex_id", ["cpp_cv_model", "octave_projection_jacobian", "java_kalman_step", "mathics_cv_model"]
)
def test_setpriv_solution_full_marks_stub_zero(ex_id, tmp_path, monkeypatch, tmp_path_factory):
    use_sandbox_mode("setpriv", monkeypatch, tmp_path_factory)
    r, messages = _grade(tmp_path / "solution", ex_id)
    assert r.isolation == "setpriv"
    assert r.score == r.max_score == 3.0, messages
    ex = find_language_exercise(ex_id)
    stub = strip_solutions((instructor_source(ex)).read_text(), ex.language)
    r, messages = _grade(tmp_path / "stub", ex_id, stub)
    assert r.score == 0.0, messages


def test_setpriv_cpp_system_attack_scores_zero_and_writes_nothing(tmp_path, monkeypatch, tmp_path_factory):
    use_sandbox_mode("setpriv", monkeypatch, tmp_path_factory)
    private = tmp_path / "grader"  # the grader's folders: private to root, as flowtrack grade requires
    private.mkdir(mode=0o700)
    outside = [private / "pwned", REPO / "pwned-by-student"]
    cmd = "; ".join(f"echo ft-attack > {p}" for p in outside)
    ex = find_language_exercise("cpp_cv_model")
    stub = strip_solutions((instructor_source(ex)).read_text(), "cpp")
    attack = stub.replace(
        '#include "exercise.hpp"\n',
        '#include "exercise.hpp"\n#include <cstdlib>\n'
        f'static int attack = std::system("{cmd}");  // a global constructor: runs before main\n',
        1,
    )
    assert attack != stub
    r, messages = _grade(tmp_path, "cpp_cv_model", attack)
    assert r.isolation == "setpriv"
    assert r.score == 0.0, messages
    for p in outside:
        assert not p.exists(), p


@pytest.mark.parametrize("ex_id", ["octave_cv_model", "cpp_projection_jacobian", "mathics_cv_model"])
def test_fallback_solution_full_marks(ex_id, tmp_path, monkeypatch, tmp_path_factory):
    use_sandbox_mode("fallback", monkeypatch, tmp_path_factory)
    r, messages = _grade(tmp_path, ex_id)
    assert r.isolation.startswith("fallback"), r.isolation
    assert r.score == r.max_score == 3.0, messages


def test_exercises_hash_covers_the_language_files(tmp_path, monkeypatch):
    ex = find_language_exercise("cpp_kalman_step")
    names = {p.name for p in ex.source_files()}
    assert {"driver.py", "toolchains.py", "cpp.py", "kalman.py", "harness.cpp", "kalman_step.hpp"} <= names
    java = {p.name for p in find_language_exercise("java_cv_model").source_files()}
    assert {"Harness.java", "CvModel.java"} <= java
    octave = {p.name for p in find_language_exercise("octave_cv_model").source_files()}
    assert "ft_harness.m" in octave and "harness.cpp" not in octave

    # the hash reads what source_files() names: editing one of them changes it, restoring restores it
    copy = tmp_path / "harness.cpp"
    copy.write_text("// the grader's harness\n")
    monkeypatch.setattr(LanguageExercise, "source_files", lambda self: [copy])
    before = exercises_hash([ex])
    assert exercises_hash([ex]) == before
    copy.write_text("// the grader's harness, changed\n")
    changed = exercises_hash([ex])
    assert changed != before
    copy.write_text("// the grader's harness\n")
    assert exercises_hash([ex]) == before
