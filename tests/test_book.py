"""The rendered book and the demo report, opened in headless Chromium.

The book is built once per module (every lesson and solution executed, ~30 s on 2 cores) and every
page is checked in a real browser by :func:`browser.check_pages`: no console errors, equations
typeset by the bundled MathJax, every image loaded, every internal link and anchor resolving, no
network. The checker itself is shown to catch each kind of breakage on a page made to fail.

Chromium is Debian's ``chromium`` + ``chromium-driver`` (``make test`` installs them); when they
are missing these tests fail with the install command, they are never skipped.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from browser import check_pages
from flowtrack_course.book import build_book, rewrite_links
from flowtrack_course.notebooks import is_jupytext_notebook

ROOT = Path(__file__).resolve().parents[1]
# myst-nb and sphinx-book-theme still use attributes that Sphinx 9 deprecates for Sphinx 11
pytestmark = [
    pytest.mark.filterwarnings("ignore:.*Check CHANGES for Sphinx API modifications"),
    # napoleon (Sphinx 9) itself reads autodoc's options the old way (the API reference)
    pytest.mark.filterwarnings("ignore:The mapping interface for autodoc options"),
]
_MD_LINK = re.compile(r"(?<!!)\[[^\]\n]*\]\(([^)\s#]+\.md)(#[^)\s]*)?\)")


def _course_sources() -> list[Path]:
    out = []
    for folder in ("lessons", "solutions"):
        out += [p for p in sorted((ROOT / folder).glob("*.md")) if p.name.lower() != "readme.md"]
    return out


@pytest.fixture(scope="module")
def book(tmp_path_factory):
    return build_book(tmp_path_factory.mktemp("book") / "site", progress=False)


# ----------------------------------------------------------------------------------------------------
# the book
# ----------------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.xdist_group("book")
def test_book_has_a_page_for_every_lesson_and_solution(book):
    out = book.out
    assert (out / "index.html").is_file() and (out / "solutions" / "index.html").is_file()
    for src in _course_sources():
        page = out / src.parent.name / (src.stem + ".html")
        assert page in book.pages and page.is_file(), f"{src.relative_to(ROOT)} has no page"
        if is_jupytext_notebook(src):
            html = page.read_text(encoding="utf-8")
            assert 'class="cell_output' in html, f"{page.name}: notebook rendered without outputs"
    assert not book.warnings, "Sphinx warnings:\n" + "\n".join(book.warnings)
    # the landing page lists every lesson in its table of contents
    index = (out / "index.html").read_text(encoding="utf-8")
    for src in sorted((ROOT / "lessons").glob("[0-9]*.md")):
        assert f'href="lessons/{src.stem}.html"' in index, f"{src.name} missing from the contents"


@pytest.mark.slow
@pytest.mark.xdist_group("book")
def test_book_reads_offline(book):
    """Math renderer bundled; no page loads a script, style sheet, font or image from the network."""
    assert (book.out / "_static" / "mathjax" / "tex-chtml.js").is_file()
    remote = re.compile(
        r"""<(?:script|img|iframe)[^>]+src=["'](?:https?:)?//|<link[^>]+href=["'](?:https?:)?//"""
    )
    offenders = {}
    for page in book.out.rglob("*.html"):
        hits = remote.findall(page.read_text(encoding="utf-8"))
        if hits:
            offenders[str(page.relative_to(book.out))] = hits[:3]
    assert not offenders, f"pages that load from the network: {offenders}"
    for css in (book.out / "_static").rglob("*.css"):
        assert not re.search(r"url\(\s*['\"]?(?:https?:)?//", css.read_text(encoding="utf-8")), css.name


@pytest.mark.slow
@pytest.mark.xdist_group("book")
def test_course_links_become_links_in_the_book(book):
    """Each relative .md link between course files is an <a> to the matching page, not plain text."""
    checked = 0
    for src in [ROOT / "lessons" / "README.md", *_course_sources()]:
        page = book.out / "index.html" if src.name == "README.md" else book.out / src.parent.name / (
            src.stem + ".html"
        )
        html = page.read_text(encoding="utf-8")
        text = re.sub(r"```.*?```", "", src.read_text(encoding="utf-8"), flags=re.DOTALL)
        for target, _anchor in _MD_LINK.findall(text):
            dest = (src.parent / target).resolve()
            if dest.parent.name not in ("lessons", "solutions") or not dest.is_file():
                continue
            want = Path(dest.parent.name) / (dest.stem + ".html")
            rel = Path(_relpath(want, page.relative_to(book.out).parent))
            assert f'href="{rel.as_posix()}' in html, f"{page.name}: no link to {rel}"
            checked += 1
    assert checked >= 5


def _relpath(target: Path, start: Path) -> str:
    import os

    return os.path.relpath(target.as_posix(), start.as_posix() or ".")


@pytest.mark.slow
@pytest.mark.xdist_group("book")
def test_every_book_page_in_headless_chromium(book, tmp_path):
    shots = tmp_path / "screenshots"
    pages = [*book.pages, book.out / "genindex.html", book.out / "search.html"]  # Sphinx's own pages too
    problems = check_pages(pages, shots)
    assert not problems, "\n".join(problems)
    assert len(list(shots.glob("*.png"))) == len(pages)


@pytest.mark.slow
@pytest.mark.xdist_group("book")
def test_api_reference_documents_every_public_module_from_its_docstrings(book):
    """api.html: a section per public module of both packages, the docstrings rendered (numpy style
    through napoleon: parameter lists, not raw "Parameters\n----------" text)."""
    import importlib
    import inspect

    from flowtrack_course.book import API_PACKAGES, api_modules

    page = book.out / "api.html"
    assert page in book.pages
    html = page.read_text(encoding="utf-8")
    all_mods = [mod for package, _, _ in API_PACKAGES for mod in api_modules(package)]
    for package, _, _ in API_PACKAGES:
        mods = api_modules(package)
        assert len(mods) > 5, mods
        for mod in mods:
            assert f'id="module-{mod}"' in html, f"{mod} is not in the API reference"
            module = importlib.import_module(mod)
            for name in getattr(module, "__all__", []):
                obj = getattr(module, name, None)
                if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                    continue
                if obj.__module__ == mod:
                    assert f'id="{mod}.{name}"' in html, f"{mod}.{name} is not documented"
                # documented exactly once, under one of the public modules exporting it (re-exports
                # such as flowtrack.kalman.BatchKalmanFilter would make every reference ambiguous)
                # (or once under its own name, for a lazy alias such as demo.detect_objects)
                places = [f"{m}.{n}" for m in all_mods for n in {name, obj.__name__}
                          if getattr(importlib.import_module(m), n, None) is obj
                          and f'id="{m}.{n}"' in html]
                assert len(places) == 1, f"{mod}.{name} is documented at {places or 'no place'}"
    for anchor in ("flowtrack.pipeline.cloud_from_depth", "flowtrack_course.course.course_root",
                   "flowtrack.tracking.MultiObjectTracker.predict_ahead",
                   "flowtrack.variational.solve_component"):
        assert f'id="{anchor}"' in html, anchor
    n_param_lists = len(re.findall(r'<dt class="field-\w+">Parameters', html))
    assert n_param_lists > 50, n_param_lists  # napoleon's field lists
    assert not re.search(r"(Parameters|Returns|Raises)\s*(<[^>]+>\s*)*-{4,}", html)  # no raw numpy headings


# ----------------------------------------------------------------------------------------------------
# the checker can fail
# ----------------------------------------------------------------------------------------------------
_BROKEN = """<!DOCTYPE html><html><head><title>broken</title></head><body>
<h1 id="top">A page with every fault</h1>
<p>Unrendered display math: $$x^2$$ and \\[ y \\].</p>
<pre>code may contain $$ and \\[ freely</pre>
<img src="missing.png" alt="missing">
<img src="http://example.invalid/remote.png" alt="remote">
<a href="nowhere.html">missing file</a>
<a href="ok.html#no-such-anchor">missing anchor</a>
<a href="ok.html#here">fine</a>
<a href="https://example.invalid/">external, not followed</a>
<script>undefined_function_call();</script>
</body></html>"""


def test_checker_reports_each_fault(tmp_path):
    (tmp_path / "ok.html").write_text('<html><body><p id="here">fine</p></body></html>')
    (tmp_path / "broken.html").write_text(_BROKEN)
    problems = check_pages([tmp_path / "ok.html", tmp_path / "broken.html"], tmp_path / "shots")
    text = "\n".join(problems)
    assert not [p for p in problems if p.startswith("ok.html")], text
    assert "raw TeX '$$'" in text and "raw TeX '\\\\['" in text
    assert "image did not load" in text and "missing.png" in text
    assert "remote.png" in text  # the network is closed
    assert "missing file" in text and "nowhere.html" in text
    assert "missing anchor ok.html#no-such-anchor" in text
    assert "undefined_function_call" in text  # the script error, from the console
    assert "ok.html#here" not in text and "example.invalid/\n" not in text
    assert len(list((tmp_path / "shots").glob("*.png"))) == 2


def test_checker_requires_math_to_be_typeset(tmp_path):
    page = tmp_path / "math.html"
    page.write_text('<html><body><span class="math notranslate nohighlight">x</span></body></html>')
    assert any("no MathJax output" in p for p in check_pages([page], None))


# ----------------------------------------------------------------------------------------------------
# building blocks (fast)
# ----------------------------------------------------------------------------------------------------
def test_rewrite_links_keeps_code_images_and_external_links():
    src = (
        "[a](x.md#sec) ![img](_static/p.png) [web](https://a.b/c.md) [top](#here)\n"
        "```python\ns = '[not](x.md)'\n```\n[gone](../setup.py)\n"
    )
    seen = []

    def resolve(t):
        seen.append(t)
        return {"x.md": "x.ipynb"}.get(t)

    out = rewrite_links(src, resolve)
    assert "[a](x.ipynb#sec)" in out
    assert "![img](_static/p.png)" in out and "[web](https://a.b/c.md)" in out and "[top](#here)" in out
    assert "s = '[not](x.md)'" in out
    assert "gone (`setup.py` in the repository)" in out
    assert seen == ["x.md", "../setup.py"]
    with pytest.raises(TypeError, match="text"):
        rewrite_links(b"bytes", resolve)


def test_build_book_rejects_bad_arguments(tmp_path):
    keep = tmp_path / "precious"
    keep.mkdir()
    (keep / "thesis.tex").write_text("do not delete")
    with pytest.raises(ValueError, match="out"):
        build_book(keep, execute=False, progress=False)
    assert (keep / "thesis.tex").exists()
    with pytest.raises(ValueError, match="jobs"):
        build_book(tmp_path / "b", jobs=0)
    with pytest.raises(ValueError, match="timeout"):
        build_book(tmp_path / "b", timeout=-1)
    with pytest.raises(FileNotFoundError, match="root"):
        build_book(tmp_path / "b", root=tmp_path)


def test_build_book_stops_at_a_failing_notebook(tmp_path):
    from flowtrack_course.notebooks import NotebookExecutionError

    (tmp_path / "lessons").mkdir()
    (tmp_path / "solutions").mkdir()
    (tmp_path / "lessons" / "README.md").write_text("# Lessons\n\n[one](01_one.md)\n")
    (tmp_path / "lessons" / "01_one.md").write_text(
        "---\njupytext:\n  text_representation:\n    extension: .md\n    format_name: myst\n"
        "kernelspec:\n  display_name: Python 3\n  language: python\n  name: python3\n---\n\n"
        "# One\n\n```{code-cell} ipython3\nassert 1 + 1 == 3, 'wrong sum'\n```\n",
        encoding="utf-8",
    )
    with pytest.raises(NotebookExecutionError, match="wrong sum") as info:
        build_book(tmp_path / "site", root=tmp_path, progress=False, jobs=1)
    assert info.value.path.endswith("01_one.md") and "assert 1 + 1 == 3" in info.value.source
    assert not (tmp_path / "site").exists()  # nothing half-built
    # the same source without the fault renders, with the link between the pages working
    (tmp_path / "lessons" / "01_one.md").write_text(
        (tmp_path / "lessons" / "01_one.md").read_text().replace("3, 'wrong sum'", "2"), encoding="utf-8"
    )
    res = build_book(tmp_path / "site", root=tmp_path, progress=False, jobs=1)
    assert 'href="lessons/01_one.html"' in (res.out / "index.html").read_text(encoding="utf-8")
    assert [p.name for p in res.pages] == ["index.html", "index.html", "01_one.html", "api.html"]
