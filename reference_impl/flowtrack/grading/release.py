"""``flowtrack release --out DIR``: the student bundle.

::

    DIR/README.md                    how to work and check (for students)
    DIR/lessons/<name>.ipynb         the lessons (jupytext sources converted, no outputs)
    DIR/exercises/<path>.ipynb       the exercise notebooks, same relative paths as exercises/

The exercise notebooks go through nbgrader's own preprocessors, in the order nbgrader's
``generate_assignment`` runs them (without its database step): ``LockCells``, ``ClearSolutions``
(``### BEGIN SOLUTION`` ... ``### END SOLUTION`` -> ``raise NotImplementedError()``), ``ClearOutput``,
``CheckCellMetadata``, ``ComputeChecksums``, ``ClearHiddenTests`` (``### BEGIN HIDDEN TESTS`` blocks
removed), ``ClearMarkScheme``, ``ComputeChecksums``, ``CheckCellMetadata``. The bundle is then
scanned (:func:`scan_bundle`); any solution marker, hidden-test marker, output or ``solutions/``
folder left in it aborts the release.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path

__all__ = ["find_course_root", "release", "release_notebook", "scan_bundle"]

MARKER = ".flowtrack-release"
FORBIDDEN = ("BEGIN SOLUTION", "END SOLUTION", "BEGIN HIDDEN TESTS", "END HIDDEN TESTS", "BEGIN MARK SCHEME")

STUDENT_README = """\
# flowtrack: lessons and exercises

This folder is your copy of the course: `lessons/` holds the lesson notebooks, `exercises/` the
graded exercises. Work in Jupyter (`jupyter lab` in this folder).

## Doing an exercise

1. Open an exercise notebook in `exercises/`. Read the text and the docstring of each function you
   are asked to write: it gives the shapes of the inputs and of the result.
2. Replace each `raise NotImplementedError()` with your code. Keep the function names and arguments;
   only the cells marked as answer cells are graded, so put all your code there. Import only the
   modules the exercise allows (using the `flowtrack` function you are asked to write scores nothing).
3. Run the notebook's public test cells: they show what is expected.
4. Check your work from a terminal:

   ```bash
   flowtrack check exercises/<exercise>.ipynb
   ```

   It runs the public tests in a sandbox exactly as the grader will, prints a table of the tests with
   what was expected (values, shapes) and your public score, and exits with status 0 when every
   public test passes.

## How you are graded

Your instructor grades the notebooks you hand in (same file names) with `flowtrack grade`. The
public tests are the ones you see; hidden tests check the same functions on other, randomised inputs
(different for every student) with stated tolerances, with partial credit. Your code runs in a
separate sandboxed process with limits on time, memory and output; editing the test cells of the
notebook changes nothing, and code that crashes, loops forever or exhausts memory scores 0 on that
test only. Your feedback lists the public tests in detail and the hidden tests by name and score.
"""


def find_course_root(start: str | os.PathLike | None = None) -> Path:
    """The course folder (holding ``exercises/`` and ``lessons/``).

    Searched from ``start`` (default: the current folder) upwards, then from the installed package's
    source tree (an editable install lives in ``<course>/reference_impl/flowtrack``).

    Raises
    ------
    FileNotFoundError
        No folder with both ``exercises/`` and ``lessons/`` was found.
    """
    candidates = []
    here = Path(start or Path.cwd()).resolve()
    candidates += [here, *here.parents]
    pkg = Path(__file__).resolve().parents[3]
    candidates += [pkg]
    for c in candidates:
        if (c / "exercises").is_dir() and (c / "lessons").is_dir():
            return c
    raise FileNotFoundError(
        f"source: no course folder (with exercises/ and lessons/) at or above {here} or at {pkg}"
    )


def _preprocessors():
    from nbgrader.preprocessors import (
        CheckCellMetadata,
        ClearHiddenTests,
        ClearOutput,
        ClearSolutions,
        ComputeChecksums,
        LockCells,
    )

    try:
        from nbgrader.preprocessors import ClearMarkScheme
    except ImportError:  # pragma: no cover - older nbgrader
        ClearMarkScheme = None
    chain = [
        LockCells(),
        ClearSolutions(),
        ClearOutput(),
        CheckCellMetadata(),
        ComputeChecksums(),
        ClearHiddenTests(),
        *([ClearMarkScheme()] if ClearMarkScheme is not None else []),
        ComputeChecksums(),
        CheckCellMetadata(),
    ]
    return chain


def release_notebook(nb):
    """Apply nbgrader's release preprocessors to an nbformat notebook; returns the student version."""
    import nbformat

    nb = nbformat.from_dict(json.loads(json.dumps(nb)))
    resources: dict = {"nbgrader": {}}
    for pp in _preprocessors():
        nb, resources = pp.preprocess(nb, resources)
    nb.metadata.pop("widgets", None)
    return nb


def _iter_exercise_notebooks(root: Path):
    for p in sorted((root / "exercises").rglob("*.ipynb")):
        rel = p.relative_to(root / "exercises")
        if any(part.startswith(".") for part in rel.parts):
            continue
        yield p, rel


def scan_bundle(bundle: str | os.PathLike) -> list[str]:
    """Problems of a bundle: solution / hidden-test markers, notebook outputs, ``solutions/``.

    Returns an empty list for a clean bundle.
    """
    bundle = Path(bundle)
    problems = []
    for p in sorted(bundle.rglob("*")):
        rel = p.relative_to(bundle)
        if "solutions" in rel.parts:
            problems.append(f"{rel}: a solutions folder")
        if not p.is_file():
            continue
        try:
            text = p.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue
        for marker in FORBIDDEN:
            if marker in text:
                problems.append(f"{rel}: contains {marker!r}")
        if p.suffix == ".ipynb":
            nb = json.loads(text)
            for i, cell in enumerate(nb.get("cells", [])):
                if cell.get("outputs") or cell.get("execution_count"):
                    problems.append(f"{rel}: cell {i} has outputs")
    return problems


_SOLUTION_LINK = re.compile(r"\[([^\]]*)\]\((?:\.\./)+solutions/[^)]*\)")


def _unlink_solutions(markdown: str) -> str:
    """Markdown links into ``solutions/`` (not part of the bundle) reduced to their text.

    >>> print(_unlink_solutions("see [the errata](../solutions/errata.md)."))
    see the errata (in the instructor's copy of the course).
    """
    return _SOLUTION_LINK.sub(r"\1 (in the instructor's copy of the course)", markdown)


def release(out: str | os.PathLike, *, source: str | os.PathLike | None = None, force: bool = False) -> dict:
    """Write the student bundle to ``out`` (see the module docstring).

    ``out`` must be missing, empty or an earlier bundle (it is then replaced); ``force`` replaces any
    folder. Returns ``{"lessons": [...], "exercises": [...], "languages": [...], "out": Path}``
    (``languages``: the C++/Java/Octave/Mathematica stubs written, relative to ``exercises/``).

    Raises
    ------
    FileExistsError
        ``out`` holds something that is not a flowtrack bundle and ``force`` is not set.
    RuntimeError
        The scan found solution code, hidden tests or outputs in the bundle (nothing is written).
    """
    import nbformat

    from ..notebooks import is_jupytext_notebook, read_notebook, strip_outputs

    root = find_course_root(source) if source is None else Path(source)
    if not (root / "exercises").is_dir():
        raise FileNotFoundError(f"source: no exercises/ folder in {root}")
    out = Path(out).resolve()
    course = root.resolve()
    if course.is_relative_to(out) or any(
        out.is_relative_to(course / d) for d in ("exercises", "lessons", "solutions", "reference_impl")
    ):
        # --force replaces ``out``: never the course itself or one of its source folders.
        raise ValueError(f"out: {out} is the course or inside its sources; choose a separate folder")
    if out.exists() and any(out.iterdir()) and not (out / MARKER).exists() and not force:
        raise FileExistsError(f"out: {out} is not empty and not a flowtrack bundle (use --force)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        (tmp / "README.md").write_text(STUDENT_README, encoding="utf-8")
        (tmp / MARKER).write_text("flowtrack student bundle\n", encoding="utf-8")
        lessons = []
        (tmp / "lessons").mkdir()
        for src in sorted((root / "lessons").glob("*.md")) if (root / "lessons").is_dir() else []:
            if is_jupytext_notebook(src):
                nb = strip_outputs(read_notebook(src))
                for cell in nb.cells:
                    if cell.cell_type == "markdown":
                        cell.source = _unlink_solutions(cell.source)
                nbformat.write(nb, tmp / "lessons" / (src.stem + ".ipynb"))
                lessons.append(src.stem + ".ipynb")
            elif src.name == "README.md":
                text = _unlink_solutions(src.read_text(encoding="utf-8"))
                (tmp / "lessons" / "README.md").write_text(text, encoding="utf-8")
        exercises = []
        (tmp / "exercises").mkdir()
        for src, rel in _iter_exercise_notebooks(root):
            try:
                nb = release_notebook(nbformat.read(src, as_version=4))
            except Exception as exc:
                where = f"exercises/{rel.as_posix()}"
                raise ValueError(f"source: nbgrader cannot release {where}: {exc}") from exc
            dest = tmp / "exercises" / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            nbformat.write(nb, dest)
            exercises.append(rel.as_posix())
        from .languages import release_languages  # hook (issue 19): C++ / Octave stubs, same paths

        languages = release_languages(root / "exercises", tmp / "exercises")
        problems = scan_bundle(tmp)
        if problems:
            raise RuntimeError("release: the bundle would leak: " + "; ".join(problems[:10]))
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"lessons": lessons, "exercises": exercises, "languages": languages, "out": out}
