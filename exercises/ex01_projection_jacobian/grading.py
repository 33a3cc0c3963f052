"""Ex01: the projection Jacobian: the trusted tests of the notebook next to this file."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Outcome,
    Variant,
    array_check,
    as_float_array,
    compare,
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


_EX01_X = np.array([[1.0, 2.0, 4.0], [0.0, 0.0, 1.0], [-0.5, 0.25, 2.0]])


def _project_variants(X, fx, fy, cx, cy) -> list[Variant]:
    from flowtrack.camera import project

    return [Variant("projection-missing-principal-point", project(X, pinhole(fx, fy)))]


def _jacobian_variants(X, fx, fy) -> list[Variant]:
    """The catalogued wrong Jacobians on these points (trusted, computed here)."""
    from flowtrack.camera import projection_jacobian

    J = projection_jacobian(X, pinhole(fx, fy))
    out = [Variant("jacobian-fx-fy-swapped", projection_jacobian(X, pinhole(fy, fx)))]
    for rows in ((0,), (1,), (0, 1)):
        W = J.copy()
        W[:, rows, 2] *= -1.0
        out.append(Variant("jacobian-sign", W))
    W = J.copy()
    W[:, :, 2] *= X[:, 2:3]
    out.append(Variant("jacobian-z-not-squared", W))
    return out


@graded_test("project: three points", "test_project", 1.0, hidden=False)
def _ex01_project_public(rng):
    from flowtrack.camera import project

    return [
        (
            "project",
            (_EX01_X, 100.0, 100.0, 50.0, 40.0),
            {},
            array_check(
                project(_EX01_X, pinhole(100, 100, 50, 40)),
                variants=_project_variants(_EX01_X, 100.0, 100.0, 50.0, 40.0),
            ),
        )
    ]


@graded_test("project: random points and intrinsics", "test_project", 2.0, hidden=True)
def _ex01_project_hidden(rng):
    from flowtrack.camera import project

    out = []
    for n in (1, 5, 20):
        X = points_in_front(rng, n)
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        cx, cy = (float(v) for v in rng.uniform(100.0, 400.0, 2))
        variants = _project_variants(X, fx, fy, cx, cy)
        check = array_check(project(X, pinhole(fx, fy, cx, cy)), variants=variants)
        out.append(("project", (X, fx, fy, cx, cy), {}, check))
    return out


def _jacobian_check(
    expected: np.ndarray, rtol: float = 1e-6, atol: float = 1e-9, variants: Sequence[Variant] = ()
) -> Check:
    """Per-entry credit: the share of the six Jacobian entries right at every point."""

    def check(outcome: Outcome) -> tuple[float, str]:
        d = compare(outcome, expected, rtol=rtol, atol=atol, variants=variants)
        if d.ok:
            return 1.0, "ok"
        got = as_float_array(outcome.value, expected.shape) if outcome.ok else None
        if got is None:
            return 0.0, d.report()
        good = [
            (i, j)
            for i in range(2)
            for j in range(3)
            if np.allclose(got[:, i, j], expected[:, i, j], rtol=rtol, atol=atol)
        ]
        wrong = [f"J[:, {i}, {j}]" for i in range(2) for j in range(3) if (i, j) not in good]
        head = f"wrong entries {', '.join(wrong)}: "
        # (which entries are wrong is the answer's choice: the hidden-safe text does not name them)
        return len(good) / 6.0, d.report().retext(head + d.public, d.safe)

    return check


@graded_test("Jacobian: three points, fx = fy and fx != fy", "test_jacobian", 2.0, hidden=False)
def _ex01_jac_public(rng):
    from flowtrack.camera import projection_jacobian

    out = []
    for fx, fy in ((100.0, 100.0), (100.0, 150.0)):  # fx != fy: a swap of fx and fy shows
        J = projection_jacobian(_EX01_X, pinhole(fx, fy))
        check = _jacobian_check(J, variants=_jacobian_variants(_EX01_X, fx, fy))
        out.append(("projection_jacobian", (_EX01_X, fx, fy), {}, check))
    return out


@graded_test("Jacobian: random points and focal lengths", "test_jacobian", 5.0, hidden=True)
def _ex01_jac_hidden(rng):
    from flowtrack.camera import projection_jacobian

    out = []
    for n in (1, 7, 30):
        X = points_in_front(rng, n)
        fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
        variants = _jacobian_variants(X, fx, fy)
        check = _jacobian_check(projection_jacobian(X, pinhole(fx, fy)), variants=variants)
        out.append(("projection_jacobian", (X, fx, fy), {}, check))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L1 = "lesson 01_camera_geometry"

MISTAKES = (
    Mistake(
        "jacobian-sign",
        "the d/dZ entries have the wrong sign: x = fx X/Z + cx decreases as Z grows, so dx/dZ = "
        f"-fx X/Z^2 (and dy/dZ = -fy Y/Z^2); see {_L1} §2 (the projection Jacobian)",
    ),
    Mistake(
        "jacobian-fx-fy-swapped",
        "fx and fy are swapped: the image x coordinate scales with fx and y with fy, so row 0 of "
        "the Jacobian carries fx and row 1 fy (they differ on real cameras); "
        f"see {_L1} §1-2 (the pinhole projection and its Jacobian)",
    ),
    Mistake(
        "jacobian-z-not-squared",
        "the d/dZ entries divide by Z instead of Z^2: d(X/Z)/dZ = -X/Z^2 (quotient rule); "
        f"see {_L1} §2 (the projection Jacobian)",
    ),
    Mistake(
        "projection-missing-principal-point",
        "the principal point is missing: pixel coordinates are fx X/Z + cx and fy Y/Z + cy, "
        f"(cx, cy) moves the origin to the image corner; see {_L1} §1 (the pinhole projection)",
    ),
)


EXERCISE = Exercise(
    id="ex01_projection_jacobian",
    title="The pinhole projection and its Jacobian",
    notebook="ex01_projection_jacobian.ipynb",
    answer_cells=("project", "projection_jacobian"),
    blocked=("flowtrack.camera", "flowtrack.symbolic"),
    allowed=('numpy',),
    tests=(_ex01_project_public, _ex01_project_hidden, _ex01_jac_public, _ex01_jac_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)


# The same exercise answered in C++, Java, Octave and Mathematica: the problem of other languages
# (flowtrack_course.polyglot.problems) and the mistakes only those answers show (there the function
# takes the intrinsics as arguments, so the focal lengths can be left out altogether).
LANGUAGE_PROBLEM = "projection_jacobian"
LANGUAGE_MISTAKES = (
    Mistake(
        "jacobian-no-focal",
        "the focal lengths are missing: u = fx X/Z + cx and v = fy Y/Z + cy, so row 0 of the Jacobian "
        f"carries fx and row 1 fy; see {_L1} §1-2 (the pinhole projection and its Jacobian)",
    ),
)
