"""The lesson and solution notebooks run, prove what they teach, and stay free of outputs.

Every jupytext notebook under ``lessons/`` and ``solutions/`` is executed top to bottom in a fresh
kernel of this interpreter (their ``assert`` cells compare each derivation with flowtrack), in a
temporary working directory and without network. Runs under pytest-xdist: each test starts its own
kernel on its own ports.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from flowtrack_course.notebooks import is_jupytext_notebook

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_DIRS = ("lessons", "solutions")
IPYNB_DIRS = ("lessons", "exercises", "solutions")

# a sympy call that derives something (not just a symbol declaration)
_DERIVATION = re.compile(
    r"\b(diff|jacobian|euler_equations|integrate|solve|dsolve|series|limit|hessian|linsolve)\s*\("
)
_SYMPY_IMPORT = re.compile(r"^\s*(import sympy\b|from sympy\b)", re.MULTILINE)
_CODE_CELL = re.compile(r"^```\{code-cell\}[^\n]*\n(.*?)^```\s*$", re.DOTALL | re.MULTILINE)
_LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _notebooks(*dirs: str) -> list[Path]:
    found = []
    for d in dirs:
        for p in sorted((ROOT / d).glob("*.md")):
            if p.name.lower() != "readme.md" and is_jupytext_notebook(p):
                found.append(p)
    return found


def _ids(paths):
    return [str(p.relative_to(ROOT)) for p in paths]


NOTEBOOKS = _notebooks(*NOTEBOOK_DIRS)
LESSONS = _notebooks("lessons")


def _code(path: Path) -> str:
    return "\n".join(_CODE_CELL.findall(path.read_text(encoding="utf-8")))


def test_there_are_notebooks_to_run():
    assert LESSONS, "no lesson notebooks found under lessons/"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_executes(path, tmp_path):
    pytest.importorskip("jupytext")
    pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    from flowtrack_course.notebooks import execute_notebook

    nb = execute_notebook(path, timeout=300, cwd=tmp_path)
    assert any(c.cell_type == "code" for c in nb.cells)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_source_is_myst_with_a_python_kernel(path):
    head = path.read_text(encoding="utf-8").split("\n---", 1)[0]
    assert "format_name: myst" in head, f"{path.name}: not a jupytext MyST notebook"
    assert re.search(r"name:\s*python3", head), f"{path.name}: kernelspec must be python3"
    assert _CODE_CELL.search(path.read_text(encoding="utf-8")), f"{path.name}: no code cell"


@pytest.mark.parametrize("path", LESSONS, ids=_ids(LESSONS))
def test_lesson_contains_a_sympy_derivation(path):
    code = _code(path)
    assert _SYMPY_IMPORT.search(code), f"{path.name}: no code cell imports sympy"
    calls = sorted(set(_DERIVATION.findall(code)))
    assert calls, f"{path.name}: sympy is imported but nothing is derived (no diff/jacobian/solve/... call)"
    assert "lambdify" in code, f"{path.name}: the derivation is never turned into numbers and checked"
    assert re.search(r"^\s*(assert\b|np\.testing\.assert_)", code, re.MULTILINE), (
        f"{path.name}: no assertion compares the derivation with flowtrack"
    )


SOLUTIONS = _notebooks("solutions")


def test_problems_1_to_5_have_a_solution_notebook():
    names = [p.name for p in SOLUTIONS]
    for n in range(1, 6):
        assert any(name.startswith(f"problem{n}_") for name in names), f"no solution notebook for Problem {n}"


@pytest.mark.parametrize("path", SOLUTIONS, ids=_ids(SOLUTIONS))
def test_solution_derives_in_sympy_and_checks_numerically(path):
    code = _code(path)
    assert _SYMPY_IMPORT.search(code), f"{path.name}: no code cell imports sympy"
    assert "lambdify" in code, f"{path.name}: the derivation is never turned into numbers"
    assert re.search(r"^\s*(assert\b|np\.testing\.assert_)", code, re.MULTILINE), (
        f"{path.name}: no assertion checks the derivation numerically"
    )


def test_no_ipynb_with_outputs():
    bad = []
    for d in IPYNB_DIRS:
        for p in sorted((ROOT / d).rglob("*.ipynb")):
            if ".ipynb_checkpoints" in p.parts:
                continue
            nb = json.loads(p.read_text(encoding="utf-8"))
            for cell in nb.get("cells", []):
                if cell.get("cell_type") == "code" and (cell.get("outputs") or cell.get("execution_count")):
                    bad.append(str(p.relative_to(ROOT)))
                    break
    assert not bad, f"notebooks with outputs or execution counts (strip them with strip_outputs): {bad}"


def _readme_links() -> list[str]:
    text = (ROOT / "lessons" / "README.md").read_text(encoding="utf-8")
    text = re.sub(r"```.*?```", "", text, flags=re.DOTALL)  # ignore code blocks
    return [t for t in _LINK.findall(text) if not re.match(r"^[a-z]+:", t) and not t.startswith("#")]


def test_lessons_readme_links_resolve():
    links = _readme_links()
    assert links, "lessons/README.md links to nothing"
    missing = [t for t in links if not (ROOT / "lessons" / t.split("#", 1)[0]).exists()]
    assert not missing, f"broken links in lessons/README.md: {missing}"


def test_lessons_readme_lists_every_lesson():
    targets = {(ROOT / "lessons" / t.split("#", 1)[0]).resolve() for t in _readme_links()}
    unlisted = [p.name for p in LESSONS if p.resolve() not in targets]
    assert not unlisted, f"lessons missing from lessons/README.md: {unlisted}"
    text = (ROOT / "lessons" / "README.md").read_text(encoding="utf-8")
    numbered = re.findall(r"^\|\s*(\d+)\s*\|", text, re.MULTILINE)
    assert [int(n) for n in numbered] == list(range(1, 8)), "the index must list the seven planned lessons"


def test_execute_notebook_reports_the_failing_cell(tmp_path):
    pytest.importorskip("jupytext")
    pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    from flowtrack_course.notebooks import NotebookExecutionError, execute_notebook

    src = tmp_path / "broken.md"
    src.write_text(
        "---\njupytext:\n  text_representation:\n    extension: .md\n    format_name: myst\n"
        "kernelspec:\n  display_name: Python 3\n  language: python\n  name: python3\n---\n\n"
        "```{code-cell} ipython3\nimport os\nopen('made_here.txt', 'w').close()\n```\n\n"
        "```{code-cell} ipython3\nvalue = 41\nassert value == 42, 'the derivation is wrong'\n```\n",
        encoding="utf-8",
    )
    work = tmp_path / "work"
    work.mkdir()
    with pytest.raises(NotebookExecutionError) as info:
        execute_notebook(src, timeout=60, cwd=work)
    err = info.value
    assert err.cell_index == 1
    assert "assert value == 42" in err.source
    assert "AssertionError" in err.traceback and "the derivation is wrong" in err.traceback
    assert "\x1b[" not in str(err)  # readable in a terminal log: no ANSI colour codes
    assert (work / "made_here.txt").exists()  # the kernel ran in cwd
