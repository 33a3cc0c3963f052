"""Ex02: optical flow from scene flow: the trusted tests of the notebook next to this file."""

from __future__ import annotations

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Variant,
    array_check,
    graded_test,
)


def pinhole(fx: float, fy: float, cx: float = 0.0, cy: float = 0.0):
    """The trusted :class:`flowtrack.camera.PinholeCamera` with these intrinsics."""
    from flowtrack.camera import PinholeCamera

    return PinholeCamera(float(fx), float(fy), float(cx), float(cy))


def points_in_front(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random points, shape (n, 3), with x, y in [-1, 1] and depth z in [0.5, 4] (in front of
    a camera)."""
    X = rng.uniform(-1.0, 1.0, size=(n, 3))
    X[:, 2] = rng.uniform(0.5, 4.0, size=n)
    return X


_EX02_X = np.array([[0.0, 0.0, 2.0], [1.0, -1.0, 4.0]])
_EX02_V = np.array([[1.0, 0.0, 0.0], [0.0, 0.5, -1.0]])


def _ex02_expected(X, V, dt, fx, fy):
    from flowtrack.camera import optical_flow_from_scene_flow

    return optical_flow_from_scene_flow(X, V, dt, pinhole(fx, fy))


def _ex02_check(X, V, dt, fx, fy, **tol) -> Check:
    """The flow, recognising the catalogued wrong answers (computed here from the same inputs)."""
    from flowtrack.camera import projection_jacobian

    J = projection_jacobian(X, pinhole(fx, fy))
    Jsign = J.copy()
    Jsign[:, :, 2] *= -1.0
    Jflat = J.copy()
    Jflat[:, :, 2] = 0.0
    variants = [
        Variant("missing-dt", np.einsum("nij,nj->ni", J, V)),
        Variant("flow-ignores-depth-motion", np.einsum("nij,nj->ni", Jflat, V) * dt),
        Variant("jacobian-sign", np.einsum("nij,nj->ni", Jsign, V) * dt),
        Variant("jacobian-fx-fy-swapped", _ex02_expected(X, V, dt, fy, fx)),
    ]
    return array_check(_ex02_expected(X, V, dt, fx, fy), variants=variants, **tol)


@graded_test("optical flow: two points", "test_optical_flow", 3.0, hidden=False)
def _ex02_public(rng):
    return [
        (
            "optical_flow",
            (_EX02_X, _EX02_V, 0.1, 500.0, 500.0),
            {},
            _ex02_check(_EX02_X, _EX02_V, 0.1, 500.0, 500.0),
        ),
        (
            "optical_flow",
            (_EX02_X, _EX02_V, 1.0, 100.0, 200.0),
            {},
            _ex02_check(_EX02_X, _EX02_V, 1.0, 100.0, 200.0),
        ),
    ]


@graded_test("optical flow: random points, velocities and time steps", "test_optical_flow", 7.0, hidden=True)
def _ex02_hidden(rng):
    out = []
    # dt != 1 in every case: a forgotten time step shows in each of them (the same score for everyone)
    sizes_and_steps = (
        (1, float(rng.uniform(0.3, 0.7))),
        (6, float(rng.uniform(0.01, 0.2))),
        (25, float(rng.uniform(1.5, 2.0))),
    )
    for n, dt in sizes_and_steps:
        X = points_in_front(rng, n)
        V = rng.normal(size=(n, 3))
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        out.append(("optical_flow", (X, V, dt, fx, fy), {}, _ex02_check(X, V, dt, fx, fy)))
    # motion along the viewing ray produces no optical flow (first order)
    X = points_in_front(rng, 5)
    V = X * rng.uniform(-2.0, 2.0, size=(5, 1))
    out.append(("optical_flow", (X, V, 0.1, 400.0, 400.0), {}, array_check(np.zeros((5, 2)), atol=1e-9)))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L1 = "lesson 01_camera_geometry"

MISTAKES = (
    Mistake(
        "missing-dt",
        "the time step is missing: J(X) v is a pixel velocity (px/s); the flow between two frames "
        f"is the displacement u = J(X) v dt; see {_L1} §3 (scene flow induces optical flow)",
    ),
    Mistake(
        "flow-ignores-depth-motion",
        "motion along Z is ignored: the Jacobian's third column -f X/Z^2 turns approaching or "
        "receding into image motion (expansion), u = J(X) v dt uses all of v; "
        f"see {_L1} §3 (scene flow induces optical flow)",
    ),
)


EXERCISE = Exercise(
    id="ex02_optical_flow",
    title="Optical flow from scene flow",
    notebook="ex02_optical_flow.ipynb",
    answer_cells=("optical_flow",),
    blocked=("flowtrack.camera", "flowtrack.symbolic"),
    allowed=('numpy',),
    tests=(_ex02_public, _ex02_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
