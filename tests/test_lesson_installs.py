"""The lessons run from the install the bundle's README names (the ``student`` extra): every
package a lesson imports unguarded comes with the core dependencies or that extra (or a package
they require)."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_CELL = re.compile(r"^```\{code-cell\}[^\n]*\n(.*?)^```", re.S | re.M)
_NAME = re.compile(r"^[A-Za-z0-9_.\-]+")


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _unguarded_imports(text: str) -> set[str]:
    """Top-level module names a lesson imports at a cell's top level (not under ``try``/``if``)."""
    out = set()
    for cell in _CELL.findall(text):
        code = "\n".join(ln for ln in cell.splitlines() if not ln.lstrip().startswith(("%", "!", ":")))
        try:
            tree = ast.parse(code)
        except SyntaxError:
            continue
        for node in tree.body:
            if isinstance(node, ast.Import):
                out |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                out.add(node.module.split(".")[0])
    return out


def _closure(names: set[str]) -> set[str]:
    """``names`` and every distribution they require (as installed here), normalised."""
    seen, todo = set(), [_norm(n) for n in names]
    while todo:
        n = todo.pop()
        if n in seen:
            continue
        seen.add(n)
        try:
            reqs = metadata.requires(n) or []
        except metadata.PackageNotFoundError:
            continue
        for r in reqs:
            if "extra ==" in r:
                continue
            m = _NAME.match(r)
            if m:
                todo.append(_norm(m.group(0)))
    return seen


def test_every_lesson_imports_only_what_the_student_install_brings():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = project["dependencies"] + project["optional-dependencies"]["student"]
    wanted = {_NAME.match(r).group(0) for r in reqs}
    allowed = _closure(wanted)
    dists = metadata.packages_distributions()
    own = {"flowtrack", "flowtrack_course", "grading_sandbox"}
    missing = []
    for lesson in sorted((ROOT / "lessons").glob("[0-9]*.md")):
        for mod in sorted(_unguarded_imports(lesson.read_text(encoding="utf-8"))):
            if mod in sys.stdlib_module_names or mod in own:
                continue
            names = {_norm(d) for d in dists.get(mod, [mod])}
            if not names & allowed:
                missing.append(f"{lesson.name}: {mod} ({', '.join(sorted(names))})")
    assert not missing, "\n".join(missing)
