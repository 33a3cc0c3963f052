"""Open static HTML pages in headless Chromium and list what a reader would see broken.

:func:`check_pages` is the reusable checker of the book test and the demo-report test. For every page
it checks, in a real browser without network:

* the page loads without SEVERE console messages (script errors, a resource that failed to load -
  including anything a page tries to fetch from the network, which is blocked);
* equations are typeset: no raw ``$$``, ``\\[``, ``\\(`` or ``\\begin{`` in the visible text
  (code blocks excepted), and MathJax output (``mjx-container``) exists when the page holds math;
* every ``<img>`` has loaded (``naturalWidth > 0``);
* every internal link (``file:`` URL) points to an existing file and, with ``#anchor``, to an
  element with that id or name.

It takes a screenshot of each page. Chromium is Debian's ``chromium`` with ``chromium-driver``
(``make test`` installs both); selenium is told their paths so it never downloads a driver.

Command line, for looking at pages by hand::

    .venv/bin/python tests/browser.py out/book/index.html out/report.html --shots /tmp/shots

and to remake the screenshots of docs/demo.md and docs/course.md (``lessons/_static/screenshots/``)::

    .venv/bin/python tests/browser.py out/report.html --screenshot report.png \
        --scroll-to tracking-and-prediction
    .venv/bin/python tests/browser.py out/book/lessons/05_multi_object_tracking.html \
        --screenshot book.png --scroll-to the-mahalanobis-cost-and-the-chi-square-gate
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
DRIVER_CANDIDATES = ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver")
INSTALL_HINT = (
    "headless Chromium is needed: `make test` installs it, or "
    "`apt-get install -y chromium chromium-driver` and `pip install -e '.[book]'` (selenium)"
)

# Visible text without code, scripts and MathJax's own markup.
_VISIBLE_TEXT_JS = """
const clone = document.body.cloneNode(true);
clone.querySelectorAll('pre, code, script, style, textarea, mjx-container, noscript, .highlight')
     .forEach(e => e.remove());
return clone.innerText;
"""
_MATH_JS = """
return {
  markers: document.querySelectorAll('.math, script[type^="math/tex"], .MathJax_Preview').length,
  rendered: document.querySelectorAll('mjx-container').length,
  mathjax: typeof window.MathJax !== 'undefined',
};
"""
_WAIT_MATHJAX_JS = """
const done = arguments[arguments.length - 1];
const mj = window.MathJax;
if (mj && mj.startup && mj.startup.promise) {
  mj.startup.promise.then(() => done('ok'), e => done('error: ' + e));
} else { done('none'); }
"""
_WAIT_IMAGES_JS = """
const done = arguments[arguments.length - 1];
const imgs = Array.from(document.images);
imgs.forEach(i => { i.loading = 'eager'; });
Promise.all(imgs.map(i => i.complete ? null : new Promise(r => {
  i.addEventListener('load', r); i.addEventListener('error', r);
}))).then(() => done(imgs.filter(i => !(i.complete && i.naturalWidth > 0))
                         .map(i => i.currentSrc || i.src || i.outerHTML.slice(0, 120))));
"""
_LINKS_JS = """
return Array.from(document.querySelectorAll('a[href]')).map(a => a.href);
"""
_RAW_TEX = ("$$", "\\[", "\\(", "\\begin{")


def find_chromium() -> tuple[str, str]:
    """Paths of the Chromium binary and its chromedriver; RuntimeError with the fix if missing."""
    binary = next((p for p in CHROMIUM_CANDIDATES if os.access(p, os.X_OK)), None) or shutil.which(
        "chromium"
    )
    driver = next((p for p in DRIVER_CANDIDATES if os.access(p, os.X_OK)), None) or shutil.which(
        "chromedriver"
    )
    if not binary or not driver:
        raise RuntimeError(f"chromium={binary!r}, chromedriver={driver!r}: {INSTALL_HINT}")
    return binary, driver


def start_browser(width: int = 1280, height: int = 900):
    """Start headless Chromium through selenium with every network path closed.

    Besides ``--headless --no-sandbox --disable-gpu --disable-background-networking``, every
    http(s) request goes to a proxy on a closed loopback port and host names do not resolve: a page
    that needs the network logs a SEVERE "failed to load" message instead of silently working.
    """
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError as exc:
        raise RuntimeError(f"selenium is not installed: {INSTALL_HINT}") from exc
    binary, driver = find_chromium()
    opts = webdriver.ChromeOptions()
    opts.binary_location = binary
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-dev-shm-usage",
        "--disable-extensions",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--hide-scrollbars",
        "--proxy-server=http://127.0.0.1:9",
        "--proxy-bypass-list=<-loopback>",
        "--host-resolver-rules=MAP * ~NOTFOUND",
        f"--window-size={width},{height}",
    ):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    os.environ.setdefault("SE_AVOID_STATS", "true")
    return webdriver.Chrome(options=opts, service=Service(executable_path=driver))


class _Anchors(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k == "id" or (tag == "a" and k == "name"):
                self.ids.add(v or "")


def _anchors(path: Path, cache: dict[Path, set[str]]) -> set[str]:
    if path not in cache:
        parser = _Anchors()
        parser.feed(path.read_text(encoding="utf-8", errors="replace"))
        cache[path] = parser.ids
    return cache[path]


def _check_links(page: Path, hrefs: list[str], cache: dict[Path, set[str]]) -> list[str]:
    problems = []
    for href in sorted(set(hrefs)):
        parts = urlsplit(href)
        if parts.scheme != "file":
            continue  # external links are not followed (no network); javascript:, mailto: ignored
        target = Path(unquote(parts.path))
        if target.is_dir():
            target = target / "index.html"
        if not target.is_file():
            problems.append(f"{page.name}: link to a missing file {target}")
            continue
        if parts.fragment and target.suffix in (".html", ".htm"):
            frag = unquote(parts.fragment)
            if frag not in _anchors(target, cache):
                problems.append(f"{page.name}: link to a missing anchor {target.name}#{frag}")
    return problems


def check_page(driver, page, screenshot: Path | None = None, cache=None) -> list[str]:
    """Check one page in an open browser (see the module docstring); returns the problems found."""
    page = Path(page).resolve()
    cache = {} if cache is None else cache
    if not page.is_file():
        return [f"{page}: no such file"]
    problems: list[str] = []
    driver.get_log("browser")  # drop messages of the previous page
    driver.get(page.as_uri())
    driver.set_script_timeout(60)
    status = driver.execute_async_script(_WAIT_MATHJAX_JS)
    if status.startswith("error"):
        problems.append(f"{page.name}: MathJax failed: {status}")
    broken = driver.execute_async_script(_WAIT_IMAGES_JS)
    problems += [f"{page.name}: image did not load: {src[:150]}" for src in broken]
    math = driver.execute_script(_MATH_JS)
    if math["markers"] and not math["rendered"]:
        problems.append(
            f"{page.name}: {math['markers']} math elements but no MathJax output "
            f"(MathJax loaded: {math['mathjax']})"
        )
    text = driver.execute_script(_VISIBLE_TEXT_JS) or ""
    for raw in _RAW_TEX:
        k = text.find(raw)
        if k >= 0:
            problems.append(f"{page.name}: raw TeX {raw!r} in the text: ...{text[max(0, k - 40) : k + 60]!r}")
    problems += _check_links(page, driver.execute_script(_LINKS_JS), cache)
    for entry in driver.get_log("browser"):
        if entry.get("level") == "SEVERE":
            problems.append(f"{page.name}: console: {entry.get('message', '')[:300]}")
    if screenshot is not None:
        screenshot.parent.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(screenshot))
    return problems


def check_pages(paths, screenshot_dir) -> list[str]:
    """Open every page in headless Chromium, check it and screenshot it.

    Parameters
    ----------
    paths : iterable of str or Path
        Local HTML files.
    screenshot_dir : str or Path or None
        Folder for one PNG per page (``NN_<name>.png``); ``None`` takes none.

    Returns
    -------
    list of str
        One line per problem, ``"<page>: <what>"``; empty when every page is fine.

    Raises
    ------
    RuntimeError
        Chromium, chromedriver or selenium is missing (with the command that installs them).
    """
    paths = [Path(p) for p in paths]
    shots = Path(screenshot_dir) if screenshot_dir is not None else None
    driver = start_browser()
    problems: list[str] = []
    cache: dict[Path, set[str]] = {}
    try:
        for k, page in enumerate(paths):
            shot = None if shots is None else shots / f"{k:02d}_{page.parent.name}_{page.stem}.png"
            problems += check_page(driver, page, shot, cache)
    finally:
        driver.quit()
    return problems


def screenshot(page, png, width: int = 1280, height: int = 860, scroll_to: str | None = None) -> Path:
    """Save a screenshot of ``page`` (optionally scrolled to the element with id ``scroll_to``)."""
    driver = start_browser(width, height)
    try:
        driver.get(Path(page).resolve().as_uri())
        driver.set_script_timeout(60)
        driver.execute_async_script(_WAIT_MATHJAX_JS)
        driver.execute_async_script(_WAIT_IMAGES_JS)
        if scroll_to:
            driver.execute_script(
                "const e = document.getElementById(arguments[0]); if (e) e.scrollIntoView();", scroll_to
            )
        png = Path(png)
        png.parent.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(png))
    finally:
        driver.quit()
    return png


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="check HTML pages in headless Chromium")
    parser.add_argument("pages", nargs="+")
    parser.add_argument("--shots", default=None, help="folder for screenshots")
    parser.add_argument("--screenshot", default=None, help="only save a screenshot of the first page here")
    parser.add_argument("--scroll-to", default=None, help="element id to scroll to for --screenshot")
    args = parser.parse_args(argv)
    if args.screenshot:
        print(screenshot(args.pages[0], args.screenshot, scroll_to=args.scroll_to))
        return 0
    problems = check_pages(args.pages, args.shots)
    for p in problems:
        print(p)
    print(f"{len(args.pages)} pages, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
