"""Every reference to a lesson's section ("lesson 2 §5", "Lesson 5, §3", "`lessons/02_....md`, §2–3")
in the course's texts points to a section number that the lesson's headings still have, and a
reference that says what it points to, "§2 (a tilted plane sliding sideways ...)", points to a section
that talks about it: each longer word of the parenthesis (its first four letters) begins a word of
the referenced section (with its subsections).

Lessons get rebuilt and renumbered; a stale "§4" sends a student to the wrong derivation. The texts
checked are :data:`TEXTS`: every Markdown file of ``solutions/`` and ``lessons/``. More texts (the
mistake catalogue's messages, exercise statements) join by adding ``(name, text)`` pairs to the list
:func:`course_texts` returns.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LESSONS = ROOT / "lessons"

#: "lesson 2", "Lesson 2", or a lesson's file, "lessons/02_variational_scene_flow.md" (with or
#: without "../", backticks, a link's closing bracket)
_ANCHOR = re.compile(r"(?:\b[Ll]essons? (?P<num>\d+)|lessons/(?P<file>\d\d)_[A-Za-z0-9_]+\.(?:md|ipynb))")
#: what may stand between the anchor and the first "§": a comma, closing backtick/parenthesis/bracket,
#: spaces, an anchor of a link target
_GAP = re.compile(r"[`)\],]*(?:\([^)\s]*\))?[`)\],]*,?\s*(?=§)")
#: one section or a range, "§5", "§5a", "§A.2", "§2–3"; further ones follow as ", §7" or " and §8"
_SECTION = re.compile(r"§\s?(?P<a>[0-9]+[a-z]?|[A-Z](?:\.[0-9]+)?)(?:[–-](?P<b>[0-9]+[a-z]?))?")
_MORE = re.compile(r"(?:,\s*|\s+and\s+)(?=§)")
#: a heading's section number: "## 5. Title", "### 5a. Title", "## Appendix A. Title", "### A.2 Title"
_HEADING = re.compile(r"^#{2,4}\s+(?:Appendix\s+)?(?P<n>[0-9]+[a-z]?|[A-Z](?:\.[0-9]+)?)[.\s]")


def lesson_sections(markdown: str) -> set[str]:
    """Section numbers of a lesson's headings (outside code cells)."""
    out, fenced = set(), False
    for line in markdown.splitlines():
        if line.startswith("```"):
            fenced = not fenced
            continue
        if not fenced:
            m = _HEADING.match(line)
            if m:
                out.add(m.group("n"))
    return out


def section_texts(markdown: str) -> dict[str, str]:
    """Each section's text (its heading to the next heading of the same or a higher level)."""
    lines, fenced, starts = markdown.splitlines(), False, []
    for i, line in enumerate(lines):
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and _HEADING.match(line):
            starts.append((i, len(line) - len(line.lstrip("#")), _HEADING.match(line).group("n")))
    out = {}
    for k, (i, level, n) in enumerate(starts):
        end = next((j for j, lv, _ in starts[k + 1:] if lv <= level), len(lines))
        out[n] = "\n".join(lines[i:end])
    return out


#: words a parenthesis after a reference may use without the section using them
_COMMON = {"about", "after", "again", "along", "before", "every", "which", "their", "there", "these",
           "those", "where", "while", "would", "other", "shows", "checked", "example"}


def topic_stems(text: str, pos: int) -> list[str]:
    """The first four letters of each word of five or more letters in the parenthesis that opens at
    ``pos`` (up to its first colon or closing parenthesis), common words left out."""
    m = re.match(r"\s*\(([^():]{0,120})", text[pos:])
    if m is None:
        return []
    words = re.findall(r"(?<![\\A-Za-z])[A-Za-z][a-z]{4,}", m.group(1))  # not LaTeX commands
    return [w[:4].lower() for w in words if w.lower() not in _COMMON]


def lesson_references(text: str) -> list[tuple[int, str, str]]:
    """``(lesson number, section, context)`` for every section reference tied to a lesson in ``text``."""
    return [(n, s, c) for n, s, c, _ in _references(text)]


def _references(text: str) -> list[tuple[int, str, str, list[str]]]:
    """As :func:`lesson_references`, with the topic stems of the parenthesis after each reference."""
    refs = []
    for m in _ANCHOR.finditer(text):
        lesson = int(m.group("num") or m.group("file"))
        pos = m.end()
        gap = _GAP.match(text, pos)
        if gap is None:
            continue
        pos = gap.end()
        while True:
            s = _SECTION.match(text, pos)
            if s is None:
                break
            context = text[max(0, m.start() - 20): s.end() + 20].replace("\n", " ")
            found = [(lesson, s.group("a"), context)]
            if s.group("b"):
                found.append((lesson, s.group("b"), context))
            pos = s.end()
            more = _MORE.match(text, pos)
            topic = [] if more is not None else topic_stems(text, pos)
            refs += [(*f, topic) for f in found]
            if more is None:
                break
            pos = more.end()
    return refs


def lesson_files() -> dict[int, Path]:
    return {int(p.name[:2]): p for p in sorted(LESSONS.glob("[0-9][0-9]_*.md"))}


def course_texts() -> list[tuple[str, str]]:
    """The texts whose lesson references are checked: ``(name, text)``."""
    paths = sorted((ROOT / "solutions").glob("*.md")) + sorted(LESSONS.glob("*.md"))
    return [(p.relative_to(ROOT).as_posix(), p.read_text(encoding="utf-8")) for p in paths]


def stale_references(texts, lessons: dict[int, str]) -> list[str]:
    """The references in ``texts`` (``(name, text)`` pairs) to a lesson or section that ``lessons``
    (number -> Markdown) lacks."""
    sections = {n: section_texts(md) for n, md in lessons.items()}
    bad = []
    for name, text in texts:
        refs = _references(text)
        for lesson, sec, context, topic in refs:
            if lesson not in sections:
                bad.append(f"{name}: lesson {lesson} does not exist: ...{context}...")
                continue
            if sec not in sections[lesson]:
                bad.append(f"{name}: lesson {lesson} has no §{sec} (it has {sorted(sections[lesson])}): "
                           f"...{context}...")
                continue
            # a range "§2–3 (...)" describes both sections together
            body = " ".join(sections[lesson].get(s_, "") for n_, s_, c_, _ in refs
                            if n_ == lesson and c_ == context)
            starts = {w[:4].lower() for w in re.findall(r"[A-Za-z]{4,}", body)}
            missing = [w for w in topic if w not in starts]
            if missing:
                bad.append(f"{name}: lesson {lesson} §{sec} does not mention {missing}: ...{context}...")
    return bad


def test_every_lesson_section_reference_exists():
    lessons = {n: p.read_text(encoding="utf-8") for n, p in lesson_files().items()}
    texts = course_texts()
    assert sum(len(lesson_references(t)) for _, t in texts) >= 8  # the parser finds the references
    assert stale_references(texts, lessons) == []


@pytest.mark.parametrize("text, expected", [
    ("see lesson 2 §5 and", [(2, "5")]),
    ("(Lesson 5, §3, has the example", [(5, "3")]),
    ("[Lesson 5, §3](../lessons/05_multi_object_tracking.md):", [(5, "3")]),
    ("checked in `lessons/04_bayes_and_kalman.md`, §3, §7, §8):", [(4, "3"), (4, "7"), (4, "8")]),
    ("`lessons/05_multi_object_tracking.md`, §2–3 (the literal LP", [(5, "2"), (5, "3")]),
    ("lesson 6 §5a and §5c", [(6, "5a"), (6, "5c")]),
    ("lesson 2 (§3)", []),          # not tied: a parenthesis opens before the section
    ("the syllabus' §3 energy", []),
    ("lesson 2 §A.1", [(2, "A.1")]),
])
def test_the_parser_reads_the_forms_the_course_uses(text, expected):
    assert [(n, s) for n, s, _ in lesson_references(text)] == expected


def test_a_stale_reference_is_reported():
    lesson = "# Lesson 9\n\n## 1. One\n\n### 1a. Sub\n\n```{code-cell} ipython3\n## 7. not a heading\n```\n"
    assert lesson_sections(lesson) == {"1", "1a"}
    bad = stale_references([("x.md", "as lesson 9 §7 shows; lesson 9, §1a; lesson 8 §1")], {9: lesson})
    assert len(bad) == 2 and "no §7" in bad[0] and "lesson 8 does not exist" in bad[1]


def test_a_reference_whose_parenthesis_names_another_topic_is_reported():
    lesson = ("## 1. Planes\n\nA fronto-parallel plane slides.\n\n"
              "## 2. Tilted\n\nA tilted plane slides sideways.\n")
    text = "checked in lesson 9, §{} (a tilted plane sliding sideways: wrong by 0.1 m/s)"
    assert stale_references([("x.md", text.format(2))], {9: lesson}) == []
    bad = stale_references([("x.md", text.format(1))], {9: lesson})
    assert len(bad) == 1 and "['tilt', 'side']" in bad[0]
