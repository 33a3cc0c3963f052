"""A grader whose sandbox cannot run the exercise is the grader's problem, never the students' score.

A child that cannot import what the exercise's allowlist names (here: numpy without its bundled
library folder ``numpy.libs``, as a mirrored ``.venv`` once lost it) is a configuration error:
``flowtrack check`` prints it with the fix and no score; ``flowtrack grade`` says so once, before
grading anyone, and exits with status 3. A class whose every student failed an exercise in exactly
the same way is reported (students' own mistakes differ) and the run exits non-zero.
"""

from __future__ import annotations

import io
import shutil
import sys
from pathlib import Path

import pytest

from flowtrack_course.grading.check.check import check_notebook
from grading_helpers import StandInSandbox, get_exercise, run_grade_with, source_notebook
from grading_sandbox import Outcome
from grading_sandbox import launch as launch_module
from grading_sandbox.testing import use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

EX = get_exercise("ex05_cv_model")


@pytest.fixture
def lost_libraries(monkeypatch):
    """The sandbox's view of site-packages without the wheels' bundled libraries (``*.libs``)."""
    use_sandbox_mode("bwrap", monkeypatch)
    real = launch_module.package_entries

    def without_libs(site, packages):
        return [e for e in real(site, packages) if not e.endswith(".libs")]

    monkeypatch.setattr(launch_module, "package_entries", without_libs)
    import numpy

    if not (Path(numpy.__file__).parents[1] / "numpy.libs").is_dir():
        pytest.skip("this numpy has no bundled library folder")


def test_check_reports_a_configuration_error_instead_of_a_score(lost_libraries):
    out = io.StringIO()
    status = check_notebook(source_notebook(EX), stream=out)
    text = out.getvalue()
    assert status == 3, text
    assert "grader configuration error" in text and "cannot import numpy" in text and "Fix:" in text
    assert "public score" not in text and "0/1" not in text and "FAIL" not in text


def _class(tmp_path: Path, n: int) -> Path:
    subs = tmp_path / "subs"
    for i in range(n):
        (subs / f"s{i}").mkdir(parents=True)
        shutil.copy(source_notebook(EX), subs / f"s{i}" / EX.notebook)
    return subs


def test_grade_stops_before_grading_anyone_and_says_why_once(lost_libraries, tmp_path):
    subs = _class(tmp_path, 2)
    logged: list[str] = []
    run = run_grade_with(subs, tmp_path / "out", exercises=[EX], log=logged.append)
    assert run.status == 3
    assert run.reason.count("grader configuration error") == 1 and "Fix:" in run.reason
    assert not (tmp_path / "out" / "grades.csv").exists()
    assert not list((tmp_path / "out").glob("*/results.json"))


def test_grade_without_nbgrader_says_what_to_install_before_grading(tmp_path, monkeypatch):
    # a student install (no `grading` extra) used to grade the whole class, then end in a traceback
    monkeypatch.setitem(sys.modules, "nbgrader", None)
    run = run_grade_with(_class(tmp_path, 1), tmp_path / "out", exercises=[EX])
    assert run.status == 3 and "flowtrack[grading]" in run.reason and "nbgrader" in run.reason
    assert not (tmp_path / "out" / "grades.csv").exists()


class _DeadSandbox(StandInSandbox):
    """A sandbox whose child never starts (the same for everyone, whatever they wrote)."""

    isolation = "stand-in"

    def run(self, calls, timeout):
        return [Outcome(False, None, "the process exited (sys.exit / os._exit) with status 1 "
                        "(while running the notebook cells)") for _ in calls]


def test_a_class_failing_an_exercise_all_the_same_way_is_reported(tmp_path):
    subs = _class(tmp_path, 3)
    run = run_grade_with(subs, tmp_path / "out", exercises=[EX], sandbox_factory=_DeadSandbox)
    assert run.status == 3
    lines = [line for line in run.summary if "failed it the same way" in line]
    assert len(lines) == 1 and "3 students who submitted ex05_cv_model" in lines[0]
    assert "the process exited" in lines[0]  # in the grader's words (the hidden-safe category)
    assert (tmp_path / "out" / "grades.csv").is_file()  # the grades are written, and flagged


def test_a_class_of_stubs_and_own_answers_is_not_reported(tmp_path):
    """Students who left the stub, and one who answered: nothing the same-way check should name."""
    import nbformat

    from flowtrack_course.grading.assign.release import release_notebook

    subs = _class(tmp_path, 3)
    stub = release_notebook(nbformat.read(source_notebook(EX), as_version=4))
    for s in ("s1", "s2"):
        nbformat.write(stub, subs / s / EX.notebook)
    run = run_grade_with(subs, tmp_path / "out", exercises=[EX])
    assert not [line for line in run.summary if "failed it the same way" in line], run.summary
    assert run.status == 0
    shutil.rmtree(subs / "s0")  # only the stubs: not the grader's doing either
    run = run_grade_with(subs, tmp_path / "out2", exercises=[EX])
    assert run.status == 0 and not [line for line in run.summary if "the same way" in line]
