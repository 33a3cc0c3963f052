r"""The camera problems: the projection Jacobian (ports and graded) and Lucas–Kanade (Java/OpenCV port).

``projection_jacobian`` (ports and graded)
    ``{"X" (3,), "fx", "fy", "cx", "cy"}`` -> ``{"J" (2, 3)}``, :math:`\partial\pi/\partial X` of
    :math:`\pi(X) = (f_x X/Z + c_x, f_y Y/Z + c_y)`. Its random points (the ports' seeded cases and
    the grader's hidden ones) are drawn by one function, :func:`draw_point`.
``lucas_kanade`` (ports)
    An image pair rendered by :func:`flowtrack.synth.make_scene`, feature points on the moving
    objects and the optical flow the reference predicts for them from the ground-truth scene flow.
    The prediction is the *exact* projection difference

    .. math::  u_i = \pi(X_i + v_i\,\Delta t) - \pi(X_i),

    with :math:`X_i` the noiseless surface point seen at the feature pixel in the first frame and
    :math:`v_i` its exact velocity, so :math:`X_i + v_i \Delta t` is where that material point is
    in the second frame (not the first-order :func:`flowtrack.camera.optical_flow_from_scene_flow`,
    whose linearisation error would be part of the tolerance otherwise). The expected flow is known
    from the rendering, not computed from the images: each case carries it.
"""

from __future__ import annotations

import numpy as np

from .base import Case, Problem

__all__ = ["LUCAS_KANADE", "PROJECTION_JACOBIAN", "draw_point", "select_lk_features"]

#: ITU-R BT.601 luma weights (OpenCV's ``COLOR_RGB2GRAY``).
_LUMA = np.array([0.299, 0.587, 0.114])

#: Lucas–Kanade settings written into every case; the ports pass them to ``calcOpticalFlowPyrLK``.
LK_WINDOW = 11  # square window side (pixels), odd
LK_MAX_LEVEL = 2  # pyramid levels above the full-resolution image
LK_ITERATIONS = 50
LK_EPSILON = 1e-3
#: Per-component tolerance (pixels) on each point's flow; pyramidal LK on these renders is typically
#: within 0.1–0.35 px of the exact flow (the shading of rotating faces changes between frames).
LK_ATOL = 0.5


def _gray(rgb: np.ndarray) -> np.ndarray:
    return np.rint(rgb.astype(np.float64) @ _LUMA).astype(np.uint8)


def select_lk_features(
    gray: np.ndarray,
    labels0: np.ndarray,
    labels1: np.ndarray,
    flow_px: np.ndarray,
    radius: int,
    min_eig: float = 5.0,
):
    r"""Shi–Tomasi feature pixels whose whole LK window lies on one moving object in both frames.

    A pixel :math:`p` is kept when (i) the smaller eigenvalue of the structure tensor
    :math:`\sum_{w} \nabla I \nabla I^\top / |w|` over the :math:`(2r+1)^2` window exceeds ``min_eig``
    and is a local maximum in a 5×5 neighbourhood, (ii) every pixel of the window around :math:`p`
    carries the same object label (> 0) in the first frame, and (iii) the window around the
    predicted destination :math:`p + u` (rounded) carries that label in the second frame. So no
    window straddles a motion boundary or an occlusion, where LK is not expected to be right.

    Parameters
    ----------
    gray : ndarray, shape (H, W)
        First image.
    labels0, labels1 : ndarray, shape (H, W) int
        Label images of the two frames (0 static, k > 0 object k).
    flow_px : ndarray, shape (H, W, 2)
        Predicted flow ``(du, dv)`` (columns, rows) of each pixel (only read at candidates).
    radius : int
        Window half-size ``r``.
    min_eig : float
        Threshold on the smaller structure-tensor eigenvalue (grey levels²).

    Returns
    -------
    ndarray, shape (K, 2) int
        ``(row, col)`` of the selected pixels, row-major order.
    """
    from scipy.ndimage import maximum_filter, minimum_filter, uniform_filter

    img = gray.astype(np.float64)
    ix = np.zeros_like(img)
    iy = np.zeros_like(img)
    ix[:, 1:-1] = (img[:, 2:] - img[:, :-2]) / 2
    iy[1:-1, :] = (img[2:, :] - img[:-2, :]) / 2
    w = 2 * radius + 1
    a, b, c = (uniform_filter(m, w) for m in (ix * ix, ix * iy, iy * iy))
    lmin = (a + c) / 2 - np.sqrt(((a - c) / 2) ** 2 + b * b)
    same0 = (minimum_filter(labels0, w) == labels0) & (maximum_filter(labels0, w) == labels0) & (labels0 > 0)
    same1 = (minimum_filter(labels1, w) == labels1) & (maximum_filter(labels1, w) == labels1)
    cand = np.argwhere(same0 & (lmin > min_eig) & (lmin == maximum_filter(lmin, 5)))
    H, W = labels0.shape
    keep = []
    for r, col in cand:
        du, dv = flow_px[r, col]
        r1, c1 = int(np.rint(r + dv)), int(np.rint(col + du))
        if 0 <= r1 < H and 0 <= c1 < W and same1[r1, c1] and labels1[r1, c1] == labels0[r, col]:
            keep.append((int(r), int(col)))
    return np.array(keep, dtype=np.int64).reshape(-1, 2)


def _lk_case(seed: int, image_size=(240, 320), dt: float = 0.1, margin: int = 16) -> Case:
    from flowtrack.camera import project
    from flowtrack.synth import make_scene

    scene = make_scene(n_objects=3, n_frames=2, image_size=image_size, dt=dt, noise=0.0, seed=seed)
    f0, f1 = scene.frames
    H, W = image_size
    pix = f0.pixels
    X, v = f0.gt_points, f0.gt_flow
    uv0 = np.stack([pix[:, 1], pix[:, 0]], axis=1).astype(np.float64)
    flow = project(X + v * dt, scene.camera) - uv0  # exact projection difference, (N, 2)
    flow_img = np.zeros((H, W, 2))
    flow_img[pix[:, 0], pix[:, 1]] = flow
    g0, g1 = _gray(f0.rgb), _gray(f1.rgb)
    feats = select_lk_features(g0, f0.label_image, f1.label_image, flow_img, LK_WINDOW // 2)
    # crop both images to the moving objects (plus a margin) to keep the vector file small; a crop
    # shifts pixel coordinates but not the flow
    rows, cols = np.nonzero((f0.label_image > 0) | (f1.label_image > 0))
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, H)
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, W)
    pts = [[float(c - c0), float(r - r0)] for r, c in feats]
    exp = [[float(x) for x in flow_img[r, c]] for r, c in feats]
    inp = {
        "image0": g0[r0:r1, c0:c1].tolist(),
        "image1": g1[r0:r1, c0:c1].tolist(),
        "points": pts,
        "win_size": LK_WINDOW,
        "max_level": LK_MAX_LEVEL,
        "iterations": LK_ITERATIONS,
        "epsilon": LK_EPSILON,
    }
    return Case(f"synth_seed{seed}_{H}x{W}_cropped", inp, {"flow": exp})


def _lk_cases() -> list[Case]:
    """Test vectors for pyramidal Lucas–Kanade on rendered image pairs.

    Each case: ``input`` = ``image0``, ``image1`` (grey uint8 as nested lists of ints, shape
    ``(h, w)``, BT.601 luma of ``make_scene(n_objects=3, n_frames=2, image_size=(240, 320), noise=0,
    seed=s)``, cropped to the moving objects), ``points`` (K, 2) feature positions ``(x, y)`` =
    (column, row) in the cropped image (see :func:`select_lk_features`), and the LK settings
    ``win_size``, ``max_level``, ``iterations``, ``epsilon``. ``expected["flow"]`` (K, 2) is the
    exact projection difference ``(du, dv)`` of the ground-truth motion (module docstring). A port
    passes iff every point is tracked (status 1) and every component is within ``atol`` = 0.5 px of
    the prediction (``rtol`` = 0).
    """
    return [_lk_case(seed) for seed in (0, 1, 2)]


LUCAS_KANADE = Problem(
    "lucas_kanade",
    "Pyramidal Lucas–Kanade on rendered image pairs",
    ("flow",),
    None,  # the expected flow comes from the rendering (each case carries it)
    rtol=0.0,
    atol=LK_ATOL,
    vector_cases=_lk_cases,
)


# -- projection_jacobian ----------------------------------------------------------------------------
def _jac_reference(inp: dict) -> dict:
    from flowtrack.camera import PinholeCamera, projection_jacobian

    cam = PinholeCamera(float(inp["fx"]), float(inp["fy"]), float(inp["cx"]), float(inp["cy"]))
    return {"J": projection_jacobian(np.asarray(inp["X"], float)[None, :], cam)[0]}


def _jac_no_focal(inp: dict) -> dict:
    return _jac_reference({**inp, "fx": 1.0, "fy": 1.0})


_INTRINSICS = ((300, 900), (300, 900), (100, 400), (100, 300))  # ranges of fx, fy, cx, cy


def draw_point(rng: np.random.Generator) -> dict:
    """A random point in front of a random camera: ``X`` with x, y in [-1, 1] and depth in [0.3, 4]
    (rounded to 1e-6), focal lengths in [300, 900] and a principal point in [100, 400] x [100, 300]
    (rounded to 1e-3), drawn in that order. The ports' seeded cases and the grader's hidden cases
    are both drawn by this function: the same seed gives the same inputs."""
    X = [
        float(np.round(rng.uniform(-1, 1), 6)),
        float(np.round(rng.uniform(-1, 1), 6)),
        float(np.round(rng.uniform(0.3, 4.0), 6)),
    ]
    fx, fy, cx, cy = (float(np.round(rng.uniform(lo, hi), 3)) for lo, hi in _INTRINSICS)
    return {"X": X, "fx": fx, "fy": fy, "cx": cx, "cy": cy}


def _jac_vector_cases() -> list[Case]:
    """Two fixed cameras (a point on the optical axis among them) and four seeded random points."""
    fixed = [
        {"X": [0.1, -0.2, 1.5], "fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5},
        {"X": [0.0, 0.0, 1.0], "fx": 500.0, "fy": 480.0, "cx": 320.0, "cy": 240.0},
    ]
    rng = np.random.default_rng(6)
    inputs = fixed + [draw_point(rng) for _ in range(4)]
    return [Case(f"point{i}", inp) for i, inp in enumerate(inputs)]


PROJECTION_JACOBIAN = Problem(
    "projection_jacobian",
    "The Jacobian of the pinhole projection",
    ("J",),
    _jac_reference,
    rtol=1e-9,
    atol=1e-9,
    public=lambda: [
        {"X": [1.0, 2.0, 4.0], "fx": 100.0, "fy": 100.0, "cx": 0.0, "cy": 0.0},
        {"X": [-0.3, 0.25, 1.5], "fx": 525.0, "fy": 520.0, "cx": 319.5, "cy": 239.5},
    ],
    hidden=lambda rng: [draw_point(rng) for _ in range(3)],
    vector_cases=_jac_vector_cases,
    vector_tolerance=(1e-12, 1e-12),
    mistakes=(("jacobian-no-focal", _jac_no_focal),),
)
