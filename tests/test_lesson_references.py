"""Every reference to a lesson's section ("lesson 2 §5", "Lesson 5, §3", "`lessons/02_....md`, §2–3")
in the course's texts points to a section number that the lesson's headings still have, and a
reference that says what it points to, "§2 (a tilted plane sliding sideways ...)", points to a section
that talks about it: each longer word of the parenthesis (its first four letters) begins a word of
the referenced section (with its subsections).

A parenthesis that ends with the reference names its topic too: "(Young's theorem; lesson 2 §A.2)".

Lessons get rebuilt and renumbered; a stale "§4" sends a student to the wrong derivation. The texts
checked (:func:`course_texts`, all discovered, none listed): every Markdown file of ``solutions/``,
``lessons/`` and ``exercises/`` (the guides, each exercise's worked solution), the Markdown cells of
every exercise notebook, and every catalogued mistake's message (the exercises' ``MISTAKES`` and
``LANGUAGE_MISTAKES``, as the grader renders them). A mistake message is what a student reads after
a wrong answer, so each of its references must say what it points to: "see lesson
02_variational_scene_flow §A.2 (red-black Gauss–Seidel)"; an existing but renumbered section number
alone would pass unnoticed.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LESSONS = ROOT / "lessons"

#: "lesson 2", "Lesson 2", a lesson's name as the mistake messages write it,
#: "lesson 02_variational_scene_flow", or a lesson's file, "lessons/02_variational_scene_flow.md" (with or
#: without "../", backticks, a link's closing bracket)
_ANCHOR = re.compile(
    r"(?:\b[Ll]essons? (?P<num>\d+)(?:_[A-Za-z0-9_]+)?|lessons/(?P<file>\d\d)_[A-Za-z0-9_]+\.(?:md|ipynb))"
)
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


def _stems(words_text: str) -> list[str]:
    words = re.findall(r"(?<![\\A-Za-z])[A-Za-z][a-z]{4,}", words_text)  # not LaTeX commands
    return [w[:4].lower() for w in words if w.lower() not in _COMMON]


def topic_stems(text: str, pos: int) -> list[str]:
    """The first four letters of each word of five or more letters in the parenthesis that opens at
    ``pos`` (up to its first colon or closing parenthesis), common words left out."""
    m = re.match(r"\s*\(([^():]{0,120})", text[pos:])
    if m is None:
        return []
    return _stems(m.group(1))


def leading_topic_stems(text: str, start: int) -> list[str]:
    """The topic stems of a parenthesis that ends with the reference starting at ``start``:
    "(Young's theorem; lesson 2 §A.2)" names "Young's theorem" (text after "(", ending in ";" or ",")."""
    m = re.search(r"\(([^()]{1,120}?)[;,]\s*$", text[max(0, start - 122):start])
    return _stems(m.group(1)) if m else []


def lesson_references(text: str) -> list[tuple[int, str, str]]:
    """``(lesson number, section, context)`` for every section reference tied to a lesson in ``text``."""
    return [(n, s, c) for n, s, c, _, _ in _references(text)]


def _references(text: str) -> list[tuple[int, str, str, list[str], int]]:
    """As :func:`lesson_references`, with the topic stems that describe each reference (a
    parenthesis after its last section, or one that ends with it) and the index of its group (one
    anchor and the sections that follow it: "lesson 6 §5a and §5c (...)" is one group, whose topic
    describes the sections together)."""
    refs = []
    for group, m in enumerate(_ANCHOR.finditer(text)):
        lesson = int(m.group("num") or m.group("file"))
        pos = m.end()
        gap = _GAP.match(text, pos)
        if gap is None:
            continue
        pos = gap.end()
        found = []
        while True:
            s = _SECTION.match(text, pos)
            if s is None:
                break
            context = text[max(0, m.start() - 20): s.end() + 20].replace("\n", " ")
            found.append((lesson, s.group("a"), context))
            if s.group("b"):
                found.append((lesson, s.group("b"), context))
            pos = s.end()
            more = _MORE.match(text, pos)
            if more is None:
                break
            pos = more.end()
        if found:
            topic = topic_stems(text, pos) + leading_topic_stems(text, m.start())
            refs += [(*f, topic, group) for f in found]
    return refs


def lesson_files() -> dict[int, Path]:
    return {int(p.name[:2]): p for p in sorted(LESSONS.glob("[0-9][0-9]_*.md"))}


def _notebook_markdown(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return "\n\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")


def mistake_messages() -> list[tuple[str, str]]:
    """``("mistake <id>", message)`` for every catalogued mistake of the course's exercises (their
    ``MISTAKES`` and ``LANGUAGE_MISTAKES``, discovered as the grader discovers them)."""
    from flowtrack_course.grading.engine.discovery import discover

    course = discover(ROOT)
    out = {m.id: m.message for m in course.catalogue.values() if m.exercise != "*"}
    for ex in course.exercises:
        for m in course.module(ex.id).__dict__.get("LANGUAGE_MISTAKES", ()):
            out[m.id] = m.message
    return [(f"mistake {k}", v) for k, v in sorted(out.items())]


def course_texts() -> list[tuple[str, str]]:
    """The texts whose lesson references are checked: ``(name, text)``."""
    paths = sorted((ROOT / "solutions").glob("*.md")) + sorted(LESSONS.glob("*.md"))
    paths += sorted((ROOT / "exercises").rglob("*.md"))
    texts = [(p.relative_to(ROOT).as_posix(), p.read_text(encoding="utf-8")) for p in paths]
    texts += [(p.relative_to(ROOT).as_posix(), _notebook_markdown(p))
              for p in sorted((ROOT / "exercises").rglob("*.ipynb")) if ".ipynb_checkpoints" not in p.parts]
    return texts + mistake_messages()


def stale_references(texts, lessons: dict[int, str]) -> list[str]:
    """The references in ``texts`` (``(name, text)`` pairs) to a lesson or section that ``lessons``
    (number -> Markdown) lacks, or whose topic the section does not talk about."""
    sections = {n: section_texts(md) for n, md in lessons.items()}
    bad = []
    for name, text in texts:
        refs = _references(text)
        for lesson, sec, context, topic, group in refs:
            if lesson not in sections:
                bad.append(f"{name}: lesson {lesson} does not exist: ...{context}...")
                continue
            if sec not in sections[lesson]:
                bad.append(f"{name}: lesson {lesson} has no §{sec} (it has {sorted(sections[lesson])}): "
                           f"...{context}...")
                continue
            # a group "§2–3 (...)", "§5a and §5c (...)" describes its sections together
            body = " ".join(sections[lesson].get(s_, "") for n_, s_, _, _, g_ in refs if g_ == group)
            starts = {w[:4].lower() for w in re.findall(r"[A-Za-z]{4,}", body)}
            missing = [w for w in topic if w not in starts]
            if missing:
                bad.append(f"{name}: lesson {lesson} §{sec} does not mention {missing}: ...{context}...")
    return bad


def references_without_topic(texts) -> list[str]:
    """The references in ``texts`` that no parenthesis describes (a mistake message must say what it
    points to: a renumbered lesson can keep the number and change the content)."""
    return [f"{name}: ...{context}..." for name, text in texts
            for _, _, context, topic, _ in _references(text) if not topic]


def test_every_lesson_section_reference_exists():
    lessons = {n: p.read_text(encoding="utf-8") for n, p in lesson_files().items()}
    texts = course_texts()
    assert sum(len(lesson_references(t)) for _, t in texts) >= 8  # the parser finds the references
    assert stale_references(texts, lessons) == []


def test_the_checked_texts_are_discovered():
    """Mistake messages, exercise notebooks and the exercises' Markdown are checked, found by
    globbing and by the grader's discovery (a new exercise joins without editing this file)."""
    names = [n for n, _ in course_texts()]
    folders = sorted(p.parent.name for p in (ROOT / "exercises").glob("*/grading.py"))
    for folder in folders:
        assert f"exercises/{folder}/{folder}.ipynb" in names, folder
        assert f"exercises/{folder}/solution.md" in names, folder
    messages = dict(mistake_messages())
    assert len(messages) >= 40 and all("lesson 0" in m for m in messages.values())
    assert "mistake jacobian-no-focal" in messages  # a LANGUAGE_MISTAKES one
    refs = sum(len(lesson_references(t)) for t in messages.values())
    assert refs >= len(messages)  # every message points to a lesson section


def test_every_mistake_message_says_what_its_reference_points_to():
    assert references_without_topic(mistake_messages()) == []


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
    ("see lesson 02_variational_scene_flow §A.2 (Gauss", [(2, "A.2")]),
    ("see lesson 05_multi_object_tracking §4-5 (ids)", [(5, "4"), (5, "5")]),
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


def test_a_renumbered_section_is_caught_through_the_topic():
    """The stale catalogue references of the rebuild ("GS §4" after Gauss–Seidel moved to §A.2)
    point to sections that still exist: only the topic a message names catches them."""
    lesson = ("## 3. Euler–Lagrange\n\nThe first variation.\n\n## 4. Full energy\n\nTwo equations.\n\n"
              "## Appendix A. Grid\n\n### A.2 Solvers\n\nRed-black Gauss–Seidel sweeps; Young's theorem.\n")
    old = [("mistake x", "a Jacobi sweep; see lesson 09_demo §4")]
    assert stale_references(old, {9: lesson}) == []          # the number alone passes ...
    assert len(references_without_topic(old)) == 1           # ... so a message must name its topic
    stale = [("mistake x", "a Jacobi sweep; see lesson 09_demo §4 (red-black Gauss–Seidel)")]
    bad = stale_references(stale, {9: lesson})
    assert len(bad) == 1 and "does not mention ['blac', 'gaus', 'seid']" in bad[0]
    right = [("mistake x", "a Jacobi sweep; see lesson 09_demo §A.2 (red-black Gauss–Seidel)")]
    assert stale_references(right, {9: lesson}) == [] and references_without_topic(right) == []
    # a parenthesis that ends with the reference names its topic as well
    assert stale_references([("nb", "(Young's theorem; lesson 9 §A.2)")], {9: lesson}) == []
    bad = stale_references([("nb", "(Young's theorem; lesson 9 §3)")], {9: lesson})
    assert len(bad) == 1 and "['youn', 'theo']" in bad[0]
