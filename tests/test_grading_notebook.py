"""The answer cells of a submitted notebook: found by nbgrader grade id, never executed here.

(The sandbox's own tests, attack suite included, are in ``reference_impl/grading_sandbox/tests``.)
"""

import json

import pytest

from flowtrack_course.grading.engine.notebook import NotebookError, extract_cells

# -- extract_cells ----------------------------------------------------------------------------------


def _cell(gid, src, kind="code"):
    cell = {"cell_type": kind, "metadata": {"nbgrader": {"grade_id": gid, "solution": True}}, "source": src}
    if kind == "code":
        cell.update(execution_count=None, outputs=[])
    return cell


def _write_nb(path, cells):
    nb = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": cells}
    path.write_text(json.dumps(nb))
    return path


def test_extract_cells_order_duplicates_and_lists(tmp_path):
    nb = _write_nb(tmp_path / "a.ipynb", [
        _cell("intro", "# text", kind="markdown"),
        _cell("second", ["def g():\n", "    return 2\n"]),
        _cell("first", "def f():\n    return 1\n"),
        _cell("second", "def g():\n    return 'duplicate'\n"),
        {"cell_type": "code", "metadata": {}, "source": "x = 1", "outputs": [], "execution_count": None},
    ])
    got = extract_cells(nb, ["first", "second"])
    assert got == [("second", "def g():\n    return 2\n"), ("first", "def f():\n    return 1\n")]


@pytest.mark.parametrize(
    "content, match",
    [
        ("{not json", "not valid JSON"),
        ("[1, 2]", "no list of cells"),
        ('{"cells": 3}', "no list of cells"),
    ],
)
def test_extract_cells_rejects_non_notebooks(tmp_path, content, match):
    p = tmp_path / "bad.ipynb"
    p.write_text(content)
    with pytest.raises(NotebookError, match=match):
        extract_cells(p, ["answer"])


def test_extract_cells_missing_markdown_and_bad_arguments(tmp_path):
    nb = _write_nb(tmp_path / "a.ipynb", [_cell("answer", "x = 1"), _cell("text", "hi", kind="markdown")])
    with pytest.raises(NotebookError, match="no cell with grade id 'other'"):
        extract_cells(nb, ["answer", "other"])
    with pytest.raises(NotebookError, match="not a code cell"):
        extract_cells(nb, ["text"])
    with pytest.raises(NotebookError, match="cannot read"):
        extract_cells(tmp_path / "missing.ipynb", ["answer"])
    with pytest.raises(TypeError, match="grade_ids"):
        extract_cells(nb, "answer")
    assert issubclass(NotebookError, ValueError)

