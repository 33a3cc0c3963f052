"""Attacks on hidden-test feedback: student code sees the hidden inputs and tries to carry them out
through what a hidden test's feedback shows, to replay them as a lookup table.

Graded for real (``run_exercise`` under bubblewrap) on ex05, whose hidden inputs are time steps and
noise levels drawn from the student's keyed seed. Oracles: the hidden inputs themselves (rebuilt
here from the seed, as the grader draws them), searched for in everything a student sees of a
hidden test; the same attack graded for two students (different hidden inputs), whose hidden
feedback must be identical (what it shows is then a function of the code alone, whatever channel
the code tries: a message, an exception class's name, an exit status, a signal, which entries are
wrong); and the empty answer's score, which a lookup table made of what leaked may not beat.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from flowtrack_course.grading.engine.jobs import GradingOptions
from flowtrack_course.grading.engine.results import feedback_markdown, results_json
from flowtrack_course.grading.engine.run import run_exercise
from flowtrack_course.grading.engine.seeds import student_seed
from grading_helpers import get_exercise
from grading_sandbox import Limits, bwrap_status

pytestmark = pytest.mark.xdist_group("sandbox")

EX = get_exercise("ex05_cv_model")
SECRET = b"k" * 32
OPTIONS = GradingOptions(secret=SECRET, limits=Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30))


@pytest.fixture(autouse=True)
def _bwrap(monkeypatch):
    ok, why = bwrap_status()
    assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")


def _notebook(tmp_path: Path, sources: dict[str, str]) -> Path:
    cells = [{"cell_type": "code", "execution_count": None, "outputs": [], "id": f"c{i}",
              "metadata": {"nbgrader": {"grade_id": gid, "solution": True}}, "source": sources[gid]}
             for i, gid in enumerate(EX.answer_cells)]
    path = tmp_path / EX.notebook
    path.write_text(json.dumps({"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": cells}))
    return path


def _grade(tmp_path: Path, student: str, transition: str, noise: str):
    """``(result, the texts a student sees of the hidden tests, of the public ones)``."""
    folder = tmp_path / student
    folder.mkdir(exist_ok=True)
    nb = _notebook(folder, {"cv_transition": transition, "cv_process_noise": noise})
    result = run_exercise(EX, nb, student, options=OPTIONS)
    data = results_json(student, [result])
    hidden = [t["output"] for t in data["tests"] if t["extra_data"]["hidden"]]
    public = [t["output"] for t in data["tests"] if not t["extra_data"]["hidden"]]
    page = feedback_markdown(student, result)
    head = "## Hidden tests that failed"
    hidden.append(page.split(head)[-1] if head in page else "")
    return result, hidden, public


def _hidden_inputs(student: str) -> list[tuple[float, ...]]:
    """The arguments of every hidden call of ex05 for ``student``, drawn as the grader draws them."""
    out = []
    for t in EX.tests:
        if t.hidden:
            calls, _ = t.build(np.random.default_rng(student_seed(student, EX.id, t.name, SECRET)))
            out += [tuple(float(a) for a in c.args) for c in calls]
    return out


def _leaks(texts: list[str], inputs: list[tuple[float, ...]]) -> list[str]:
    """The hidden inputs found in ``texts`` (as Python prints them, or to 4 significant digits)."""
    found = []
    for args in inputs:
        for x in args:
            for form in (repr(x), f"{x:.4g}", f"{x:.4f}"):
                if any(form in t for t in texts):
                    found.append(form)
    return found


LEAK_MESSAGE = (
    "def cv_transition(dt):\n    raise ValueError(f'\\nLEAK {dt!r}')\n",
    "def cv_process_noise(dt, q):\n    raise ValueError(f'\\nLEAK {dt!r} {q!r}')\n",
)
LEAK_CLASS = (
    "class Leak(Exception):\n    pass\n\ndef cv_transition(dt):\n    raise Leak('LEAK ' + repr(dt))\n",
    "class Leak(Exception):\n    pass\n\n"
    "def cv_process_noise(dt, q):\n    raise Leak(f'LEAK {dt!r} {q!r}')\n",
)
STUB = ("def cv_transition(dt):\n    raise NotImplementedError()\n",
        "def cv_process_noise(dt, q):\n    raise NotImplementedError()\n")


def _replay_table(texts: list[str]) -> tuple[str, str]:
    """The attacker's resubmission: the answers to every hidden input that leaked, computed outside
    the sandbox with the course's own library, as a lookup table."""
    from flowtrack.kalman import constant_velocity_model, white_noise_acceleration_Q

    table_f, table_q = {}, {}
    for text in texts:
        for dt, q in re.findall(r"LEAK (\S+?)(?: (\S+?))?(?:\\n|'|\"|\s|$)", text):
            try:
                d = float(dt)
            except ValueError:
                continue
            table_f[repr(d)] = constant_velocity_model(d, 1.0, 1.0, dim=2)[0].tolist()
            if q:
                try:
                    table_q[f"{d!r} {float(q)!r}"] = white_noise_acceleration_Q(d, float(q), dim=2).tolist()
                except ValueError:
                    continue
    transition = f"TABLE = {table_f!r}\n\ndef cv_transition(dt):\n    return TABLE[repr(float(dt))]\n"
    noise = (f"TABLE = {table_q!r}\n\ndef cv_process_noise(dt, q):\n"
             "    return TABLE[f'{float(dt)!r} {float(q)!r}']\n")
    return transition, noise


@pytest.mark.parametrize("attack", [LEAK_MESSAGE, LEAK_CLASS], ids=["message", "exception-class"])
def test_hidden_inputs_do_not_leak_through_exception_messages(attack, tmp_path):
    student = "mallory"
    _, hidden, public = _grade(tmp_path, student, *attack)
    assert _leaks(hidden, _hidden_inputs(student)) == [], hidden
    # the student's own message still reaches the public feedback (the public inputs are no secret)
    assert any("LEAK 0.5" in t for t in public), public
    assert any("raised" in t for t in hidden), hidden  # and the hidden tests say what happened


@pytest.mark.parametrize("attack", [LEAK_MESSAGE, LEAK_CLASS], ids=["message", "exception-class"])
def test_a_lookup_table_replayed_from_hidden_feedback_scores_as_the_empty_answer(attack, tmp_path):
    # hidden inputs depend only on the key and the student: what leaked once is what the next
    # submission is asked, so a table of the reference's answers to it would score
    student = "mallory"
    _, hidden, _ = _grade(tmp_path, student, *attack)
    replayed, _, _ = _grade(tmp_path, student, *_replay_table(hidden))
    empty, _, _ = _grade(tmp_path, student, *STUB)
    assert replayed.score == empty.score, (replayed.score, empty.score, hidden)


# Residual channels: what the code chooses besides a message. Each attack encodes the hidden time
# step in one of them; graded for two students, the hidden feedback must not differ.
CHANNELS = {
    "exit-status": ("import os\ndef cv_transition(dt):\n    os._exit(int(dt * 100) % 120 + 1)\n",
                    "import os\ndef cv_process_noise(dt, q):\n    os._exit(int(q * 10) % 120 + 1)\n"),
    "signal": ("import os, signal\nSIGS = [signal.SIGSEGV, signal.SIGABRT, signal.SIGFPE, signal.SIGBUS,"
               " signal.SIGILL, signal.SIGTERM, signal.SIGUSR1, signal.SIGUSR2]\n"
               "def cv_transition(dt):\n    os.kill(os.getpid(), SIGS[int(dt * 10) % 8])\n",
               "import os, signal\nSIGS = [signal.SIGSEGV, signal.SIGABRT, signal.SIGFPE, signal.SIGBUS,"
               " signal.SIGILL, signal.SIGTERM, signal.SIGUSR1, signal.SIGUSR2]\n"
               "def cv_process_noise(dt, q):\n    os.kill(os.getpid(), SIGS[int(q) % 8])\n"),
    "wrong-entries": (
        # the right F, with as many wrong entries as tenths in dt, starting at an entry chosen by it
        "import numpy as np\ndef cv_transition(dt):\n    F = np.eye(4)\n    F[0, 2] = F[1, 3] = dt\n"
        "    k = int(dt * 10) % 16\n    F.flat[k:k + k % 7 + 1] += 1000.0 * dt\n    return F\n",
        "import numpy as np\ndef cv_process_noise(dt, q):\n    Q = np.zeros((4, 4))\n"
        "    Q.flat[int(q) % 16] = q * 1e3\n    return Q\n"),
    "shape": ("import numpy as np\ndef cv_transition(dt):\n    return np.zeros((int(dt * 100) + 1, 1))\n",
              "import numpy as np\n"
              "def cv_process_noise(dt, q):\n    return np.zeros((int(q * 10) + 1, 2))\n"),
    # (a type of the fixed list, ValueError or TypeError, is a choice the feedback shows by design: a
    # class the code names after the input is not)
    "exception-class-name": (
        "def cv_transition(dt):\n    raise type('L%d' % int(dt * 1e6), (Exception,), {})('x')\n",
        "def cv_process_noise(dt, q):\n    raise type('Q%d' % int(q * 1e6), (ValueError,), {})(q)\n"),
}


@pytest.mark.parametrize("channel", sorted(CHANNELS))
def test_hidden_feedback_is_the_same_whatever_the_hidden_inputs(channel, tmp_path):
    students = ("alice", "bob")
    assert _hidden_inputs(students[0]) != _hidden_inputs(students[1])
    seen = []
    for s in students:
        result, hidden, _ = _grade(tmp_path, s, *CHANNELS[channel])
        assert result.score < result.max_score
        seen.append(hidden)
    assert seen[0] == seen[1], seen
    assert _leaks(seen[0], _hidden_inputs(students[0])) == []
