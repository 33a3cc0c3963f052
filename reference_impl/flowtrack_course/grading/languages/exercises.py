"""Language exercises: one :class:`LanguageExercise` per (problem, language), graded like the notebooks.

A language exercise is an :class:`~flowtrack_course.grading.spec.Exercise` whose "notebook" is the student's
source file ``<lang>/<problem>/<problem>.<ext>`` (relative to ``exercises/``; in a submission,
``SUBMISSIONS/<student>/exercises/<lang>/<problem>/...``) and whose one answer "cell" is the
driver (:mod:`flowtrack_course.grading.languages.driver`) carrying that file. ``run_exercise`` asks it for
its cells with :meth:`LanguageExercise.extract_cells`; everything else (sandbox, seeds, scoring,
feedback, ``results.json``, ``grades.csv``) is the notebooks' machinery.

Tests: a public test on the problem's fixed inputs (1 point) and a hidden test on inputs drawn from
the student's keyed seed (2 points). Each is one call of the driver's ``run_cases`` with the cases
in the shared vectors format (inputs only). The scorer compares every output with the Python
reference's under the problem's tolerances (``|got - exp| <= atol + rtol |exp|``): the fraction of
the points is the mean over cases of the share of correct outputs. An output that matches one of
the problem's catalogued mistakes, or a generic one (``generic-sign``, ``generic-transpose``,
``generic-scale``), adds a ``mistake <id>: <message>`` line to the message.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..engine.spec import Call, Exercise, GradedTest, Outcome, as_float_array
from .driver import driver_cell
from .problems import PROBLEMS, Problem
from .toolchains import TOOLCHAINS, Toolchain, support_text

__all__ = [
    "BLOCKED",
    "answered_exercises",
    "LANGUAGE_EXERCISES",
    "LanguageExercise",
    "find_language_exercise",
    "materialise",
    "public_vectors",
    "release_languages",
    "strip_solutions",
    "submitted_exercises",
]

#: Modules the sandboxed child (and so anything the student's program starts) cannot load: the
#: reference that computes the expected values, and solvers that would do the work.
BLOCKED = (
    "flowtrack.kalman",
    "flowtrack.camera",
    "flowtrack.association",
    "flowtrack.tracking",
    "flowtrack_course.ports",
    "flowtrack.symbolic",
    "scipy.optimize",
)

#: What a Mathematica answer's sandbox holds besides the standard library: Mathics3 and what it needs,
#: nothing else (no flowtrack at all). Its zygote (:class:`~flowtrack_course.grading.sandbox.SandboxPool`)
#: imports these before forking a child per exercise: ``mathics.__main__`` loads the builtins and
#: ``mathics.profile_mathics`` builds one pristine set of definitions, so that a child starts the
#: interpreter in milliseconds instead of seconds (the harness falls back to building its own).
#: The zygote preloads only where nothing in its view is blocked, so ``scipy.optimize`` (a
#: dependency of Mathics3, whose own solvers are the language's ecosystem anyway) is not blocked there.
MATHICS_ALLOWED = ("numpy", "mathics", "mathics.__main__", "mathics.profile_mathics")

PUBLIC_POINTS = 1.0
HIDDEN_POINTS = 2.0
MAX_SOURCE_BYTES = 256 * 1024


@dataclass(frozen=True)
class LanguageExercise(Exercise):
    """An :class:`Exercise` answered in ``language`` (a key of :data:`TOOLCHAINS`) for ``problem``."""

    language: str = ""
    problem: str = ""

    @property
    def toolchain(self) -> Toolchain:
        return TOOLCHAINS[self.language]

    @property
    def spawns(self) -> bool:
        """The driver starts compilers and programs (every language but Mathics3, run in-process):
        ``run_exercise`` then lets the sandbox's child start processes (``Sandbox(spawn=True)``)."""
        return self.toolchain.inproc(self.problem) is None

    def source_files(self) -> list[Path]:
        """The grader's files this item's grading depends on beyond its tests' module: the driver, the
        toolchains and problems modules and the language's harness files (``exercises_hash`` hashes
        them, so a change of any of them re-grades finished students)."""
        here = Path(__file__).resolve().parent
        files = [here / "driver.py", here / "toolchains.py", here / "problems.py", here / "exercises.py"]
        files += sorted(p for p in (here / "files" / self.language).rglob("*") if p.is_file())
        return files

    def extract_cells(self, path: Path) -> tuple[list[tuple[str, str]], list[str]]:
        """The driver cell carrying the student's file ``path``, or ``([], [why])``."""
        name = self.toolchain.source_name(self.problem)
        if not path.is_file():
            return [], [f"file not submitted: {self.language}/{self.problem}/{name}"]
        data = path.read_bytes()
        if len(data) > MAX_SOURCE_BYTES:
            return [], [f"{name} is larger than {MAX_SOURCE_BYTES} bytes"]
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            return [], [f"{name} is not UTF-8 text"]
        tc = self.toolchain
        try:
            blobs = tc.blobs(self.problem)
        except Exception as exc:  # a missing toolchain is the grading machine's problem: say so
            return [], [f"cannot grade {tc.title} here: {exc}"]
        cell = driver_cell(
            files={name: text, **tc.support_files(self.problem)},
            blobs=blobs,
            build=tc.build_commands(self.problem),
            run=tc.run_command(self.problem),
            env={"LANG": "C.UTF-8", "OMP_NUM_THREADS": "1"},
            compile_seconds=tc.compile_seconds,
            run_seconds=tc.run_seconds,
            output_bytes=256 * 1024,
            inproc=tc.inproc(self.problem),
        )
        return [(f"{self.language}:{name}", cell)], []


# -- scoring ---------------------------------------------------------------------------------------
def _matches(got: np.ndarray, want: np.ndarray, rtol: float, atol: float) -> bool:
    want = np.asarray(want, dtype=float)
    return got.shape == want.shape and bool(np.all(np.abs(got - want) <= atol + rtol * np.abs(want)))


def _generic_mistake(got: np.ndarray, exp: np.ndarray, rtol: float, atol: float) -> str | None:
    if not np.any(np.abs(exp) > atol):
        return None
    if _matches(got, -exp, rtol, atol):
        return "generic-sign"
    if exp.ndim == 2 and exp.shape[0] == exp.shape[1] and _matches(got, exp.T, rtol, atol):
        return "generic-transpose"
    big = np.abs(exp) > atol
    ratio = got[big] / exp[big]
    if ratio.size and np.all(np.isfinite(ratio)) and abs(ratio[0] - 1) > 1e-6 and ratio[0] != 0:
        if _matches(got, ratio[0] * exp, rtol, atol):
            return "generic-scale"
    return None


_GENERIC = {
    "generic-sign": "the result has the opposite sign",
    "generic-transpose": "the result is the transpose of the expected matrix",
    "generic-scale": "the result is off by a constant factor",
}


def _score_cases(
    problem: Problem, cases: list[dict], expected: list[dict], outcome: Outcome, show: bool
) -> tuple[float, str]:
    if not outcome.ok:
        return 0.0, outcome.error or "the program failed"
    value = outcome.value if isinstance(outcome.value, dict) else {}
    fractions, notes, mistakes = [], [], {}
    for case, exp in zip(cases, expected):
        res = value.get(case["id"])
        if not isinstance(res, dict) or not res.get("ok") or not isinstance(res.get("value"), dict):
            err = res.get("error") if isinstance(res, dict) else None
            fractions.append(0.0)
            notes.append(f"case {case['id']}: {err or 'no result'}")
            continue
        outputs = res["value"]
        good = 0
        for name, want in exp.items():
            want = np.asarray(want, dtype=float)
            got = as_float_array(outputs.get(name), want.shape)
            if got is None:
                shape = as_float_array(outputs.get(name))
                notes.append(
                    f"case {case['id']}: {name} "
                    + (
                        "missing or not numbers"
                        if shape is None
                        else f"has shape {shape.shape}, expected {want.shape}"
                    )
                )
                continue
            if _matches(got, want, problem.rtol, problem.atol):
                good += 1
                continue
            worst = float(np.max(np.abs(got - want)))
            notes.append(f"case {case['id']}: {name} differs (largest error {worst:.3g})")
            found = None
            for mid, msg, wrong in problem.mistakes:
                try:
                    alt = wrong(case["input"]).get(name)
                except Exception:  # a mistaken formula may not apply to these inputs
                    alt = None
                if alt is not None and _matches(got, np.asarray(alt, float), problem.rtol, problem.atol):
                    found = (mid, msg)
                    break
            if found is None:
                gid = _generic_mistake(got, want, problem.rtol, problem.atol)
                found = (gid, f"{name}: {_GENERIC[gid]}") if gid else None
            if found:
                mistakes.setdefault(found[0], found[1])
        fractions.append(good / max(1, len(exp)))
    score = float(np.mean(fractions)) if fractions else 0.0
    n_ok = sum(f >= 1.0 for f in fractions)
    if score >= 1.0:
        return 1.0, f"all {len(cases)} cases correct"
    lines = [f"{n_ok}/{len(cases)} cases correct"]
    if show:
        lines += notes[:6] + (["..."] if len(notes) > 6 else [])
    lines += [f"mistake {mid}: {msg}" for mid, msg in mistakes.items()]
    return score, "\n".join(lines)


def _test(problem: Problem, hidden: bool) -> GradedTest:
    def build(rng: np.random.Generator):
        inputs = problem.hidden(rng) if hidden else problem.public()
        cases = [
            {"id": f"{'hidden' if hidden else 'public'}-{i}", "input": inp} for i, inp in enumerate(inputs)
        ]
        expected = [
            {k: np.asarray(v, float) for k, v in problem.reference(c["input"]).items()} for c in cases
        ]
        doc = {"problem": problem.name, "cases": cases}

        def scorer(outcomes: Sequence[Outcome]) -> tuple[float, str]:
            if len(outcomes) != 1:
                return 0.0, "no result from the sandbox"
            return _score_cases(problem, cases, expected, outcomes[0], show=not hidden)

        return [Call("run_cases", (doc,))], scorer

    build.__wrapped__ = problem.reference  # grade.exercises_hash hashes the module defining the problem
    name = f"{'hidden' if hidden else 'public'}: {problem.title}"
    return GradedTest(
        name, f"test_{problem.name}", HIDDEN_POINTS if hidden else PUBLIC_POINTS, hidden, build, timeout=0.0
    )


def _exercise(language: str, problem: Problem) -> LanguageExercise:
    tc = TOOLCHAINS[language]
    timeout = tc.compile_seconds + tc.run_seconds + 30.0  # the wall-clock limit of one test's batch
    tests = tuple(
        GradedTest(t.name, t.grade_id, t.points, t.hidden, t.build, timeout)
        for t in (_test(problem, False), _test(problem, True))
    )
    return LanguageExercise(
        id=f"{language}_{problem.name}",
        title=f"{problem.title} ({tc.title})",
        notebook=f"{language}/{problem.name}/{tc.source_name(problem.name)}",
        answer_cells=(tc.source_name(problem.name),),
        blocked=tuple(b for b in BLOCKED if b != "scipy.optimize") if language == "mathics" else BLOCKED,
        allowed=MATHICS_ALLOWED if language == "mathics" else None,
        packages=("flowtrack",),
        tests=tests,
        language=language,
        problem=problem.name,
    )


LANGUAGE_EXERCISES: tuple[LanguageExercise, ...] = tuple(
    _exercise(lang, p) for lang in TOOLCHAINS for p in PROBLEMS.values()
    if p.languages is None or lang in p.languages
)


def find_language_exercise(key: str | Path) -> LanguageExercise | None:
    """The language exercise with id ``key`` or whose source file is named like ``key`` (a path or a
    name; the file names are unique: ``cv_model.cpp``, ``CvModel.java``, ``cv_model.m``, ...).

    Examples
    --------
    >>> find_language_exercise("somewhere/KalmanStep.java").id, find_language_exercise("ex05_cv_model")
    ('java_kalman_step', None)
    """
    key = str(key)
    name = Path(key).name
    for ex in LANGUAGE_EXERCISES:
        if key == ex.id or name == Path(ex.notebook).name:
            return ex
    return None


# -- files of the bundle ---------------------------------------------------------------------------
_BLOCK = re.compile(
    r"^([ \t]*)(?://|%|\(\*)\s*BEGIN SOLUTION.*?^[ \t]*(?://|%|\(\*)\s*END SOLUTION[^\n]*\n", re.M | re.S
)
_TODO = {
    "cpp": "// YOUR CODE HERE",
    "java": "// YOUR CODE HERE",
    "octave": "% YOUR CODE HERE",
    "mathics": "(* YOUR CODE HERE *)",
}


def strip_solutions(text: str, language: str) -> str:
    """Replace every ``BEGIN SOLUTION`` ... ``END SOLUTION`` block by a ``YOUR CODE HERE`` comment.

    Examples
    --------
    >>> text = "f\\n  % BEGIN SOLUTION\\n  x = 1;\\n  % END SOLUTION\\nend\\n"
    >>> print(strip_solutions(text, "octave"), end="")
    f
      % YOUR CODE HERE
    end
    """
    out = _BLOCK.sub(lambda m: f"{m.group(1)}{_TODO[language]}\n", text)
    if "BEGIN SOLUTION" in out or "END SOLUTION" in out:
        raise ValueError("text: unbalanced BEGIN SOLUTION / END SOLUTION markers")
    return out


def public_vectors(problem: Problem) -> dict:
    """The public cases of ``problem`` in the shared vectors format, expected values included."""
    cases = []
    for i, inp in enumerate(problem.public()):
        expected = {k: np.asarray(v, dtype=float).tolist() for k, v in problem.reference(inp).items()}
        cases.append(
            {
                "id": f"public-{i}",
                "input": inp,
                "expected": expected,
                "rtol": problem.rtol,
                "atol": problem.atol,
            }
        )
    return {"problem": problem.name, "cases": cases}


def materialise(ex: LanguageExercise, source_dir: Path, dest: Path, *, stub: bool) -> list[Path]:
    """Write the exercise's folder into ``dest``: the student file (its stub with ``stub=True``), the
    grader's support files, the public tests' vectors ``public.json`` and the local build files."""
    from ...ports.vectors import dumps

    tc = ex.toolchain
    dest.mkdir(parents=True, exist_ok=True)
    name = tc.source_name(ex.problem)
    text = (source_dir / name).read_text(encoding="utf-8")
    files = {name: strip_solutions(text, ex.language) if stub else text}
    if ex.language == "cpp":
        files["exercise.hpp"] = support_text("cpp", f"{ex.problem}.hpp")
        files["harness.cpp"] = support_text("cpp", "harness.cpp")
        files["CMakeLists.txt"] = support_text("cpp", "CMakeLists.txt").replace("@PROBLEM@", ex.problem)
    elif ex.language == "java":
        from .toolchains import FILES, JAVA_CLASSPATH

        files["Harness.java"] = support_text("java", "Harness.java")
        (dest / "api").mkdir(exist_ok=True)
        for p in sorted((FILES / "java" / "api").iterdir(), key=lambda p: p.name):
            if p.name.endswith(".java") and p.name != name:  # the other exercises' signatures
                files[f"api/{p.name}"] = p.read_text(encoding="utf-8")
        files["run_public_tests.sh"] = (
            f"#!/bin/sh\n# Compile and run the public tests of {ex.problem}:  sh run_public_tests.sh\n"
            f"set -e\nCP={JAVA_CLASSPATH}\nmkdir -p classes\n"
            'javac -encoding UTF-8 -cp "$CP" -sourcepath api -implicit:class -d classes '
            f"Harness.java {name}\n"
            f'java -cp "classes:$CP" Harness --check {ex.problem} public.json\n'
        )
    elif ex.language == "mathics":
        files["ft_mathics.py"] = support_text("mathics", "ft_mathics.py")
    else:
        files["ft_harness.m"] = support_text("octave", "ft_harness.m")
        files["run_public_tests.m"] = (
            f"% Run the public tests of {ex.problem}:  octave-cli --norc run_public_tests.m\n"
            f"ok = ft_harness('{ex.problem}', 'public.json', true);\nif ~ok\n  exit(1);\nend\n"
        )
    doc = public_vectors(PROBLEMS[ex.problem])
    files["public.json"] = dumps(doc)
    written = []
    for rel, body in files.items():
        p = dest / rel
        p.write_text(body, encoding="utf-8")
        written.append(p)
    return written


def answered_exercises(student_dir: str | Path) -> tuple[LanguageExercise, ...]:
    """The language exercises one student's folder holds a source file of (by file name, anywhere
    below it: Gradescope uploads are often flat)."""
    root = Path(student_dir)
    if not root.is_dir():
        return ()
    exts = {tc.extension for tc in TOOLCHAINS.values()}
    names = {p.name for p in root.rglob("*") if p.suffix in exts}
    return tuple(ex for ex in LANGUAGE_EXERCISES if Path(ex.notebook).name in names)


def submitted_exercises(submissions: str | Path) -> tuple[LanguageExercise, ...]:
    """The language exercises at least one student folder of ``submissions`` holds a source file of.

    ``flowtrack grade`` adds them to the notebooks, so a class answering only in Python gets the same
    ``grades.csv`` as before, and every answered (exercise, language) item gets its column.
    """
    root = Path(submissions)
    found: set[str] = set()
    for d in sorted(root.iterdir()) if root.is_dir() else []:
        if d.is_dir() and not d.name.startswith("."):
            found.update(ex.id for ex in answered_exercises(d))
    return tuple(ex for ex in LANGUAGE_EXERCISES if ex.id in found)


def release_languages(source: Path, dest: Path) -> list[str]:
    """Write the stubs of every language exercise found under ``source`` (the course's ``exercises/``)
    into ``dest`` (the bundle's ``exercises/``) at the same relative paths, with the public tests,
    the build files and each language's ``README.md``; return the student files written (relative)."""
    written = []
    for ex in LANGUAGE_EXERCISES:
        folder = Path(source) / ex.language / ex.problem
        if not (folder / ex.toolchain.source_name(ex.problem)).is_file():
            continue
        materialise(ex, folder, Path(dest) / ex.language / ex.problem, stub=True)
        readme = Path(source) / ex.language / "README.md"
        if readme.is_file():
            (Path(dest) / ex.language / "README.md").write_text(
                readme.read_text(encoding="utf-8"), encoding="utf-8"
            )
        written.append(ex.notebook)
    return written
