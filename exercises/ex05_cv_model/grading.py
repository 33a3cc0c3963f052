"""Ex05: constant-velocity model: the trusted tests of the notebook next to this file."""

from __future__ import annotations

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Outcome,
    Report,
    Variant,
    array_check,
    as_float_array,
    compare,
    graded_test,
    safe_error,
)


def _ex05_F(dt):
    from flowtrack.kalman import constant_velocity_model

    return constant_velocity_model(dt, 1.0, 1.0, dim=2)[0]


def _ex05_Q(dt, q):
    from flowtrack.kalman import white_noise_acceleration_Q

    return white_noise_acceleration_Q(dt, q, dim=2)


@graded_test("F: dt = 0.5", "test_F", 1.0, hidden=False)
def _ex05_F_public(rng):
    return [("cv_transition", (0.5,), {}, array_check(_ex05_F(0.5)))]


@graded_test("F: random dt", "test_F", 2.0, hidden=True)
def _ex05_F_hidden(rng):
    return [
        ("cv_transition", (dt,), {}, array_check(_ex05_F(dt))) for dt in rng.uniform(0.01, 2.0, 3).tolist()
    ]


def _ex05_Q_variants(dt: float, q: float) -> list[Variant]:
    g = np.array([dt**2 / 2.0, dt])
    q1d = np.outer(g, g)
    cont = np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    return [
        Variant("q-block-diagonal", q * np.kron(np.eye(2), q1d)),
        Variant("q-continuous-white-noise", q * np.kron(cont, np.eye(2))),
        Variant("q-missing-q", np.kron(q1d, np.eye(2))),
    ]


def _ex05_Q_properties(dt: float, q: float) -> Check:
    """The public test only checks what the visible asserts check: shape, symmetry, Q[0,0], Q[2,0]."""
    expected = _ex05_Q(dt, q)
    variants = _ex05_Q_variants(dt, q)

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, Report(outcome.error or "the call failed", safe_error(outcome.error))
        got = as_float_array(outcome.value, (4, 4))
        if got is None:
            return 0.0, Report("expected an array of shape (4, 4)")
        full = compare(outcome, expected, rtol=1e-9, atol=1e-12, variants=variants)
        if not np.allclose(got, got.T, rtol=1e-9, atol=1e-12):
            return 0.0, full.report().retext("Q is not symmetric")
        for i, j in ((0, 0), (2, 0)):
            if not np.isclose(got[i, j], expected[i, j], rtol=1e-9, atol=1e-12):
                what = {(0, 0): "var(px)", (2, 0): "cov(vx, px)"}[(i, j)]
                return 0.0, full.report().retext(
                    f"Q[{i}, {j}] = {what} is wrong: expected {expected[i, j]:.6g}, got {got[i, j]:.6g}"
                )
        # what the visible asserts check is right; the mistakes still show when the rest is wrong
        return 1.0, full.report().retext("ok")

    return check


@graded_test("Q: shape, symmetry, var(px) and cov(vx, px) for dt = 0.5, q = 2", "test_Q", 2.0, hidden=False)
def _ex05_Q_public(rng):
    return [("cv_process_noise", (0.5, 2.0), {}, _ex05_Q_properties(0.5, 2.0))]


@graded_test("Q: the full matrix for random dt and q", "test_Q", 5.0, hidden=True)
def _ex05_Q_hidden(rng):
    # Q1d kron I2 and the syllabus' blkdiag(Q1d, Q1d) differ for every dt, q > 0
    out = []
    for dt, q in zip(rng.uniform(0.01, 2.0, 3).tolist(), rng.uniform(0.1, 10.0, 3).tolist()):
        check = array_check(_ex05_Q(dt, q), variants=_ex05_Q_variants(dt, q))
        out.append(("cv_process_noise", (dt, q), {}, check))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L4 = "lesson 04_bayes_and_kalman"

MISTAKES = (
    Mistake(
        "q-block-diagonal",
        "Q is block-diagonal blkdiag(Q1d, Q1d), which fits the state order [px, vx, py, vy]; for "
        "[px, py, vx, vy] each Q1d entry couples a position with its own velocity: Q = Q1d kron I2 "
        f"(the syllabus listings' bug); see {_L4} §3 (deriving Q, the ordering bug)",
    ),
    Mistake(
        "q-continuous-white-noise",
        "this is the continuous white-noise model (dt^3/3, dt^2/2, dt); the exercise asks for the "
        "discrete white-noise acceleration Q = q G G^T with G = [dt^2/2, dt] (dt^4/4, dt^3/2, dt^2); "
        f"see {_L4} §3 (deriving Q)",
    ),
    Mistake(
        "q-missing-q",
        f"Q is not scaled by the acceleration variance q (Q = q G G^T); see {_L4} §3 (deriving Q)",
    ),
)


EXERCISE = Exercise(
    id="ex05_cv_model",
    title="The constant-velocity model: F and the white-noise-acceleration Q",
    notebook="ex05_cv_model.ipynb",
    answer_cells=("cv_transition", "cv_process_noise"),
    blocked=("flowtrack.kalman", "flowtrack.symbolic", "flowtrack.tracking"),
    allowed=('numpy',),
    tests=(_ex05_F_public, _ex05_F_hidden, _ex05_Q_public, _ex05_Q_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)


# The same exercise answered in C++, Java, Octave and Mathematica (the problem of other languages,
# flowtrack_course.polyglot.problems): their mistakes are this exercise's.
LANGUAGE_PROBLEM = "cv_model"
