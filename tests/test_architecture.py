"""The layers stay apart (docs/ARCHITECTURE.md): parsed with ``ast``, never imported.

- ``flowtrack`` (the library) never imports ``flowtrack_course`` (the tooling) nor ``grading_sandbox``;
- ``grading_sandbox`` (the sandbox) imports nothing of the course: neither the library nor the
  tooling, names no course folder, and says "flowtrack" only in its configuration of names;
- the grading engine (``flowtrack_course.grading.engine``) imports no exercise, no export, no
  command, no port and no other-language code, and names no exercise of the course; an exercise's
  grading module is written with the engine's authoring API only;
- the polyglot stack (``flowtrack_course.polyglot``: toolchains, problems, per-language drivers)
  imports neither the grader nor the ports' command, which never import each other;
- no import cycle between modules, imports inside functions included (``if TYPE_CHECKING:``
  imports, which never run, excepted);
- no module uses another module's private names (``from flowtrack.x import _name``, or
  ``x._name`` on an imported module); underscore modules (``_validation``, ``_graph``, ...) are
  helpers shared by their package and may be used whole, but only by their package: the tooling
  never imports a private module of the library;
- no file of the library, the tooling or the sandbox (Python, or the harnesses in other languages)
  has more than 900 lines.

The checker itself is tested on small made-up packages first, so that a green run means something.
"""

from __future__ import annotations

import ast
import re
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "reference_impl"
LIBRARY, TOOLING, SANDBOX = "flowtrack", "flowtrack_course", "grading_sandbox"
ENGINE = "flowtrack_course.grading.engine"
MAX_LINES = 900


# --------------------------------------------------------------------------------------------------
# the checker
@dataclass
class ImportGraph:
    modules: dict[str, Path] = field(default_factory=dict)
    packages: set[str] = field(default_factory=set)
    #: module -> [(imported module, line, at module level)]
    edges: dict[str, list[tuple[str, int, bool]]] = field(default_factory=dict)
    #: module -> [(imported module, line)] of the imports that never run (``if TYPE_CHECKING:``)
    typing_only: dict[str, list[tuple[str, int]]] = field(default_factory=dict)
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
    """Yield ``(node, at_module_level, runs)``; ``if TYPE_CHECKING:`` bodies count as not at module
    level and as never run."""
    stack = [(n, True, True) for n in tree.body]
    while stack:
        node, top, runs = stack.pop()
        yield node, top, runs
        inner_top = top and not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        inner_runs = runs
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            inner_top = inner_runs = False
        stack.extend((c, inner_top, inner_runs) for c in ast.iter_child_nodes(node))


def build_graph(src: Path, roots: tuple[str, ...], skip: tuple[str, ...] = ()) -> ImportGraph:
    """Parse every module of the packages ``roots`` under ``src`` (but those in the packages ``skip``)."""
    g = ImportGraph()
    for root in roots:
        for path in sorted((src / root).rglob("*.py")):
            name = _module_name(path, src)
            if any(name == s or name.startswith(s + ".") for s in skip):
                continue
            g.modules[name] = path
            if path.name == "__init__.py":
                g.packages.add(name)
    for name, path in g.modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        package = name if name in g.packages else name.rpartition(".")[0]
        running = g.edges.setdefault(name, [])
        never = g.typing_only.setdefault(name, [])
        aliases: dict[str, str] = {}  # local name -> one of our modules

        def ours(mod: str) -> bool:
            return mod.split(".")[0] in roots

        for node, top, runs in _walk_with_level(tree):

            def add(target: str, line: int, top: bool = top, runs: bool = runs,
                    running: list = running, never: list = never) -> None:
                if runs:
                    running.append((target, line, top))
                else:
                    never.append((target, line))

            if isinstance(node, ast.Import):
                for a in node.names:
                    if ours(a.name):
                        add(a.name, node.lineno)
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
                        add(sub, node.lineno)
                        aliases[a.asname or a.name] = sub
                        continue
                    add(target, node.lineno)
                    if _is_private(a.name) and not _private_module(target) and target != name:
                        g.private.append((name, node.lineno, f"from {target} import {a.name}"))
            elif isinstance(node, ast.Call) and ast.unparse(node.func) in (
                "importlib.import_module", "import_module", "__import__"
            ):
                arg = node.args[0] if node.args else None
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    mod = arg.value
                    if ours(mod):
                        add(mod, node.lineno)
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


def cycles(g: ImportGraph, module_level_only: bool = False) -> list[list[str]]:
    """Strongly connected components (size > 1, or a self-import) of the import graph: every import
    that runs (inside functions too), or only those at module level."""
    adj = {
        m: sorted({t for t, _, top in es if (top or not module_level_only) and t in g.modules})
        for m, es in g.edges.items()
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan (the graph has ~200 nodes: recursion is fine)
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


def imports_of(g: ImportGraph, importer: str, imported: tuple[str, ...]) -> list[tuple[str, int, str]]:
    """Every import (at any level, ``TYPE_CHECKING`` ones included) by a module of ``importer`` (a
    package or module name) of a module of one of ``imported``."""

    def inside(mod: str, pkg: str) -> bool:
        return mod == pkg or mod.startswith(pkg + ".")

    return [
        (m, line, t)
        for m in g.modules
        if inside(m, importer)
        for t, line in [(t, line) for t, line, _ in g.edges.get(m, [])] + g.typing_only.get(m, [])
        if any(inside(t, i) for i in imported)
    ]


def layer_violations(g: ImportGraph) -> list[tuple[str, int, str]]:
    """Every import (at any level) of the tooling or the sandbox by a library module."""
    return imports_of(g, LIBRARY, (TOOLING, SANDBOX))


# --------------------------------------------------------------------------------------------------
# the checker on made-up packages: it finds what it must find
def _write(src: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = src / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(textwrap.dedent(text))
    return src


def test_checker_finds_cycles_also_through_function_level_imports(tmp_path):
    src = _write(tmp_path, {
        "flowtrack/__init__.py": "",
        "flowtrack/a.py": "from .b import f\n",
        "flowtrack/b.py": "from flowtrack import c\n",
        "flowtrack/c.py": "import flowtrack.a\n",
        "flowtrack/d.py": "def g():\n    from .e import h\n",
        "flowtrack/e.py": "from .d import g\n",
        "flowtrack/f.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .g import x\n",
        "flowtrack/g.py": "from .f import y\n",
    })
    g = build_graph(src, (LIBRARY,))
    assert cycles(g, module_level_only=True) == [["flowtrack.a", "flowtrack.b", "flowtrack.c"]]
    # d <-> e is a cycle hidden in a function; f <-> g is not one (a TYPE_CHECKING import never runs)
    assert cycles(g) == [["flowtrack.a", "flowtrack.b", "flowtrack.c"], ["flowtrack.d", "flowtrack.e"]]
    assert imports_of(g, "flowtrack.f", ("flowtrack.g",)) == [("flowtrack.f", 3, "flowtrack.g")]


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
    # (the sandbox's own tests expose the repository's library in their sandboxes: not part of it)
    return build_graph(SRC, (LIBRARY, TOOLING, SANDBOX), skip=(f"{SANDBOX}.tests",))


def _shown(graph, found) -> str:
    return "\n".join(f"{graph.modules[m].relative_to(ROOT)}:{line} imports {t}" for m, line, t in found)


def test_all_packages_are_parsed(graph):
    expected = {"flowtrack.kalman", "flowtrack.tracking", "flowtrack_course.cli",
                f"{ENGINE}.run", f"{SANDBOX}.sandbox"}
    assert expected <= set(graph.modules)
    assert sum(len(es) for es in graph.edges.values()) > 50


def test_the_library_never_imports_the_tooling(graph):
    bad = layer_violations(graph)
    assert not bad, "the library imports the course tooling or the sandbox:\n" + _shown(graph, bad)


def test_the_sandbox_imports_nothing_of_the_course(graph):
    bad = imports_of(graph, SANDBOX, (LIBRARY, TOOLING))
    assert not bad, "the sandbox imports the course:\n" + _shown(graph, bad)
    # nor names it: no course folder, and the course's name only in its configuration of names
    course_paths = re.compile(r"exercises/|solutions/|lessons/|reference_impl|cpp_java_matlab_ports")
    for name, path in graph.modules.items():
        if not (name == SANDBOX or name.startswith(SANDBOX + ".")):
            continue
        text = path.read_text(encoding="utf-8")
        assert not course_paths.search(text), (path, course_paths.search(text).group(0))
        if name != f"{SANDBOX}.config":
            assert "flowtrack" not in text.lower(), path


# what the engine may never import: the commands above it, the exports, the other languages
# (a source of exercises the commands compose), the ports
ABOVE_THE_ENGINE = tuple(
    f"flowtrack_course.{m}"
    for m in ("grading.assign", "grading.check", "grading.grade", "grading.export", "grading.languages",
              "grading.sources", "grading.cli", "ports", "polyglot", "cli", "demo", "book", "widgets",
              "notebooks")
)


def test_the_engine_imports_no_exercise_export_command_or_port(graph):
    bad = imports_of(graph, ENGINE, ABOVE_THE_ENGINE)
    assert not bad, "the grading engine imports a layer above it:\n" + _shown(graph, bad)


def test_the_engine_names_no_exercise_and_exercises_use_its_authoring_api():
    from flowtrack_course.grading.engine.discovery import discover

    course = discover(ROOT)
    assert len(course) >= 12
    for path in sorted((SRC / "flowtrack_course" / "grading" / "engine").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        named = [ex.id for ex in course if ex.id in text]
        assert not named, f"{path.relative_to(ROOT)} names the exercises {named}: it must find them"
    # an exercise folder's modules import the library, the engine's authoring API and third parties
    allowed = (f"{ENGINE}.authoring", f"{ENGINE}.symbolic")
    for path in sorted((ROOT / "exercises").glob("*/*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            mods = ([a.name for a in node.names] if isinstance(node, ast.Import)
                    else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            for mod in mods:
                if mod.split(".")[0] in (TOOLING, SANDBOX):
                    assert mod in allowed, f"{path.relative_to(ROOT)} imports {mod}"


POLYGLOT, PORTS, GRADING = "flowtrack_course.polyglot", "flowtrack_course.ports", "flowtrack_course.grading"


@pytest.mark.parametrize(("importer", "imported"), [
    (POLYGLOT, (GRADING, PORTS)),  # the stack both build and run other languages with
    (PORTS, (GRADING,)),
    (GRADING, (PORTS,)),
])
def test_the_polyglot_stack_serves_the_ports_and_the_grader_which_never_import_each_other(
    graph, importer, imported
):
    bad = imports_of(graph, importer, imported)
    assert not bad, f"{importer} imports {imported}:\n" + _shown(graph, bad)


def test_no_import_cycles_even_inside_functions(graph):
    found = cycles(graph)
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


@pytest.mark.parametrize("layer", [LIBRARY, TOOLING, SANDBOX])
def test_no_private_names_across_modules(graph, layer):
    bad = [
        f"{graph.modules[m].relative_to(ROOT)}:{line}: {text}"
        for m, line, text in graph.private
        if m.split(".")[0] == layer
    ]
    assert not bad, "private names used across modules (make them public or move the code):\n" + "\n".join(
        bad
    )


def test_the_tooling_imports_no_private_module_of_the_library(graph):
    found = imports_of(graph, TOOLING, (LIBRARY,)) + imports_of(graph, SANDBOX, (LIBRARY,))
    bad = [(m, line, t) for m, line, t in found if _private_module(t)]
    assert not bad, "the tooling imports private modules of the library:\n" + _shown(graph, bad)


#: the sources of the library, the tooling and the sandbox: Python and the harnesses in other languages
SOURCE_SUFFIXES = (".py", ".cpp", ".hpp", ".java", ".m", ".wl")


def test_no_file_over_900_lines():
    sources = [p for p in sorted(SRC.rglob("*")) if p.suffix in SOURCE_SUFFIXES]
    assert {p.suffix for p in sources} >= {".py", ".cpp", ".java", ".m"}
    long = {
        str(p.relative_to(ROOT)): n
        for p in sources
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert not long, f"files over {MAX_LINES} lines (split them along their parts): {long}"


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


# --------------------------------------------------------------------------------------------------
# docs/ARCHITECTURE.md names every package and module, and only ones that exist
ARCHITECTURE = ROOT / "docs" / "ARCHITECTURE.md"
_NAMED = re.compile(r"`((?:flowtrack|flowtrack_course|grading_sandbox)(?:\.\w+)*)`")


def _code_modules() -> dict[str, Path]:
    """Every package and module of the three packages (harness files and test modules aside: a
    package's own ``tests`` is named as a package)."""
    out = {}
    for root in (LIBRARY, TOOLING, SANDBOX):
        for path in sorted((SRC / root).rglob("*.py")):
            rel = path.relative_to(SRC)
            if "files" in rel.parts or "__pycache__" in rel.parts:
                continue
            name = _module_name(path, SRC)
            if ".tests." in name:
                continue
            out[name] = path
    return out


def _resolves(name: str, modules: dict[str, Path]) -> bool:
    """``name`` is a module, or an attribute (a class, function, constant) of one."""
    import importlib

    if name in modules:
        return True
    module, _, attr = name.rpartition(".")
    while module and module not in modules:
        module, _, more = module.rpartition(".")
        attr = f"{more}.{attr}"
    if not module:
        return False
    obj = importlib.import_module(module)
    for part in attr.split("."):
        if not hasattr(obj, part):
            return False
        obj = getattr(obj, part)
    return True


def test_the_architecture_page_names_every_module_and_no_missing_one():
    modules = _code_modules()
    named = set(_NAMED.findall(ARCHITECTURE.read_text(encoding="utf-8")))
    assert len(modules) > 100 and "flowtrack_course.polyglot.problems.kalman" in modules
    missing = sorted(m for m in named if not _resolves(m, modules))
    assert not missing, f"docs/ARCHITECTURE.md names modules that do not exist: {missing}"
    unnamed = sorted(set(modules) - named)
    assert not unnamed, f"docs/ARCHITECTURE.md does not name these packages and modules: {unnamed}"


def test_the_page_check_catches_a_stale_and_a_missing_module():
    modules = _code_modules()
    assert not _resolves("flowtrack.realdata", modules)  # a module that was removed
    assert not _resolves("flowtrack.kalman.NoSuchFilter", modules)
    assert _resolves("flowtrack.kalman.KalmanFilter", modules)
    assert _resolves("flowtrack_course.course.add_course_option", modules)
