r"""Test-vector problems for the Java/OpenCV and Mathematica ports: Lucas–Kanade and scalar Riccati.

Both functions return JSON-plain dicts ``{"problem", "cases": [{"id", "input", "expected", "rtol",
"atol"}]}`` (floats, ints and lists only) and are deterministic; the vector registry of
:mod:`flowtrack_course.ports.vectors` writes them to ``cpp_java_matlab_ports/vectors/<problem>.json``.

``lucas_kanade``
    An image pair rendered by :func:`flowtrack.synth.make_scene`, feature points on the moving
    objects and the optical flow the reference predicts for them from the ground-truth scene flow.
    The prediction is the *exact* projection difference

    .. math::  u_i = \pi(X_i + v_i\,\Delta t) - \pi(X_i),

    with :math:`X_i` the noiseless surface point seen at the feature pixel in the first frame and
    :math:`v_i` its exact velocity, so :math:`X_i + v_i \Delta t` is where that material point is
    in the second frame (not the first-order :func:`flowtrack.camera.optical_flow_from_scene_flow`,
    whose linearisation error would be part of the tolerance otherwise).
``steady_state_scalar``
    The predicted steady-state variance of the scalar model :math:`x_t = f x_{t-1} + w`,
    :math:`z_t = h x_t + v`, :math:`w \sim \mathcal N(0, q)`, :math:`v \sim \mathcal N(0, r)`,
    in closed form (the positive root of the scalar Riccati equation).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["lucas_kanade", "steady_state_scalar", "select_lk_features", "scalar_riccati_P"]

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


def _lk_case(seed: int, image_size=(240, 320), dt: float = 0.1, margin: int = 16) -> dict:
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
    return {
        "id": f"synth_seed{seed}_{H}x{W}_cropped",
        "input": {
            "image0": g0[r0:r1, c0:c1].tolist(),
            "image1": g1[r0:r1, c0:c1].tolist(),
            "points": pts,
            "win_size": LK_WINDOW,
            "max_level": LK_MAX_LEVEL,
            "iterations": LK_ITERATIONS,
            "epsilon": LK_EPSILON,
        },
        "expected": {"flow": exp},
        "rtol": 0.0,
        "atol": LK_ATOL,
    }


def lucas_kanade() -> dict:
    r"""Test vectors for pyramidal Lucas–Kanade on rendered image pairs.

    Each case: ``input`` = ``image0``, ``image1`` (grey uint8 as nested lists of ints, shape
    ``(h, w)``, BT.601 luma of ``make_scene(n_objects=3, n_frames=2, image_size=(240, 320),
    noise=0, seed=s)``, cropped to the moving objects), ``points`` (K, 2) feature positions
    ``(x, y)`` = (column, row) in the cropped image (see :func:`select_lk_features`), and the LK
    settings ``win_size``, ``max_level``, ``iterations``, ``epsilon``. ``expected["flow"]`` (K, 2)
    is the exact projection difference ``(du, dv)`` of the ground-truth motion (module docstring).
    A port passes iff every point is tracked (status 1) and every component is within
    ``atol`` = 0.5 px of the prediction (``rtol`` = 0).

    Returns
    -------
    dict
        ``{"problem": "lucas_kanade", "cases": [...]}``.
    """
    return {"problem": "lucas_kanade", "cases": [_lk_case(seed) for seed in (0, 1, 2)]}


def scalar_riccati_P(f: float, h: float, q: float, r: float) -> float:
    r"""Predicted steady-state variance of the scalar Kalman filter, closed form.

    The fixed point of :math:`P \mapsto f^2 P - f^2 P^2 h^2 / (h^2 P + r) + q` satisfies
    :math:`h^2 P^2 + \beta P - q r = 0` with :math:`\beta = r (1 - f^2) - q h^2`; its positive root is

    .. math::  P = \frac{-\beta + \sqrt{\beta^2 + 4 h^2 q r}}{2 h^2}
                 = \frac{2 q r}{\beta + \sqrt{\beta^2 + 4 h^2 q r}},

    (the second form is used when :math:`\beta > 0`, avoiding cancellation).

    Parameters
    ----------
    f, h : float
        Transition and measurement coefficients, ``h != 0``.
    q, r : float
        Process and measurement noise variances, both > 0.

    Returns
    -------
    float

    Examples
    --------
    >>> print(f"{scalar_riccati_P(1.0, 1.0, 1.0, 1.0):.12f}")  # golden ratio
    1.618033988750
    """
    for name, val in (("f", f), ("h", h), ("q", q), ("r", r)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
            raise TypeError(f"{name}: expected a finite real number, got {val!r}")
    if h == 0:
        raise ValueError("h: must be non-zero (an unobserved state has no steady state unless |f| < 1)")
    if q <= 0 or r <= 0:
        raise ValueError(f"q, r: expected q > 0 and r > 0, got q={q!r}, r={r!r}")
    a = h * h
    beta = r * (1.0 - f * f) - q * a
    disc = math.sqrt(beta * beta + 4.0 * a * q * r)
    if beta > 0:
        return 2.0 * q * r / (beta + disc)
    return (-beta + disc) / (2.0 * a)


def steady_state_scalar() -> dict:
    r"""Test vectors for the steady-state variance of the scalar model.

    ``input`` = ``{"f", "h", "q", "r"}``; ``expected`` = ``{"P": predicted steady-state variance,
    "P_post": posterior variance P - P² h² / (h² P + r)}`` from :func:`scalar_riccati_P`. Cases: the
    random walk with ``q = r = 1`` (``P`` = golden ratio), a stable and an unstable ``f``, a small and
    a large noise ratio, and seeded random models.

    Returns
    -------
    dict
        ``{"problem": "steady_state_scalar", "cases": [...]}``.
    """
    models = [
        ("random_walk_unit", 1.0, 1.0, 1.0, 1.0),
        ("random_walk_q0.01_r4", 1.0, 1.0, 0.01, 4.0),
        ("stable_f0.5", 0.5, 1.0, 0.2, 1.0),
        ("unstable_f1.2_h2", 1.2, 2.0, 0.5, 3.0),
        ("precise_sensor", 1.0, 1.0, 10.0, 1e-4),
    ]
    rng = np.random.default_rng(6)
    for i in range(5):
        f = float(np.round(rng.uniform(-1.5, 1.5), 6))
        h = float(np.round(rng.uniform(0.2, 3.0), 6))
        q = float(np.round(10 ** rng.uniform(-2, 1), 6))
        r = float(np.round(10 ** rng.uniform(-2, 1), 6))
        models.append((f"random_{i}", f, h, q, r))
    cases = []
    for cid, f, h, q, r in models:
        P = scalar_riccati_P(f, h, q, r)
        P_post = P - P * P * h * h / (h * h * P + r)
        cases.append(
            {
                "id": cid,
                "input": {"f": f, "h": h, "q": q, "r": r},
                "expected": {"P": P, "P_post": P_post},
                "rtol": 1e-10,
                "atol": 1e-12,
            }
        )
    return {"problem": "steady_state_scalar", "cases": cases}
