r"""Ex12, one pixel's linearised RGB-D data term: trusted tests of the notebook next to this file.

The student writes the two coefficient rows :math:`a_I = J^\top\nabla I` and
:math:`a_D = J^\top\nabla D - e_z` (``data_term_rows``), a pixel's 3×3 normal matrix and right-hand
side (``pixel_normal_equations``): :math:`N = w_I a_I a_I^\top + w_D a_D a_D^\top` (half the Hessian
of the pixel's energy), :math:`b = -(w_I r_I a_I + w_D r_D a_D)` (minus half its gradient at 0), and
the motion the pixel cannot see (``unseen_direction``): the unit vector along
:math:`a_I \times a_D`, graded up to its sign. The reference is
:func:`flowtrack.rgbd_flow.pixel_normal_equations`; the rows are read off it (with :math:`r = 1` and one
weight switched off, :math:`b = -a`), so the functions are graded against the estimator's own data
term; the unseen direction is the eigenvector of the reference's :math:`N` with the eigenvalue 0.
"""

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
    tuple_check,
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


_X = np.array([[0.0, 0.0, 1.0], [0.2, -0.1, 2.0], [-0.3, 0.4, 0.8]])
_GI = np.array([[1.0, 0.0], [0.5, -0.25], [0.0, 2.0]])
_GD = np.array([[0.0, 0.0], [0.01, 0.0], [-0.02, 0.005]])
_RI = np.array([0.5, -0.1, 0.05])
_RD = np.array([0.0, 0.002, -0.001])


def _reference(X, gi, ri, gd, rd, fx, fy, wi, wd):
    from flowtrack.rgbd_flow import pixel_normal_equations

    return pixel_normal_equations(X, gi, ri, gd, rd, pinhole(fx, fy), wi, wd)


def _rows(X, gi, gd, fx, fy):
    """(a_I, a_D) from the reference: with r = 1 and the other weight 0, b = -a."""
    n = len(X)
    a_i = -_reference(X, gi, np.ones(n), gd, np.zeros(n), fx, fy, 1.0, 0.0)[1]
    a_d = -_reference(X, gi, np.zeros(n), gd, np.ones(n), fx, fy, 0.0, 1.0)[1]
    return a_i, a_d


def _rows_check(X, gi, gd, fx, fy):
    a_i, a_d = _rows(X, gi, gd, fx, fy)
    return tuple_check([array_check(a_i), array_check(a_d)], ["a_I", "a_D"])


def _normal_check(X, gi, ri, gd, rd, fx, fy, wi, wd):
    N, b = _reference(X, gi, ri, gd, rd, fx, fy, wi, wd)
    # N holds w / sigma^2-sized numbers next to zeros: relative 1e-6 with an absolute floor on its scale
    atol = 1e-9 * max(1.0, float(np.abs(N).max()))
    return tuple_check([array_check(N, atol=atol), array_check(b, atol=atol)], ["N", "b"])


def _random_pixels(rng, n):
    X = points_in_front(rng, n)
    gi = rng.normal(scale=0.5, size=(n, 2))
    gd = rng.normal(scale=0.02, size=(n, 2))
    ri = rng.normal(scale=0.1, size=n)
    rd = rng.normal(scale=0.005, size=n)
    fx, fy = (float(v) for v in rng.uniform(200.0, 800.0, 2))
    return X, gi, ri, gd, rd, fx, fy


def unseen_reference(a_i: np.ndarray, a_d: np.ndarray) -> np.ndarray:
    """The unit null vector of each pixel's normal matrix, from the reference's N (unit weights):
    the eigenvector of its eigenvalue 0 (numpy ``eigh``), shape (n, 3), sign as numpy gives it."""
    N = np.einsum("ni,nj->nij", a_i, a_i) + np.einsum("ni,nj->nij", a_d, a_d)
    return np.linalg.eigh(N)[1][:, :, 0]


def _aligned(v: np.ndarray, to: np.ndarray) -> np.ndarray:
    """``v`` with each row's sign flipped where it points away from the same row of ``to``."""
    return v * np.where(np.sum(v * to, axis=1) < 0.0, -1.0, 1.0)[:, None]


def unseen_check(a_i: np.ndarray, a_d: np.ndarray) -> Check:
    """Unit vectors with N u = 0, one per pixel, either sign per row (relative 1e-6 once each row's
    sign is matched to the expected one); the catalogued wrong answers are matched the same way."""
    u = unseen_reference(a_i, a_d)
    cross = np.cross(a_i, a_d)
    wrong = [
        ("unseen-not-normalised", cross),
        ("unseen-seen-direction", a_i / np.linalg.norm(a_i, axis=1, keepdims=True)),
        ("unseen-seen-direction", a_d / np.linalg.norm(a_d, axis=1, keepdims=True)),
    ]

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            err = outcome.error or "the call failed"
            return 0.0, Report(err, safe_error(err))
        got = as_float_array(outcome.value, u.shape)
        if got is None or not np.all(np.isfinite(got)):
            d = compare(outcome, u)
            return 0.0, d.report()
        got = _aligned(got, u)
        variants = [Variant(k, _aligned(v, got)) for k, v in wrong]
        d = compare(Outcome(True, got.tolist()), u, variants=variants)
        return (1.0 if d.ok else 0.0), d.report()

    return check


@graded_test("data-term rows: three pixels", "test_rows", 1.0, hidden=False)
def _ex12_rows_public(rng):
    return [("data_term_rows", (_X, _GI, _GD, 100.0, 100.0), {}, _rows_check(_X, _GI, _GD, 100.0, 100.0))]


@graded_test("data-term rows: random pixels and focal lengths", "test_rows", 2.0, hidden=True)
def _ex12_rows_hidden(rng):
    out = []
    for n in (1, 6, 25):
        X, gi, _, gd, _, fx, fy = _random_pixels(rng, n)
        out.append(("data_term_rows", (X, gi, gd, fx, fy), {}, _rows_check(X, gi, gd, fx, fy)))
    return out


@graded_test("normal equations: three pixels", "test_normal_equations", 2.0, hidden=False)
def _ex12_normal_public(rng):
    out = []
    for wi, wd in ((1.0, 1.0), (2500.0, 62500.0)):
        args = (_X, _GI, _RI, _GD, _RD, 100.0, 100.0, wi, wd)
        out.append(("pixel_normal_equations", args, {}, _normal_check(*args)))
    return out


@graded_test(
    "normal equations: random pixels, residuals and weights", "test_normal_equations", 3.0, hidden=True
)
def _ex12_normal_hidden(rng):
    out = []
    for n in (1, 6, 25):
        X, gi, ri, gd, rd, fx, fy = _random_pixels(rng, n)
        wi = rng.uniform(0.0, 3000.0, size=n)  # per-pixel weights (the IRLS weights of the estimator)
        wd = rng.uniform(0.0, 1e5, size=n)
        args = (X, gi, ri, gd, rd, fx, fy, wi, wd)
        out.append(("pixel_normal_equations", args, {}, _normal_check(*args)))
    # scalar weights, one term switched off: N has rank 1
    X, gi, ri, gd, rd, fx, fy = _random_pixels(rng, 4)
    args = (X, gi, ri, gd, rd, fx, fy, 0.0, 1.0)
    out.append(("pixel_normal_equations", args, {}, _normal_check(*args)))
    return out


@graded_test("the motion a pixel cannot see: three pixels", "test_unseen", 0.5, hidden=False)
def _ex12_unseen_public(rng):
    a_i, a_d = _rows(_X, _GI, _GD, 100.0, 100.0)
    return [("unseen_direction", (a_i, a_d), {}, unseen_check(a_i, a_d))]


@graded_test("the motion a pixel cannot see: random pixels", "test_unseen", 1.5, hidden=True)
def _ex12_unseen_hidden(rng):
    out = []
    for n in (1, 7, 30):
        X, gi, _, gd, _, fx, fy = _random_pixels(rng, n)
        a_i, a_d = _rows(X, gi, gd, fx, fy)
        out.append(("unseen_direction", (a_i, a_d), {}, unseen_check(a_i, a_d)))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L2 = "lesson 02_variational_scene_flow"

MISTAKES = (
    Mistake(
        "unseen-not-normalised",
        "this is a_I x a_D, the right direction but not of unit length: divide each row by its norm; "
        f"see {_L2} §1 (the aperture problem in 3-D)",
    ),
    Mistake(
        "unseen-seen-direction",
        "this is a direction the pixel does see, a row of its data term (a_D is the surface normal, "
        "along which depth sees the motion; a_I the direction brightness sees); the unseen one is "
        "orthogonal to both rows: a_I x a_D, normalised; "
        f"see {_L2} §1 (the geometric reading of the aperture problem)",
    ),
)


EXERCISE = Exercise(
    id="ex12_rgbd_data_term",
    title="The linearised RGB-D data term of one pixel",
    notebook="ex12_rgbd_data_term.ipynb",
    answer_cells=("data_term_rows", "pixel_normal_equations", "unseen_direction"),
    blocked=("flowtrack.rgbd_flow", "flowtrack._rgbd_kernels", "flowtrack.sceneflow", "flowtrack.symbolic",
             "flowtrack.camera"),
    allowed=('numpy',),
    tests=(_ex12_rows_public, _ex12_rows_hidden, _ex12_normal_public, _ex12_normal_hidden,
           _ex12_unseen_public, _ex12_unseen_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
