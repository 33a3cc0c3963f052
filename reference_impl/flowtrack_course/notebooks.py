"""Run the course's lesson notebooks (jupytext MyST sources) and keep them free of outputs.

The lessons are kept as jupytext MyST Markdown files (``.md``) so that no output is ever committed.
:func:`execute_notebook` reads such a source with jupytext and runs every code cell with nbclient in a
fresh IPython kernel started from *this* interpreter (``sys.executable``), so the notebook sees the
same ``flowtrack`` as the caller. A failing cell raises :class:`NotebookExecutionError` naming the
notebook, the cell number, the cell's source and the kernel's traceback.

jupytext, nbformat, nbclient and ipykernel are needed only here (the ``lessons`` extra); they are
imported lazily so that ``import flowtrack_course.notebooks`` never fails.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

from flowtrack.validation import positive

__all__ = [
    "NotebookExecutionError",
    "execute_notebook",
    "is_jupytext_notebook",
    "read_notebook",
    "strip_outputs",
]

_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
_HEADER = re.compile(r"\A---\s*\n(.*?)\n---\s*\n", re.DOTALL)


class NotebookExecutionError(RuntimeError):
    """A cell of a notebook raised. Attributes: ``path``, ``cell_index``, ``source``, ``traceback``."""

    def __init__(self, path, cell_index, source, traceback):
        self.path = str(path)
        self.cell_index = cell_index
        self.source = source
        self.traceback = _ANSI.sub("", traceback)
        where = f"cell {cell_index}" if cell_index is not None else "an unknown cell"
        super().__init__(
            f"{self.path}: {where} failed\n"
            f"----- cell source -----\n{source}\n"
            f"----- traceback -----\n{self.traceback}"
        )


def is_jupytext_notebook(path) -> bool:
    """True if ``path`` is a Markdown file with a jupytext header (``jupytext:`` in its front matter).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> header = "---\\njupytext:\\n  text_representation:\\n    format_name: myst\\n---\\n"
    >>> _ = (d / "a.md").write_text(header)
    >>> _ = (d / "README.md").write_text("# Lessons\\n")
    >>> is_jupytext_notebook(d / "a.md"), is_jupytext_notebook(d / "README.md")
    (True, False)
    """
    p = Path(path)
    if p.suffix != ".md" or not p.is_file():
        return False
    m = _HEADER.match(p.read_text(encoding="utf-8"))
    return bool(m) and re.search(r"^jupytext:", m.group(1), re.MULTILINE) is not None


def read_notebook(path):
    """Read a jupytext source (``.md``, ``.py``) or an ``.ipynb`` into an nbformat v4 notebook."""
    import jupytext

    return jupytext.read(str(path))


def strip_outputs(nb):
    """Remove outputs, execution counts and execution metadata from every code cell, in place.

    Works on nbformat notebooks and on plain dicts of the same layout; returns ``nb``.

    Examples
    --------
    >>> nb = {"cells": [{"cell_type": "code", "source": "1", "execution_count": 3,
    ...                  "outputs": [{"output_type": "execute_result"}],
    ...                  "metadata": {"execution": {"iopub.status.busy": "..."}, "tags": ["x"]}},
    ...                 {"cell_type": "markdown", "source": "text", "metadata": {}}]}
    >>> strip_outputs(nb)["cells"][0]
    {'cell_type': 'code', 'source': '1', 'execution_count': None, 'outputs': [], 'metadata': {'tags': ['x']}}
    """
    for cell in nb["cells"]:
        if cell.get("cell_type") == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
            cell.get("metadata", {}).pop("execution", None)
    return nb


def _kernel_manager(kernel_name: str, socket_dir: str):
    """An AsyncKernelManager whose kernel is launched with ``sys.executable``.

    The kernel talks over Unix-domain sockets in ``socket_dir`` (a fresh directory per kernel), not
    TCP: jupyter_client picks TCP ports by binding port 0 and releasing it before the kernel binds,
    so kernels started at the same moment by parallel test workers (or anything else that opens a
    local port) can collide, and a collision shows up as a notebook that waits forever.
    """
    from jupyter_client.manager import AsyncKernelManager

    km = AsyncKernelManager(kernel_name=kernel_name, transport="ipc", ip=os.path.join(socket_dir, "k"))
    spec = km.kernel_spec
    if spec is not None and spec.language == "python":
        spec.argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    return km


def execute_notebook(path, timeout: float = 600, cwd=None, kernel_name: str = "python3"):
    """Execute a notebook (jupytext source or ``.ipynb``) top to bottom and return it with outputs.

    Parameters
    ----------
    path : str or Path
        The notebook; jupytext sources (MyST ``.md``, percent ``.py``) are converted in memory.
    timeout : float
        Seconds allowed per cell (> 0).
    cwd : str or Path, optional
        Working directory of the kernel (default: the notebook's folder). Pass a temporary
        directory to keep files a notebook writes out of the repository.
    kernel_name : str
        Kernel spec name; a Python kernel is always started from the current interpreter.

    Returns
    -------
    nbformat.NotebookNode
        The executed notebook (call :func:`strip_outputs` before saving it anywhere committed).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        ``timeout`` is not a finite number > 0 (``TypeError`` if it is not a number).
    NotebookExecutionError
        A cell raised (or timed out / the kernel died); the message holds the cell's source and the
        traceback.
    """
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError, CellTimeoutError, DeadKernelError

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"path: no notebook at {path}")
    timeout = positive(timeout, "timeout")
    cwd = Path(cwd) if cwd is not None else path.resolve().parent
    if not cwd.is_dir():
        raise ValueError(f"cwd must be an existing directory, got {cwd}")

    nb = read_notebook(path)
    env = dict(os.environ)
    # pytest's conftest forces Agg; the kernel should use its inline backend (no show() warnings).
    env.pop("MPLBACKEND", None)
    env.setdefault("PYDEVD_DISABLE_FILE_VALIDATION", "1")
    socket_dir = tempfile.mkdtemp(prefix="ftk-")  # short: Unix socket paths are limited to ~107 bytes
    km = _kernel_manager(kernel_name, socket_dir)
    client = NotebookClient(
        nb,
        km=km,
        timeout=timeout,
        kernel_name=kernel_name,
        resources={"metadata": {"path": str(cwd)}},
        allow_errors=False,
    )
    code_cells = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    try:
        client.execute(env=env, cwd=str(cwd))
    except CellExecutionError as exc:
        idx, src = _failing_cell(nb, code_cells)
        raise NotebookExecutionError(path, idx, src, str(exc)) from None
    except (CellTimeoutError, DeadKernelError) as exc:
        idx, src = _failing_cell(nb, code_cells)
        raise NotebookExecutionError(path, idx, src, f"{type(exc).__name__}: {exc}") from None
    finally:
        # nbclient leaves a kernel manager it did not create running: shut the kernel down here
        # (otherwise every executed notebook leaves a kernel behind until this process exits)
        _shutdown(km)
        shutil.rmtree(socket_dir, ignore_errors=True)
    return nb


def _shutdown(km) -> None:
    from jupyter_core.utils import run_sync

    try:
        if run_sync(km.is_alive)():
            run_sync(km.shutdown_kernel)(now=True)
    except Exception:  # a kernel that is already gone is fine
        pass


def _failing_cell(nb, code_cells):
    """The first code cell with an error output, else the last one that started executing."""
    last = None
    for i in code_cells:
        cell = nb.cells[i]
        if any(o.get("output_type") == "error" for o in cell.get("outputs", [])):
            return i, cell.source
        if cell.get("execution_count") is not None or cell.get("metadata", {}).get("execution"):
            last = i
    if last is None:
        return None, ""
    return last, nb.cells[last].source
