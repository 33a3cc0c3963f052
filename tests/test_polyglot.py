"""One polyglot stack serves the ports and the language grader.

- each problem's cases have a single source: the ports' seeded vector cases and the grader's hidden
  cases for the same seed are the same inputs, and what the grader sends into a sandbox and writes
  into the students' ``public.json`` is the problem's own document;
- one id per mistake in every language: every id the language grader names is in the course's
  catalogue (the notebooks' mistakes, and the few only other languages show, defined in the grading
  module of the exercise they belong to) and its feedback line is the catalogue's (message and
  lesson pointer);
- one registry of languages and toolchains, one ``ToolchainMissing``, one Wolfram-language writer;
- the layers: the stack imports neither the grader nor the ports' command, and those two never
  import each other (any import, also inside a function).

No compiler or sandbox is needed here; the ports' and the grader's own tests run the toolchains.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from flowtrack_course.grading.engine.mistakes import GENERIC
from flowtrack_course.grading.engine.spec import Outcome
from flowtrack_course.grading.languages import PROBLEMS as GRADER_PROBLEMS
from flowtrack_course.grading.languages import TOOLCHAINS, ToolchainMissing, materialise
from flowtrack_course.grading.languages.exercises import _score_cases
from flowtrack_course.polyglot import base, mathics, toolchains
from flowtrack_course.polyglot.problems import GRADED_PROBLEMS, PROBLEMS, VECTOR_PROBLEMS
from flowtrack_course.ports import runner
from flowtrack_course.ports.vectors import VECTORS_DIR, generate, problem_names
from grading_helpers import (
    COURSE_SET,
    LANGUAGE_EXERCISES,
    LANGUAGES,
    exercise_module,
    find_language_exercise,
    instructor_source,
)

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "reference_impl" / "flowtrack_course"
#: the mistakes the language grader names, with their messages: the course's
CATALOGUE = LANGUAGES.catalogue
mistake_line = CATALOGUE.line
#: the mistakes only answers in other languages show
OTHER_LANGUAGES = [m for m in CATALOGUE.values() if m.id not in COURSE_SET.catalogue]


# -- one source of cases -----------------------------------------------------------------------------
def test_the_grader_and_the_ports_read_one_registry_of_problems():
    assert GRADER_PROBLEMS is GRADED_PROBLEMS
    assert all(PROBLEMS[name] is p for name, p in GRADED_PROBLEMS.items())
    assert {ex.problem for ex in LANGUAGE_EXERCISES} == set(GRADED_PROBLEMS)
    assert problem_names() == sorted(VECTOR_PROBLEMS)
    assert {p.stem for p in VECTORS_DIR.glob("*.json")} == set(VECTOR_PROBLEMS)
    for name in ("white_noise_q", "projection_jacobian"):
        assert generate(name) == VECTOR_PROBLEMS[name].vectors()
    # a problem served to both is one object with both kinds of cases
    assert set(GRADED_PROBLEMS) & set(VECTOR_PROBLEMS) == {"projection_jacobian"}


def _sent(ex_id: str, hidden: bool, seed: int) -> dict:
    """The document the grader's test sends into the sandbox (inputs only) for ``seed``."""
    ex = find_language_exercise(ex_id)
    test = next(t for t in ex.tests if t.hidden == hidden)
    calls, _scorer = test.build(np.random.default_rng(seed))
    (call,) = calls
    return call.args[0]


def test_the_ports_seeded_cases_are_the_graders_hidden_cases_for_the_same_seed():
    """The vector file's random points were drawn from seed 6; the grader's hidden test for a student
    whose seed is 6 gets the same points, from the same function (no second generator)."""
    committed = json.loads((VECTORS_DIR / "projection_jacobian.json").read_text())
    seeded = [c for c in committed["cases"] if c["id"] not in ("point0", "point1")]
    assert len(seeded) == 4
    for ex_id in ("cpp_projection_jacobian", "mathics_projection_jacobian"):
        sent = _sent(ex_id, hidden=True, seed=6)["cases"]
        assert [c["input"] for c in sent] == [c["input"] for c in seeded[:3]]
        assert all("expected" not in c for c in sent)  # expected values never enter a sandbox
    p = PROBLEMS["projection_jacobian"]
    for case in seeded[:3]:  # and the grader's reference gives the committed expected values
        np.testing.assert_allclose(p.reference(case["input"])["J"], case["expected"]["J"],
                                   rtol=case["rtol"], atol=case["atol"])


@pytest.mark.parametrize("problem", sorted(GRADED_PROBLEMS))
def test_the_graders_cases_and_public_json_are_the_problems_documents(problem, tmp_path):
    p = GRADED_PROBLEMS[problem]
    ex = next(e for e in LANGUAGE_EXERCISES if e.problem == problem)
    public = p.document(p.public_cases())
    materialise(ex, instructor_source(ex).parent, tmp_path, stub=True)
    assert json.loads((tmp_path / "public.json").read_text()) == public
    inputs = [{"id": c["id"], "input": c["input"]} for c in public["cases"]]
    assert _sent(ex.id, hidden=False, seed=0) == {"problem": problem, "cases": inputs}
    hidden = p.document(p.hidden_cases(np.random.default_rng(11)), expected=False)
    assert _sent(ex.id, hidden=True, seed=11) == hidden
    assert hidden["cases"] and hidden["cases"] != inputs


# -- one id per mistake ------------------------------------------------------------------------------
def _outcome(cases, outputs):
    return Outcome(True, {c["id"]: {"ok": True, "value": {k: np.asarray(v).tolist() for k, v in o.items()}}
                          for c, o in zip(cases, outputs)})


@pytest.mark.parametrize("problem", sorted(GRADED_PROBLEMS))
def test_every_language_mistake_is_the_catalogues_with_its_message(problem):
    p = GRADED_PROBLEMS[problem]
    assert p.mistakes
    assert set(p.generic) <= {g.id for g in GENERIC}
    cases = [{"id": c.id, "input": c.input} for c in p.hidden_cases(np.random.default_rng(3))]
    expected = [{k: np.asarray(v, float) for k, v in p.reference(c["input"]).items()} for c in cases]
    for mid, wrong in p.mistakes:
        assert mid in CATALOGUE, f"{problem}: {mid} is not in the notebooks' mistake catalogue"
        assert "lesson 0" in CATALOGUE[mid].message
        outputs = [{**exp, **wrong(c["input"])} for c, exp in zip(cases, expected)]
        _score, msg = _score_cases(p, cases, expected, _outcome(cases, outputs), show=False,
                                   catalogue=CATALOGUE)
        assert mid in msg.mistakes, (mid, msg)  # the matcher's id; its line comes from CATALOGUE
    # the ids only answers in other languages show are catalogued for those problems, by the grading
    # module of the exercise the problem is a form of
    ids = {mid for q in GRADED_PROBLEMS.values() for mid, _ in q.mistakes}
    assert {m.id for m in OTHER_LANGUAGES} <= ids
    owner = {ex.problem: ex.exercise for ex in LANGUAGE_EXERCISES}
    for m in OTHER_LANGUAGES:
        problem = next(name for name, q in GRADED_PROBLEMS.items() if m.id in {i for i, _ in q.mistakes})
        assert m.exercise == owner[problem]
        assert m.id in {x.id for x in exercise_module(m.exercise).LANGUAGE_MISTAKES}
    assert {m.id for m in OTHER_LANGUAGES} == {"kalman-no-predict", "kalman-prior-cov", "jacobian-no-focal"}


def test_a_shared_mistake_has_one_id_in_python_and_in_other_languages():
    _ex05_Q_variants = exercise_module("ex05_cv_model")._ex05_Q_variants
    python_ids = {v.mistake for v in _ex05_Q_variants(0.5, 2.0)}
    language_ids = {mid for mid, _ in GRADED_PROBLEMS["cv_model"].mistakes}
    assert language_ids <= python_ids  # q-block-diagonal, q-continuous-white-noise
    assert "cv-q-blockdiag" not in CATALOGUE


# -- one registry of languages, one ToolchainMissing, one WL writer ---------------------------------
def test_one_registry_of_languages_and_toolchains():
    assert TOOLCHAINS is toolchains.TOOLCHAINS
    assert ToolchainMissing is base.ToolchainMissing
    assert tuple(runner.LANG_MODULES) == toolchains.LANGUAGES
    assert {ex.language for ex in LANGUAGE_EXERCISES} == set(toolchains.GRADED_LANGUAGES)
    assert all(ex.toolchain is TOOLCHAINS[ex.language] for ex in LANGUAGE_EXERCISES)
    for lang in toolchains.LANGUAGES:
        module = __import__(runner.LANG_MODULES[lang], fromlist=["TOOLCHAIN"])
        assert module.TOOLCHAIN is TOOLCHAINS[lang] and module.PORTS


def test_a_missing_tool_names_its_package_for_the_grader_and_the_ports(monkeypatch):
    monkeypatch.setattr(base.shutil, "which", lambda name: None)
    monkeypatch.setattr(base.glob, "glob", lambda pattern: [])
    with pytest.raises(ToolchainMissing, match=r"g\+\+.*apt-get install -y .*g\+\+") as grader:
        TOOLCHAINS["cpp"].check()
    assert "libpcl-dev" not in str(grader.value)  # an answer needs no PCL
    with pytest.raises(ToolchainMissing, match="libpcl-dev"):
        TOOLCHAINS["cpp"].check(ports=True)
    with pytest.raises(ToolchainMissing, match="libopencv-java"):
        TOOLCHAINS["java"].check(ports=True)


def test_the_ports_and_the_sandbox_share_one_wolfram_language_writer():
    shipped = TOOLCHAINS["mathics"].support_files("cv_model")["ft_mathics.py"]
    assert Path(mathics.harness().__file__).read_text(encoding="utf-8") == shipped
    assert mathics.to_wl([1e-300, -2.5]) == mathics.harness().to_wl([1e-300, -2.5]) == "{1.*^-300, -2.5}"


# -- the layers ------------------------------------------------------------------------------------------
def _imports(path: Path) -> set[str]:
    """Every module ``path`` imports (module level and inside functions), relative ones resolved."""
    package = ".".join(path.relative_to(PKG.parent).with_suffix("").parts)
    if path.name != "__init__.py":
        package = package.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base_mod = node.module or ""
            if node.level:
                parts = package.split(".")
                base_mod = ".".join(parts[: len(parts) - node.level + 1] + ([base_mod] if base_mod else []))
            out.add(base_mod)
            out.update(f"{base_mod}.{a.name}" for a in node.names)
    return out


def _importing(folder: Path, prefix: str) -> list[str]:
    return [
        f"{p.relative_to(PKG)} imports {m}"
        for p in sorted(folder.rglob("*.py"))
        if "files" not in p.relative_to(folder).parts
        for m in sorted(_imports(p))
        if m == prefix or m.startswith(prefix + ".")
    ]


def test_the_import_resolver_sees_relative_and_function_level_imports():
    found = _imports(PKG / "grading" / "languages" / "exercises.py")
    assert {"flowtrack_course.polyglot.problems", "grading_sandbox.cache"} <= found


@pytest.mark.parametrize(
    ("folder", "forbidden"),
    [
        ("polyglot", "flowtrack_course.grading"),
        ("polyglot", "flowtrack_course.ports"),
        ("ports", "flowtrack_course.grading"),
        ("grading", "flowtrack_course.ports"),
    ],
)
def test_the_ports_and_the_grader_import_the_stack_never_each_other(folder, forbidden):
    assert not _importing(PKG / folder, forbidden)
