"""Language exercises: one :class:`LanguageExercise` per (problem, language), graded like the notebooks.

A language exercise is an :class:`~flowtrack_course.grading.engine.spec.Exercise` whose "notebook" is
the student's source file ``<lang>/<problem>/<file>`` (relative to the bundle's ``exercises/``; in a
submission, ``SUBMISSIONS/<student>/exercises/<lang>/<problem>/...``) and whose one answer "cell" is
the driver (:mod:`flowtrack_course.grading.languages.driver`) carrying that file. The engine asks it
for its cells (:meth:`LanguageExercise.extract_cells`), whether it starts programs
(:attr:`~LanguageExercise.spawns`) and which files its grading depends on
(:meth:`~LanguageExercise.source_files`); everything else (sandbox, seeds, scoring, feedback,
``results.json``, ``grades.csv``) is the notebooks' machinery.

Which language exercises a course has is discovered like its notebooks: an exercise folder's grading
module that sets ``LANGUAGE_PROBLEM`` (a problem of :mod:`flowtrack_course.polyglot.problems`) is
answered in every language that problem is set in, and its ``LANGUAGE_MISTAKES`` are the mistakes
only those answers show, with their messages (:func:`language_exercises`). The problems, their
cases and the wrong answers that recognise their mistakes are the polyglot stack's (the ports'
vectors come from the same definitions); how each language is built and run is its
:mod:`flowtrack_course.polyglot` toolchain.

Tests: a public test on the problem's fixed inputs (1 point) and a hidden test on inputs drawn from
the student's keyed seed (2 points). Each is one call of the driver's ``run_cases`` with the cases
in the shared vectors format (inputs only). The scorer compares every output with the Python
reference's under the problem's tolerances (``|got - exp| <= atol + rtol |exp|``): the fraction of
the points is the mean over cases of the share of correct outputs. A wrong output is explained by
the engine's one mistake matcher (:func:`~flowtrack_course.grading.engine.mistakes.diagnose`): one
of the problem's catalogued mistakes, or a generic one the problem allows (``generic-sign``,
``generic-transpose``, ``generic-scale``); each adds the course catalogue's line
``mistake <id>: <message>`` (the same id and message as in the notebooks) to the feedback. A hidden
test's feedback says why it failed in the grader's words: a build that failed (the number of
compiler errors and the line of the first), a limit, that the program reported an error for a
case, a wrong shape or wrong values (:func:`program_error`); never the compiler's or the program's
own text, nor which cases or entries failed or by how much, which the student's code controls.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import polyglot
from ...polyglot.base import ToolchainMissing
from ...polyglot.problems import GRADED_PROBLEMS, Problem
from ...polyglot.toolchains import GRADED_LANGUAGES, TOOLCHAINS, Toolchain
from ...polyglot.vectors import dumps
from ..engine.discovery import ExerciseSet
from ..engine.feedback import Report, compare, safe_error
from ..engine.mistakes import Catalogue, Mistake, Variant, consistent_mistakes
from ..engine.spec import Call, Exercise, GradedTest, Outcome, as_float_array
from .driver import driver_cell

__all__ = [
    "BLOCKED",
    "LANGUAGE_MISTAKES",
    "LANGUAGE_PROBLEM",
    "LanguageExercise",
    "language_catalogue",
    "language_exercises",
    "materialise",
    "program_error",
    "public_vectors",
    "strip_solutions",
]

#: The name of a grading module's polyglot problem (the exercise answered in other languages).
LANGUAGE_PROBLEM = "LANGUAGE_PROBLEM"
#: The name of a grading module's mistakes only the answers in other languages show.
LANGUAGE_MISTAKES = "LANGUAGE_MISTAKES"

#: Modules the sandboxed child (and so anything the student's program starts) cannot load: the
#: reference that computes the expected values, and solvers that would do the work.
BLOCKED = (
    "flowtrack.kalman",
    "flowtrack.camera",
    "flowtrack.association",
    "flowtrack.tracking",
    "flowtrack_course.polyglot",
    "flowtrack_course.ports",
    "flowtrack.symbolic",
    "scipy.optimize",
)

#: What a Mathematica answer's sandbox holds besides the standard library: Mathics3 and what it needs,
#: nothing else (no flowtrack at all). Its zygote (:class:`grading_sandbox.SandboxPool`)
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
    """An :class:`Exercise` answered in ``language`` (a key of :data:`TOOLCHAINS`) for ``problem``;
    ``exercise`` is the id of the course's exercise (its folder) it is a form of."""

    language: str = ""
    problem: str = ""
    exercise: str = ""

    @property
    def toolchain(self) -> Toolchain:
        return TOOLCHAINS[self.language]

    @property
    def source_name(self) -> str:
        """The file the student writes (``cv_model.cpp``, ``CvModel.java``, ...)."""
        return self.toolchain.source_name(self.problem)

    @property
    def spawns(self) -> bool:
        """The driver starts compilers and programs (every language but Mathics3, run in-process):
        the engine then lets the sandbox's child start processes (``Sandbox(spawn=True)``)."""
        return self.toolchain.inproc(self.problem) is None

    def source_files(self) -> list[Path]:
        """The grader's files this item's grading depends on beyond its tests' module: the driver,
        the scoring, the polyglot stack's modules that build and run the language and define the
        problem, and the language's harness files (``exercises_hash`` hashes them, so a change of any
        of them re-grades finished students)."""
        here = Path(__file__).resolve().parent
        stack = Path(polyglot.__file__).resolve().parent
        problem = Path(inspect.getsourcefile(GRADED_PROBLEMS[self.problem].reference)).resolve()
        files = [here / "driver.py", here / "exercises.py"]
        files += [stack / f for f in ("base.py", "vectors.py", "toolchains.py", f"{self.language}.py")]
        files += [stack / "problems" / "base.py", problem]
        files += sorted(p for p in (stack / "files" / self.language).rglob("*") if p.is_file())
        return files

    def environment_problem(self) -> str:
        """The language's toolchain when this machine lacks it (what is missing and how to install
        it), else "": grading cannot happen here, and that is never the student's score."""
        try:
            self.toolchain.check()
        except ToolchainMissing as exc:
            return str(exc)
        return ""

    def harness_blobs(self) -> dict[str, bytes]:
        """The harness artefacts built from the grader's own sources (the C++ object, the Java class),
        cached in the sandbox's cache (:func:`grading_sandbox.cache.cache_root`), which every
        student's sandbox reads."""
        from grading_sandbox.cache import cache_root

        return self.toolchain.blobs(self.problem, cache_root() / "languages" / self.language)

    def extract_cells(self, path: Path) -> tuple[list[tuple[str, str]], list[str]]:
        """The driver cell carrying the student's file ``path``, or ``([], [why])``."""
        name = self.source_name
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
            blobs = self.harness_blobs()
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


def _diagnosis(problem: Problem, case: dict, name: str, got: np.ndarray, want: np.ndarray) -> Report:
    """What one wrong output of one case shows: the problem's catalogued mistakes, or a generic one
    the problem allows, with its relation (a :class:`~..engine.feedback.Report` of no text)."""
    variants = []
    for mid, wrong in problem.mistakes:
        try:
            alt = wrong(case["input"]).get(name)
        except Exception:  # a mistaken formula may not apply to these inputs
            alt = None
        if alt is not None:
            variants.append(Variant(mid, np.asarray(alt, dtype=float)))
    d = compare(Outcome(True, got.tolist()), want, rtol=problem.rtol, atol=problem.atol, variants=variants)
    keep = [m for m in d.mistakes if not m.startswith("generic-") or m in problem.generic]
    return Report("", "", keep, d.checked, {m: r for m, r in d.relations if m in keep})


_RAISED = re.compile(r"^(?:RuntimeError: )?")
_BUILD_FAILED = re.compile(r"build failed \(([\w.+-]+), exit -?\d+\):")
_LIMIT = re.compile(r"(the build|the program) (timed out after|printed more than) [0-9.]+ (s|bytes)")
_NO_RESULT = re.compile(r"the program printed no result")


def program_error(error: str, source_name: str, *, builds: bool = True) -> str:
    r"""A failed run of the student's program in words a hidden test may show: the grader's own
    facts (the build failed, how many compiler errors and the line of the first in
    ``source_name``, which depend on the source only, never on the hidden inputs; a time or output
    limit; no result), never a compiler's or a program's text, nor an exit status, which the
    student's code controls. Only the driver's own messages are read, at the start of the text
    (what follows is the student's); ``builds`` false (an interpreter run in the driver's process)
    reads no build report at all.

    >>> program_error("RuntimeError: build failed (g++, exit 1):\n"
    ...               "cv_model.cpp:9:5: error: expected ';'\ncv_model.cpp:12:1: error: x", "cv_model.cpp")
    'the build failed (g++): 2 compiler errors, the first at line 9 of cv_model.cpp'
    >>> program_error("RuntimeError: the program printed no result (exit 55): 0.55", "a.cpp")
    'the program printed no result'
    >>> program_error("Leak: 0.55", "a.cpp")
    'the program failed (your code raised an exception)'
    """
    text = str(error or "").strip()
    body = text[_RAISED.match(text).end():]
    m = _BUILD_FAILED.match(body) if builds else None
    if m:
        log = body[m.end():]
        errors = [ln for ln in log.splitlines() if re.search(r"\berror\b", ln)]
        first = re.search(rf"^{re.escape(source_name)}:(\d+)(?::\d+)?:\s*(?:fatal )?error", log, re.M)
        out = f"the build failed ({m.group(1)})"
        if errors:
            out += f": {len(errors)} compiler error{'s' if len(errors) != 1 else ''}"
        if first:
            out += f", the first at line {int(first.group(1))} of {source_name}"
        return out
    m = _LIMIT.match(body)
    if m:
        return m.group(0)
    if _NO_RESULT.match(body):
        return "the program printed no result"
    return f"the program failed ({safe_error(text)})"


def _score_cases(
    problem: Problem, cases: list[dict], expected: list[dict], outcome: Outcome, show: bool,
    *, catalogue: Catalogue, source_name: str = "", builds: bool = True,
) -> tuple[float, Report]:
    """The fraction of the points and the message of one call: the mean over cases of the share of
    right outputs. The message (a :class:`~..engine.feedback.Report`) names the failing cases: in
    its public text with what the program said, in its hidden-safe text (``show`` false: a hidden
    test) in the grader's words only (:func:`program_error`; each reason once, without cases,
    entries or errors, which the program chooses); it carries the mistakes recognised (their lines
    come from ``catalogue``)."""
    if not outcome.ok:
        err = outcome.error or "the program failed"
        return 0.0, Report(err, program_error(err, source_name, builds=builds))
    value = outcome.value if isinstance(outcome.value, dict) else {}
    fractions, notes, safe_notes, diagnoses = [], [], [], []
    for case, exp in zip(cases, expected):
        res = value.get(case["id"])
        if not isinstance(res, dict) or not res.get("ok") or not isinstance(res.get("value"), dict):
            err = res.get("error") if isinstance(res, dict) else None
            fractions.append(0.0)
            notes.append(f"case {case['id']}: {err or 'no result'}")
            safe_notes.append("the program reported an error for a case" if err else "a case got no result")
            continue
        outputs = res["value"]
        good = 0
        for name, want in exp.items():
            want = np.asarray(want, dtype=float)
            got = as_float_array(outputs.get(name), want.shape)
            if got is None:
                shape = as_float_array(outputs.get(name))
                note = f"case {case['id']}: {name} " + (
                    "missing or not numbers" if shape is None
                    else f"has shape {shape.shape}, expected {want.shape}"
                )
                notes.append(note)
                safe_notes.append(f"{name}: " + ("missing or not numbers" if shape is None
                                                 else f"wrong shape (expected {want.shape})"))
                continue
            if _matches(got, want, problem.rtol, problem.atol):
                good += 1
                continue
            worst = float(np.max(np.abs(got - want)))
            notes.append(f"case {case['id']}: {name} differs (largest error {worst:.3g})")
            safe_notes.append(f"{name}: wrong values (beyond the relative tolerance rtol={problem.rtol:g})")
            diagnoses.append(_diagnosis(problem, case, name, got, want))
        fractions.append(good / max(1, len(exp)))
    score = float(np.mean(fractions)) if fractions else 0.0
    n_ok = sum(f >= 1.0 for f in fractions)
    if score >= 1.0:
        done = f"all {len(cases)} cases correct"
        return 1.0, Report(done, done)
    # every wrong output agrees on a catalogued mistake where it shows; a generic one needs two
    mistakes = [m for m in consistent_mistakes(diagnoses) if m in catalogue]
    head = f"{n_ok}/{len(cases)} cases correct"
    public = [head] + (notes[:6] + (["..."] if len(notes) > 6 else []) if show else [])
    # which cases failed and how far off they are is the program's choice (it saw the hidden inputs):
    # each reason once, in a fixed order
    safe = [head, *sorted(set(safe_notes))]
    return score, Report("\n".join(public), "\n".join(safe), mistakes)


def _test(
    problem: Problem, hidden: bool, catalogue: Catalogue, timeout: float, source_name: str = "",
    builds: bool = True,
) -> GradedTest:
    def build(rng: np.random.Generator):
        chosen = problem.hidden_cases(rng) if hidden else problem.public_cases()
        doc = problem.document(chosen, expected=False)
        cases = doc["cases"]
        expected = [
            {k: np.asarray(v, float) for k, v in problem.reference(c["input"]).items()} for c in cases
        ]

        def scorer(outcomes: Sequence[Outcome]) -> tuple[float, str]:
            if len(outcomes) != 1:
                return 0.0, "no result from the sandbox"
            return _score_cases(problem, cases, expected, outcomes[0], show=not hidden, catalogue=catalogue,
                                source_name=source_name, builds=builds)

        return [Call("run_cases", (doc,))], scorer

    build.__wrapped__ = problem.reference  # exercises_hash hashes the module defining the problem
    name = f"{'hidden' if hidden else 'public'}: {problem.title}"
    return GradedTest(
        name, f"test_{problem.name}", HIDDEN_POINTS if hidden else PUBLIC_POINTS, hidden, build, timeout
    )


def _exercise(language: str, problem: Problem, owner: str, catalogue: Catalogue) -> LanguageExercise:
    tc = TOOLCHAINS[language]
    timeout = tc.compile_seconds + tc.run_seconds + 30.0  # the wall-clock limit of one test's batch
    return LanguageExercise(
        id=f"{language}_{problem.name}",
        title=f"{problem.title} ({tc.title})",
        notebook=f"{language}/{problem.name}/{tc.source_name(problem.name)}",
        answer_cells=(tc.source_name(problem.name),),
        blocked=tuple(b for b in BLOCKED if b != "scipy.optimize") if language == "mathics" else BLOCKED,
        allowed=MATHICS_ALLOWED if language == "mathics" else (),
        packages=("flowtrack",),
        # an interpreter run in the driver's own process (Mathics3) could raise any text: no build report
        tests=(_test(problem, False, catalogue, timeout, tc.source_name(problem.name), language != "mathics"),
               _test(problem, True, catalogue, timeout, tc.source_name(problem.name), language != "mathics")),
        mistakes=tuple(catalogue[mid] for mid, _ in problem.mistakes),
        catalogue=catalogue,
        language=language,
        problem=problem.name,
        exercise=owner,
    )


def _declared(course: ExerciseSet) -> dict[str, tuple[str, tuple[Mistake, ...]]]:
    """``{problem: (exercise id, its language-only mistakes)}`` of the course's grading modules."""
    out: dict[str, tuple[str, tuple[Mistake, ...]]] = {}
    for ex in course:
        module = course.module(ex.id)
        name = module.__dict__.get(LANGUAGE_PROBLEM)
        own = tuple(m.of(ex.id) for m in module.__dict__.get(LANGUAGE_MISTAKES, ()))
        if name is None:
            if own:
                raise ValueError(f"{ex.id}: {LANGUAGE_MISTAKES} without a {LANGUAGE_PROBLEM}")
            continue
        if name not in GRADED_PROBLEMS:
            known = ", ".join(GRADED_PROBLEMS)
            raise ValueError(
                f"{ex.id}: {LANGUAGE_PROBLEM} = {name!r} is no problem of other languages ({known})"
            )
        if name in out:
            raise ValueError(f"{ex.id}: the problem {name!r} is already {out[name][0]}'s")
        out[name] = (ex.id, own)
    return out


def language_catalogue(course: ExerciseSet) -> Catalogue:
    """The mistakes the answers in other languages of ``course`` may name: the course's catalogue and
    the language-only mistakes its grading modules define (``LANGUAGE_MISTAKES``).

    Raises
    ------
    ValueError
        A declared problem names a mistake the course defines nowhere (its line would have no
        message), or a grading module's declaration is wrong.
    """
    declared = _declared(course)
    catalogue = Catalogue([*course.catalogue.values(), *(m for _, own in declared.values() for m in own)])
    for name, (owner, _own) in declared.items():
        missing = [mid for mid, _ in GRADED_PROBLEMS[name].mistakes if mid not in catalogue]
        if missing:
            raise ValueError(
                f"{owner}: the answers in other languages to {name!r} recognise {', '.join(missing)}, "
                f"which no exercise of the course defines (add them to its {LANGUAGE_MISTAKES})"
            )
    return catalogue


def language_exercises(course: ExerciseSet) -> tuple[LanguageExercise, ...]:
    """The course's language exercises: one per graded language and problem a grading module
    declares (``LANGUAGE_PROBLEM``), in the languages the problem is set in, ordered by language
    (:data:`~flowtrack_course.polyglot.toolchains.GRADED_LANGUAGES`) then problem (the
    ``grades.csv`` columns); their mistakes' messages are :func:`language_catalogue`'s.

    Examples
    --------
    >>> from pathlib import Path
    >>> from flowtrack_course.grading.engine.discovery import discover
    >>> empty = Path(__import__("tempfile").mkdtemp()); (empty / "exercises").mkdir()
    >>> language_exercises(discover(empty))
    ()
    """
    declared = _declared(course)
    if not declared:
        return ()
    catalogue = language_catalogue(course)
    return tuple(
        _exercise(lang, p, declared[p.name][0], catalogue)
        for lang in GRADED_LANGUAGES
        for p in GRADED_PROBLEMS.values()
        if p.name in declared and (p.languages is None or lang in p.languages)
    )


# -- files of the bundle ---------------------------------------------------------------------------
_BLOCK = re.compile(
    r"^([ \t]*)(?://|%|\(\*)\s*BEGIN SOLUTION.*?^[ \t]*(?://|%|\(\*)\s*END SOLUTION[^\n]*\n", re.M | re.S
)


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
    todo = TOOLCHAINS[language].todo
    out = _BLOCK.sub(lambda m: f"{m.group(1)}{todo}\n", text)
    if "BEGIN SOLUTION" in out or "END SOLUTION" in out:
        raise ValueError("text: unbalanced BEGIN SOLUTION / END SOLUTION markers")
    return out


def public_vectors(problem: Problem) -> dict:
    """The public cases of ``problem`` in the shared vectors format, expected values included."""
    return problem.document(problem.public_cases())


def materialise(ex: LanguageExercise, source_dir: Path, dest: Path, *, stub: bool) -> list[Path]:
    """Write the exercise's folder into ``dest``: the student file (its stub with ``stub=True``), the
    grader's support files, the public tests' vectors ``public.json`` and the local build files."""
    tc = ex.toolchain
    dest.mkdir(parents=True, exist_ok=True)
    name = tc.source_name(ex.problem)
    text = (source_dir / name).read_text(encoding="utf-8")
    files = {name: strip_solutions(text, ex.language) if stub else text}
    files.update(tc.bundle_files(ex.problem))
    files["public.json"] = dumps(public_vectors(GRADED_PROBLEMS[ex.problem]))
    for rel in files:
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
    written = []
    for rel, body in files.items():
        p = dest / rel
        p.write_text(body, encoding="utf-8")
        written.append(p)
    return written
