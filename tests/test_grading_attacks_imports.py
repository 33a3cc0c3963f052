"""Library calls: an exercise's allowlist of imports decides what a student may call.

The red team solved exercises with a library that does the work (networkx's matching for the
Hungarian algorithm, filterpy's Kalman filter, flowtrack's own Mahalanobis distance, scipy's sparse
solver). Under the allowlist those packages are not in the sandbox at all (bubblewrap) or refused by
the child (both modes): the import fails with a message naming what the exercise allows, and the
submission scores 0 - what an empty answer scores.
"""

import json
import re
from pathlib import Path

import pytest

from flowtrack_course.grading.engine.jobs import GradingOptions
from flowtrack_course.grading.engine.run import run_exercise
from grading_helpers import EXERCISES, SANDBOX_MODES, get_exercise, source_notebook, use_sandbox_mode
from grading_sandbox import Call, Limits, Sandbox

pytestmark = pytest.mark.xdist_group("sandbox")

LIMITS = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30, processes=16)


@pytest.fixture(params=SANDBOX_MODES)
def mode(request, monkeypatch, tmp_path_factory):
    return use_sandbox_mode(request.param, monkeypatch, tmp_path_factory)


def _may_import(notebook: Path) -> tuple[str, ...]:
    """The names of the notebook's "**You may import:** a, b (remark). **Not:** ..." line."""
    cells = json.loads(notebook.read_text())["cells"]
    text = "".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
    m = re.search(r"\*\*You may import:\*\*(.*?)(?:\*\*Not:\*\*|\n\n|$)", text, re.S)
    assert m, f"{notebook.name} has no 'You may import' line"
    listed = re.sub(r"\([^)]*\)", "", m.group(1)).strip().rstrip(".")
    return tuple(n.strip() for n in listed.split(",") if n.strip())


@pytest.mark.parametrize("ex", EXERCISES, ids=lambda e: e.id)
def test_notebook_import_line_is_the_allowlist(ex):
    assert ex.allowed and ex.allowed[0] == "numpy"
    assert _may_import(source_notebook(ex)) == ex.allowed


# exercise, the cheat's import, its answer cells (defining every answer function)
CHEATS = [
    ("ex08_hungarian", "networkx",
     "import networkx as nx\nimport numpy as np\n"
     "def hungarian(C):\n    G = nx.Graph()\n    return np.zeros((0, 2))\n"),
    ("ex05_cv_model", "filterpy",
     "from filterpy.common import Q_discrete_white_noise\nimport numpy as np\n"
     "def cv_transition(dt):\n    return np.eye(4)\n"
     "def cv_process_noise(dt, q):\n    return Q_discrete_white_noise(2, dt, q, block_size=2)\n"),
    ("ex06_kalman_predict_update", "filterpy",
     "from filterpy.kalman import predict, update\n"
     "def kf_predict(x, P, F, Q):\n    return predict(x, P, F, Q)\n"
     "def kf_update(x, P, z, H, R):\n    return update(x, P, z, R, H)[:2]\n"),
    ("ex07_mahalanobis_gating", "flowtrack",
     "from flowtrack.kalman import KalmanFilter\nimport numpy as np\n"
     "def mahalanobis_cost(z_pred, S, Z):\n    return KalmanFilter.mahalanobis\n"
     "def gated_cost(z_pred, S, Z, prob):\n    return KalmanFilter.mahalanobis\n"),
    ("ex03_gauss_seidel", "scipy",
     "from scipy.sparse.linalg import spsolve\nimport numpy as np\n"
     "def red_black_sweep(v, rhs, c, lam):\n    return spsolve\n"
     "def solve_gauss_seidel(a, b, dt, lam):\n    return spsolve\n"),
]


def _notebook(tmp_path, ex, source):
    cells = [{"cell_type": "code", "execution_count": None, "outputs": [], "id": f"c{i}",
              "metadata": {"nbgrader": {"grade_id": gid, "solution": True}},
              "source": source if i == 0 else "pass\n"} for i, gid in enumerate(ex.answer_cells)]
    nb = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": cells}
    path = tmp_path / ex.notebook
    path.write_text(json.dumps(nb))
    return path


@pytest.mark.parametrize("ex_id, module, source", CHEATS, ids=[c[0] for c in CHEATS])
def test_library_calls_fail_on_import(mode, ex_id, module, source, tmp_path):
    ex = get_exercise(ex_id)
    with Sandbox([("a", source)], blocked=ex.blocked, allowed=ex.allowed, packages=ex.packages,
                 limits=LIMITS) as sb:
        (out,) = sb.run([Call(ex.answer_cells[0])], timeout=20)  # the cell failed: not defined
        assert not out.ok
        err = sb.cell_errors["a"]
    assert f"{module} is not available in this exercise" in err, err
    assert "you may import: " + ", ".join(ex.allowed) in err, err
    notebook = _notebook(tmp_path, ex, source)
    result = run_exercise(ex, notebook, "mallory", options=GradingOptions(limits=LIMITS))
    assert result.score == 0.0
    assert any("not available in this exercise" in p for p in result.problems), result.problems


def test_allowed_packages_still_work(mode):
    # ex06 allows scipy.linalg: scipy (and numpy, which it needs) are in the sandbox
    src = ("import scipy.linalg\nimport numpy as np\n"
           "def f():\n    return scipy.linalg.inv(2 * np.eye(2)).tolist()\n")
    allowed = get_exercise("ex06_kalman_predict_update").allowed
    with Sandbox([("a", src)], allowed=allowed, limits=LIMITS) as sb:
        (out,) = sb.run([Call("f")], timeout=20)
    assert out.ok and out.value == [[0.5, 0.0], [0.0, 0.5]], (out, sb.cell_errors)
