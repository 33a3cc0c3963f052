"""A self-contained HTML report: one file, images embedded as data URIs, inline CSS, no script.

The demo's ``report.html`` is built from :class:`Section` objects (paragraphs, tables, figures) so
that the same :class:`Table` also gives the Markdown of ``metrics.md``. Nothing in the page refers
to the network or to other files, so it opens offline, can be mailed or attached to an LMS.

Examples
--------
>>> t = Table(["method", "EPE3D (mm)", "Acc3DS"], [["graph", 0.714, 1.0]], digits=[None, 2, None])
>>> print(t.markdown())
| method | EPE3D (mm) | Acc3DS |
|---|---:|---:|
| graph | 0.71 | 1.000 |
>>> html = render_report("demo", [Section("Scene flow", paragraphs=["<b>bold</b> & co"], tables=[t])])
>>> "&lt;b&gt;bold&lt;/b&gt; &amp; co" in html and "<td>graph</td>" in html and "http" not in html
True
"""

from __future__ import annotations

import base64
import html
import numbers
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Figure", "Section", "Table", "data_uri", "render_markdown", "render_report", "write_report"]

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, Helvetica, Arial, sans-serif;
       max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #3465a4; padding-bottom: .2em; }
h2 { margin-top: 2em; border-bottom: 1px solid #ccc; padding-bottom: .15em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .95em; }
th, td { border: 1px solid #bbb; padding: .25em .6em; }
th { background: #eef2f7; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
caption { caption-side: bottom; font-size: .85em; color: #555; text-align: left; padding-top: .3em; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .9em; color: #444; }
.note { background: #fff8e1; border-left: 4px solid #f0b400; padding: .4em .8em; }
pre { background: #f6f8fa; padding: .6em; overflow-x: auto; }
nav ul { columns: 2; }
"""


def _fmt(v, digits: int | None = None) -> str:
    if isinstance(v, bool) or v is None:
        return "—" if v is None else ("yes" if v else "no")
    if isinstance(v, numbers.Integral):
        return str(int(v))
    if isinstance(v, numbers.Real):
        v = float(v)
        if v != v:  # NaN
            return "—"
        if digits is not None:
            return f"{v:.{digits}f}"
        return f"{v:.3f}" if abs(v) < 10 else f"{v:.2f}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


@dataclass
class Table:
    """A table with a header row; numbers right-aligned (3 decimals below 10, 2 above).

    Parameters
    ----------
    header : list of str
    rows : list of list
        Cells: str (left-aligned) or numbers (formatted, right-aligned); None shows "—".
    caption : str
        Shown under the table (and after it in Markdown).
    digits : list of int or None, optional
        Decimals of each column's numbers (None: the default rule).
    """

    header: list
    rows: list
    caption: str = ""
    digits: list | None = None

    def __post_init__(self):
        for i, r in enumerate(self.rows):
            if len(r) != len(self.header):
                raise ValueError(f"rows[{i}] has {len(r)} cells, the header {len(self.header)}")
        if self.digits is None:
            self.digits = [None] * len(self.header)
        if len(self.digits) != len(self.header):
            raise ValueError(f"digits must have {len(self.header)} entries, got {len(self.digits)}")

    def _numeric(self, j: int) -> bool:
        return any(isinstance(r[j], numbers.Real) and not isinstance(r[j], bool) for r in self.rows)

    def markdown(self) -> str:
        """GitHub-flavoured Markdown (numeric columns right-aligned)."""
        align = ["---:" if self._numeric(j) else "---" for j in range(len(self.header))]
        lines = ["| " + " | ".join(self.header) + " |", "|" + "|".join(align) + "|"]
        lines += ["| " + " | ".join(_fmt(c, d) for c, d in zip(r, self.digits)) + " |" for r in self.rows]
        if self.caption:
            lines += ["", self.caption]
        return "\n".join(lines)

    def html(self) -> str:
        """An HTML ``<table>`` with escaped cells."""
        num = [self._numeric(j) for j in range(len(self.header))]
        out = ["<table>"]
        if self.caption:
            out.append(f"<caption>{html.escape(self.caption)}</caption>")
        out.append("<tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in self.header) + "</tr>")
        for r in self.rows:
            cells = []
            for j, c in enumerate(r):
                cls = ' class="num"' if num[j] else ""
                cells.append(f"<td{cls}>{html.escape(_fmt(c, self.digits[j]))}</td>")
            out.append("<tr>" + "".join(cells) + "</tr>")
        out.append("</table>")
        return "\n".join(out)


@dataclass
class Figure:
    """An image file (PNG, GIF or JPEG) to embed, with a caption."""

    path: Path
    caption: str = ""


@dataclass
class Section:
    """A titled part of the report: paragraphs (plain text, escaped), tables, figures, a note."""

    title: str
    paragraphs: list = field(default_factory=list)
    tables: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    note: str = ""
    code: str = ""


def data_uri(path) -> str:
    """``data:<mime>;base64,...`` of an image file (PNG, GIF, JPEG).

    Raises
    ------
    ValueError
        An unknown extension, or content that does not start with that format's signature.
    """
    path = Path(path)
    mime = _MIME.get(path.suffix.lower())
    if mime is None:
        raise ValueError(f"path must be a .png, .gif or .jpg image, got {path}")
    data = path.read_bytes()
    magic = {"image/png": b"\x89PNG\r\n\x1a\n", "image/gif": b"GIF8", "image/jpeg": b"\xff\xd8"}[mime]
    if not data.startswith(magic):
        raise ValueError(f"{path} is not a valid {mime} file")
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def _anchor(title: str) -> str:
    return "".join(ch if ch.isalnum() else "-" for ch in title.lower()).strip("-")


def render_report(title: str, sections, intro: str = "") -> str:
    """The whole HTML page as a string (see the module docstring)."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html.escape(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    if intro:
        parts.append(f"<p>{html.escape(intro)}</p>")
    parts.append("<nav><ul>")
    for s in sections:
        parts.append(f'<li><a href="#{_anchor(s.title)}">{html.escape(s.title)}</a></li>')
    parts.append("</ul></nav>")
    for s in sections:
        parts.append(f'<h2 id="{_anchor(s.title)}">{html.escape(s.title)}</h2>')
        if s.note:
            parts.append(f'<p class="note">{html.escape(s.note)}</p>')
        for p in s.paragraphs:
            parts.append(f"<p>{html.escape(p)}</p>")
        for t in s.tables:
            parts.append(t.html())
        for f in s.figures:
            alt = html.escape(f.caption or Path(f.path).name)
            parts.append(
                f'<figure><img src="{data_uri(f.path)}" alt="{alt}">'
                f"<figcaption>{html.escape(f.caption)}</figcaption></figure>"
            )
        if s.code:
            parts.append(f"<pre>{html.escape(s.code)}</pre>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def render_markdown(title: str, sections) -> str:
    """The tables (and notes) of the sections as Markdown; sections with neither are left out.

    Examples
    --------
    >>> t = Table(["a"], [[1]])
    >>> print(render_markdown("m", [Section("S", tables=[t]), Section("empty", paragraphs=["x"])]))
    # m
    <BLANKLINE>
    ## S
    <BLANKLINE>
    | a |
    |---:|
    | 1 |
    <BLANKLINE>
    """
    md = [f"# {title}", ""]
    for s in sections:
        if s.tables or s.note:
            md += [f"## {s.title}", ""]
            if s.note:
                md += [s.note, ""]
            for t in s.tables:
                md += [t.markdown(), ""]
    return "\n".join(md)


def write_report(path, title: str, sections, intro: str = "") -> Path:
    """Write :func:`render_report` to ``path`` (UTF-8) and return the path."""
    path = Path(path)
    path.write_text(render_report(title, sections, intro), encoding="utf-8")
    return path
