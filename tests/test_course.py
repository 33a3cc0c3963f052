"""The one way the tooling finds the course folder: --course DIR, else $FLOWTRACK_COURSE, else the
current folder (flowtrack_course.course); never the tooling's own location."""

import ast
import os
from pathlib import Path

import pytest

from flowtrack_course.course import ENV, CourseNotFound, course_root, ports_dir, use_course, vectors_dir

ROOT = Path(__file__).resolve().parents[1]


def _course(tmp_path: Path, *parts: str) -> Path:
    for p in parts:
        (tmp_path / p).mkdir(parents=True)
    return tmp_path


def test_option_beats_environment_beats_current_folder(tmp_path, monkeypatch):
    a = _course(tmp_path / "a", "lessons", "exercises", "cpp_java_matlab_ports")
    b = _course(tmp_path / "b", "lessons", "exercises", "cpp_java_matlab_ports")
    c = _course(tmp_path / "c", "lessons", "exercises", "cpp_java_matlab_ports")
    monkeypatch.chdir(c)
    monkeypatch.delenv(ENV, raising=False)
    assert course_root() == c.resolve()
    monkeypatch.setenv(ENV, str(b))
    assert course_root() == b.resolve()
    assert course_root(a) == a.resolve()
    assert ports_dir(a) == a.resolve() / "cpp_java_matlab_ports"
    assert vectors_dir() == b.resolve() / "cpp_java_matlab_ports" / "vectors"


def test_the_error_names_the_folder_its_origin_and_what_is_missing(tmp_path, monkeypatch):
    d = _course(tmp_path, "lessons")
    monkeypatch.chdir(d)
    monkeypatch.delenv(ENV, raising=False)
    with pytest.raises(CourseNotFound, match=r"current folder\) has no exercises/, cpp_java_matlab_ports/"):
        course_root()
    monkeypatch.setenv(ENV, str(d / "nowhere"))
    with pytest.raises(FileNotFoundError, match=rf"nowhere \(from \${ENV}\) does not exist"):
        course_root()
    with pytest.raises(CourseNotFound, match=r"from --course\) has no pyproject.toml; pass --course DIR"):
        course_root(d, need=("lessons", "pyproject.toml"))
    with pytest.raises(TypeError, match="course"):
        course_root(3)
    with pytest.raises(TypeError, match="need"):
        course_root(d, need="lessons")


def test_use_course_exports_the_folder_to_what_runs_next(tmp_path, monkeypatch):
    d = _course(tmp_path, "cpp_java_matlab_ports")
    monkeypatch.setenv(ENV, "/nonexistent")
    assert use_course(d, need=("cpp_java_matlab_ports",)) == d.resolve()
    assert os.environ[ENV] == str(d.resolve())
    from flowtrack_course.ports import vectors

    assert vectors.PORTS_DIR == d.resolve() / "cpp_java_matlab_ports"  # looked up when read


def test_the_cli_commands_take_course(tmp_path, monkeypatch, capsys):
    from flowtrack_course.cli import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(ENV, raising=False)
    for argv in (["release", "--out", str(tmp_path / "b")], ["ports", "--lang", "octave"],
                 ["gradescope", "--out", str(tmp_path / "a.zip")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert f"course folder {tmp_path.resolve()} (the current folder) has no" in err, err
        assert main([*argv, "--course", str(tmp_path / "missing")]) == 2
        assert "(from --course) does not exist" in capsys.readouterr().err


def test_no_tool_counts_parent_folders():
    """No ``Path(__file__).parents[N]`` / ``.parent.parent`` in the packages: the course folder is
    chosen by the user, and the library's own folder is ``Path(flowtrack.__file__).parent``."""
    bad = []
    for path in sorted((ROOT / "reference_impl").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            text = ast.unparse(node) if isinstance(node, (ast.Attribute, ast.Subscript)) else ""
            if "__file__" in text and (".parents" in text or ".parent.parent" in text):
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno}: {text}")
    assert not bad, "\n".join(sorted(set(bad)))


def test_a_lesson_run_from_lessons_finds_its_course(tmp_path, monkeypatch):
    """`jupyter lab lessons/` runs a lesson in lessons/: the course is the folder holding it."""
    c = _course(tmp_path / "c", "lessons", "exercises", "cpp_java_matlab_ports")
    monkeypatch.delenv(ENV, raising=False)
    monkeypatch.chdir(c / "lessons")
    assert course_root() == c.resolve()
    # any other folder named lessons/ outside a course is still not one
    monkeypatch.chdir(_course(tmp_path / "x", "lessons") / "lessons")
    with pytest.raises(CourseNotFound):
        course_root()
