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
Last, ``system_null_dimension`` counts the null directions of the smoothed system
:math:`\operatorname{diag}(N_p) + \lambda\,(L\otimes I_3)` on textures whose answer the lesson
derives (random texture 0, stripes 1, no texture 2, one textured pixel 0; one per pixel or two
without smoothing), against the eigenvalues of the reference's matrices.
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


@graded_test("data-term rows: three pixels", "test_rows", 0.5, hidden=False)
def _ex12_rows_public(rng):
    return [("data_term_rows", (_X, _GI, _GD, 100.0, 100.0), {}, _rows_check(_X, _GI, _GD, 100.0, 100.0))]


@graded_test("data-term rows: random pixels and focal lengths", "test_rows", 1.5, hidden=True)
def _ex12_rows_hidden(rng):
    out = []
    for n in (1, 6, 25):
        X, gi, _, gd, _, fx, fy = _random_pixels(rng, n)
        out.append(("data_term_rows", (X, gi, gd, fx, fy), {}, _rows_check(X, gi, gd, fx, fy)))
    return out


@graded_test("normal equations: three pixels", "test_normal_equations", 1.0, hidden=False)
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


def null_dimension_reference(N: np.ndarray, H: int, W: int, lam: float) -> int:
    """Number of eigenvalues of diag(N_p) + lam (L kron I_3) at most 1e-9 times the largest (numpy
    ``eigvalsh``; ``L`` the grid Laplacian of :func:`flowtrack.variational.grid_laplacian`)."""
    import scipy.sparse as sps

    from flowtrack.variational import grid_laplacian

    A = sps.block_diag(list(N)) + lam * sps.kron(grid_laplacian(H, W), sps.eye(3))
    ev = np.linalg.eigvalsh(A.toarray())
    return int(np.sum(ev <= 1e-9 * ev[-1]))


def _pixel_nullities(N: np.ndarray) -> int:
    """The null directions of the pixels one by one (smoothness left out): sum of 3 - rank N_p."""
    ev = np.linalg.eigvalsh(N)
    return int(np.sum(ev <= 1e-9 * ev[:, -1:]))


def null_dimension_check(N: np.ndarray, H: int, W: int, lam: float) -> Check:
    """The exact count; the per-pixel count (no smoothness) and the rank are the catalogued wrong
    answers."""
    k = null_dimension_reference(N, H, W, lam)
    variants = [Variant("null-dimension-no-smoothness", np.array(float(_pixel_nullities(N)))),
                Variant("null-dimension-rank", np.array(float(3 * H * W - k)))]
    return array_check(np.array(float(k)), rtol=0.0, atol=1e-9, variants=variants)


def grid_pixels(H: int, W: int, f: float = 100.0) -> np.ndarray:
    """The points of a fronto-parallel plane at Z = 1 seen by an H x W camera with focal length f
    and the principal point at the grid's centre, row-major, shape (H * W, 3)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    X = np.stack([(xx - (W - 1) / 2) / f, (yy - (H - 1) / 2) / f, np.ones_like(xx)], axis=-1)
    return X.reshape(-1, 3)


def texture(rng: np.random.Generator, kind: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Brightness and depth gradients, shape (n, 2) each, of a texture on the plane: ``random``,
    ``vertical stripes`` (I_y = 0), ``horizontal stripes`` (I_x = 0), ``flat`` (no texture, flat
    depth), ``flat but one pixel`` and ``stripes but one pixel`` (one random pixel textured)."""
    gi = np.zeros((n, 2))
    gd = np.zeros((n, 2))
    mag = rng.uniform(0.5, 1.5, n) * rng.choice([-1.0, 1.0], n)
    if kind == "random":
        gi = rng.normal(size=(n, 2))
        gd = rng.normal(scale=0.01, size=(n, 2))
    elif kind in ("vertical stripes", "stripes but one pixel"):
        gi[:, 0] = mag
    elif kind == "horizontal stripes":
        gi[:, 1] = mag
    if kind.endswith("but one pixel"):
        p = int(rng.integers(n))
        # gradients at an angle to the stripes, and a depth slope steep enough that the pixel sees
        # the two motions across the optical axis by a clear margin (no near-zero eigenvalue)
        a, b = rng.uniform(0.0, 2.0 * np.pi, 2)
        gi[p] = rng.uniform(0.5, 1.5) * np.array([np.cos(a), np.sin(a)])
        gd[p] = rng.uniform(0.1, 0.2) * np.array([np.cos(b), np.sin(b)])
    return gi, gd


#: the textures of the hidden test and the null-space dimension each has for lam > 0
TEXTURES = {"random": 0, "vertical stripes": 1, "horizontal stripes": 1, "flat": 2,
            "flat but one pixel": 0, "stripes but one pixel": 0}


def _system(rng, kind, H, W):
    X = grid_pixels(H, W)
    gi, gd = texture(rng, kind, H * W)
    z = np.zeros(H * W)
    return _reference(X, gi, z, gd, z, 100.0, 100.0, 1.0, 1.0)[0]


@graded_test("null directions of the smoothed system: stripes", "test_null_dimension", 0.5, hidden=False)
def _ex12_null_public(rng):
    X = grid_pixels(3, 4)
    gi = np.column_stack([np.linspace(0.5, 1.0, 12), np.zeros(12)])
    z = np.zeros(12)
    N = _reference(X, gi, z, np.zeros((12, 2)), z, 100.0, 100.0, 1.0, 1.0)[0]
    return [("system_null_dimension", (N, 3, 4, lam), {}, null_dimension_check(N, 3, 4, lam))
            for lam in (0.0, 1.0)]


@graded_test("null directions of the smoothed system: textures, grids and λ", "test_null_dimension", 1.5,
             hidden=True)
def _ex12_null_hidden(rng):
    out = []
    kinds = [*TEXTURES, "random"]
    for j, kind in enumerate(kinds):
        H, W = (int(v) for v in rng.integers(3, 6, 2))
        lam = 0.0 if j == len(kinds) - 1 else float(rng.uniform(0.05, 5.0))  # the last without smoothing
        N = _system(rng, kind, H, W)
        out.append(("system_null_dimension", (N, H, W, lam), {}, null_dimension_check(N, H, W, lam)))
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
    Mistake(
        "null-dimension-no-smoothness",
        "this counts each pixel's null directions on its own (the block-diagonal diag(N_p), one or two "
        "per pixel), as if λ were 0: with λ > 0 a field stays unseen only if it is constant over the "
        "grid (L does not see it) and no pixel's data term sees it; "
        f"see {_L2} §1 (how λ resolves it)",
    ),
    Mistake(
        "null-dimension-rank",
        "this is the rank of diag(N_p) + λ(L ⊗ I_3), not the dimension of its null space: that is "
        "3HW minus the rank; "
        f"see {_L2} §1 (how λ resolves it)",
    ),
)


EXERCISE = Exercise(
    id="ex12_rgbd_data_term",
    title="The linearised RGB-D data term of one pixel",
    notebook="ex12_rgbd_data_term.ipynb",
    answer_cells=("data_term_rows", "pixel_normal_equations", "unseen_direction", "system_null_dimension"),
    blocked=("flowtrack.rgbd_flow", "flowtrack._rgbd_kernels", "flowtrack.sceneflow", "flowtrack.symbolic",
             "flowtrack.camera"),
    allowed=('numpy',),
    tests=(_ex12_rows_public, _ex12_rows_hidden, _ex12_normal_public, _ex12_normal_hidden,
           _ex12_unseen_public, _ex12_unseen_hidden, _ex12_null_public, _ex12_null_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
