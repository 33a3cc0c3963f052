"""Project invariants: the set-up commands, CI entry point and notebook hygiene."""

import json
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_readme_gives_the_two_setup_commands():
    text = (ROOT / "README.md").read_text()
    assert "make demo" in text and "make test" in text


def test_readme_is_an_entry_page():
    """About 150 lines: what flowtrack is, the two commands, where each audience starts, one figure
    and the table of headline numbers; the long explanations live in docs/ and the exercises' README."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 180
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(figures) == 1 and (ROOT / figures[0]).is_file()
    for audience in ("student", "instructor", "self-study reader"):
        assert f"**{audience}**" in text
    for doc in ("docs/ARCHITECTURE.md", "docs/demo.md", "docs/course.md", "exercises/README.md"):
        assert f"]({doc})" in text, doc


def test_ci_runs_the_readme_test_command():
    lines = [ln.strip() for ln in (ROOT / ".ci/run").read_text().splitlines()]
    assert "make test" in lines


def _tracked(*patterns: str) -> list[str]:
    """Files git tracks that match ``patterns`` (read-only ``git ls-files``)."""
    res = subprocess.run(["git", "ls-files", "--", *patterns], cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, f"git ls-files failed: {res.stderr}"
    return res.stdout.split()


def notebooks_with_outputs(paths) -> list[str]:
    """The ``.ipynb`` files among ``paths`` that have a code cell with outputs or an execution count."""
    bad = []
    for path in paths:
        nb = json.loads(Path(path).read_text(encoding="utf-8"))
        code = [c for c in nb.get("cells", []) if c.get("cell_type") == "code"]
        if any(c.get("outputs") or c.get("execution_count") is not None for c in code):
            bad.append(str(path))
    return bad


_FRONT_MATTER = re.compile(r"\A---\s*\n(.*?)\n---\s*\n", re.DOTALL)


def _jupytext_sources() -> list[Path]:
    """Tracked ``.md`` files under lessons/ and solutions/ whose front matter has a ``jupytext:`` key."""
    found = []
    for rel in _tracked("lessons/*.md", "solutions/*.md"):
        m = _FRONT_MATTER.match((ROOT / rel).read_text(encoding="utf-8"))
        if m and re.search(r"^jupytext:", m.group(1), re.MULTILINE):
            found.append(ROOT / rel)
    return found


def test_no_committed_notebook_has_outputs():
    assert not notebooks_with_outputs(ROOT / rel for rel in _tracked("*.ipynb"))


def test_output_check_flags_a_notebook_with_outputs(tmp_path):
    """The check above is not vacuous: it catches outputs and execution counts, and passes clean ones."""
    nbformat = pytest.importorskip("nbformat")
    v4 = nbformat.v4

    def write(name, cell):
        nb = v4.new_notebook(cells=[v4.new_markdown_cell("# t"), cell])
        path = tmp_path / name
        nbformat.write(nb, str(path))
        return path

    clean = write("clean.ipynb", v4.new_code_cell("x = 1"))
    stream = write(
        "stream.ipynb",
        v4.new_code_cell("print(1)", outputs=[v4.new_output("stream", name="stdout", text="1\n")]),
    )
    result = write(
        "result.ipynb",
        v4.new_code_cell(
            "1", execution_count=3, outputs=[v4.new_output("execute_result", {"text/plain": "1"})]
        ),
    )
    counted = write("counted.ipynb", v4.new_code_cell("x = 1", execution_count=1))
    assert notebooks_with_outputs([clean]) == []
    assert notebooks_with_outputs([clean, stream, result, counted]) == [
        str(stream),
        str(result),
        str(counted),
    ]


def test_no_ipynb_is_tracked_under_lessons():
    assert _tracked("lessons/*.ipynb", "lessons/**/*.ipynb") == [], "lessons are MyST .md sources only"


def test_jupytext_sources_round_trip_to_notebooks_without_outputs(tmp_path):
    jupytext = pytest.importorskip("jupytext")
    sources = _jupytext_sources()
    dirs = {p.parent.name for p in sources}
    assert dirs == {"lessons", "solutions"}, f"expected jupytext sources in lessons/ and solutions/: {dirs}"
    written = []
    for src in sources:
        nb = jupytext.read(str(src))
        code = [c.source for c in nb.cells if c.cell_type == "code"]
        assert code, f"{src.name}: no code cell"
        out = tmp_path / (src.stem + ".ipynb")
        jupytext.write(nb, str(out), fmt="ipynb")
        back = jupytext.read(str(out))
        assert [c.source for c in back.cells if c.cell_type == "code"] == code, f"{src.name}: round trip"
        # and back to MyST: the same cells again
        again = jupytext.reads(jupytext.writes(back, fmt="md:myst"), fmt="md:myst")
        assert [(c.cell_type, c.source) for c in again.cells] == [(c.cell_type, c.source) for c in nb.cells]
        written.append(out)
    assert not notebooks_with_outputs(written)


def test_cli_help_on_every_subcommand():
    from flowtrack_course.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert sub.choices, "no sub-commands"
    for name, p in sub.choices.items():
        assert p.format_help().startswith("usage: flowtrack " + name)


ARCHITECTURE = ROOT / "docs" / "ARCHITECTURE.md"


def _module_tables() -> set[str]:
    """The modules named in the first column of docs/ARCHITECTURE.md's module tables
    (``flowtrack.kalman``; a short name after a full one, ``bayes``, is flowtrack.bayes)."""
    names = set()
    for line in ARCHITECTURE.read_text(encoding="utf-8").splitlines():
        cells = line.split("|")
        if len(cells) < 3 or not re.match(r"`flowtrack(_course)?\.\w+`", cells[1].strip()):
            continue
        ticked = re.findall(r"`([\w.]+)`", cells[1])
        package = ticked[0].rsplit(".", 1)[0]
        names |= {t if "." in t else f"{package}.{t}" for t in ticked}
    return names


def test_module_tables_match_the_code():
    """Every public top-level module of both packages is in the module tables of
    docs/ARCHITECTURE.md (the README's entry page points there), and every module there exists (the
    variational solvers, for one, live in flowtrack.variational)."""

    def public(package: str) -> set[str]:
        base = ROOT / "reference_impl" / package
        mods = {p.stem for p in base.glob("*.py")} | {p.parent.name for p in base.glob("*/__init__.py")}
        return {f"{package}.{m}" for m in mods if not m.startswith("_")}

    listed = _module_tables()
    code = public("flowtrack") | public("flowtrack_course")
    assert not code - listed, f"modules missing from the module tables: {sorted(code - listed)}"
    assert not listed - code, f"the module tables name modules that do not exist: {sorted(listed - code)}"
    assert "docs/ARCHITECTURE.md" in (ROOT / "README.md").read_text(encoding="utf-8")


def _headline():
    """``benchmarks/headline.py``, the generator of the README's table of headline numbers."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("headline", ROOT / "benchmarks" / "headline.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_headline_numbers_are_generated_from_the_results():
    """The README's table is what ``benchmarks/headline.py`` makes of ``benchmarks/RESULTS.md``
    now, and it has a row for every headline (none skipped)."""
    headline = _headline()
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text(encoding="utf-8")
    block = headline.table(results)
    assert block in readme, "README.md's headline numbers are stale: run python benchmarks/headline.py"
    assert headline.rewrite(readme, block) == readme
    rows = [ln for ln in block.splitlines() if ln.startswith("| ") and not ln.startswith("| what")]
    assert len(rows) == len(headline.ROWS) >= 10
    # the stale figures of the old hand-written table are gone
    assert "113 s" not in readme and "1.76 s" not in readme


def test_the_headline_generator_follows_the_results_and_refuses_missing_numbers():
    headline = _headline()
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text(encoding="utf-8")
    changed = results.replace("| whole class < 300 s | 40.5 s |", "| whole class < 300 s | 412.0 s |")
    assert changed != results
    row = next(ln for ln in headline.table(changed).splitlines() if "flowtrack grade --jobs 2`, 100" in ln)
    assert "412.0 s" in row and row.endswith("| **no** |")
    with pytest.raises(ValueError, match="grading wall time"):
        headline.table(results.replace("| whole class < 300 s |", "| the whole class |"))
    with pytest.raises(ValueError, match="no section"):
        headline.section(results, "# No such benchmark")


def test_readme_points_to_documents_that_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "API document" not in text  # there is none: the API reference is generated (make book)
    assert "out/book/api.html" in text
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)#\s]+)\)", doc.read_text(encoding="utf-8")):
            if not re.match(r"[a-z]+:", target):
                assert (doc.parent / target).exists(), (doc.name, target)
