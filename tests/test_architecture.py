"""The two layers stay apart (docs/ARCHITECTURE.md): parsed with ``ast``, never imported.

- ``flowtrack`` (the library) never imports ``flowtrack_course`` (the tooling);
- no import cycle between modules (imports at module level; a function-level import runs later and
  cannot deadlock the import system);
- no module uses another module's private names (``from flowtrack.x import _name``, or
  ``x._name`` on an imported module); underscore modules (``_validation``, ``_graph``, ...) are
  helpers shared by their package and may be used whole.

The checker itself is tested on small made-up packages first, so that a green run means something.
"""

from __future__ import annotations

import ast
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "reference_impl"
LIBRARY, TOOLING = "flowtrack", "flowtrack_course"


# --------------------------------------------------------------------------------------------------
# the checker
@dataclass
class ImportGraph:
    modules: dict[str, Path] = field(default_factory=dict)
    packages: set[str] = field(default_factory=set)
    #: module -> [(imported module, line, at module level)]
    edges: dict[str, list[tuple[str, int, bool]]] = field(default_factory=dict)
    #: (module, line, text) of every use of another module's private name
    private: list[tuple[str, int, str]] = field(default_factory=list)


def _module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_module(module: str) -> bool:
    """An underscore helper module (``flowtrack._validation``) or inside one."""
    return any(_is_private(p) for p in module.split("."))


def _walk_with_level(tree: ast.Module):
    """Yield ``(node, at_module_level)``; ``if TYPE_CHECKING:`` bodies count as not at module level."""
    stack = [(n, True) for n in tree.body]
    while stack:
        node, top = stack.pop()
        yield node, top
        inner_top = top and not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            inner_top = False
        stack.extend((c, inner_top) for c in ast.iter_child_nodes(node))


def build_graph(src: Path, roots: tuple[str, ...]) -> ImportGraph:
    """Parse every module of the packages ``roots`` under ``src``."""
    g = ImportGraph()
    for root in roots:
        for path in sorted((src / root).rglob("*.py")):
            name = _module_name(path, src)
            g.modules[name] = path
            if path.name == "__init__.py":
                g.packages.add(name)
    for name, path in g.modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        package = name if name in g.packages else name.rpartition(".")[0]
        edges = g.edges.setdefault(name, [])
        aliases: dict[str, str] = {}  # local name -> one of our modules

        def ours(mod: str) -> bool:
            return mod.split(".")[0] in roots

        for node, top in _walk_with_level(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if ours(a.name):
                        edges.append((a.name, node.lineno, top))
                        top_name = a.name.split(".")[0]
                        aliases[a.asname or top_name] = a.name if a.asname else top_name
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if not ours(target):
                    continue
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    if sub in g.modules:  # a submodule
                        edges.append((sub, node.lineno, top))
                        aliases[a.asname or a.name] = sub
                        continue
                    edges.append((target, node.lineno, top))
                    if _is_private(a.name) and not _private_module(target) and target != name:
                        g.private.append((name, node.lineno, f"from {target} import {a.name}"))
            elif isinstance(node, ast.Call) and ast.unparse(node.func) in (
                "importlib.import_module", "import_module", "__import__"
            ):
                arg = node.args[0] if node.args else None
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    mod = arg.value
                    if ours(mod):
                        edges.append((mod, node.lineno, top))
        for node in ast.walk(tree):  # x._name on a module imported under the name x
            if isinstance(node, ast.Attribute) and _is_private(node.attr):
                base = ast.unparse(node.value)
                mod = aliases.get(base.split(".")[0])
                if mod is None:
                    continue
                mod = ".".join([mod, *base.split(".")[1:]])
                if mod in g.modules and mod != name and not _private_module(mod):
                    g.private.append((name, node.lineno, f"{base}.{node.attr}"))
    return g


def cycles(g: ImportGraph) -> list[list[str]]:
    """Strongly connected components (size > 1, or a self-import) of the module-level import graph."""
    adj = {m: sorted({t for t, _, top in es if top and t in g.modules}) for m, es in g.edges.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan (the graph has ~80 nodes: recursion is fine)
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in adj.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in adj.get(v, []):
                out.append(sorted(comp))

    for v in sorted(adj):
        if v not in index:
            visit(v)
    return out


def layer_violations(g: ImportGraph) -> list[tuple[str, int, str]]:
    """Every import (at any level) of the tooling by a library module."""
    return [
        (m, line, t)
        for m, es in g.edges.items()
        if m.split(".")[0] == LIBRARY
        for t, line, _ in es
        if t.split(".")[0] == TOOLING
    ]


# --------------------------------------------------------------------------------------------------
# the checker on made-up packages: it finds what it must find
def _write(src: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = src / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(textwrap.dedent(text))
    return src


def test_checker_finds_a_cycle_but_not_a_function_level_one(tmp_path):
    src = _write(tmp_path, {
        "flowtrack/__init__.py": "",
        "flowtrack/a.py": "from .b import f\n",
        "flowtrack/b.py": "from flowtrack import c\n",
        "flowtrack/c.py": "import flowtrack.a\n",
        "flowtrack/d.py": "def g():\n    from .e import h\n",
        "flowtrack/e.py": "from .d import g\n",
    })
    g = build_graph(src, (LIBRARY,))
    assert cycles(g) == [["flowtrack.a", "flowtrack.b", "flowtrack.c"]]


def test_checker_finds_the_library_importing_the_tooling(tmp_path):
    src = _write(tmp_path, {
        "flowtrack/__init__.py": "",
        "flowtrack/a.py": "def f():\n    import flowtrack_course.widgets\n",
        "flowtrack/b.py": "import importlib\nM = importlib.import_module('flowtrack_course.cli')\n",
        "flowtrack_course/__init__.py": "from flowtrack import a\n",
        "flowtrack_course/widgets.py": "",
        "flowtrack_course/cli.py": "",
    })
    g = build_graph(src, (LIBRARY, TOOLING))
    assert sorted((m, t) for m, _, t in layer_violations(g)) == [
        ("flowtrack.a", "flowtrack_course.widgets"), ("flowtrack.b", "flowtrack_course.cli")]


def test_checker_finds_private_names_across_modules(tmp_path):
    src = _write(tmp_path, {
        "flowtrack/__init__.py": "",
        "flowtrack/_validation.py": "def _scalar(x):\n    return x\n",
        "flowtrack/a.py": "def _helper():\n    pass\ndef __dunder__():\n    pass\n",
        "flowtrack/b.py": """
            from ._validation import _scalar          # fine: an underscore helper module
            from .a import __dunder__                 # fine: not private
            from .a import _helper                    # private
            from . import a
            import flowtrack.a as fa
            a._helper()                               # private
            fa._helper()                              # private
            def _mine():
                pass
            _mine()                                   # fine: its own
            """,
    })
    g = build_graph(src, (LIBRARY,))
    found = sorted(text for _, _, text in g.private)
    assert found == ["a._helper", "fa._helper", "from flowtrack.a import _helper"]


# --------------------------------------------------------------------------------------------------
# the real packages
@pytest.fixture(scope="module")
def graph() -> ImportGraph:
    return build_graph(SRC, (LIBRARY, TOOLING))


def test_both_packages_are_parsed(graph):
    expected = {"flowtrack.kalman", "flowtrack.tracking", "flowtrack_course.cli",
                "flowtrack_course.grading.grade"}
    assert expected <= set(graph.modules)
    assert sum(len(es) for es in graph.edges.values()) > 50


def test_the_library_never_imports_the_tooling(graph):
    bad = [
        f"{graph.modules[m].relative_to(ROOT)}:{line} imports {t}" for m, line, t in layer_violations(graph)
    ]
    assert not bad, "the library imports the course tooling:\n" + "\n".join(bad)


def test_no_import_cycles(graph):
    found = cycles(graph)
    assert not found, "import cycles (module level):\n" + "\n".join(" <-> ".join(c) for c in found)


@pytest.mark.parametrize("layer", [LIBRARY, TOOLING])
def test_no_private_names_across_modules(graph, layer):
    bad = [
        f"{graph.modules[m].relative_to(ROOT)}:{line}: {text}"
        for m, line, text in graph.private
        if m.split(".")[0] == layer
    ]
    assert not bad, "private names used across modules (make them public or move the code):\n" + "\n".join(
        bad
    )


def test_the_library_package_lists_no_tooling():
    """``flowtrack.__init__``'s lazy submodules are library modules that exist."""
    tree = ast.parse((SRC / LIBRARY / "__init__.py").read_text(encoding="utf-8"))
    names = next(
        ast.literal_eval(n.value)
        for n in tree.body
        if isinstance(n, ast.Assign) and any(getattr(t, "id", "") == "_SUBMODULES" for t in n.targets)
    )
    for n in names:
        assert (SRC / LIBRARY / f"{n}.py").is_file() or (SRC / LIBRARY / n / "__init__.py").is_file(), n
    assert not names & {p.stem for p in (SRC / TOOLING).iterdir()}
