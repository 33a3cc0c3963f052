"""The Mathematica port, run on Mathics3, on the shared vectors: one test per problem.

Every case of every problem is run, the 1000-step ``kalman_cv2d`` case too (Mathics3 is slow,
about 70 ms per filter step, so that case alone takes over a minute). The port runs once per
module; the harness-can-fail test reuses its answers (same inputs) and redoes only the comparison,
which is what it tests. Also: the ``steady_state_scalar`` vector against scipy's DARE solver and
the Riccati recursion iterated to convergence.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from flowtrack_course.polyglot import mathics as lang_mathics
from flowtrack_course.polyglot.problems.kalman import STEADY_STATE_SCALAR, scalar_riccati_P
from flowtrack_course.ports.vectors import VECTORS_DIR
from ports_helpers import (
    BUILD_DIR,
    assert_every_case_passes,
    failing_cases,
    perturbed_vectors,
    run_port,
    vector_case_ids,
)

pytestmark = pytest.mark.xdist_group("ports-mathics")

PROBLEMS = list(lang_mathics.PROBLEMS)


@pytest.fixture(scope="module")
def mathics_results():
    return run_port(lang_mathics.run, VECTORS_DIR, BUILD_DIR)


@pytest.mark.parametrize("problem", PROBLEMS)
def test_port_passes_every_vector_case(mathics_results, problem):
    assert_every_case_passes(mathics_results, problem)


def test_the_long_kalman_case_is_run(mathics_results):
    # Mathics3 used to abort a fold of this length ($IterationLimit counted over the whole evaluation)
    doc = json.loads((VECTORS_DIR / "kalman_cv2d.json").read_text())
    longest = max(doc["cases"], key=lambda c: len(c["input"]["measurements"]))
    assert len(longest["input"]["measurements"]) >= 1000
    got = [r for r in mathics_results if r.problem == "kalman_cv2d" and r.case_id == longest["id"]]
    assert len(got) == 1 and got[0].passed, got


def test_harness_reports_exactly_the_perturbed_cases(mathics_results, tmp_path):
    folder, spoilt = perturbed_vectors(tmp_path, PROBLEMS)
    results = lang_mathics.run(folder, BUILD_DIR, reuse=True)
    assert failing_cases(results, PROBLEMS) == spoilt
    assert len(results) == sum(len(vector_case_ids(p)) for p in PROBLEMS)


def test_steady_state_vector_matches_scipy_dare_and_iteration():
    for case in STEADY_STATE_SCALAR.vectors()["cases"]:
        inp, exp = case["input"], case["expected"]
        f, h, q, r = inp["f"], inp["h"], inp["q"], inp["r"]
        P_dare = solve_discrete_are(np.array([[f]]), np.array([[h]]), np.array([[q]]), np.array([[r]]))[0, 0]
        assert exp["P"] == pytest.approx(P_dare, rel=1e-9), case["id"]
        P = 1.0
        for _ in range(100000):  # the Riccati recursion converges to the same fixed point
            P_next = f * f * P - (f * P * h) ** 2 / (h * h * P + r) + q
            if abs(P_next - P) <= 1e-15 * P_next:
                break
            P = P_next
        assert exp["P"] == pytest.approx(P_next, rel=1e-9), case["id"]
        assert exp["P_post"] == pytest.approx(P - P * P * h * h / (h * h * P + r), rel=1e-9)
    with pytest.raises(ValueError, match="h"):
        scalar_riccati_P(1.0, 0.0, 1.0, 1.0)
    with pytest.raises(TypeError, match="q"):
        scalar_riccati_P(1.0, 1.0, "1", 1.0)


def test_wl_round_trip():
    x = [[1e-300, -2.5e17, 0.1 + 0.2], [3.0, -0.0, 7]]
    text = lang_mathics.to_wl(x)
    assert "*^" in text and "e" not in text.replace("*^", "")
    assert lang_mathics.parse_input_form(text) == [[1e-300, -2.5e17, 0.30000000000000004], [3.0, -0.0, 7.0]]
    with pytest.raises(TypeError, match="value"):
        lang_mathics.to_wl(["a"])
