"""Ex06: Kalman predict and update: the trusted tests of the notebook next to this file."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Variant,
    array_check,
    graded_test,
    tuple_check,
)


def _ex06_model(rng, n: int, m: int):
    A = rng.normal(size=(n, n))
    P = A @ A.T + 0.1 * np.eye(n)
    B = rng.normal(size=(n, n))
    Q = 0.1 * (B @ B.T)
    F = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    H = rng.normal(size=(m, n))
    C = rng.normal(size=(m, m))
    R = C @ C.T + 0.2 * np.eye(m)
    x = rng.normal(size=n)
    z = rng.normal(size=m)
    return x, P, F, Q, z, H, R


def _ex06_predict(x, P, F, Q):
    from flowtrack.kalman import KalmanFilter

    m = 1
    kf = KalmanFilter(F, np.zeros((m, len(x))), Q, np.eye(m), x, P)
    kf.predict()
    return kf.x, kf.P


def _ex06_update(x, P, z, H, R):
    from flowtrack.kalman import KalmanFilter

    n = len(x)
    kf = KalmanFilter(np.eye(n), H, np.zeros((n, n)), R, x, P)
    kf.update(z)
    return kf.x, kf.P


def _state_check(
    expected: tuple[np.ndarray, np.ndarray],
    x_variants: Sequence[Variant] = (),
    P_variants: Sequence[Variant] = (),
) -> Check:
    return tuple_check(
        [array_check(expected[0], rtol=1e-6, atol=1e-9, variants=x_variants),
         array_check(expected[1], rtol=1e-6, atol=1e-9, variants=P_variants)],
        ("x", "P"),
    )


def _predict_check(x, P, F, Q) -> Check:
    return _state_check(_ex06_predict(x, P, F, Q), P_variants=[Variant("predict-without-Q", F @ P @ F.T)])


def _update_check(x, P, z, H, R) -> Check:
    """The update, recognising S = H P H^T (no R) in x and in either form of P."""
    S0 = H @ P @ H.T
    K0 = np.linalg.solve(S0, H @ P).T
    x0 = x + K0 @ (z - H @ x)
    IKH = np.eye(len(x)) - K0 @ H
    P_short = IKH @ P
    P_joseph = IKH @ P @ IKH.T + K0 @ R @ K0.T
    return _state_check(
        _ex06_update(x, P, z, H, R),
        x_variants=[Variant("innovation-without-R", x0)],
        P_variants=[Variant("innovation-without-R", 0.5 * (P_short + P_short.T)),
                    Variant("innovation-without-R", P_joseph)],
    )


_EX06_F = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
_EX06_Q = 0.01 * np.eye(4)
_EX06_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_EX06_R = 0.5 * np.eye(2)
_EX06_x = np.array([0.0, 0.0, 1.0, 2.0])
_EX06_P = np.eye(4)
_EX06_z = np.array([1.5, 1.0])


@graded_test("predict: constant-velocity model", "test_predict", 1.0, hidden=False)
def _ex06_predict_public(rng):
    args = (_EX06_x, _EX06_P, _EX06_F, _EX06_Q)
    return [("kf_predict", args, {}, _predict_check(*args))]


@graded_test("predict: random models", "test_predict", 2.0, hidden=True)
def _ex06_predict_hidden(rng):
    out = []
    for n in (1, 3, 4, 6):
        x, P, F, Q, *_ = _ex06_model(rng, n, 1)
        out.append(("kf_predict", (x, P, F, Q), {}, _predict_check(x, P, F, Q)))
    return out


@graded_test("update: position measurement", "test_update", 2.0, hidden=False)
def _ex06_update_public(rng):
    args = (_EX06_x, 2.0 * _EX06_P, _EX06_z, _EX06_H, _EX06_R)
    return [("kf_update", args, {}, _update_check(*args))]


@graded_test("update: random models", "test_update", 3.0, hidden=True)
def _ex06_update_hidden(rng):
    out = []
    for n, m in ((1, 1), (4, 2), (6, 3), (3, 3)):
        x, P, _, _, z, H, R = _ex06_model(rng, n, m)
        out.append(("kf_update", (x, P, z, H, R), {}, _update_check(x, P, z, H, R)))
    return out


def velocity_nees_reference(v_meas, v_true, C, alpha):
    """eps_k = e_k^T (C_k + alpha^2 v_k v_k^T)^-1 e_k with e_k = v_meas_k - v_true_k (lesson 6 §5b)
    and their mean: shapes (K,) and ()."""
    v = np.asarray(v_meas, dtype=float)
    e = v - np.asarray(v_true, dtype=float)
    Cs = np.asarray(C, dtype=float) + alpha**2 * np.einsum("ki,kj->kij", v, v)
    eps = np.einsum("ki,ki->k", e, np.linalg.solve(Cs, e[..., None])[..., 0])
    return eps, float(eps.mean())


def _nees_check(v_meas, v_true, C, alpha):
    eps, mean = velocity_nees_reference(v_meas, v_true, C, alpha)
    e = np.asarray(v_meas) - np.asarray(v_true)
    no_shared, _ = velocity_nees_reference(v_meas, v_true, C, 0.0)
    Cs = np.asarray(C) + alpha**2 * np.einsum("ki,kj->kij", v_meas, v_meas)
    not_inverted = np.einsum("ki,kij,kj->k", e, Cs, e)
    truth_shared = np.einsum("ki,ki->k", e, np.linalg.solve(
        np.asarray(C) + alpha**2 * np.einsum("ki,kj->kij", v_true, v_true), e[..., None])[..., 0])
    variants = [Variant("nees-shared-error-left-out", no_shared),
                Variant("nees-covariance-not-inverted", not_inverted),
                Variant("nees-shared-error-along-the-truth", truth_shared)]
    mean_variants = [Variant(v.mistake, np.array(float(np.mean(v.value)))) for v in variants]
    checks = [array_check(eps, variants=variants), array_check(np.array(mean), variants=mean_variants)]
    return tuple_check(checks, ["eps", "mean"])


_EX06_VM = np.array([[0.10, 0.00, 0.00], [0.00, 0.05, 0.02], [0.03, -0.04, 0.00]])
_EX06_VT = np.array([[0.12, 0.01, 0.00], [0.00, 0.04, 0.02], [0.02, -0.04, 0.01]])
_EX06_CV = np.array([np.eye(3) * 1e-4, np.diag([1e-4, 4e-4, 1e-4]), np.eye(3) * 2e-4])


@graded_test("velocity NEES: three measurements", "test_nees", 0.5, hidden=False)
def _ex06_nees_public(rng):
    args = (_EX06_VM, _EX06_VT, _EX06_CV, 0.5)
    return [("velocity_nees", args, {}, _nees_check(*args))]


@graded_test("velocity NEES: random velocities, covariances and shared-error fractions", "test_nees", 1.5,
             hidden=True)
def _ex06_nees_hidden(rng):
    out = []
    for K in (1, 5, 20):
        v_true = rng.normal(scale=0.1, size=(K, 3))
        A = rng.normal(scale=0.01, size=(K, 3, 3))
        C = A @ np.swapaxes(A, 1, 2) + 1e-5 * np.eye(3)
        v_meas = v_true + rng.normal(scale=0.02, size=(K, 3))
        alpha = float(rng.uniform(0.2, 0.8))
        args = (v_meas, v_true, C, alpha)
        out.append(("velocity_nees", args, {}, _nees_check(*args)))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L4 = "lesson 04_bayes_and_kalman"
_L6 = "lesson 06_flow_to_tracks"
_5B = "§5b (coasting through an occlusion and a crossing, with and without flow)"

MISTAKES = (
    Mistake(
        "innovation-without-R",
        "the innovation covariance lacks R: S = H P H^T + R, the measurement noise adds to the "
        "predicted spread (without it the filter trusts the measurement too much); "
        f"see {_L4} §4 (the Kalman gain, derived from the measurement and its covariance)",
    ),
    Mistake(
        "predict-without-Q",
        "the predicted covariance lacks Q: P = F P F^T + Q, the process noise is what keeps the "
        "filter from becoming over-confident; "
        f"see {_L4} §2 and §6 (the constant-velocity model, the steady state)",
    ),    Mistake(
        "nees-shared-error-left-out",
        "the covariance lacks the error the whole cluster shares, alpha^2 v v^T along the measured "
        "velocity: the flow residuals cannot see it, and without it the filter trusts the velocity "
        f"far too much; see {_L6} {_5B}",
    ),
    Mistake(
        "nees-covariance-not-inverted",
        "this is e^T C e: the normalised error weighs e by the inverse covariance, e^T C^-1 e "
        f"(solve with C); see {_L6} {_5B}",
    ),
    Mistake(
        "nees-shared-error-along-the-truth",
        "the shared error is modelled along the true velocity: the filter only has the measured one, "
        f"alpha^2 v_meas v_meas^T; see {_L6} {_5B}",
    ),
)


EXERCISE = Exercise(
    id="ex06_kalman_predict_update",
    title="Kalman predict and update",
    notebook="ex06_kalman_predict_update.ipynb",
    answer_cells=("kf_predict", "kf_update", "velocity_nees"),
    blocked=("flowtrack.kalman", "flowtrack.tracking", "flowtrack.particle", "flowtrack.bayes"),
    allowed=('numpy', 'scipy.linalg'),
    tests=(_ex06_predict_public, _ex06_predict_hidden, _ex06_update_public, _ex06_update_hidden,
           _ex06_nees_public, _ex06_nees_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)


# The same exercise answered in C++, Java, Octave and Mathematica: the problem of other languages
# (flowtrack_course.polyglot.problems) and the mistakes only those answers show (there one function
# does a whole predict/update step).
LANGUAGE_PROBLEM = "kalman_step"
LANGUAGE_MISTAKES = (
    Mistake(
        "kalman-no-predict",
        "the update starts from x and P as they were: a step first predicts them (x = F x, "
        "P = F P F^T + Q), then updates the prediction with z; "
        f"see {_L4} §2 and §4 (the constant-velocity model, the Kalman gain)",
    ),
    Mistake(
        "kalman-prior-cov",
        "P is the predicted covariance F P F^T + Q: the update must shrink it, P = (I - K H) P "
        f"(the measurement adds information); see {_L4} §4 (the Kalman gain and the posterior covariance)",
    ),
)
