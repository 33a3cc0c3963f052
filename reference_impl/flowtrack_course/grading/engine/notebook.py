"""Extracting the graded cells of an nbgrader notebook, without executing anything.

Cells are matched by ``metadata.nbgrader.grade_id`` (nbgrader's authoring format) and must be code
cells. The text is returned as data; nothing here imports, compiles or runs it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path

from .text import clip_message

__all__ = ["MAX_NOTEBOOK_BYTES", "NotebookError", "answer_cells", "extract_cells", "max_notebook_bytes",
           "read_notebook", "select_cells"]


# A notebook of the ten exercises is some 20 kB; outputs with figures make a few hundred kB.
MAX_NOTEBOOK_BYTES = 4 << 20


class NotebookError(ValueError):
    """A submission notebook that cannot be graded as it is (not JSON, not a notebook, cells missing)."""


def _source(cell: dict) -> str:
    src = cell.get("source", "")
    if isinstance(src, list):
        if not all(isinstance(s, str) for s in src):
            raise NotebookError("a cell's source is not text")
        return "".join(src)
    if not isinstance(src, str):
        raise NotebookError("a cell's source is not text")
    return src


def extract_cells(
    nb_path: str | Path, grade_ids: Sequence[str], *, max_bytes: int | None = None
) -> list[tuple[str, str]]:
    """Return ``(grade_id, source)`` of the requested code cells, in notebook order.

    Parameters
    ----------
    nb_path : str or Path
        The notebook file (``.ipynb``, nbformat 4).
    grade_ids : sequence of str
        The nbgrader ``grade_id`` values to extract. When a notebook holds the same id twice, the
        first cell wins.
    max_bytes : int, optional
        Largest notebook read (default :func:`max_notebook_bytes`).

    Returns
    -------
    list of (str, str)
        One entry per requested id, ordered as the cells appear in the notebook.

    Raises
    ------
    NotebookError
        The file is larger than ``max_bytes``, not JSON, not a notebook, a requested id is missing,
        or names a cell that is not a code cell.
    TypeError
        ``grade_ids`` is a string or holds non-strings.

    Examples
    --------
    >>> import json, tempfile, os
    >>> nb = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": [
    ...     {"cell_type": "code", "execution_count": None, "outputs": [], "id": "a",
    ...      "metadata": {"nbgrader": {"grade_id": "answer", "solution": True}},
    ...      "source": "def f(x):\\n    return x\\n"}]}
    >>> d = tempfile.mkdtemp(); p = os.path.join(d, "ex.ipynb")
    >>> _ = open(p, "w").write(json.dumps(nb))
    >>> extract_cells(p, ["answer"])
    [('answer', 'def f(x):\\n    return x\\n')]
    """
    if isinstance(grade_ids, str | bytes) or not all(isinstance(g, str) for g in grade_ids):
        raise TypeError("grade_ids must be a sequence of str (nbgrader grade ids)")
    return select_cells(read_notebook(nb_path, max_bytes=max_bytes), grade_ids, Path(nb_path).name)


def max_notebook_bytes() -> int:
    """The size cap of a notebook: ``$FLOWTRACK_MAX_NOTEBOOK_BYTES`` if set, else
    :data:`MAX_NOTEBOOK_BYTES`."""
    value = os.environ.get("FLOWTRACK_MAX_NOTEBOOK_BYTES", "").strip()
    if not value:
        return MAX_NOTEBOOK_BYTES
    try:
        n = int(value)
    except ValueError:
        n = 0
    if n <= 0:
        raise ValueError(f"FLOWTRACK_MAX_NOTEBOOK_BYTES must be a positive number of bytes, got {value!r}")
    return n


def read_notebook(nb_path: str | Path, *, max_bytes: int | None = None) -> list:
    """The raw cell dicts of a notebook (parsed once, with :func:`json.loads`; never more than
    ``max_bytes`` read: a larger file is refused before it is parsed)."""
    path = Path(nb_path)
    limit = max_notebook_bytes() if max_bytes is None else int(max_bytes)
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            raw = fh.read(limit + 1) if size <= limit else b""
    except OSError as exc:
        raise NotebookError(f"cannot read the notebook {path.name}: {exc.strerror or exc}") from None
    if size > limit or len(raw) > limit:
        raise NotebookError(
            f"{path.name} is {max(size, len(raw))} bytes, more than a notebook may have ({limit} bytes; "
            "clear its outputs)"
        )
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise NotebookError(f"{path.name} is not a notebook: it is not valid JSON") from None
    if not isinstance(data, dict) or not isinstance(data.get("cells"), list):
        raise NotebookError(f"{path.name} is not a notebook: it has no list of cells")
    return data["cells"]


def select_cells(cells: list, grade_ids: Sequence[str], name: str = "the notebook") -> list[tuple[str, str]]:
    """``(grade_id, source)`` of the requested code cells among the raw ``cells`` (see
    :func:`extract_cells`, whose errors it raises; ``name`` is the notebook's name in them)."""
    wanted = set(grade_ids)
    found: dict[str, tuple[int, str]] = {}
    for index, cell in enumerate(cells):
        if not isinstance(cell, dict):
            raise NotebookError(f"{name} is not a notebook: cell {index} is not an object")
        meta = cell.get("metadata") or {}
        nbg = meta.get("nbgrader") if isinstance(meta, dict) else None
        gid = nbg.get("grade_id") if isinstance(nbg, dict) else None
        if not isinstance(gid, str) or gid not in wanted or gid in found:
            continue
        if cell.get("cell_type") != "code":
            raise NotebookError(f"the cell {gid!r} in {name} is not a code cell")
        found[gid] = (index, _source(cell))
    missing = [g for g in grade_ids if g not in found]
    if missing:
        raise NotebookError(
            f"{name} has no cell with grade id {', '.join(map(repr, missing))} "
            "(was the cell deleted, or its metadata changed?)"
        )
    order = sorted(dict.fromkeys(grade_ids), key=lambda g: found[g][0])
    return [(g, found[g][1]) for g in order]


def answer_cells(notebook: Path, grade_ids: Sequence[str]) -> tuple[list[tuple[str, str]], list[str]]:
    """The answer cells of a submitted ``notebook`` that can be extracted, and a message for each that
    cannot (what :meth:`~.spec.Exercise.extract_cells` does for a notebook).

    A notebook that is missing or not JSON breaks every cell; a single missing cell breaks only the
    functions it defines (the others are still graded).
    """
    notebook = Path(notebook)
    if not notebook.is_file():
        return [], [f"notebook not submitted: {notebook.name}"]
    try:
        raw = read_notebook(notebook)  # size-capped, parsed once
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        return [], [clip_message(f"{type(exc).__name__}: {exc}")]
    try:
        return list(select_cells(raw, list(grade_ids), notebook.name)), []
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        first = clip_message(f"{type(exc).__name__}: {exc}")
    cells: list[tuple[str, str]] = []
    problems: list[str] = []
    for gid in grade_ids:
        try:
            cells += list(select_cells(raw, [gid], notebook.name))
        except (ValueError, OSError, UnicodeDecodeError) as exc:
            problems.append(clip_message(f"cell {gid!r}: {exc}"))
    if not cells:
        problems = [first]  # the whole notebook is unusable: say it once
    return cells, problems
