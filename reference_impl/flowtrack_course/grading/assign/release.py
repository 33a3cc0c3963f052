"""``flowtrack release --out DIR``: the student bundle.

::

    DIR/README.md                    how to work and check (for students)
    DIR/lessons/<name>.ipynb         the lessons (jupytext sources converted, no outputs)
    DIR/exercises/<notebook>         each exercise's notebook (its ``Exercise.notebook``, e.g.
                                     ``exercises/exNN_name.ipynb``), made from the course's
                                     ``exercises/<id>/`` folder
    DIR/exercises/<id>/              the exercise's grading files
                                     (:func:`~..engine.discovery.grading_files`: its grading
                                     module), which ``flowtrack check`` runs
    DIR/exercises/<lang>/<problem>/  the stubs of the answers in other languages, at the students'
                                     paths (the course keeps their sources in the exercises'
                                     folders: :mod:`..languages.source`)

The exercise notebooks go through nbgrader's own preprocessors, in the order nbgrader's
``generate_assignment`` runs them (without its database step): ``LockCells``, ``ClearSolutions``
(``### BEGIN SOLUTION`` ... ``### END SOLUTION`` -> ``raise NotImplementedError()``), ``ClearOutput``,
``CheckCellMetadata``, ``ComputeChecksums``, ``ClearHiddenTests`` (``### BEGIN HIDDEN TESTS`` blocks
removed), ``ClearMarkScheme``, ``ComputeChecksums``, ``CheckCellMetadata``. The bundle is then
scanned (:func:`scan_bundle`); any solution marker, hidden-test marker, output or ``solutions/``
folder left in it (in a notebook, a lesson, a stub or any other file) aborts the release.

A student's ``flowtrack check`` runs an exercise's public tests from its grading module: the
bundle's own copy (``exercises/<id>/grading.py``), or the course folder's when one is given
(``--course``, ``$FLOWTRACK_COURSE``). A grading module is the instructor's test code, as the tests
inside the installed package were before exercises had folders: it computes the expected values with
the reference implementation (which the student has installed anyway) and draws the hidden inputs,
which stay keyed by the instructor's secret (never in the bundle); notebooks, worked solutions, the
course's test answers (``cases.py``) and every file holding a solution block stay in the course.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Protocol, runtime_checkable

from ...course import course_root
from ..engine.discovery import grading_files
from ..sources import course_catalog

__all__ = ["Releasable", "find_course_root", "release", "release_notebook", "scan_bundle"]


@runtime_checkable
class Releasable(Protocol):
    """A source of exercises with files of its own in the bundle (the answers in other languages)."""

    def release(self, source: Path, dest: Path) -> list[str]:
        """Write the student's files of the exercises found under ``source`` (the course's
        ``exercises/``) into ``dest`` (the bundle's); return them relative to ``dest``."""
        ...


MARKER = ".flowtrack-release"
FORBIDDEN = ("BEGIN SOLUTION", "END SOLUTION", "BEGIN HIDDEN TESTS", "END HIDDEN TESTS", "BEGIN MARK SCHEME")

STUDENT_README = """\
# flowtrack: your copy of the course

This folder holds the course's lessons and its graded exercises:

- `lessons/`: seven lesson notebooks, from the pinhole camera to a multi-object tracker (start with
  `lessons/README.md`);
- `exercises/`: the exercise notebooks; each one says what to implement, which modules you may
  import, and how it is graded. `exercises/<exercise>/` holds the tests `flowtrack check` runs;
  `exercises/cpp/`, `java/`, `octave/` and `mathics/` hold some of the exercises to answer in those
  languages instead (each language's `README.md` says how).

## Install (once)

You need Python 3.11 or newer. In a terminal, in this folder:

```bash
python3 -m venv .venv
source .venv/bin/activate          # Windows: .venv\\Scripts\\activate
python -m pip install "flowtrack[student]"
```

Your instructor may give you the course package as a folder or a file instead; install it the same
way, e.g. `python -m pip install "/path/to/flowtrack[student]"`. The `student` extra installs
JupyterLab and what the exercises, `flowtrack check` and the lessons need (numpy, scipy, sympy,
OpenCV, filterpy); it leaves out
open3d (only lessons 3 and 6 use it, for rigid ICP flow: `python -m pip install open3d` if you want
to run those cells) and the tools that build the course book.

Then start Jupyter with `jupyter lab` and open `lessons/README.md` or an exercise.

## Doing an exercise

1. Open an exercise notebook in `exercises/`. Read the text and the docstring of each function you
   are asked to write: it gives the shapes of the inputs and of the result.
2. Replace each `raise NotImplementedError()` with your code. Keep the function names and arguments;
   only the answer cells are graded, so put all your code there (imports included). Import only the
   modules the exercise allows (calling the `flowtrack` function you are asked to write scores
   nothing).
3. Run the notebook's test cells: they show what is expected.
4. Check your work from a terminal:

   ```bash
   flowtrack check exercises/<exercise>.ipynb
   ```

   It runs the public tests in a sandbox exactly as the grader will and prints a table of the tests,
   your public score and, for each failed test, what was expected against what you returned (the
   worst entry and where it is). When your answer is a mistake the course has seen before, a line
   `mistake <id>: ...` names it, says why it is wrong and which lesson section explains it. It
   exits with status 0 when every public test passes. The tests it runs are in the folders
   `exercises/<exercise>/` of this copy: leave them as they are.

## How you are graded

Your instructor grades the notebooks you hand in (same file names) with `flowtrack grade`. The
public tests are the ones you see; hidden tests check the same functions on other, randomised inputs
(different for every student, of the same difficulty: the same code earns the same score for
everyone) with stated tolerances, with partial credit. Your code runs in a separate sandboxed
process with limits on time, memory and output; editing the test cells changes nothing, and code
that crashes, loops forever or exhausts memory scores 0 on that test only. Your feedback shows the
public tests in detail; for a failed hidden test it says which check failed and why (wrong values
at which entries, a wrong shape, a time-out, an exception) without showing its inputs, and names
the mistakes it recognises.

## The syllabus' problems

Problems 1-5 of the syllabus are posed in the lessons (where each one belongs) and several of them
are graded in the exercises (exercises 1, 2, 5, 7, 8, 10 and 11). Work them out yourself: the
worked answers are not part of this copy; your instructor publishes them after the deadline.
"""


def find_course_root(start: str | os.PathLike | None = None) -> Path:
    """The course folder (holding ``exercises/`` and ``lessons/``): ``start`` (``--course``), else
    ``$FLOWTRACK_COURSE``, else the current folder (:func:`flowtrack_course.course.course_root`).

    Raises
    ------
    FileNotFoundError
        That folder lacks ``exercises/`` or ``lessons/`` (the message says which and how to choose
        another).
    """
    return course_root(start, need=("exercises", "lessons"))


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


def release(
    out: str | os.PathLike,
    *,
    source: str | os.PathLike | None = None,
    force: bool = False,
    with_checks: bool = True,
) -> dict:
    """Write the student bundle to ``out`` (see the module docstring).

    ``with_checks`` is accepted for scripts written when the grading modules were an option; every
    bundle holds them now (``False`` is refused: a bundle without them cannot check anything).

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

    from ...notebooks import is_jupytext_notebook, read_notebook, strip_outputs

    if not with_checks:
        raise ValueError("with_checks: every bundle holds the grading modules `flowtrack check` runs")
    root = find_course_root(source)
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
                nb = student_lesson(strip_outputs(read_notebook(src)))
                nbformat.write(nb, tmp / "lessons" / (src.stem + ".ipynb"))
                lessons.append(src.stem + ".ipynb")
            elif src.name == "README.md":
                text = student_lessons_readme(src.read_text(encoding="utf-8"))
                (tmp / "lessons" / "README.md").write_text(text, encoding="utf-8")
        exercises = []
        (tmp / "exercises").mkdir()
        catalog = course_catalog(root)
        for ex in catalog.default():
            src = catalog.course.source_notebook(ex)
            try:
                nb = release_notebook(nbformat.read(src, as_version=4))
            except Exception as exc:
                where = src.relative_to(root).as_posix()
                raise ValueError(f"source: nbgrader cannot release {where}: {exc}") from exc
            dest = tmp / "exercises" / ex.notebook
            dest.parent.mkdir(parents=True, exist_ok=True)
            nbformat.write(nb, dest)
            exercises.append(ex.notebook)
            folder = catalog.course.folder(ex.id)
            for p in grading_files(folder):  # what `flowtrack check` runs
                target = tmp / "exercises" / ex.id / p.relative_to(folder)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(p, target)
        languages = []  # the stubs of the answers in other languages, at the same paths
        for source in catalog.sources:
            if isinstance(source, Releasable):
                languages += source.release(root / "exercises", tmp / "exercises")
        problems = scan_bundle(tmp) + scan_worked_answers(tmp)
        if problems:
            raise RuntimeError("release: the bundle would leak: " + "; ".join(problems[:10]))
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"lessons": lessons, "exercises": exercises, "languages": languages, "out": out}


# --------------------------------------------------------------------------------------------------
# the student's lessons: worked answers withheld, links that work inside the bundle

#: Tag of a lesson cell holding a worked answer to one of the syllabus' problems (MyST:
#: ``:tags: [worked-answer]`` in a code cell's options, ``+++ {"tags": ["worked-answer"]}`` before a
#: markdown cell). The book and the instructors' copy keep these cells; the student bundle does not.
WORKED_ANSWER_TAG = "worked-answer"

WITHHELD = (
    "> **Your turn.** The worked answer to this part is not in your copy of the course: work it out "
    "yourself (the exercise named above grades it). Your instructor publishes the worked answers "
    "after the deadline."
)

_LESSON_LINK = re.compile(r"\]\((\.\./lessons/|)(\d\d_[A-Za-z0-9_]+)\.md(#[^)]*)?\)")
_OUTSIDE_LINK = re.compile(r"\[([^\]]*)\]\((?:\.\./)+(?!lessons/|exercises/)[^)\s]+\)")


def bundle_links(markdown: str) -> str:
    """Links of a lesson's markdown rewritten for the bundle.

    Lesson sources (``02_variational_scene_flow.md``) become the bundle's notebooks
    (``02_variational_scene_flow.ipynb``); links to files outside ``lessons/`` and ``exercises/``
    (solutions, the package's source, benchmarks) become their text.

    >>> bundle_links("[lesson 2](02_variational_scene_flow.md#1-the-energy), [Problem 1](../solutions/p1.md)")
    '[lesson 2](02_variational_scene_flow.ipynb#1-the-energy), Problem 1'
    """
    text = _LESSON_LINK.sub(lambda m: f"]({m.group(1)}{m.group(2)}.ipynb{m.group(3) or ''})", markdown)
    return _OUTSIDE_LINK.sub(r"\1", text)


def _tags(cell) -> list:
    tags = cell.get("metadata", {}).get("tags", [])
    return list(tags) if isinstance(tags, (list, tuple)) else []


def student_lesson(nb):
    """A lesson for the bundle: worked-answer cells replaced by one note per run of them, links fixed."""
    import nbformat

    cells = []
    withheld = False
    for cell in nb.cells:
        if WORKED_ANSWER_TAG in _tags(cell):
            if not withheld:
                cells.append(nbformat.v4.new_markdown_cell(WITHHELD))
            withheld = True
            continue
        withheld = False
        if cell.cell_type == "markdown":
            cell.source = bundle_links(cell.source)
        cells.append(cell)
    nb.cells = cells
    return nb


def scan_worked_answers(bundle: str | os.PathLike) -> list[str]:
    """Lessons of a bundle that still hold a worked-answer cell (a problem for the release)."""
    problems = []
    for p in sorted(Path(bundle).rglob("*.ipynb")):
        nb = json.loads(p.read_text(encoding="utf-8"))
        for i, cell in enumerate(nb.get("cells", [])):
            if WORKED_ANSWER_TAG in _tags(cell):
                problems.append(f"{p.relative_to(bundle)}: cell {i} is a worked answer")
    return problems


def student_lessons_readme(text: str) -> str:
    """The lessons' README for students: the table of lessons (links to the bundle's notebooks) and
    what to do, without the instructors' notes (jupytext sources, solutions, headless runs)."""
    table = [ln for ln in text.splitlines() if ln.startswith("|")]
    head = [
        "# Lessons",
        "",
        "Seven lesson notebooks take you from a pinhole camera to a multi-object tracker for robot",
        "manipulation. Every derivation is done in sympy and checked against the course's reference",
        "implementation `flowtrack` inside the notebook. Open them in Jupyter (`jupyter lab`) and run",
        "them from the top. Where a lesson poses one of the syllabus' problems, work it out before you",
        "read on; the exercise that grades it is named there.",
        "",
    ]
    return "\n".join(head + [bundle_links(ln) for ln in table]) + "\n"
