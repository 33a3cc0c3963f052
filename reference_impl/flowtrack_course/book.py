r"""Build the course book: every lesson and solution, executed, as a static HTML site that reads offline.

``python -m flowtrack_course.book --out out/book`` (what ``make book`` runs) does four things:

1. **Collect** the sources: ``lessons/README.md`` (the landing page), the lesson notebooks
   ``lessons/NN_*.md``, everything in ``solutions/`` (worked-solution notebooks and the errata
   page) and the pictures in ``lessons/_static/``.
2. **Execute** every notebook top to bottom with :func:`flowtrack_course.notebooks.execute_notebook`
   (a fresh kernel of this interpreter per notebook, ``jobs`` of them at a time, each in its own
   scratch directory) and keep the outputs. A failing cell stops the build with the notebook, the
   cell and the traceback.
3. **Stage** a Sphinx source tree in a scratch directory (never in the repository): the executed
   notebooks as ``.ipynb``, the landing page as ``index.md``, a generated ``solutions/index.md``
   and a generated ``conf.py``. Relative Markdown links between course files
   (``../solutions/problem1_projection_jacobian.md#step-2``) are rewritten to the staged documents so
   that they resolve in the built site; a link to a repository file that is not part of the book
   becomes plain text naming that file.
4. **Render** with Sphinx + myst-nb (MyST Markdown, ``$...$``/``$$...$$`` math) and the
   ``sphinx-book-theme``. Equations are typeset by MathJax 3 shipped inside the
   ``sphinx-mathjax-offline`` wheel and copied into ``_static/mathjax``: nothing is fetched from a
   CDN when the book is read, and the ipywidgets loader scripts are left out (widgets need a live
   kernel; each lesson shows a static figure in their place).

The result, ``OUT/index.html``, opens from the file system without network.

Examples
--------
>>> from flowtrack_course.book import rewrite_links
>>> rewrite_links("see [Problem 1](../solutions/p1.md#step-2) and [the code](../setup.py)",
...               lambda target: {"../solutions/p1.md": "../solutions/p1.ipynb"}.get(target))
'see [Problem 1](../solutions/p1.ipynb#step-2) and the code (`setup.py` in the repository)'
"""

from __future__ import annotations

import argparse
import functools
import io
import multiprocessing
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from flowtrack.validation import positive, positive_int

from . import course as _course

__all__ = [
    "API_PACKAGES",
    "API_PAGE",
    "BookResult",
    "api_members",
    "api_modules",
    "build_book",
    "course_root",
    "main",
    "rewrite_links",
]

# a Markdown link that is not an image: [text](target "optional title")
_LINK = re.compile(r"(?<!!)\[(?P<text>[^\]\n]*)\]\((?P<target>[^)\s]+)(?P<title>\s+\"[^\"]*\")?\)")
_FENCE = re.compile(r"^(```|~~~)", re.MULTILINE)
_SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


@dataclass
class BookResult:
    """What :func:`build_book` made.

    Attributes
    ----------
    out : pathlib.Path
        The site's folder; ``out / "index.html"`` is the landing page.
    pages : list of pathlib.Path
        Every HTML page rendered from a course source (landing page first).
    execute_seconds : dict
        Wall time of each executed notebook (``{repo-relative path: seconds}``).
    build_seconds : float
        Wall time of the whole build.
    warnings : list of str
        Sphinx's warnings (broken references would be listed here).
    """

    out: Path
    pages: list[Path]
    execute_seconds: dict[str, float] = field(default_factory=dict)
    build_seconds: float = 0.0
    warnings: list[str] = field(default_factory=list)


def course_root(root=None) -> Path:
    """The course folder holding ``lessons/`` and ``solutions/``: ``root`` (``--course``), else
    ``$FLOWTRACK_COURSE``, else the current folder (:func:`flowtrack_course.course.course_root`)."""
    return _course.course_root(root, need=("lessons", "solutions"))


def rewrite_links(text: str, resolve: Callable[[str], str | None]) -> str:
    """Rewrite the relative Markdown links of ``text`` outside fenced code blocks.

    Parameters
    ----------
    text : str
        Markdown (MyST) source.
    resolve : callable
        ``resolve(target_without_anchor) -> new target or None``; called for every link whose
        target has no URL scheme and does not start with ``#`` or ``/``. ``None`` turns the link
        into plain text: ``text (`path` in the repository)``, with ``path`` the target stripped of
        leading ``../``.

    Returns
    -------
    str
        The rewritten source (images ``![..](..)`` and links inside code fences are left alone).
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__}")

    def one(m: re.Match) -> str:
        target = m.group("target")
        if _SCHEME.match(target) or target.startswith(("#", "/")):
            return m.group(0)
        path, sep, anchor = target.partition("#")
        new = resolve(path)
        if new is None:
            shown = re.sub(r"^(\.\./|\./)+", "", path).rstrip("/") or path
            return f"{m.group('text')} (`{shown}` in the repository)"
        return f"[{m.group('text')}]({new}{sep}{anchor}{m.group('title') or ''})"

    parts = []
    inside = False
    pos = 0
    for fence in _FENCE.finditer(text):
        chunk = text[pos : fence.start()]
        parts.append(chunk if inside else _LINK.sub(one, chunk))
        line_end = text.find("\n", fence.start())
        line_end = len(text) if line_end < 0 else line_end + 1
        parts.append(text[fence.start() : line_end])
        pos = line_end
        inside = not inside
    tail = text[pos:]
    parts.append(tail if inside else _LINK.sub(one, tail))
    return "".join(parts)


# ----------------------------------------------------------------------------------------------------
# sources
# ----------------------------------------------------------------------------------------------------
@dataclass
class _Source:
    src: Path  # file in the repository
    staged: str  # path in the Sphinx tree, posix, with suffix
    notebook: bool


def _collect(root: Path) -> list[_Source]:
    from .notebooks import is_jupytext_notebook

    readme = root / "lessons" / "README.md"
    if not readme.is_file():
        raise FileNotFoundError(f"root: {readme} is missing (the book's landing page)")
    sources = [_Source(readme, "index.md", False)]
    for folder in ("lessons", "solutions"):
        for p in sorted((root / folder).glob("*.md")):
            if p.name.lower() == "readme.md":
                continue
            nb = is_jupytext_notebook(p)
            stem = f"{folder}/{p.stem}"
            sources.append(_Source(p, stem + (".ipynb" if nb else ".md"), nb))
    if not any(s.notebook for s in sources):
        raise FileNotFoundError(f"root: no lesson notebooks under {root / 'lessons'}")
    return sources


def _execute_one(path: str, timeout: float, cwd: str):
    """Worker: execute one notebook; return (path, notebook JSON, seconds) or (path, None, error).

    A :class:`~flowtrack_course.notebooks.NotebookExecutionError` is returned as its fields (it does not
    survive pickling across the process boundary) and re-raised by the parent.
    """
    import nbformat

    from .notebooks import NotebookExecutionError, execute_notebook

    t0 = time.perf_counter()
    try:
        nb = execute_notebook(path, timeout=timeout, cwd=cwd)
    except NotebookExecutionError as exc:
        return path, None, (exc.cell_index, exc.source, exc.traceback)
    return path, nbformat.writes(nb), time.perf_counter() - t0


def _execute_all(paths: list[Path], jobs: int, timeout: float, scratch: Path, progress: bool):
    from tqdm.auto import tqdm

    results: dict[Path, tuple[str, float]] = {}
    bar = tqdm(total=len(paths), desc="executing notebooks", unit="nb", disable=not progress)
    try:
        # "spawn": a forked copy of a threaded parent (pytest, Jupyter) can hang in its kernel client
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            futures = []
            for p in paths:
                cwd = scratch / "run" / f"{p.parent.name}-{p.stem}"
                cwd.mkdir(parents=True, exist_ok=True)
                futures.append(pool.submit(_execute_one, str(p), timeout, str(cwd)))
            for fut in as_completed(futures):
                path, text, info = fut.result()
                if text is None:
                    from .notebooks import NotebookExecutionError

                    for f in futures:
                        f.cancel()
                    raise NotebookExecutionError(path, *info)
                results[Path(path)] = (text, info)
                bar.set_postfix_str(f"{Path(path).name} {info:.0f} s")
                bar.update()
    finally:
        bar.close()
    return results


def _solutions_index(sources: list[_Source]) -> str:
    sols = [s for s in sources if s.staged.startswith("solutions/")]
    lines = [
        "# Worked solutions",
        "",
        "Each syllabus problem worked in sympy and checked numerically against `flowtrack`, and the",
        "errata: what the syllabus gets wrong, with the evidence.",
        "",
        "```{toctree}",
        ":maxdepth: 1",
        "",
    ]
    lines += [Path(s.staged).stem for s in sols]
    lines += ["```", ""]
    return "\n".join(lines)


def _index_toc(sources: list[_Source]) -> str:
    lessons = [s for s in sources if s.staged.startswith("lessons/")]
    lines = ["", "## Contents", "", "```{toctree}", ":maxdepth: 1", ":caption: Lessons", ""]
    lines += [s.staged.rsplit(".", 1)[0] for s in lessons]
    lines += ["```", "", "```{toctree}", ":maxdepth: 1", ":caption: Solutions", ""]
    lines += ["solutions/index"]
    lines += ["```", "", "```{toctree}", ":maxdepth: 1", ":caption: Reference", ""]
    lines += [API_PAGE.removesuffix(".md")]
    lines += ["```", ""]
    return "\n".join(lines)


#: The API reference's page in the book (``api.html``), generated from the docstrings.
API_PAGE = "api.md"
#: The packages it documents: the library, the course's tooling, the sandbox.
API_PACKAGES = (
    ("flowtrack", "The library: flowtrack",
     "What lessons, exercises and ports are checked against; it never imports the tooling."),
    ("flowtrack_course", "The course's tooling: flowtrack_course",
     "Grading, port harnesses, the book, notebooks, widgets, the demo app and the ``flowtrack`` command."),
    ("grading_sandbox", "The sandbox: grading_sandbox",
     "Runs student code for the grader and sends back plain data; it knows nothing of the course."),
)


def api_modules(package: str) -> list[str]:
    """The public modules of ``package`` (itself first, then every module and sub-package whose
    dotted name has no part starting with ``_`` and no ``tests`` part), sorted.

    Examples
    --------
    >>> mods = api_modules("flowtrack")
    >>> mods[0], "flowtrack.kalman" in mods, any(m.startswith("flowtrack._") for m in mods)
    ('flowtrack', True, False)
    """
    import importlib
    import pkgutil

    pkg = importlib.import_module(package)
    names = [m.name for m in pkgutil.walk_packages(pkg.__path__, prefix=package + ".")]
    public = [n for n in names if not any(p.startswith("_") or p == "tests" for p in n.split("."))]
    return [package, *sorted(public)]


def _api_page() -> str:
    """The API reference (MyST): one autodoc section per public module of :data:`API_PACKAGES`
    (docstrings in numpy style, rendered by napoleon)."""
    lines = [
        "# API reference",
        "",
        "Every public module of the three packages, generated from the docstrings (the contracts: names,",
        "arguments, shapes, raised errors). `flowtrack` is the library; `flowtrack_course` the tooling",
        "built on it; `grading_sandbox` the sandbox the grader runs student code in (see the architecture",
        "notes, `docs/ARCHITECTURE.md` in the repository).",
        "",
    ]
    documented = {mod: api_members(mod) for mod in _public_modules()}
    for package, title, blurb in API_PACKAGES:
        lines += [f"## {title}", "", blurb, ""]
        for mod in api_modules(package):
            members = documented[mod]
            lines += [f"### `{mod}`", "", "```{eval-rst}", f".. automodule:: {mod}"]
            if members is None:  # no __all__: autodoc's own rule (what the module defines)
                lines += ["   :members:"]
            elif members:
                lines += ["   :members: " + ", ".join(members)]
            lines += ["   :show-inheritance:", "```", ""]
    return "\n".join(lines)


@functools.lru_cache(maxsize=1)
def _public_modules() -> tuple[str, ...]:
    return tuple(mod for package, _, _ in API_PACKAGES for mod in api_modules(package))


def api_members(mod: str) -> list[str] | None:
    """The names of ``mod.__all__`` the API reference documents under ``mod`` (``None`` when ``mod``
    has no ``__all__``: autodoc then documents what the module itself defines).

    Every object is documented once, at its canonical place, so that a cross-reference has one
    target: a class or function under the public module that defines it (``obj.__module__``), a
    name re-exported from a private module (or a constant) under the deepest public module
    exporting that same object (``flowtrack.synth.shapes.Box``, not ``flowtrack.synth.Box``). A lazy
    alias (``flowtrack_course.demo.detect_objects``) is documented under its own name where it is
    defined (``flowtrack.pipeline.detections_from_clusters``). Sub-modules listed in ``__all__`` get their
    own section and are left out here.

    Examples
    --------
    >>> "BatchKalmanFilter" in api_members("flowtrack.batch_kalman")
    True
    >>> "BatchKalmanFilter" in api_members("flowtrack.kalman")  # re-exported: documented once
    False
    """
    import importlib
    import inspect

    module = importlib.import_module(mod)
    names = getattr(module, "__all__", None)
    if names is None:
        return None
    public = _public_modules()
    out = []
    for name in names:
        obj = getattr(module, name, None)
        if inspect.ismodule(obj):
            continue
        if _canonical_module(name, obj, mod, public) == (mod, name):
            out.append(name)
    return out


def _canonical_module(name: str, obj, mod: str, public: tuple[str, ...]) -> tuple[str, str] | None:
    """``(module, name)`` under which the API reference documents ``obj`` (exported by ``mod`` as
    ``name``), or ``None`` when autodoc cannot reach it (a lazy ``__getattr__`` alias of an object
    defined in a private module)."""
    import importlib
    import inspect

    if inspect.isfunction(obj) or inspect.isclass(obj):
        home, own = getattr(obj, "__module__", None), getattr(obj, "__name__", name)
        if home in public:
            defining = importlib.import_module(home)
            exported = getattr(defining, "__all__", None)
            if vars(defining).get(own) is obj and (exported is None or own in exported):
                return home, own
    exporters = []
    for other in public:
        m = importlib.import_module(other)
        if name in (getattr(m, "__all__", None) or ()) and vars(m).get(name) is obj:
            exporters.append(other)
    if not exporters:
        return (mod, name) if name in vars(importlib.import_module(mod)) else None
    return max(exporters, key=lambda m: (m.count("."), m)), name


def _mathjax_dir() -> Path:
    """The folder holding ``mathjax/tex-chtml.js`` inside the ``sphinx-mathjax-offline`` wheel."""
    import importlib.util

    spec = importlib.util.find_spec("sphinx-mathjax-offline")  # the wheel's package has a hyphen
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(
            "sphinx-mathjax-offline is not installed: pip install -e '.[book]' (it ships MathJax 3)"
        )
    static = Path(next(iter(spec.submodule_search_locations))) / "static"
    if not (static / "mathjax" / "tex-chtml.js").is_file():
        raise RuntimeError(f"no mathjax/tex-chtml.js under {static}")
    return static


def _conf_py(title: str) -> str:
    mathjax_parent = str(_mathjax_dir())
    return f'''# Generated by flowtrack_course.book: do not edit (rebuilt on every `make book`).
project = {title!r}
author = "flowtrack developers"
copyright = "flowtrack developers, MIT licence"
extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
root_doc = "index"
exclude_patterns = ["_build", "_scratch", "_doctrees", "**.ipynb_checkpoints", "lessons/_static"]
source_suffix = {{".md": "myst-nb", ".ipynb": "myst-nb"}}
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence"]
myst_heading_anchors = 4
myst_dmath_double_inline = True
nb_execution_mode = "off"          # executed beforehand by flowtrack_course.book
nb_ipywidgets_js = {{}}             # no widget loaders from a CDN: widgets need a live kernel
nb_merge_streams = True
suppress_warnings = ["mystnb.unknown_mime_type", "misc.highlighting_failure"]
html_theme = "sphinx_book_theme"
html_title = {title!r}
html_theme_options = {{
    "home_page_in_toc": True,
    "show_navbar_depth": 1,
    "use_download_button": True,
    "use_fullscreen_button": False,
    "navigation_with_keys": False,
}}
# MathJax 3 from the sphinx-mathjax-offline wheel, copied to _static/mathjax (no CDN)
html_static_path = [{mathjax_parent!r}]
html_context = {{"default_mode": "light"}}  # else the theme logs an error on a fresh browser
mathjax_path = "mathjax/tex-chtml.js"
html_show_sourcelink = False
# the API reference (api.md): numpy-style docstrings through napoleon
autodoc_member_order = "bysource"
autodoc_typehints = "none"         # the docstrings state the types (and shapes)
autodoc_inherit_docstrings = False
napoleon_google_docstring = False
napoleon_use_ivar = True           # dataclass "Attributes" as fields, not a second description
napoleon_use_rtype = False
napoleon_use_param = False         # types as written ("array_like, shape (N, 3)"), not cross-references
html_last_updated_fmt = None
'''


def _prepare_out(out: Path) -> None:
    if out.exists():
        if not out.is_dir():
            raise ValueError(f"out must be a folder, got the file {out}")
        entries = list(out.iterdir())
        if entries and not (out / ".buildinfo").exists():
            raise ValueError(
                f"out: {out} is not empty and holds no earlier book (.buildinfo missing); "
                "refusing to delete it"
            )
        shutil.rmtree(out)
    out.mkdir(parents=True)


def build_book(
    out,
    *,
    root=None,
    execute: bool = True,
    jobs: int | None = None,
    timeout: float = 600,
    staging=None,
    progress: bool = True,
    title: str = "flowtrack: scene flow and object tracking",
) -> BookResult:
    """Execute the lessons and solutions and render them to a static offline HTML site.

    Parameters
    ----------
    out : str or Path
        Output folder (created; an earlier book there is replaced; any other non-empty folder is
        refused).
    root : str or Path, optional
        The course folder holding ``lessons/`` and ``solutions/`` (default: :func:`course_root`).
    execute : bool
        Run every notebook first (default). ``False`` renders the sources without outputs (fast,
        for checking layout and links only).
    jobs : int, optional
        Notebooks executed at the same time (default: ``min(2, cpu count)``).
    timeout : float
        Seconds allowed per notebook cell (> 0).
    staging : str or Path, optional
        Keep the generated Sphinx source tree here (must be empty or missing); default: a
        temporary folder removed afterwards.
    progress : bool
        Show a progress bar while notebooks execute.
    title : str
        The site's title.

    Returns
    -------
    BookResult
        The output folder, its course pages, per-notebook execution times, Sphinx's warnings.

    Raises
    ------
    FileNotFoundError
        ``root`` without ``lessons/README.md`` or without lesson notebooks.
    ValueError
        ``out`` is a file or a non-empty folder that is not a book; ``staging`` not empty;
        ``jobs``/``timeout`` not positive (``TypeError``: not an integer / not a number).
    flowtrack_course.notebooks.NotebookExecutionError
        A notebook cell failed (names the notebook, the cell and the traceback).
    RuntimeError
        Sphinx failed.
    """
    import nbformat
    from sphinx.application import Sphinx

    from .notebooks import read_notebook

    t_start = time.perf_counter()
    root = course_root(root)
    if jobs is None:
        jobs = max(1, min(2, os.cpu_count() or 1))
    jobs = positive_int(jobs, "jobs")
    timeout = positive(timeout, "timeout")  # checked here too: before any worker starts
    out = Path(out).resolve()
    sources = _collect(root)

    tmp = None
    if staging is None:
        tmp = tempfile.TemporaryDirectory(prefix="flowtrack-book-")
        src_dir = Path(tmp.name)
    else:
        src_dir = Path(staging).resolve()
        if src_dir.exists() and any(src_dir.iterdir()):
            raise ValueError(f"staging must be an empty or missing folder, got {src_dir}")
        src_dir.mkdir(parents=True, exist_ok=True)
    try:
        executed: dict[Path, tuple[str, float]] = {}
        if execute:
            # the kernels run in scratch folders: they find the course (lesson 7 reads the ports'
            # vectors) through $FLOWTRACK_COURSE, which they inherit
            saved = os.environ.get(_course.ENV)
            os.environ[_course.ENV] = str(root)
            try:
                executed = _execute_all(
                    [s.src for s in sources if s.notebook], jobs, timeout, src_dir / "_scratch", progress
                )
            finally:
                if saved is None:
                    os.environ.pop(_course.ENV, None)
                else:
                    os.environ[_course.ENV] = saved
        staged_of = {s.src.resolve(): s.staged for s in sources}
        dirs = {
            (root / "solutions").resolve(): "solutions/index.md",
            (root / "lessons").resolve(): "index.md",
        }

        def resolver(src: _Source) -> Callable[[str], str | None]:
            here = Path(src.staged).parent

            def resolve(target: str) -> str | None:
                if not target:
                    return target
                dest = (src.src.parent / target).resolve()
                staged = staged_of.get(dest) or dirs.get(dest)
                if staged is None:
                    static = root / "lessons" / "_static"
                    if static in dest.parents and dest.is_file():
                        staged = "lessons/_static/" + dest.relative_to(static).as_posix()
                    else:
                        return None
                return os.path.relpath(staged, here.as_posix() or ".").replace(os.sep, "/")

            return resolve

        for s in sources:
            dest = src_dir / s.staged
            dest.parent.mkdir(parents=True, exist_ok=True)
            fix = resolver(s)
            if s.notebook:
                if s.src in executed:
                    nb = nbformat.reads(executed[s.src][0], as_version=4)
                else:
                    nb = read_notebook(s.src)
                for cell in nb.cells:
                    if cell.cell_type == "markdown":
                        cell.source = rewrite_links(cell.source, fix)
                nb.metadata.pop("jupytext", None)
                nbformat.write(nb, str(dest))
            else:
                text = rewrite_links(s.src.read_text(encoding="utf-8"), fix)
                if s.staged == "index.md":
                    text = text.rstrip("\n") + "\n" + _index_toc(sources)
                dest.write_text(text, encoding="utf-8")
        (src_dir / "solutions").mkdir(exist_ok=True)
        (src_dir / "solutions" / "index.md").write_text(_solutions_index(sources), encoding="utf-8")
        static = root / "lessons" / "_static"
        if static.is_dir():
            shutil.copytree(static, src_dir / "lessons" / "_static", dirs_exist_ok=True)
        (src_dir / API_PAGE).write_text(_api_page(), encoding="utf-8")
        (src_dir / "conf.py").write_text(_conf_py(title), encoding="utf-8")

        _prepare_out(out)
        status, warning = io.StringIO(), io.StringIO()
        from sphinx.util.console import nocolor

        nocolor()
        try:
            app = Sphinx(
                str(src_dir),
                str(src_dir),
                str(out),
                str(src_dir / "_doctrees"),
                "html",
                status=status,
                warning=warning,
                freshenv=True,
                parallel=1,  # reading 20 pages is quick; Sphinx's parallel reader forks
            )
            app.build(force_all=True)
        except Exception as exc:  # sphinx raises its own error types
            raise RuntimeError(
                f"Sphinx failed: {exc}\n----- warnings -----\n{warning.getvalue()}"
            ) from exc
        if app.statuscode:
            raise RuntimeError(f"Sphinx exited with status {app.statuscode}:\n{warning.getvalue()}")
    finally:
        if tmp is not None:
            tmp.cleanup()

    shutil.rmtree(out / ".doctrees", ignore_errors=True)
    pages = [out / (s.staged.rsplit(".", 1)[0] + ".html") for s in sources]
    pages.insert(pages.index(out / "index.html") + 1, out / "solutions" / "index.html")
    pages.append(out / API_PAGE.replace(".md", ".html"))
    missing = [p for p in pages if not p.is_file()]
    if missing:
        raise RuntimeError(f"Sphinx did not write {missing}")
    warnings = [w for w in warning.getvalue().splitlines() if w.strip()]
    return BookResult(
        out=out,
        pages=pages,
        execute_seconds={str(p.relative_to(root)): sec for p, (_, sec) in executed.items()},
        build_seconds=time.perf_counter() - t_start,
        warnings=warnings,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m flowtrack_course.book --out out/book [--no-execute] [--jobs N]``."""
    parser = argparse.ArgumentParser(
        prog="python -m flowtrack_course.book",
        description="Execute the lessons and solutions and render them to a static HTML book "
        "that reads offline (open OUT/index.html).",
    )
    parser.add_argument("--out", default="out/book", help="output folder (default: out/book)")
    parser.add_argument("--course", "--root", dest="root", metavar="DIR", default=None,
                        help="the course folder (default: $FLOWTRACK_COURSE, else the current folder)")
    parser.add_argument("--no-execute", action="store_true", help="render without running notebooks")
    parser.add_argument("--jobs", type=int, default=None, help="notebooks run at once (default: 2)")
    parser.add_argument("--timeout", type=float, default=600, help="seconds per cell (default: 600)")
    parser.add_argument("--staging", default=None, help="keep the Sphinx source tree in this folder")
    parser.add_argument("--strict", action="store_true", help="fail on any Sphinx warning")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        res = build_book(
            args.out,
            root=args.root,
            execute=not args.no_execute,
            jobs=args.jobs,
            timeout=args.timeout,
            staging=args.staging,
            progress=not args.no_progress,
        )
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for name, sec in sorted(res.execute_seconds.items()):
        print(f"  executed {name:<45} {sec:6.1f} s")
    for w in res.warnings:
        print(f"  warning: {w}", file=sys.stderr)
    print(f"book: {len(res.pages)} pages in {res.build_seconds:.0f} s -> {res.out / 'index.html'}")
    if args.strict and res.warnings:
        print(f"error: {len(res.warnings)} Sphinx warnings (--strict)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
