"""flowtrack works from a wheel installed outside any checkout, against a course folder named by
``--course``: the tooling never finds the course by counting its own parent folders.

The wheel is built from a copy of the sources (``pip wheel --no-deps``) and installed with
``--no-deps`` into a fresh virtual environment made without ``--system-site-packages``. Its
dependencies (numpy, scipy, open3d, nbgrader, ...) are not downloaded again: a ``.pth`` file in the
fresh environment adds the test environment's site-packages *after* its own. That keeps the test
offline and quick, and still proves the point: the flowtrack packages the fresh environment imports
are the wheel's (a ``.pth`` path line does not run the ``.pth`` files of the folder it adds, so the
editable install of this checkout stays invisible), checked below. (``--system-site-packages``
would not do: a venv made from this venv's interpreter sees the *base* interpreter's packages, not
this venv's.)

Then, from an unrelated folder and with ``$FLOWTRACK_COURSE`` unset, the installed ``flowtrack``
command runs ``release``, ``check``, ``grade``, ``gradescope`` and ``ports --lang octave``, each with
``--course <checkout>`` (the exercises are the course's folders, not part of the wheel).
Octave is a Debian package (``make test`` installs it); without it the test fails, never skips.
"""

from __future__ import annotations

import shutil
import site
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from wheel_helpers import build_wheel, clean_env, run

ROOT = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("wheel")]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv folder, environment without FLOWTRACK_COURSE) with the wheel installed."""
    tmp = tmp_path_factory.mktemp("wheel")
    env = clean_env()
    wheel = build_wheel(tmp, env)
    venv = tmp / "venv"
    run([sys.executable, "-m", "venv", venv], tmp, env)  # no --system-site-packages
    py = venv / "bin" / "python"
    run([py, "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel], tmp, env)
    purelib = "import sysconfig; print(sysconfig.get_path('purelib'))"
    fresh_site = Path(run([py, "-c", purelib], tmp, env).strip())
    ours = [p for p in site.getsitepackages() if Path(p).is_dir()] or [sysconfig.get_path("purelib")]
    (fresh_site / "zz_flowtrack_test_deps.pth").write_text("".join(p + "\n" for p in ours))
    return venv, env


def test_the_wheel_is_what_the_fresh_environment_imports(installed, tmp_path):
    venv, env = installed
    code = ("import flowtrack, flowtrack_course.grading.engine.run as g, grading_sandbox as s; "
            "print(flowtrack.__file__); print(g.__file__); print(s.__file__)")
    out = run([venv / "bin" / "python", "-c", code], tmp_path, env)
    for line in out.split():
        assert Path(line).is_relative_to(venv), f"{line} is not the installed wheel's"
        assert not Path(line).is_relative_to(ROOT)
    site = Path(out.split()[0]).parents[1]
    assert not (site / "grading_sandbox" / "tests").exists()  # the sandbox's tests stay in the checkout


def test_release_from_another_folder_with_course(installed, tmp_path):
    venv, env = installed
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = run([venv / "bin" / "flowtrack", "release", "--course", ROOT, "--out", tmp_path / "bundle"],
               elsewhere, env)
    assert "wrote" in out
    assert sorted(p.name for p in (tmp_path / "bundle" / "exercises").glob("*.ipynb")) == sorted(
        p.name for p in (ROOT / "exercises").glob("*/*.ipynb"))
    n_lessons = len(list((ROOT / "lessons").glob("[0-9]*.md")))
    assert len(list((tmp_path / "bundle" / "lessons").glob("*.ipynb"))) == n_lessons
    # the other languages' harness files are the wheel's package data (the polyglot stack's files/)
    lang = tmp_path / "bundle" / "exercises"
    for rel in ("cpp/cv_model/harness.cpp", "cpp/cv_model/exercise.hpp", "java/cv_model/Harness.java",
                "java/cv_model/api/KalmanStep.java", "octave/cv_model/ft_harness.m",
                "mathics/cv_model/ft_mathics.py", "octave/cv_model/public.json"):
        assert (lang / rel).is_file(), rel
    # without --course (and no $FLOWTRACK_COURSE) the current folder is the course: a clear error
    proc = subprocess.run([venv / "bin" / "flowtrack", "release", "--out", tmp_path / "b2"],
                          cwd=elsewhere, env=env, capture_output=True, text=True)
    assert proc.returncode == 2
    assert f"course folder {elsewhere.resolve()} (the current folder) has no exercises/, lessons/" in (
        proc.stderr
    )


def test_octave_port_from_another_folder_with_course(installed, tmp_path):
    venv, env = installed
    if shutil.which("octave") is None:
        pytest.fail("octave is missing: apt-get install octave (make test installs it)")
    out = run([venv / "bin" / "flowtrack", "ports", "--lang", "octave", "--course", ROOT, "--build-dir",
                tmp_path / "build", "--no-progress"], tmp_path, env)
    assert "octave" in out and " 0 failed" in out, out


def test_check_grade_and_gradescope_from_another_folder_with_course(installed, tmp_path):
    venv, env = installed
    flowtrack = venv / "bin" / "flowtrack"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    solution = ROOT / "exercises" / "ex05_cv_model" / "ex05_cv_model.ipynb"
    out = run([flowtrack, "check", "--course", ROOT, solution], elsewhere, env)
    assert "public score: 3 / 3" in out
    subs = tmp_path / "subs"
    (subs / "ana").mkdir(parents=True)
    shutil.copy(solution, subs / "ana" / solution.name)
    out = run([flowtrack, "grade", "--course", ROOT, subs, "--out", tmp_path / "graded", "--no-progress"],
               elsewhere, env)
    assert "graded 1 students" in out
    table = (tmp_path / "graded" / "grades.csv").read_text().splitlines()
    header, row = table[0].split(","), dict(zip(table[0].split(","), table[1].split(",")))
    assert header[0] == "student" and "ex05_cv_model" in header and float(row["ex05_cv_model"]) == 10.0
    run([flowtrack, "gradescope", "--course", ROOT, "--out", tmp_path / "ag.zip", "--exercises", "ex05"],
         elsewhere, env)
    assert (tmp_path / "ag.zip").is_file()
    import zipfile

    with zipfile.ZipFile(tmp_path / "ag.zip") as zf:
        names = zf.namelist()
    assert "course/exercises/ex05_cv_model/grading.py" in names
    assert "flowtrack/reference_impl/grading_sandbox/sandbox.py" in names
