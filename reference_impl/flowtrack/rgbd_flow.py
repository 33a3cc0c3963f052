r"""Dense scene flow from two RGB-D frames: a variational estimator in the spirit of PD-Flow, started
from matches.

:func:`rgbd_scene_flow` estimates the 3-D velocity of every pixel of frame :math:`t` from the colour
(grey) images *and* the depth maps of two frames, with no correspondences given: the syllabus'
brightness constancy and depth constancy (section 2), tied to the 3-D motion by the projection
Jacobian, plus a smoothness term (section 3). The design follows PD-Flow (Jaimez, Souiai,
González-Jiménez and Cremers, ICRA 2015): photometric and geometric data terms, robust penalties,
smoothing weighted down across depth edges, warping. A linearised data term only sees a displacement
of a pixel or two, and next to a silhouette it can pull a point onto the surface behind; so, as in
large-displacement variational flow (Brox and Malik, LDOF, 2011), the refinement starts from, and is
tied to, a field of *matches* found by search (:mod:`flowtrack._rgbd_match`, the rigid motions of the
depth segments :mod:`flowtrack._rgbd_segments`).

The unknown
-----------
Per pixel :math:`p` of frame :math:`t` with valid depth :math:`Z_p` the point is
:math:`X_p = Z_p\,((x_p - c_x)/f_x,\ (y_p - c_y)/f_y,\ 1)^\top` and the unknown is its displacement
over the frame interval, :math:`s_p = v_p\,\Delta t` (metres; the returned velocity is
:math:`v = s/\Delta t`). At :math:`t + \Delta t` the point is :math:`X_p + s_p` and its image is
:math:`\pi(X_p + s_p) = x_p + u_p`, so the optical flow is :math:`u_p = \pi(X_p + s_p) - \pi(X_p)`.

The robust RGB-D energy
-----------------------
With :math:`I_0, I_1` the grey images and :math:`D_1` the depth map at :math:`t + \Delta t`,

.. math::

    E(s) = \sum_p m_p \Big[\rho_I\Big(\frac{I_1(\pi(X_p + s_p)) - I_0(p)}{\sigma_I}\Big)
           + \rho_D\Big(\frac{D_1(\pi(X_p + s_p)) - (Z_p + s_{p,z})}{\sigma_D(Z_p)}\Big)\Big]
           + \sum_p c_p\,\rho_M\big(\lVert \Sigma_p^{-1/2}(s_p - \hat s_p)\rVert\big)
           + \lambda \sum_{(p,q)\in\mathcal E} w_{pq}\,
             \rho_S\Big(\frac{\lVert s_p - s_q\rVert}{\sigma_S}\Big),

- the photometric term is brightness constancy :math:`I_1(x + u) = I_0(x)` (after the brightness
  change between the frames is removed, see below);
- the geometric term is depth constancy in its corrected form :math:`D_1(x + u) = D_0(x) + v_Z\,\Delta t`
  (range flow: the depth seen at the new image position is the old depth plus the motion along the
  optical axis), its scale the depth noise of a disparity-based sensor,
  :math:`\sigma_D(Z) = \sqrt{\sigma_d^2 + (\sigma_{d2} Z^2)^2}` (``sigma_d``, ``sigma_d_z2``);
- the match term ties :math:`s_p` to the matched displacement :math:`\hat s_p` (LDOF's matching
  term), :math:`\Sigma_p = \mathrm{diag}(\sigma_\perp^2, \sigma_\perp^2, 2\sigma_D^2)` with
  :math:`\sigma_\perp = \sigma_m Z_p / f` (a match is good to ``sigma_m`` pixels across the ray and to
  the noise of two depths along it), :math:`c_p` = ``match_weight`` where the pixel is matched, 0
  where it is not, ``hidden_weight`` where it is hidden (below);
- :math:`\mathcal E` are the 4-neighbour edges, and :math:`w_{pq} = 1 / (1 + \lVert X_p - X_q\rVert^2 /
  d_{pq}^2)` weighs smoothing down across depth edges (an inverse 3-D neighbour distance, PD-Flow's
  choice in a smooth form), :math:`d_{pq} = \kappa\,\bar Z_{pq} / f + 2\sigma_D` the distance expected
  between neighbours on one surface (``edge_scale`` :math:`= \kappa`);
- :math:`\rho(x) = 2(\sqrt{1 + x^2} - 1)` (Charbonnier: :math:`\approx x^2` for small :math:`x`,
  :math:`\approx 2|x|`, i.e. L1 / TV, for large) or :math:`\rho(x) = x^2` (``penalty="quadratic"``);
- :math:`m_p \in \{0, 1\}` switches the data terms off where they cannot hold: depth at :math:`t`
  invalid (the pixel then has no point and is filled by smoothing only, its output is NaN), the warped
  position outside the image, and, for the geometric term, no valid depth under
  :math:`\pi(X_p + s_p)` at :math:`t + \Delta t` or a depth edge there. A pixel whose warped depth is
  clearly *in front* of the moved point (:math:`D_1 < Z + s_z - \tau`, the point is hidden at
  :math:`t + \Delta t`) is occluded: both data terms are off there. With ``truncate_depth`` the
  geometric term is also off where the warped depth is clearly *behind* the moved point
  (:math:`D_1 > Z + s_z + \tau`): the point cannot be there, and a depth term would drag it onto the
  background — the silhouette failure of a linearised depth term. :math:`\tau` = ``occlusion`` plus
  twice the growth of :math:`\sigma_D` with depth. A pixel the matching found *hidden* at
  :math:`t + \Delta t` (or leaving the image) has no data term at all.

The start: matches
------------------
``init="matches"`` (the default; :mod:`flowtrack._rgbd_match`): OpenCV's DIS optical flow and a coarse
exhaustive block search on the grey and log-depth images, both directions, the candidate with the lowest
matching cost per pixel; a pixel is *matched* where that cost is low, its neighbourhood textured, the
forward-backward check passes and it is not on a depth edge; it is lifted to 3-D with the depth at
:math:`t + \Delta t` read at :math:`x + u` (of the four pixels around it, the one nearest its own
depth). Then every depth-connected segment of frame :math:`t` is aligned rigidly (six parameters, robust
photometric and geometric residuals, Gauss–Newton coarse to fine, :mod:`flowtrack._rgbd_segments`,
started from its matches and from the best shift of the whole segment searched as one template, which
finds it by its outline when none of its pixels matches): a pixel takes its segment's rigid motion where
that fits it at least about as well as its own match — the motion of a nearly uniform or turning face,
which no pixel can match alone. Every pixel still without a match takes the displacement of the
geodesically nearest matched pixel, the path length counting depth jumps (so a hidden pixel moves with
its own surface). That field starts the refinement on the ``levels`` finest pyramid levels; the match
term keeps the refinement near it. ``init="zero"`` is the classic coarse-to-fine scheme from zero
displacement on every level that fits (large motions and the silhouette failure above are then out of
reach); ``init`` may also be an (H, W, 3) array of velocities (NaN: unknown) used as the match.

Brightness changes
------------------
The gain and offset between the frames, :math:`I_1(x + u) \approx a I_0(x) + b`, are fitted robustly
on the pixels matched with a low cost (the matching cost itself subtracts local means and does not
see a global change), and :math:`I_1` is replaced by :math:`(I_1 - b)/a`. With ``structure_sigma``
:math:`> 0` both images are also replaced by their texture, :math:`I - G_\sigma * I` (the
structure-texture split of Wedel et al., 2009): the shading of a turning face changes, its texture
does not.

Linearisation
-------------
Around the current estimate :math:`s^0` (the warp), with :math:`X' = X + s^0`,
:math:`J = \partial\pi/\partial X\,(X')` (:func:`flowtrack.camera.projection_jacobian`; at
:math:`s^0 = 0` this is the syllabus' :math:`u = J(X)\,v\,\Delta t`) and the images and their
gradients sampled at :math:`\pi(X')`:

.. math::

    I_1(\pi(X + s)) - I_0 &\approx r_I + a_I^\top (s - s^0), \qquad a_I = J^\top \nabla I, \\
    D_1(\pi(X + s)) - Z - s_z &\approx r_D + a_D^\top (s - s^0), \qquad a_D = J^\top \nabla D_1 - e_z,

with :math:`r_I, r_D` the residuals at :math:`s^0` and :math:`\nabla I` the mean of the gradients of
:math:`I_0` and of the warped :math:`I_1`. Each pixel's data term is then quadratic in :math:`s_p`
with the 3×3 normal matrix :math:`N_p = c_I a_I a_I^\top + c_D a_D a_D^\top`
(:func:`pixel_normal_equations`): rank at most 2, two equations for three unknowns, its null space
the 3-D aperture direction :math:`a_I \times a_D`; only the smoothness term fixes that component.

Discretisation and solver
-------------------------
The robust penalties are handled by iteratively reweighted least squares (the lagged-nonlinearity
scheme of Brox et al., 2004): with the weights
:math:`c = \rho'(x)/(2x\sigma^2) = 1/(\sigma^2\sqrt{1 + x^2})` of the current iterate, a quadratic
majoriser of :math:`E` is minimised, which is the sparse symmetric positive definite system

.. math::  (N_p + C_p + \lambda \textstyle\sum_q W_{pq})\, s_p - \lambda \sum_q W_{pq}\, s_q
           = N_p s^0_p - g_p + C_p \hat s_p \quad \text{for every pixel } p, \qquad
           g_p = c_I r_I a_I + c_D r_D a_D,

:math:`C_p` the (diagonal) reweighted match term, :math:`W_{pq} = w_{pq} c_{S,pq}` — an edge-weighted
grid Laplacian
(:func:`flowtrack.variational.grid_laplacian`) coupling 3×3 blocks. It is solved by conjugate
gradients preconditioned with the 3×3 block diagonal (each block inverted in closed form), warm-started
from the current iterate, ``cg_iterations`` iterations per reweighting. (Red-black Gauss–Seidel, the
solver of :func:`flowtrack.variational.red_black_sweep`, was tried first: the smoothness makes the
system stiff, :math:`\lambda/\sigma_S^2 \gg c_I |a_I|^2`, and Gauss–Seidel needs
:math:`O(\kappa)` sweeps for the smooth, near-constant error modes — a uniform translation hardly
moved at the coarse levels — where CG needs :math:`O(\sqrt\kappa)`.)

Coarse-to-fine: the images are blurred and halved (depth: the mean of the valid pixels of each 2×2
block), ``levels`` levels (from zero: until the short side would drop below ``min_size``); the match
field is carried down as confidence-weighted block means. At level :math:`\ell` the camera is
:math:`f/2^\ell,\ (c + 1/2)/2^\ell - 1/2`. The displacement is in metres, so it is carried from level
to level by bilinear interpolation without rescaling. Each level runs ``warps`` warps (images and
depth resampled at :math:`\pi(X + s^0)` — the exact projection, not the linearised one — then
``irls`` reweightings of ``cg_iterations`` CG iterations each). The inner loops are compiled with
numba (:mod:`flowtrack._rgbd_kernels`); ``backend="numpy"`` runs the same iterations vectorised.

Invalid depth
-------------
0, NaN and inf depths are invalid. An invalid pixel of frame :math:`t` has no data term, and its
edges are weighted by a small constant (``0.05``), so it is filled in by its neighbours but hardly
couples them; its output is NaN. Nothing is ever computed from a NaN: invalid depths are replaced
by 0 and masked before any arithmetic, so the output at valid pixels is finite.

Examples
--------
A fronto-parallel textured plane 1 m away moving sideways by 5 mm per frame:

>>> import numpy as np
>>> from flowtrack.camera import PinholeCamera
>>> cam = PinholeCamera(200.0, 200.0, 39.5, 29.5)
>>> yy, xx = np.mgrid[0:60, 0:80]
>>> tex = lambda x: 0.5 + 0.2 * np.sin(x[0] / 3.0) * np.cos(x[1] / 4.0)
>>> I0 = tex(((xx - 39.5) / 200.0 * 200, yy))
>>> I1 = tex(((xx - 39.5) / 200.0 * 200 - 1.0, yy))   # 5 mm at 1 m = 1 px to the right
>>> D = np.ones((60, 80))
>>> v = rgbd_scene_flow(I0, D, I1, D, cam, dt=0.1)
>>> np.round(np.median(v[10:-10, 10:-10].reshape(-1, 3), axis=0), 3) + 0.0
array([0.05, 0.  , 0.  ])
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ._rgbd_energy import Linearised, depth_sigma, pcg
from ._rgbd_match import geodesic_fill, match_field
from ._rgbd_segments import rigid_field
from ._validation import nonnegative, positive, positive_int
from .camera import PinholeCamera, check_camera

__all__ = [
    "BACKENDS",
    "PENALTIES",
    "grey_image",
    "pixel_normal_equations",
    "rgbd_point_flow",
    "rgbd_scene_flow",
]

PENALTIES = ("charbonnier", "quadratic")

#: weight of the smoothness edges that touch a pixel without depth at t
_HOLE_EDGE_WEIGHT = 0.05
#: pyramid levels refined from a match (``levels=None``): the match is good to a pixel or two
_MATCHED_LEVELS = 2
#: images with a shorter side start from zero: DIS's 8 px patches and the block search's windows
#: need more pixels per object than so small an image has (OpenCV's DIS itself needs 12 px)
_MIN_MATCH_SIZE = 64

_DEFAULTS = {
    "lam": None,
    "sigma_i": 0.02,
    "sigma_d": 0.004,
    "sigma_d_z2": None,
    "sigma_s": None,
    "edge_scale": 3.0,
    "occlusion": 0.02,
    "penalty": "charbonnier",
    "levels": None,
    "min_size": 6,
    "warps": None,
    "irls": 2,
    "cg_iterations": 15,
    "blur": 0.8,
    "use_depth": True,
    "use_color": True,
    "init": "matches",
    "match_weight": 1.0,
    "sigma_m": 1.0,
    "truncate_depth": None,
    "depth_filter": None,
    "fill_depth_scale": 0.005,
    "fill_grey_scale": 1.0,
    "hidden_weight": 0.1,
    "fill_reach": 50.0,
    "rigid": True,
    "structure_sigma": 0.0,
    "rigid_margin": 0.5,
    "rigid_prior": 1e-2,
    "rigid_still": 0.2,
    "rigid_agree_px": 0.5,
    "rigid_levels": 4,
    "rigid_min_pixels": 40,
    "rigid_max_pixels": 1500,
    "match_window": 7,
    "match_depth_weight": 0.05,
    "match_depth_trunc": 0.1,
    "search_radius": 28,
    "match_cost": 3.0,
    "match_fb": 1.0,
    "match_sure": 1.5,
    "match_margin": 0.002,
    "match_max_dz": 0.1,
    "match_texture": 0.3,
    "backend": "auto",
    "return_info": False,
}

#: defaults that depend on the start: from matches they were chosen on the training split of the
#: held-out protocol (benchmarks/_evalscenes.py); from zero they are the classic coarse-to-fine
#: estimator's, chosen on flowtrack.synth scenes
_FROM_MATCHES = {"lam": 0.2, "sigma_s": 0.0005, "warps": 2, "truncate_depth": True, "sigma_d_z2": 0.0015,
                 "depth_filter": True}
_FROM_ZERO = {"lam": 0.05, "sigma_s": 0.001, "warps": 3, "truncate_depth": False, "sigma_d_z2": 0.0,
              "depth_filter": False}

BACKENDS = ("auto", "numba", "numpy")
INITS = ("zero", "matches")
_KERNELS: list = []


def _kernels():
    """The numba kernels (:mod:`flowtrack._rgbd_kernels`), or None without numba; imported once."""
    if not _KERNELS:
        try:
            from . import _rgbd_kernels
        except ImportError:  # pragma: no cover - numba is a dependency; this is the documented fallback
            _rgbd_kernels = None
        _KERNELS.append(_rgbd_kernels)
    return _KERNELS[0]


# --------------------------------------------------------------------------------------------------
# per-pixel data term
# --------------------------------------------------------------------------------------------------
def _jt(X, gx, gy, fx, fy):
    r"""``J(X)^T (gx, gy)`` for the projection Jacobian at points ``X`` (..., 3); returns (..., 3)."""
    iz = 1.0 / X[..., 2]
    a = np.empty(X.shape)
    a[..., 0] = fx * gx * iz
    a[..., 1] = fy * gy * iz
    a[..., 2] = -(fx * gx * X[..., 0] + fy * gy * X[..., 1]) * iz * iz
    return a


def pixel_normal_equations(X, grad_i, r_i, grad_d, r_d, cam: PinholeCamera, w_i=1.0, w_d=1.0):
    r"""The linearised data term of pixels: its 3×3 normal matrix and right-hand side.

    For a point :math:`X` (camera frame at :math:`t`, already moved by the current estimate) the data
    term linearised in the displacement increment :math:`\delta` is

    .. math::  E_p(\delta) = w_I\,(r_I + a_I^\top\delta)^2 + w_D\,(r_D + a_D^\top\delta)^2, \qquad
               a_I = J^\top \nabla I, \quad a_D = J^\top \nabla D - e_z,

    with :math:`J = \partial\pi/\partial X` (:func:`flowtrack.camera.projection_jacobian`),
    :math:`\nabla I, \nabla D` the image gradients (per pixel) and :math:`r_I, r_D` the photometric
    and geometric residuals. :math:`\nabla E_p = 0` is :math:`N\delta = b` with

    .. math::  N = w_I a_I a_I^\top + w_D a_D a_D^\top, \qquad b = -(w_I r_I a_I + w_D r_D a_D).

    :math:`N` has rank at most 2: two equations, three unknowns. Its null space is spanned by
    :math:`a_I \times a_D`, the motion neither term sees (the aperture problem in 3-D).

    Parameters
    ----------
    X : array_like, shape (..., 3)
        Points, Z > 0.
    grad_i, grad_d : array_like, shape (..., 2)
        :math:`(\partial_x I, \partial_y I)` (grey per pixel) and :math:`(\partial_x D, \partial_y D)`
        (metres per pixel) at the warped positions.
    r_i, r_d : array_like, shape (...)
        Residuals :math:`I_1(\pi(X)) - I_0` and :math:`D_1(\pi(X)) - Z`.
    cam : PinholeCamera
    w_i, w_d : float or array_like, shape (...)
        Weights (e.g. :math:`1/\sigma_I^2`, :math:`1/\sigma_D^2`), >= 0.

    Returns
    -------
    N : ndarray, shape (..., 3, 3)
    b : ndarray, shape (..., 3)

    Examples
    --------
    >>> from flowtrack.camera import PinholeCamera
    >>> cam = PinholeCamera(100.0, 100.0, 0.0, 0.0)
    >>> N, b = pixel_normal_equations([0.0, 0.0, 1.0], [1.0, 0.0], 0.5, [0.0, 0.0], 0.0, cam)
    >>> N + 0.0   # x from the photometric term (100 px per metre, squared), z from the geometric one
    array([[1.e+04, 0.e+00, 0.e+00],
           [0.e+00, 0.e+00, 0.e+00],
           [0.e+00, 0.e+00, 1.e+00]])
    >>> b + 0.0
    array([-50.,   0.,   0.])
    """
    cam = check_camera(cam)
    X = np.asarray(X, dtype=np.float64)
    if X.ndim < 1 or X.shape[-1] != 3:
        raise ValueError(f"X must have shape (..., 3), got {X.shape}")
    if not np.isfinite(X).all() or (X[..., 2] <= 0).any():
        raise ValueError("X must be finite with Z > 0")
    batch = X.shape[:-1]
    gi = np.asarray(grad_i, dtype=np.float64)
    gd = np.asarray(grad_d, dtype=np.float64)
    for name, g in (("grad_i", gi), ("grad_d", gd)):
        if g.shape != (*batch, 2):
            raise ValueError(f"{name} must have shape {(*batch, 2)}, got {g.shape}")
    ri = np.broadcast_to(np.asarray(r_i, dtype=np.float64), batch)
    rd = np.broadcast_to(np.asarray(r_d, dtype=np.float64), batch)
    wi = np.broadcast_to(np.asarray(w_i, dtype=np.float64), batch)
    wd = np.broadcast_to(np.asarray(w_d, dtype=np.float64), batch)
    if (wi < 0).any() or (wd < 0).any():
        raise ValueError("w_i and w_d must be >= 0")
    a_i = _jt(X, gi[..., 0], gi[..., 1], cam.fx, cam.fy)
    a_d = _jt(X, gd[..., 0], gd[..., 1], cam.fx, cam.fy)
    a_d[..., 2] -= 1.0
    N = wi[..., None, None] * a_i[..., :, None] * a_i[..., None, :]
    N = N + wd[..., None, None] * a_d[..., :, None] * a_d[..., None, :]
    b = -((wi * ri)[..., None] * a_i + (wd * rd)[..., None] * a_d)
    return N, b


# --------------------------------------------------------------------------------------------------
# image helpers
# --------------------------------------------------------------------------------------------------
def grey_image(img, name: str = "img") -> np.ndarray:
    """A colour or grey image as float64 grey levels: uint8 in [0, 1] (RGB or RGBA by the ITU-R 601
    luma weights 0.299, 0.587, 0.114; grey divided by 255), float as it is.

    >>> grey_image(np.array([[[255, 255, 255], [255, 0, 0]]], dtype=np.uint8)).round(3).tolist()
    [[1.0, 0.299]]
    """
    a = np.asarray(img)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        g = a[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    elif a.ndim == 2:
        g = a.astype(np.float64)
    else:
        raise ValueError(f"{name} must be an image of shape (H, W, 3) or (H, W), got {a.shape}")
    return g / 255.0 if a.dtype == np.uint8 else g


def _down(a: np.ndarray) -> np.ndarray:
    """2×2 block sums of an (H, W, ...) array, padding odd sizes by repeating the last row/column."""
    H, W = a.shape[:2]
    if H % 2:
        a = np.concatenate([a, a[-1:]], axis=0)
    if W % 2:
        a = np.concatenate([a, a[:, -1:]], axis=1)
    return a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]


def _down_depth(D: np.ndarray) -> np.ndarray:
    """Mean of the valid (> 0) depths of each 2×2 block, 0 where none is valid."""
    s = _down(D)
    n = _down((D > 0).astype(np.float64))
    return np.where(n > 0, s / np.maximum(n, 1.0), 0.0)


def _grad(a: np.ndarray):
    """Central differences along x (columns) and y (rows); one-sided at the border."""
    gx = np.empty_like(a)
    gy = np.empty_like(a)
    gx[:, 1:-1] = 0.5 * (a[:, 2:] - a[:, :-2])
    gx[:, 0] = a[:, 1] - a[:, 0]
    gx[:, -1] = a[:, -1] - a[:, -2]
    gy[1:-1] = 0.5 * (a[2:] - a[:-2])
    gy[0] = a[1] - a[0]
    gy[-1] = a[-1] - a[-2]
    return gx, gy


def _sample(stack: np.ndarray, x: np.ndarray, y: np.ndarray):
    """Bilinear samples of ``stack (H, W, C)`` at float pixel positions; (values (..., C), inside)."""
    H, W = stack.shape[:2]
    inside = (x >= 0) & (y >= 0) & (x <= W - 1) & (y <= H - 1)
    xc = np.clip(x, 0, W - 1)
    yc = np.clip(y, 0, H - 1)
    x0 = np.minimum(np.floor(xc).astype(np.intp), max(W - 2, 0))
    y0 = np.minimum(np.floor(yc).astype(np.intp), max(H - 2, 0))
    ax = (xc - x0)[..., None]
    ay = (yc - y0)[..., None]
    x1 = np.minimum(x0 + 1, W - 1)
    y1 = np.minimum(y0 + 1, H - 1)
    top = stack[y0, x0] * (1 - ax) + stack[y0, x1] * ax
    bot = stack[y1, x0] * (1 - ax) + stack[y1, x1] * ax
    return top * (1 - ay) + bot * ay, inside


# --------------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------------
def _check_image(img, name):
    arr = np.asarray(img)
    if arr.dtype == np.uint8:
        if arr.ndim != 3 or arr.shape[2] != 3:
            raise ValueError(f"{name} must be uint8 (H, W, 3) RGB or float grey (H, W), "
                             f"got uint8 {arr.shape}")
    elif np.issubdtype(arr.dtype, np.floating):
        if arr.ndim != 2:
            raise ValueError(f"{name} must be float grey (H, W) or uint8 (H, W, 3) RGB, "
                             f"got float {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"{name} contains NaN or inf")
    else:
        raise ValueError(f"{name} must be uint8 (H, W, 3) RGB or float grey (H, W), got dtype {arr.dtype}")
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise ValueError(f"{name} must be at least 2×2 pixels, got {arr.shape}")
    return arr


def _check_depth(depth, name, shape):
    arr = np.asarray(depth)
    if not np.issubdtype(arr.dtype, np.floating):
        raise ValueError(f"{name} must be float depth in metres, shape {shape}, got dtype {arr.dtype}")
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape} (the image's), got {arr.shape}")
    arr = arr.astype(np.float64)
    valid = np.isfinite(arr) & (arr > 0)
    with np.errstate(invalid="ignore"):
        if (arr < 0).any():
            raise ValueError(f"{name} must be >= 0 (0, NaN or inf mark invalid pixels)")
    if not valid.any():
        raise ValueError(f"{name} has no valid depth (every pixel is 0, NaN or inf)")
    return np.where(valid, arr, 0.0)


def _options(options):
    unknown = set(options) - set(_DEFAULTS)
    if unknown:
        raise TypeError(f"rgbd_scene_flow got unknown option(s) {sorted(unknown)}; "
                        f"known: {sorted(_DEFAULTS)}")
    o = {**_DEFAULTS, **options}
    # the defaults that depend on the start (None: not given)
    by_start = _FROM_ZERO if isinstance(o["init"], str) and o["init"] == "zero" else _FROM_MATCHES
    for k, v in by_start.items():
        if o[k] is None:
            o[k] = v
    # lam = 0 leaves every pixel's aperture null space (rank-2 data term) unresolved: a singular system
    o["lam"] = positive(o["lam"], "lam")
    for k in ("sigma_i", "sigma_d", "sigma_s", "edge_scale", "occlusion"):
        o[k] = positive(o[k], k)
    o["blur"] = nonnegative(o["blur"], "blur")
    o["structure_sigma"] = nonnegative(o["structure_sigma"], "structure_sigma")
    o["match_weight"] = nonnegative(o["match_weight"], "match_weight")
    o["sigma_d_z2"] = nonnegative(o["sigma_d_z2"], "sigma_d_z2")
    o["sigma_m"] = positive(o["sigma_m"], "sigma_m")
    o["hidden_weight"] = nonnegative(o["hidden_weight"], "hidden_weight")
    for k in ("match_depth_weight", "search_radius", "match_texture", "match_margin"):
        o[k] = nonnegative(o[k], k)
    for k in ("match_depth_trunc", "match_cost", "match_fb", "match_sure", "match_max_dz", "fill_depth_scale",
              "fill_grey_scale", "fill_reach"):
        o[k] = positive(o[k], k)
    o["match_window"] = positive_int(o["match_window"], "match_window")
    if o["penalty"] not in PENALTIES:
        raise ValueError(f"penalty must be one of {PENALTIES}, got {o['penalty']!r}")
    if o["levels"] is not None:
        o["levels"] = positive_int(o["levels"], "levels")
    o["min_size"] = positive_int(o["min_size"], "min_size", minimum=2)
    for k in ("warps", "irls", "cg_iterations"):
        o[k] = positive_int(o[k], k)
    for k in ("use_depth", "use_color", "return_info", "truncate_depth", "rigid", "depth_filter"):
        if not isinstance(o[k], (bool, np.bool_)):
            raise TypeError(f"{k} must be a bool, got {type(o[k]).__name__}")
    if o["backend"] not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {o['backend']!r}")
    if o["backend"] == "numba" and _kernels() is None:
        raise ValueError("backend='numba' needs numba, which is not importable")
    if isinstance(o["init"], str):
        if o["init"] not in INITS:
            raise ValueError(f"init must be one of {INITS} or an (H, W, 3) velocity array, got {o['init']!r}")
    else:
        init = np.asarray(o["init"])
        if init.ndim != 3 or init.shape[2] != 3 or not np.issubdtype(init.dtype, np.number):
            raise ValueError(f"init must be one of {INITS} or an (H, W, 3) velocity array, got {init.shape}")
    if not (o["use_depth"] or o["use_color"]):
        raise ValueError("use_depth and use_color cannot both be False (no data term)")
    return o


# --------------------------------------------------------------------------------------------------
# the estimator
# --------------------------------------------------------------------------------------------------
def _pyramid(I0, D0, I1, D1, cam, levels):
    pyr = []
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    for lev in range(levels):
        if lev > 0:
            I0 = _down(ndimage.gaussian_filter(I0, 1.0, mode="nearest")) / 4.0
            I1 = _down(ndimage.gaussian_filter(I1, 1.0, mode="nearest")) / 4.0
            D0, D1 = _down_depth(D0), _down_depth(D1)
            fx, fy, cx, cy = fx / 2, fy / 2, (cx + 0.5) / 2 - 0.5, (cy + 0.5) / 2 - 0.5
        pyr.append((I0, D0, I1, D1, (fx, fy, cx, cy)))
    return pyr


def _n_levels(H, W, min_size, levels):
    n = 1
    while min(H, W) / 2**n >= min_size:
        n += 1
    return n if levels is None else min(levels, n)


def _upsample(s, shape):
    """Bilinear resampling of a level's displacement (h, w, 3) onto the next finer grid (H, W)."""
    H, W = shape
    h, w = s.shape[:2]
    y = np.clip((np.arange(H) - 0.5) / 2.0, 0, h - 1)
    x = np.clip((np.arange(W) - 0.5) / 2.0, 0, w - 1)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    out, _ = _sample(s, xx, yy)
    return out


def _initial_match(init, shape, dt):
    """An explicit initial velocity field as a match: (H, W, 3) velocities, NaN where unknown."""
    v = np.asarray(init, dtype=np.float64)
    ok = np.isfinite(v).all(axis=-1)
    return {"m": np.where(ok[..., None], v * dt, 0.0), "conf": ok.astype(np.float64),
            "hidden": np.zeros(shape, bool)}


def _match_pyramid(target, weight, hidden, n):
    """Match targets, weights and hidden masks on every level (weighted 2×2 means; hidden: majority)."""
    out = [(target, weight, hidden)]
    h = hidden.astype(np.float64)
    for _ in range(1, n):
        ws = _down(weight)
        target = np.where(ws[..., None] > 0,
                          _down(weight[..., None] * target) / np.maximum(ws, 1e-300)[..., None], 0.0)
        weight = ws / 4.0
        h = _down(h) / 4.0
        out.append((target, weight, h > 0.5))
    return out


def _filter_depth(D, o):
    """Each valid depth replaced by the mean of the valid depths of its 3×3 neighbourhood on the same
    surface (within the occlusion threshold of it). The noise of a single reading would otherwise
    favour sub-pixel shifts of a static surface: sampling a noisy depth map between pixels averages
    the noise down, so a depth term prefers to land between them."""
    valid = D > 0
    tau = o["occlusion"] + 2.0 * (depth_sigma(D, o) - o["sigma_d"])
    H, W = D.shape
    P = np.pad(D, 1)
    num = np.zeros((H, W))
    den = np.zeros((H, W))
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            q = P[dy:dy + H, dx:dx + W]
            w = (q > 0) & (np.abs(q - D) <= tau)
            num += np.where(w, q, 0.0)
            den += w
    return np.where(valid, num / np.maximum(den, 1.0), 0.0)


def _edge_weights(X, valid, intr, sigma_d, edge_scale):
    """w_pq = 1 / (1 + |X_p - X_q|^2 / d_pq^2); a small constant where an end has no depth."""
    f = 0.5 * (intr[0] + intr[1])
    out = []
    pairs = ((X[1:], X[:-1], valid[1:], valid[:-1]), (X[:, 1:], X[:, :-1], valid[:, 1:], valid[:, :-1]))
    for a, b, va, vb in pairs:
        d2 = np.sum((a - b) ** 2, axis=-1)
        zbar = 0.5 * (a[..., 2] + b[..., 2])
        ref = edge_scale * zbar / f + 2.0 * sigma_d
        w = 1.0 / (1.0 + d2 / ref**2)
        out.append(np.where(va & vb, w, _HOLE_EDGE_WEIGHT))
    return out


def _level(I0, D0, I1, D1, intr, s, o, match=None):
    H, W = I0.shape
    m_t, c_m, hidden = (None, None, None) if match is None else match
    if c_m is not None and not c_m.any():
        m_t = c_m = None
    K = None if o["backend"] == "numpy" else _kernels()
    fx, fy, cx, cy = intr
    valid0 = D0 > 0
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    Z = np.where(valid0, D0, 1.0)  # placeholder depth 1 at invalid pixels (never used: no data there)
    X = np.stack([(xx - cx) / fx * Z, (yy - cy) / fy * Z, Z], axis=-1)
    wv, wh = _edge_weights(X, valid0, intr, o["sigma_d"], o["edge_scale"])
    # depth noise of a disparity-based sensor grows with Z^2
    sig_d = depth_sigma(Z, o)
    tau_occ = o["occlusion"] + 2.0 * (sig_d - o["sigma_d"])
    sig_m = None
    if m_t is not None:
        # a match is good to sigma_m pixels across the ray; along it, to the noise of two depths
        lat = o["sigma_m"] * Z / (0.5 * (fx + fy))
        sig_m = np.stack([lat, lat, np.broadcast_to(np.sqrt(2.0) * sig_d, Z.shape)], axis=-1)
    I0x, I0y = _grad(I0)
    I1x, I1y = _grad(I1)
    valid1 = D1 > 0
    # the depth gradient is trusted where the 3×3 neighbourhood has depth and no edge
    ok1 = ndimage.minimum_filter(valid1.astype(np.uint8), size=3, mode="nearest").astype(bool)
    D1x, D1y = _grad(D1)
    edge = np.maximum(np.abs(D1x), np.abs(D1y)) > (o["edge_scale"] * D1 / (0.5 * (fx + fy)) * 2.0
                                                    + 3.0 * o["sigma_d"])
    ok1 &= ~ndimage.maximum_filter(edge, size=3, mode="nearest")
    stack = np.stack([I1, I1x, I1y, D1, D1x, D1y, ok1.astype(np.float64)], axis=-1)
    use_i = 1.0 if o["use_color"] else 0.0
    use_d = 1.0 if o["use_depth"] else 0.0
    for _ in range(o["warps"]):
        Xw = X + s
        Zw = np.maximum(Xw[..., 2], 1e-3 * Z)
        xw = fx * Xw[..., 0] / Zw + cx
        yw = fy * Xw[..., 1] / Zw + cy
        if K is None:
            smp, inside = _sample(stack, xw, yw)
        else:
            smp = np.empty((H, W, stack.shape[2]))
            inside = np.empty((H, W), dtype=np.bool_)
            K.sample(stack, xw, yw, smp, inside)
        inside &= valid0 & (Xw[..., 2] > 1e-3 * Z)
        Iw, Ixw, Iyw, Dw, Dxw, Dyw, okw = np.moveaxis(smp, -1, 0)
        ok_d = inside & (okw > 0.999)
        # occluded at t+1: something clearly in front of the moved point
        occluded = ok_d & (Dw < Zw - tau_occ)
        m_i = (inside & ~occluded) * use_i
        m_d = (ok_d & ~occluded) * use_d
        if hidden is not None:
            m_i = m_i * ~hidden
            m_d = m_d * ~hidden
        if o["truncate_depth"]:
            # a surface clearly behind the moved point: the warp is wrong there or the point is on a
            # silhouette; the depth term would drag it onto the background
            m_d = m_d * (Dw <= Zw + tau_occ)
        gx = 0.5 * (Ixw + I0x)
        gy = 0.5 * (Iyw + I0y)
        Xj = np.concatenate([Xw[..., :2], Zw[..., None]], axis=-1)
        a_i = _jt(Xj, gx, gy, fx, fy)
        a_d = _jt(Xj, np.where(ok_d, Dxw, 0.0), np.where(ok_d, Dyw, 0.0), fx, fy)
        a_d[..., 2] -= 1.0
        r_i = np.where(inside, Iw - I0, 0.0)
        r_d = np.where(ok_d, Dw - Zw, 0.0)
        prob = Linearised(s.copy(), a_i, r_i, m_i, a_d, r_d, m_d, wv, wh, o["lam"],
                           o["sigma_i"], sig_d, o["sigma_s"], o["penalty"],
                           m_t=m_t, c_m=c_m, sigma_m=sig_m)
        for _ in range(o["irls"]):
            if K is None:
                N, rhs, Wv, Wh = prob.system(s)
                pcg(N, rhs, Wv, Wh, s, o["cg_iterations"])
            else:
                c_i, c_d, Wv, Wh = prob.weights(s)
                M = np.empty((H, W, 6))
                rhs = np.empty((H, W, 3))
                K.assemble(a_i, a_d, c_i, c_d, r_i, r_d, prob.s0, Wv, Wh, M, rhs)
                prob.add_match(M, rhs, s)
                K.pcg(M, rhs, Wv, Wh, s, o["cg_iterations"])
    return s, prob


def _estimate(I0, D0, I1, D1, cam, o, match):
    """Coarse to fine from zero, or from a match: ``{"m": (H, W, 3) displacements (m), "conf": (H, W)
    confidence in [0, 1] (0: no match), "hidden": (H, W) bool (the point is hidden at t+1: no data
    term, the displacement of the nearest matched pixel of its surface)}``; returns (s, problem, levels)."""
    H, W = I0.shape
    levels = o["levels"]
    if levels is None and match is not None:
        levels = _MATCHED_LEVELS
    n = _n_levels(H, W, o["min_size"], levels)
    pyr = _pyramid(I0, D0, I1, D1, cam, n)
    mpyr = [None] * n
    s = None
    if match is not None:
        known = (match["conf"] > 0) & ~match["hidden"]
        sig_d = depth_sigma(D0, o)
        fill, dist = geodesic_fill(match["m"], known, D0, I0,
                                   depth_scale=o["fill_depth_scale"] + 2.0 * (sig_d - o["sigma_d"]),
                                   grey_scale=o["fill_grey_scale"], edge_jump=o["occlusion"],
                                   kernels=None if o["backend"] == "numpy" else _kernels())
        # a surface without any matched pixel within reach keeps its own (unconfident) match; a pixel
        # moved rigidly with its segment keeps that motion even where it has no data term
        keep = (dist > o["fill_reach"]) & ~match["hidden"]
        if "rigid" in match:
            keep |= match["rigid"]
        fill = np.where(keep[..., None], match["m"], fill)
        target = np.where(known[..., None], match["m"], fill)
        weight = (o["match_weight"] * np.where(known, match["conf"], 0.0)
                  + o["hidden_weight"] * match["hidden"])
        mpyr = _match_pyramid(target, weight, match["hidden"], n)
        match["init"] = fill
        s = fill
        for _ in range(n - 1):
            s = _down(s) / 4.0
    prob = None
    for lev in range(n - 1, -1, -1):
        Il0, Dl0, Il1, Dl1, intr = pyr[lev]
        h, w = Il0.shape
        if s is None:
            s = np.zeros((h, w, 3))
        elif s.shape[:2] != (h, w):
            s = _upsample(s, (h, w))
        s, prob = _level(Il0, Dl0, Il1, Dl1, intr, s, o, mpyr[lev])
    return s, prob, n


def rgbd_scene_flow(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options):
    r"""Dense 3-D velocities of the pixels of an RGB-D frame from it and the next frame.

    Finds a field of matches (optical flow by search, lifted with the depths; the rigid motion of each
    depth-connected surface), then minimises the energy of the module documentation (photometric +
    geometric data terms linearised through the projection Jacobian, a term tying the field to the
    matches, robust smoothness weighted down across depth edges) on the finest pyramid levels with
    warping, by IRLS and block-Jacobi preconditioned conjugate gradients.

    Parameters
    ----------
    rgb_t, rgb_t1 : ndarray
        uint8 (H, W, 3) RGB, or float grey (H, W) in [0, 1] (``sigma_i`` is on that scale); both the
        same kind.
    depth_t, depth_t1 : ndarray, float, shape (H, W)
        Depth Z in metres; 0, NaN or inf marks an invalid pixel.
    cam : PinholeCamera
        Intrinsics of the (registered) colour and depth images.
    dt : float, > 0
        Time between the frames (s).
    **options
        Where two defaults are given, the first applies from matches (chosen on the training split
        of ``benchmarks/_evalscenes.py``), the second with ``init="zero"`` (the classic estimator).

        *The start.* ``init`` (``"matches"``): ``"matches"``, ``"zero"`` (coarse to fine from zero
        displacement; by default an image under 64 px on a side starts from zero) or an (H, W, 3) array of
        velocities (m/s, NaN: unknown) used as the match. ``match_weight`` (1.0) and ``sigma_m``
        (1.0 px): weight and scale of the match term; ``hidden_weight`` (0.1): its weight at hidden
        pixels (tied to their surface's motion). ``rigid`` (True): move well-aligned depth segments
        rigidly. The matching's own thresholds (``search_radius`` 28 px, ``match_window``,
        ``match_depth_weight``, ``match_depth_trunc``, ``match_cost``, ``match_fb``, ``match_sure``,
        ``match_margin``, ``match_max_dz``, ``match_texture``; ``fill_depth_scale``,
        ``fill_grey_scale``, ``fill_reach``; ``rigid_margin``, ``rigid_agree_px``,
        ``rigid_prior``, ``rigid_still``, ``rigid_levels``, ``rigid_min_pixels``,
        ``rigid_max_pixels``) are documented in :mod:`flowtrack._rgbd_match` and
        :mod:`flowtrack._rgbd_segments`.

        *The energy.* ``lam`` (0.2 / 0.05): smoothness weight :math:`\lambda`, > 0 (without
        smoothing each pixel's data term has rank 2 and the system is singular: the aperture
        problem). ``sigma_i`` (0.02): photometric scale (grey levels in [0, 1]); residuals well above
        it are treated as outliers by the Charbonnier penalty. ``sigma_d`` (0.004 m) and
        ``sigma_d_z2`` (0.0015 / 0 m per m²): geometric scale :math:`\sigma_D(Z)`.
        ``sigma_s`` (0.0005 / 0.001 m): smoothness scale: neighbour displacement differences well
        above it are discontinuities. ``edge_scale`` (3.0): :math:`\kappa` of the edge weights
        :math:`w_{pq}`, in pixel footprints. ``occlusion`` (0.02 m): a warped depth this much in
        front of the moved point marks it occluded. ``truncate_depth`` (True / False): no geometric
        term where the warped depth is this much behind the moved point. ``penalty``
        (``"charbonnier"``): or ``"quadratic"`` (every term squared: the weights are constant and
        each warp minimises its linearised energy, up to the CG iterations). ``use_color``,
        ``use_depth`` (True): switch a data term off (ablation).

        *The images.* ``blur`` (0.8 px): Gaussian pre-smoothing of the images. ``structure_sigma``
        (0: off): replace both images by their texture :math:`I - G_\sigma * I`.
        ``depth_filter`` (True / False): replace each depth by the mean of its 3×3 neighbours on the
        same surface.

        *The solver.* ``levels`` (None: 2 from matches, as many as fit from zero): pyramid levels;
        ``min_size`` (6): smallest side of the coarsest level. ``warps`` (2 / 3), ``irls`` (2),
        ``cg_iterations`` (15): per level, warps; per warp, reweightings; per reweighting, CG
        iterations. ``backend`` (``"auto"``): ``"numba"`` (compiled loops,
        :mod:`flowtrack._rgbd_kernels`), ``"numpy"`` (vectorised, about 5x slower) or ``"auto"``
        (numba when importable). ``return_info`` (False): also return a dict with ``levels``, the
        finest level's linearised problem (``problem``, for tests and teaching) and the ``match``
        (its field ``m``, confidence ``conf``, ``hidden`` mask, optical ``flow``, brightness
        ``gain``, the segments and which pixels moved rigidly).

    Returns
    -------
    ndarray, shape (H, W, 3)
        Velocity (m/s) of each pixel's point, camera frame at t; NaN where ``depth_t`` is invalid.

    Raises
    ------
    ValueError
        Shapes that disagree, ``dt <= 0``, wrong dtypes or channel counts, negative depth, no valid
        depth (each names the argument).
    TypeError
        ``cam`` not a :class:`~flowtrack.camera.PinholeCamera`, unknown option.
    """
    I0 = _check_image(rgb_t, "rgb_t")
    I1 = _check_image(rgb_t1, "rgb_t1")
    if I1.dtype.kind != I0.dtype.kind or I1.shape != I0.shape:
        raise ValueError(f"rgb_t1 must be like rgb_t ({I0.dtype} {I0.shape}), got {I1.dtype} {I1.shape}")
    shape = I0.shape[:2]
    D0 = _check_depth(depth_t, "depth_t", shape)
    D1 = _check_depth(depth_t1, "depth_t1", shape)
    cam = check_camera(cam)
    if cam.width is not None and cam.height is not None and (cam.height, cam.width) != shape:
        raise ValueError(f"cam is for {cam.height}×{cam.width} images, the images are {shape[0]}×{shape[1]}")
    dt = positive(dt, "dt")
    if "init" not in options and min(shape) < _MIN_MATCH_SIZE:
        options = {**options, "init": "zero"}  # too small to match: the classic estimator
    o = _options(options)
    if not isinstance(o["init"], str) and np.shape(o["init"])[:2] != shape:
        raise ValueError(f"init must have shape {(*shape, 3)} (the image's), got {np.shape(o['init'])}")
    I0, I1 = grey_image(I0, "rgb_t"), grey_image(I1, "rgb_t1")
    if o["blur"] > 0:
        I0 = ndimage.gaussian_filter(I0, o["blur"], mode="nearest")
        I1 = ndimage.gaussian_filter(I1, o["blur"], mode="nearest")
    if o["depth_filter"]:
        D0, D1 = _filter_depth(D0, o), _filter_depth(D1, o)
    match = None
    if not isinstance(o["init"], str):
        match = _initial_match(o["init"], shape, dt)
    elif o["init"] == "matches":
        K = None if o["backend"] == "numpy" else _kernels()
        intr = (cam.fx, cam.fy, cam.cx, cam.cy)
        match = match_field(I0, D0, I1, D1, intr, o, K)
        a, b = match["gain"]
        I1n = (I1 - b) / a
        if o["structure_sigma"] > 0:
            # structure-texture split (Wedel et al. 2009): the shading of a turning face changes
            # between the frames, its texture does not; the photometric terms see the texture
            T0 = I0 - ndimage.gaussian_filter(I0, o["structure_sigma"], mode="nearest")
            T1 = I1n - ndimage.gaussian_filter(I1n, o["structure_sigma"], mode="nearest")
        else:
            T0, T1 = I0, I1n
        if o["rigid"]:
            pyr = _pyramid(T0, D0, T1, D1, cam, _n_levels(*shape, o["min_size"], o["rigid_levels"]))
            match = rigid_field(match, I0, D0, I1, D1, pyr, intr, o)
        I0, I1 = T0, T1
    s, prob, n = _estimate(I0, D0, I1, D1, cam, o, match)
    v = s / dt
    v[~(D0 > 0)] = np.nan
    if o["return_info"]:
        return v, {"levels": n, "problem": prob, "match": match}
    return v


def rgbd_point_flow(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options):
    r""":func:`rgbd_scene_flow` as point-cloud flow: the cloud of frame t and the velocity of each point.

    The cloud is the back-projection of ``depth_t`` at its valid pixels in row-major order, i.e.
    ``backproject(depth_t, cam)[valid]`` with ``valid = isfinite(depth_t) & (depth_t > 0)`` — the
    order of :attr:`flowtrack.synth.Frame.points` and of the demo's clouds — so the velocities line up
    with any subsample of it taken by index.

    Parameters
    ----------
    rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options
        As in :func:`rgbd_scene_flow`.

    Returns
    -------
    points : ndarray, shape (N, 3)
        Camera-frame points at t (metres), N = number of valid pixels of ``depth_t``.
    velocities : ndarray, shape (N, 3)
        Their velocities (m/s), finite.

    Examples
    --------
    >>> from flowtrack.synth import make_scene
    >>> scene = make_scene(n_objects=1, n_frames=2, image_size=(48, 64), seed=0)
    >>> f0, f1 = scene.frames
    >>> X, v = rgbd_point_flow(f0.rgb, f0.depth, f1.rgb, f1.depth, scene.camera, scene.dt)
    >>> bool(np.allclose(X, f0.points)) and v.shape == f0.gt_flow.shape
    True
    """
    v = rgbd_scene_flow(rgb_t, depth_t, rgb_t1, depth_t1, cam, dt, **options)
    if isinstance(v, tuple):  # return_info=True
        v = v[0]
    D0 = _check_depth(depth_t, "depth_t", v.shape[:2])
    valid = D0 > 0
    from .camera import backproject

    return backproject(D0, cam)[valid], v[valid]
