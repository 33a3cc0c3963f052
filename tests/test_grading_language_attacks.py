"""Attacks in C++, Java, Octave and Mathematica: each scores as an honest wrong answer, changes
nothing outside.

Every attack is a student's source file for a language exercise, graded by ``run_exercise`` under
bubblewrap (required). The answers are the stubs' (all zeros), so an honest submission scores 0 and
so must every attack: ``system()`` / ``Runtime.exec`` writing outside the sandbox, code at load time
(a C++ global constructor, a Java static initialiser, an Octave statement before the function),
fork bombs, infinite loops, huge output, and reading the reference (the Python ``flowtrack.kalman``
inside the sandbox, which must be a stub: the control run with it unblocked proves the attack would
otherwise earn full marks) or the instructor's solutions in the repository.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.languages import TOOLCHAINS, strip_solutions
from flowtrack_course.polyglot import toolchains as toolchains_module
from grading_helpers import find_language_exercise, instructor_source
from grading_sandbox import bwrap_status

pytestmark = pytest.mark.xdist_group("sandbox")

REPO = Path(__file__).resolve().parents[1]
SOLUTION = {
    "cpp": instructor_source(find_language_exercise("cpp_cv_model")),
    "octave": instructor_source(find_language_exercise("octave_cv_model")),
    "java": instructor_source(find_language_exercise("java_cv_model")),
    "mathics": instructor_source(find_language_exercise("mathics_cv_model")),
}


@pytest.fixture(autouse=True)
def _bwrap_and_short_limits(monkeypatch):
    ok, why = bwrap_status()
    assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    # Mathics3 alone needs several seconds to start: a shorter limit would make its attacks vacuous
    short = {
        k: dataclasses.replace(v, run_seconds=30.0 if k == "mathics" else 5.0) for k, v in TOOLCHAINS.items()
    }
    monkeypatch.setattr(toolchains_module, "TOOLCHAINS", short)
    monkeypatch.setitem(TOOLCHAINS, "cpp", short["cpp"])
    monkeypatch.setitem(TOOLCHAINS, "octave", short["octave"])
    monkeypatch.setitem(TOOLCHAINS, "java", short["java"])
    monkeypatch.setitem(TOOLCHAINS, "mathics", short["mathics"])


def _programs_left() -> list[int]:
    left = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if b"ft-attack" in (d / "cmdline").read_bytes() or (d / "cmdline").read_bytes().startswith(
                    b"./program\0cases.json"
                ):
                    left.append(int(d.name))
            except OSError:
                pass
    return left


def _grade(tmp_path: Path, language: str, text: str, exercise=None) -> tuple[float, list[str]]:
    ex = exercise or find_language_exercise(f"{language}_cv_model")
    path = tmp_path / "exercises" / ex.notebook
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    t0 = time.monotonic()
    r = run_exercise(ex, path, "mallory")
    assert time.monotonic() - t0 < 240
    time.sleep(0.5)
    assert _programs_left() == [], "an attack's process outlived its sandbox"
    return r.score, [t.message for t in r.tests] + r.problems


def _stub(language: str) -> str:
    return strip_solutions(SOLUTION[language].read_text(), language)


def _cpp_with(prelude: str) -> str:
    """The C++ stub with ``prelude`` (code at file scope) added after the include."""
    return _stub("cpp").replace('#include "exercise.hpp"\n', '#include "exercise.hpp"\n' + prelude, 1)


def _java_with(static: str) -> str:
    """The Java stub with a static initialiser (runs when the harness first touches the class)."""
    return _stub("java").replace(
        "    private CvModel() {}\n", "    static {\n" + static + "\n    }\n\n    private CvModel() {}\n", 1
    )


def _mathics_with(body: str) -> str:
    """The Mathematica stub with ``body`` evaluated inside the function."""
    return _stub("mathics").replace(
        "  (* YOUR CODE HERE *)\n", "  (* YOUR CODE HERE *)\n  " + body + ";\n", 1
    )


def _octave_with(body: str) -> str:
    """The Octave stub with ``body`` run at the start of the function."""
    return _stub("octave").replace("  F = zeros(4);\n", body + "\n  F = zeros(4);\n", 1)


def test_honest_stub_scores_zero_in_every_language(tmp_path):
    for language in ("cpp", "java", "mathics", "octave"):
        assert _grade(tmp_path / language, language, _stub(language))[0] == 0.0


def test_system_writing_outside_changes_nothing(tmp_path):
    outside = [tmp_path / "pwned-host", REPO / "pwned-by-student", Path.home() / "pwned-by-student"]
    cmd = "; ".join(f"echo ft-attack > {p}" for p in outside) + "; touch /usr/pwned /etc/pwned"
    cpp = _cpp_with(
        "#include <cstdlib>\n"
        f'static int attack = std::system("{cmd}");  // a global initialiser: runs before main\n'
    )
    octave = _octave_with(f"  system('{cmd}');")
    java = _java_with(
        "        try {\n"
        f'            Runtime.getRuntime().exec(new String[] {{"sh", "-c", "{cmd}"}}).waitFor();\n'
        "        } catch (Exception e) {\n"
        "            throw new RuntimeException(e);\n"
        "        }"
    )
    mathics = _mathics_with(f'Run["{cmd}"]')
    for language, text in (("cpp", cpp), ("octave", octave), ("java", java), ("mathics", mathics)):
        score, messages = _grade(tmp_path / language, language, text)
        assert score == 0.0, messages
        for p in outside:
            assert not p.exists(), p
    assert not Path("/usr/pwned").exists()


def test_fork_bombs_are_contained(tmp_path):
    cpp = _cpp_with(
        "#include <unistd.h>\nstatic int attack = [] { for (;;) fork(); return 0; }();  // ft-attack\n"
    )
    octave = _octave_with("  system('b() { b | b & }; b; sleep 100 # ft-attack');")
    java = _java_with(
        "        for (;;) {\n"
        "            try {\n"
        '                new ProcessBuilder("sh", "-c", "sleep 100 # ft-attack").start();\n'
        "            } catch (Exception e) {\n"
        "                // keep trying: the process limit must hold\n"
        "            }\n"
        "        }"
    )
    for language, text in (("cpp", cpp), ("octave", octave), ("java", java)):
        score, messages = _grade(tmp_path / language, language, text)
        assert score == 0.0, messages


def test_infinite_loops_time_out(tmp_path):
    cpp = _cpp_with("static volatile int attack = [] { volatile long i = 0; for (;;) ++i; return 0; }();\n")
    octave = _octave_with("  while true\n  end")
    java = _java_with("        for (long i = 0; ; ++i) { if (i < 0) break; }")
    for language, text in (("cpp", cpp), ("octave", octave), ("java", java)):
        score, messages = _grade(tmp_path / language, language, text)
        assert score == 0.0, messages
        assert any("timed out" in m for m in messages), messages


def test_huge_output_is_cut(tmp_path):
    cpp = _cpp_with(
        "#include <cstdio>\n"
        "static int attack = [] {\n"
        '    for (long i = 0; i < 100000000; ++i) std::puts("OUTPUT x {}");\n'
        "    return 0;\n}();\n"
    )
    octave = _octave_with("  for i = 1:10000000\n    printf('OUTPUT x {}\\n');\n  end")
    java = _java_with('        for (long i = 0; i < 100000000L; ++i) System.out.println("OUTPUT x {}");')
    for language, text in (("cpp", cpp), ("octave", octave), ("java", java)):
        score, messages = _grade(tmp_path / language, language, text)
        assert score == 0.0, messages
        # cut at the output cap, or stopped by the file-size limit / the time limit (then still cut)
        stopped = ("printed more than", "no result", "timed out")
        assert any(w in m for m in messages for w in stopped), messages


_STEAL = (
    "import sys, glob; "
    "sys.path[:0] = ['/opt/flowtrack-sandbox/lib'] + glob.glob('/opt/flowtrack-sandbox/site/*'); "
    "from flowtrack.kalman import constant_velocity_model as m; "
    "F, H, Q, R = m(float(sys.argv[1]), float(sys.argv[2]), 1.0, 2); "
    "print(' '.join(repr(float(v)) for v in list(F.ravel()) + list(Q.ravel())))"
)


def _cpp_steal() -> str:
    """Run the sandbox's own Python (the parent of the program) on the reference and print its answer."""
    return (
        '#include "exercise.hpp"\n#include <cstdio>\n#include <string>\n#include <unistd.h>\n'
        "void cv_model(double dt, double q, Eigen::Matrix4d& F, Eigen::Matrix4d& Q) {\n"
        '    std::string py = "/proc/" + std::to_string(getppid()) + "/exe";\n'
        f'    std::string cmd = py + " -I -S -c \\"{_STEAL}\\" ";\n'
        '    cmd += std::to_string(dt) + " " + std::to_string(q);\n'
        '    FILE* f = popen(cmd.c_str(), "r");\n'
        "    if (!f) return;\n"
        '    for (int i = 0; i < 16; ++i) if (std::fscanf(f, "%lf", &F(i / 4, i % 4)) != 1) break;\n'
        '    for (int i = 0; i < 16; ++i) if (std::fscanf(f, "%lf", &Q(i / 4, i % 4)) != 1) break;\n'
        "    pclose(f);\n}\n"
    )


def test_reading_the_reference_inside_the_sandbox_fails(tmp_path):
    real = find_language_exercise("cpp_cv_model")
    # control: with the reference not blocked the same attack earns marks (the test can fail)
    open_ex = dataclasses.replace(real, blocked=tuple(b for b in real.blocked if b != "flowtrack.kalman"))
    score, messages = _grade(tmp_path / "control", "cpp", _cpp_steal(), open_ex)
    assert score > 0.0, messages
    score, messages = _grade(tmp_path / "attack", "cpp", _cpp_steal(), real)
    assert score == 0.0, messages


def test_reading_the_instructor_solutions_fails(tmp_path):
    octave = _octave_with(
        "  try\n"
        f"    src = fileread('{SOLUTION['octave']}');\n"
        "    eval(regexprep(src, '^function.*?\\n', '', 'once'));\n"
        "  catch\n"
        "  end"
    )
    assert SOLUTION["octave"].is_file() and os.access(SOLUTION["octave"], os.R_OK)
    score, messages = _grade(tmp_path, "octave", octave)
    assert score == 0.0, messages
    # Mathics3 runs in the sandbox's own process: the instructor's file is not there either. The
    # attack loads it (its cvModel is the solution) and renames the stub's own definition.
    get = f'Get["{SOLUTION["mathics"]}"];\ncvModel0[dt_, q_] :='
    mathics = _stub("mathics").replace("cvModel[dt_, q_] :=", get, 1)
    assert "cvModel0" in mathics
    # control: run outside any sandbox (the bundle's own harness), the attack passes the public tests
    from flowtrack_course.grading.languages import materialise

    ex = find_language_exercise("mathics_cv_model")
    local = tmp_path / "local"
    materialise(ex, SOLUTION["mathics"].parent, local, stub=True)
    (local / "cv_model.wl").write_text(mathics)
    cmd = [sys.executable, "ft_mathics.py", "--check", "cv_model", "public.json", "cv_model.wl"]
    proc = subprocess.run(cmd, cwd=local, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and proc.stdout.count(" PASS ") == 2, proc.stdout + proc.stderr
    score, messages = _grade(tmp_path / "mathics", "mathics", mathics)
    assert score == 0.0, messages


def test_mathics_fork_bomb_loop_and_output_are_contained(tmp_path):
    attacks = {
        "fork": _mathics_with('Run["b() { b | b & }; b; sleep 100 # ft-attack"]'),
        "loop": _mathics_with("While[True, Null]"),
        "output": _mathics_with('Do[Print["OUTPUT x {}"], {i, 10^7}]'),
    }
    for kind, text in attacks.items():
        score, messages = _grade(tmp_path / kind, "mathics", text)
        assert score == 0.0, (kind, messages)
