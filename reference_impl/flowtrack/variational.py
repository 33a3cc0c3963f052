r"""Variational scene flow on the pixel grid (syllabus section 3, Problem 2).

The quadratic energy on the grid
--------------------------------
Let :math:`X_t, X_{t+1} : \Omega \to \mathbb{R}^3` be the point maps of two RGB-D frames on an
:math:`H \times W` pixel grid (shape ``(H, W, 3)``), :math:`m_p \in \{0, 1\}` a data mask
(1 where both depths are valid) and :math:`\mathcal{E}` the 4-neighbour edges of the grid. The
discrete counterpart of the syllabus' energy is

.. math::

    E(v) = \sum_p m_p \,\| X_t(p) + v(p)\,\Delta t - X_{t+1}(p) \|^2
           + \lambda \sum_{(p,q) \in \mathcal{E}} \| v(p) - v(q) \|^2 .

Each edge appears once. Since :math:`\sum_{(p,q)} (v_p - v_q)^2 = v^\top L v` with
:math:`L = L_{\text{grid}}` the grid-graph Laplacian (:func:`grid_laplacian`), setting
:math:`\nabla E = 0` gives, for each component :math:`k` separately (the syllabus' :math:`E_k`),

.. math::

    (\Delta t^2 M + \lambda L)\, v_k = \Delta t\, M\, (b_k - a_k), \qquad M = \operatorname{diag}(m),

with :math:`a_k, b_k` the k-th components of :math:`X_t, X_{t+1}`. This is the discrete
Euler–Lagrange equation :math:`\Delta t^2 v - \lambda_c \Delta v = \Delta t (b - a)` of Problem 2:
on a grid of spacing :math:`h`, :math:`-L v / h^2` is the 5-point Laplacian :math:`\Delta_h v` (and
its rows at the border are the ghost-cell Neumann condition :math:`\partial v / \partial n = 0`,
the natural boundary condition of the variational problem), and the discrete energy is
:math:`h^{-2}` times a Riemann sum of the continuous one with :math:`\lambda = \lambda_c / h^2`.

Internally the system is divided by :math:`\Delta t^2`,

.. math::  (M + \alpha L)\, v = M d, \qquad \alpha = \lambda / \Delta t^2, \quad
           d = (X_{t+1} - X_t) / \Delta t,

which has the same solution and the same relative residual.

Solvers
-------
``"dct"``
    Exact. :math:`L` is diagonalised by the orthonormal type-II DCT: with
    :math:`\mu_{kl} = (2 - 2\cos(\pi k/H)) + (2 - 2\cos(\pi l/W))` (computed as
    :math:`4\sin^2(\pi k / 2H) + 4 \sin^2(\pi l / 2W)`), :math:`\hat v_{kl} = \hat d_{kl} /
    (1 + \alpha \mu_{kl})`. Needs the full data term (:math:`M = I`); :math:`O(HW \log HW)`.
``"cg"``
    Jacobi-preconditioned conjugate gradients (:func:`scipy.sparse.linalg.cg`, ``rtol=tol``) on
    the assembled sparse system, all three components in one block-diagonal solve. Supports masks.
``"gauss_seidel"``
    Red-black Gauss–Seidel (:func:`red_black_sweep`), vectorised with checkerboard masks.

Agreement guarantee
-------------------
The iterative solvers stop when the relative residual
:math:`\|B - A V\|_F / \|B\|_F < \text{tol}` (``V, B`` of shape ``(HW, 3)``, :math:`A = M + \alpha L`);
the true residual is recomputed at the end and reported in ``info["residual"]``. Because
:math:`\|V - V^*\|_F \le \|A^{-1}\|_2 \|B - AV\|_F`, the error is at most
:math:`\text{tol}\,\|B\|_F / \lambda_{\min}(A)`. With the full data term :math:`\lambda_{\min}(A) = 1`
(the constant mode), so every method is within :math:`\text{tol}\,\|d\|_F` of the exact (DCT)
solution, :math:`d = (X_{t+1} - X_t)/\Delta t`, in the Frobenius norm. With a mask,
:math:`\lambda_{\min}(A)` can be small (large holes, small :math:`\alpha`) and the bound is weaker
by that factor.

Invalid depth and singular systems
----------------------------------
``X_t`` / ``X_t1`` may hold NaN where depth is invalid (as :func:`flowtrack.camera.backproject`
returns). The effective mask is ``mask & finite(X_t) & finite(X_t1)`` (all three components), so an
invalid pixel never contributes data; its flow is filled in by the smoothness term. inf is
rejected. ``method="dct"`` needs every pixel to carry data, so it raises ``ValueError`` when the
effective mask is not all ones (NaN in the input or a non-trivial ``mask``); use ``"cg"`` or
``"gauss_seidel"`` there.

The grid graph is connected, so for :math:`\lambda > 0` the matrix :math:`M + \alpha L` is positive
definite as soon as one pixel has data; with no data at all a ``ValueError`` is raised. For
:math:`\lambda = 0` the problem decouples per pixel: :math:`v = d` where there is data and NaN
(undetermined) elsewhere; every method returns this closed form without iterating.

Robust smoothness (Charbonnier)
-------------------------------
``regularizer="charbonnier"`` minimises

.. math::

    E_\psi(v) = \sum_p m_p \| X_t(p) + v(p)\Delta t - X_{t+1}(p) \|^2
                + \lambda \sum_{(p,q)} \psi\big(\|v(p) - v(q)\|^2\big), \qquad
    \psi(s^2) = 2\varepsilon^2 \Big(\sqrt{1 + s^2/\varepsilon^2} - 1\Big),

so :math:`\psi(s^2) \approx s^2` for :math:`s \ll \varepsilon` (quadratic) and
:math:`\psi(s^2) \approx 2 \varepsilon s` for :math:`s \gg \varepsilon` (total-variation-like: a
jump costs linearly, so it is not smeared out). Because :math:`\psi` is concave in :math:`s^2`,
:math:`\psi(s^2) \le \psi(s_0^2) + w\,(s^2 - s_0^2)` with
:math:`w = \psi'(s_0^2) = 1/\sqrt{1 + s_0^2/\varepsilon^2} \in (0, 1]`, and iteratively reweighted
least squares (IRLS) — solve :math:`(M + \alpha L_w) v = M d` with the edge weights :math:`w_{pq}`
of the current iterate, then update the weights — is a majorise–minimise scheme: :math:`E_\psi`
never increases. The first iterate (all :math:`w = 1`) is the quadratic solution, computed with
``method``; the reweighted systems are solved with warm-started Jacobi-PCG whatever ``method`` is.

Public functions
----------------
:func:`variational_scene_flow` (the three components), :func:`solve_component` (one component, the
syllabus' :math:`E_k`), :func:`red_black_sweep` (one Gauss–Seidel sweep: the exercise),
:func:`grid_laplacian` (sparse :math:`L`, optionally edge-weighted) and :func:`variational_energy`.

Examples
--------
A uniform translation is reproduced exactly by every method:

>>> import numpy as np
>>> X_t = np.random.default_rng(0).normal(size=(4, 5, 3))
>>> X_t1 = X_t + np.array([0.1, 0.0, -0.2])
>>> v = variational_scene_flow(X_t, X_t1, dt=0.1, lam=1.0)
>>> np.allclose(v, [1.0, 0.0, -2.0])
True
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.fft
import scipy.sparse as sp

from ._graph import block_pcg, laplacian
from ._validation import as_array, nonnegative, positive, positive_int

__all__ = [
    "METHODS",
    "REGULARIZERS",
    "grid_laplacian",
    "red_black_sweep",
    "solve_component",
    "variational_energy",
    "variational_scene_flow",
]

METHODS = ("dct", "cg", "gauss_seidel")
REGULARIZERS = ("quadratic", "charbonnier")


# --------------------------------------------------------------------------------------------------
# grid operators
# --------------------------------------------------------------------------------------------------
def _grid_shape(H, W) -> tuple[int, int]:
    return positive_int(H, "H"), positive_int(W, "W")


def grid_laplacian(H: int, W: int, *, weights=None) -> sp.csr_matrix:
    r"""Grid-graph Laplacian of an ``H x W`` pixel grid with 4-neighbour edges.

    Pixel ``(i, j)`` has index ``i * W + j`` (row-major, as ``np.ravel``). With edge weights
    :math:`w_{pq}` (all 1 by default)

    .. math::  L = D - A, \qquad A_{pq} = w_{pq} \text{ for 4-neighbours}, \qquad
               D_{pp} = \sum_q A_{pq}, \qquad v^\top L v = \sum_{(p,q)} w_{pq} (v_p - v_q)^2 .

    Unweighted, this is minus the 5-point Laplacian with a homogeneous Neumann (ghost-cell)
    boundary: interior rows read :math:`4 v_{ij} - v_{i\pm1,j} - v_{i,j\pm1}`; border pixels have
    degree 3 (corners 2). It is symmetric positive semi-definite with the constants as null space.

    Parameters
    ----------
    H, W : int
        Grid size (>= 1).
    weights : tuple of two arrays, optional
        ``(w_vertical (H-1, W), w_horizontal (H, W-1))``: the weight of the edge between
        ``(i, j)`` and ``(i+1, j)``, and between ``(i, j)`` and ``(i, j+1)``; finite and >= 0.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (H*W, H*W)

    Examples
    --------
    >>> grid_laplacian(2, 2).toarray()
    array([[ 2., -1., -1.,  0.],
           [-1.,  2.,  0., -1.],
           [-1.,  0.,  2., -1.],
           [ 0., -1., -1.,  2.]])
    """
    H, W = _grid_shape(H, W)
    idx = np.arange(H * W).reshape(H, W)
    if weights is None:
        wv = np.ones((H - 1, W))
        wh = np.ones((H, W - 1))
    else:
        if not isinstance(weights, (tuple, list)) or len(weights) != 2:
            raise ValueError("weights must be a pair (w_vertical (H-1, W), w_horizontal (H, W-1))")
        wv = as_array(weights[0], "weights[0]", (H - 1, W))
        wh = as_array(weights[1], "weights[1]", (H, W - 1))
        if (wv < 0).any() or (wh < 0).any():
            raise ValueError("weights must be >= 0")
    rows = np.concatenate([idx[:-1, :].ravel(), idx[:, :-1].ravel()])
    cols = np.concatenate([idx[1:, :].ravel(), idx[:, 1:].ravel()])
    w = np.concatenate([wv.ravel(), wh.ravel()])
    n = H * W
    adj = sp.coo_matrix((w, (rows, cols)), shape=(n, n))
    return laplacian((adj + adj.T).tocsr())


def _degree(H: int, W: int) -> np.ndarray:
    """Number of 4-neighbours of each pixel, shape (H, W)."""
    deg = np.zeros((H, W))
    deg[1:, :] += 1
    deg[:-1, :] += 1
    deg[:, 1:] += 1
    deg[:, :-1] += 1
    return deg


def _neighbour_sum(v: np.ndarray) -> np.ndarray:
    """Sum of the (existing) 4-neighbours of every pixel; ``v`` is (H, W) or (H, W, C)."""
    s = np.zeros_like(v)
    s[1:] += v[:-1]
    s[:-1] += v[1:]
    s[:, 1:] += v[:, :-1]
    s[:, :-1] += v[:, 1:]
    return s


def _apply_A(v, m, alpha, deg):
    """(M + alpha L) v for v (H, W, C), m and deg (H, W)."""
    return (m + alpha * deg)[..., None] * v - alpha * _neighbour_sum(v)


# --------------------------------------------------------------------------------------------------
# Gauss–Seidel
# --------------------------------------------------------------------------------------------------
def _checkerboard(H: int, W: int) -> tuple[np.ndarray, np.ndarray]:
    i, j = np.indices((H, W))
    red = (i + j) % 2 == 0
    return red, ~red


def _sweep(v, rhs, inv_diag, lam, red, black):
    """Unchecked red-black sweep on (H, W, C) arrays; ``inv_diag`` is (H, W, 1)."""
    for colour in (red, black):
        new = (rhs + lam * _neighbour_sum(v)) * inv_diag
        np.copyto(v, new, where=colour[..., None])
    return v


def red_black_sweep(v, rhs, diag_data, lam):
    r"""One red-black Gauss–Seidel sweep for :math:`(\operatorname{diag}(c) + \lambda L)\, v = r`.

    Row :math:`p` of the system reads
    :math:`(c_p + \lambda \deg_p)\, v_p - \lambda \sum_{q \sim p} v_q = r_p`, so Gauss–Seidel sets

    .. math::  v_p \leftarrow \frac{r_p + \lambda \sum_{q \sim p} v_q}{c_p + \lambda \deg_p}.

    On a checkerboard colouring the 4-neighbours of a red pixel ``(i + j even)`` are all black, so
    all red pixels can be updated at once from the current black values, then all black pixels
    from the new red values. One sweep = red half-step + black half-step; it is exactly a
    Gauss–Seidel sweep in the red-then-black ordering (converges for any SPD system).

    Parameters
    ----------
    v : ndarray, shape (H, W) or (H, W, C)
        Current iterate; **updated in place** (and returned). Each trailing component is an
        independent system with the same matrix.
    rhs : ndarray, same shape as ``v``
        Right-hand side :math:`r`.
    diag_data : ndarray, shape (H, W)
        Data weights :math:`c_p \ge 0` (e.g. :math:`\Delta t^2 m_p`).
    lam : float
        Smoothness weight :math:`\lambda \ge 0`. Every diagonal :math:`c_p + \lambda \deg_p` must be
        > 0.

    Returns
    -------
    ndarray
        ``v`` after the sweep.

    Examples
    --------
    With no smoothness a sweep solves the diagonal system exactly:

    >>> import numpy as np
    >>> v = np.zeros((2, 3))
    >>> red_black_sweep(v, np.full((2, 3), 4.0), np.full((2, 3), 2.0), 0.0)
    array([[2., 2., 2.],
           [2., 2., 2.]])
    """
    if not isinstance(v, np.ndarray) or v.dtype != np.float64:
        raise TypeError("v must be a float64 ndarray (it is updated in place)")
    if v.ndim not in (2, 3) or v.size == 0:
        raise ValueError(f"v must have shape (H, W) or (H, W, C), got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError("v contains NaN or inf")
    H, W = v.shape[:2]
    rhs = as_array(rhs, "rhs", v.shape)
    c = as_array(diag_data, "diag_data", (H, W))
    if (c < 0).any():
        raise ValueError("diag_data must be >= 0")
    lam = nonnegative(lam, "lam")
    diag = c + lam * _degree(H, W)
    if (diag <= 0).any():
        raise ValueError("diag_data + lam * degree must be > 0 at every pixel (the system is singular)")
    red, black = _checkerboard(H, W)
    squeeze = v.ndim == 2
    v3 = v[..., None] if squeeze else v
    rhs3 = rhs[..., None] if squeeze else rhs
    _sweep(v3, rhs3, (1.0 / diag)[..., None], lam, red, black)
    return v


# --------------------------------------------------------------------------------------------------
# core solvers on the scaled system (M + alpha L) V = M D, V and D of shape (H, W, C)
# --------------------------------------------------------------------------------------------------
def _rel_residual(v, rhs, m, alpha, deg, rhs_norm):
    return float(np.linalg.norm(rhs - _apply_A(v, m, alpha, deg)) / rhs_norm)


def _solve_dct(d, alpha):
    """Exact solve of (I + alpha L) V = D for D (H, W, C): DCT-II over rows and columns."""
    H, W = d.shape[:2]
    mu_h = 4.0 * np.sin(np.pi * np.arange(H) / (2.0 * H)) ** 2
    mu_w = 4.0 * np.sin(np.pi * np.arange(W) / (2.0 * W)) ** 2
    denom = 1.0 + alpha * (mu_h[:, None] + mu_w[None, :])  # >= 1: no division by zero, alpha >= 0
    # dctn over axes (0, 1) done as two 1-D passes, in place after the first (measurably faster)
    x = scipy.fft.dct(d, type=2, axis=0, norm="ortho")
    x = scipy.fft.dct(x, type=2, axis=1, norm="ortho", overwrite_x=True)
    x /= denom[..., None]
    x = scipy.fft.idct(x, type=2, axis=1, norm="ortho", overwrite_x=True)
    return scipy.fft.idct(x, type=2, axis=0, norm="ortho", overwrite_x=True)


def _solve_cg(rhs, A, x0, tol, max_iter, history):
    """Jacobi-PCG on the block-diagonal system diag(A, ..., A) for rhs (n, C). Returns (x, its).

    Stops at ``||rhs - A x||_F < tol ||rhs||_F`` (one CG on the stacked system, as
    ``scipy.sparse.linalg.cg``), restarting on the true residual; ``history`` (a list or None)
    receives the true relative residual after every iteration.
    """
    callback = None
    if history is not None:
        b_norm = np.linalg.norm(rhs)

        def callback(x):
            history.append(float(np.linalg.norm(rhs - A @ x) / b_norm))

    x, its, _ = block_pcg(A, rhs, tol, max_iter, X0=x0, per_column=False, callback=callback)
    return x, its


def _solve_gauss_seidel(rhs, m, alpha, v0, tol, max_iter, history):
    H, W = m.shape
    deg = _degree(H, W)
    inv_diag = (1.0 / (m + alpha * deg))[..., None]
    red, black = _checkerboard(H, W)
    rhs_norm = np.linalg.norm(rhs)
    v = v0.copy()
    its = 0
    while its < max_iter:
        _sweep(v, rhs, inv_diag, alpha, red, black)
        its += 1
        rel = _rel_residual(v, rhs, m, alpha, deg, rhs_norm)
        if history is not None:
            history.append(rel)
        if rel < tol:
            break
    return v, its


def _solve_quadratic(d, m, alpha, method, tol, max_iter, record=False):
    """Solve (M + alpha L) V = M D for D (H, W, C) (zeros where m == 0). Returns (V, info).

    ``record``: keep the relative residual of every CG iteration (one extra product per iteration;
    Gauss–Seidel computes it anyway for its stopping test).
    """
    H, W, C = d.shape
    n = H * W
    info = {"method": method, "iterations": 0, "residual_history": [], "converged": True, "residual": 0.0}
    if alpha == 0.0:  # decoupled pixels: closed form, NaN where undetermined
        return np.where(m[..., None] > 0, d, np.nan), info
    if method == "dct":  # m == 1 everywhere (checked by the caller): rhs = d
        v = _solve_dct(d, alpha)
        if record:  # the direct solve needs no residual; compute it only when asked for
            d_norm = np.linalg.norm(d)
            res = _rel_residual(v, d, m, alpha, _degree(H, W), d_norm) if d_norm > 0 else 0.0
            info["residual"] = res
            info["residual_history"] = [res]
        return v, info
    rhs = m[..., None] * d
    rhs_norm = np.linalg.norm(rhs)
    if rhs_norm == 0.0:
        return np.zeros_like(d), info
    if max_iter is None:
        max_iter = 10 * n if method == "cg" else max(10_000, 10 * n)
    history: list[float] = []
    x0 = np.zeros_like(d)
    if method == "cg":
        A = (sp.diags(m.ravel()) + alpha * grid_laplacian(H, W)).tocsr()
        x, its = _solve_cg(rhs.reshape(n, C), A, x0.reshape(n, C), tol, max_iter, history if record else None)
        v = x.reshape(H, W, C)
    else:
        v, its = _solve_gauss_seidel(rhs, m, alpha, x0, tol, max_iter, history)
    res = _rel_residual(v, rhs, m, alpha, _degree(H, W), rhs_norm)
    info.update(iterations=its, residual=res, residual_history=history)
    if not res < tol:
        info["converged"] = False
        warnings.warn(
            f"{method} did not reach tol={tol:g} in max_iter={max_iter} iterations "
            f"(relative residual {res:.3g}); increase max_iter",
            RuntimeWarning,
            stacklevel=3,
        )
    return v, info


def _charbonnier_weights(v, eps):
    """IRLS edge weights w = 1/sqrt(1 + |v_p - v_q|^2/eps^2): (vertical (H-1,W), horizontal (H,W-1))."""
    gv = np.sum((v[1:] - v[:-1]) ** 2, axis=-1)
    gh = np.sum((v[:, 1:] - v[:, :-1]) ** 2, axis=-1)
    return 1.0 / np.sqrt(1.0 + gv / eps**2), 1.0 / np.sqrt(1.0 + gh / eps**2)


def _energy(v, d, m, dt, lam, regularizer, eps):
    """Energy of v for the data velocity d (zeros where m == 0); X_t + v dt - X_t1 = dt (v - d)."""
    data = dt**2 * float(np.sum(m[..., None] * (v - d) ** 2))
    gv = np.sum((v[1:] - v[:-1]) ** 2, axis=-1)
    gh = np.sum((v[:, 1:] - v[:, :-1]) ** 2, axis=-1)
    if regularizer == "quadratic":
        smooth = float(gv.sum() + gh.sum())
    else:
        psi = lambda s2: 2.0 * eps**2 * (np.sqrt(1.0 + s2 / eps**2) - 1.0)  # noqa: E731
        smooth = float(psi(gv).sum() + psi(gh).sum())
    return data + lam * smooth


def _solve_charbonnier(d, m, alpha, dt, lam, eps, method, tol, max_iter, irls_max_iter, irls_tol, record):
    H, W, C = d.shape
    n = H * W
    v, info0 = _solve_quadratic(d, m, alpha, method, tol, max_iter, record)
    info = dict(info0)
    energies = [_energy(v, d, m, dt, lam, "charbonnier", eps)]
    inner = [info0["iterations"]]
    rhs = (m[..., None] * d).reshape(n, C)
    if max_iter is None:
        max_iter = 10 * n
    change = np.inf
    k = 0
    for k in range(1, irls_max_iter + 1):  # noqa: B007
        wv, wh = _charbonnier_weights(v, eps)
        A = (sp.diags(m.ravel()) + alpha * grid_laplacian(H, W, weights=(wv, wh))).tocsr()
        x, its = _solve_cg(rhs, A, v.reshape(n, C), tol, max_iter, None)
        v_new = x.reshape(H, W, C)
        change = float(np.linalg.norm(v_new - v) / max(np.linalg.norm(v_new), np.finfo(float).tiny))
        v = v_new
        inner.append(its)
        energies.append(_energy(v, d, m, dt, lam, "charbonnier", eps))
        if change < irls_tol:
            break
    if not change < irls_tol:
        warnings.warn(
            f"IRLS stopped after irls_max_iter={irls_max_iter} reweightings with relative change "
            f"{change:.3g} >= irls_tol={irls_tol:g}; increase irls_max_iter",
            RuntimeWarning,
            stacklevel=3,
        )
    info.update(
        {
            "regularizer": "charbonnier",
            "irls_iterations": k,
            "irls_change": change,
            "irls_converged": change < irls_tol,
            "inner_iterations": inner,
            "energy_history": energies,
        }
    )
    return v, info


# --------------------------------------------------------------------------------------------------
# validation shared by the public entry points
# --------------------------------------------------------------------------------------------------
def _check_choice(value, name, allowed):
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
    return value


def _check_mask(mask, H, W):
    if mask is None:
        return np.ones((H, W))
    arr = as_array(mask, "mask", (H, W))
    if not np.isin(arr, (0.0, 1.0)).all():
        raise ValueError("mask must be boolean-like (only 0/1 or False/True values), shape (H, W)")
    return arr


def _prepare(a, b, dt, lam, mask, method, tol, max_iter, names, shape):
    """Validate, build the effective mask m (H, W) and the data velocity d (zeros where m == 0)."""
    if a.shape != b.shape:
        raise ValueError(
            f"{names[1]} must have the same shape as {names[0]} {shape}={a.shape}, got {b.shape}"
        )
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{names[0]} must have shape {shape} with H, W >= 1, got {a.shape}")
    H, W = a.shape[:2]
    dt = positive(dt, "dt")
    lam = nonnegative(lam, "lam")
    method = _check_choice(method, "method", METHODS)
    tol = positive(tol, "tol")
    if tol >= 1.0:
        raise ValueError(f"tol must be in (0, 1), got {tol}")
    if max_iter is not None:
        max_iter = positive_int(max_iter, "max_iter")
    diff = b - a  # NaN where either is NaN (inf was rejected); a new array, a and b stay untouched
    if mask is None and not np.isnan(diff).any():  # the common case: full data term, no copies
        diff *= 1.0 / dt
        return diff, np.ones((H, W)), dt, lam, method, tol, max_iter
    user_mask = _check_mask(mask, H, W)
    finite = ~np.isnan(diff) if diff.ndim == 2 else ~np.isnan(diff).any(axis=-1)
    m = user_mask * finite
    if method == "dct" and not (m == 1.0).all():
        if (user_mask == 1.0).all():
            raise ValueError(
                f"{names[0]}/{names[1]} contain NaN (invalid depth): method='dct' needs data at every "
                "pixel; use method='cg' or method='gauss_seidel'"
            )
        raise ValueError("mask is not all True: method='dct' needs the full data term; use method='cg'")
    if lam > 0 and not m.any():
        raise ValueError(
            "mask (combined with the finite pixels of the input) selects no pixel with data: "
            "the system is singular"
        )
    if not (m == 1.0).all():
        ok = m > 0
        diff = np.where(ok if a.ndim == 2 else ok[..., None], diff, 0.0)
    diff *= 1.0 / dt
    return diff, m, dt, lam, method, tol, max_iter


# --------------------------------------------------------------------------------------------------
# public solvers
# --------------------------------------------------------------------------------------------------
def solve_component(a, b, dt, lam, mask=None, method="dct", tol=1e-10, max_iter=None, return_info=False):
    r"""Minimise the scalar energy :math:`E_k` of one component (syllabus section 3, Problem 2).

    .. math::

        E_k(v) = \sum_p m_p (a_p + v_p \Delta t - b_p)^2 + \lambda \sum_{(p,q)} (v_p - v_q)^2,
        \qquad (\Delta t^2 M + \lambda L)\, v = \Delta t\, M (b - a).

    Parameters
    ----------
    a, b : array_like, shape (H, W)
        The component at time t and t + dt; NaN marks invalid pixels (no data there).
    dt : float
        Time step (> 0).
    lam : float
        Smoothness weight (>= 0).
    mask : array_like of bool, shape (H, W), optional
        Pixels with data (default: all finite pixels).
    method : {"dct", "cg", "gauss_seidel"}
        Solver, see the module documentation.
    tol : float
        Relative-residual tolerance of the iterative solvers, in (0, 1).
    max_iter : int, optional
        Iteration cap (CG iterations or Gauss–Seidel sweeps); default ``10*H*W`` for CG and
        ``max(10000, 10*H*W)`` for Gauss–Seidel. A ``RuntimeWarning`` is issued if it is reached.
    return_info : bool
        Also return the ``info`` dict of :func:`variational_scene_flow`.

    Returns
    -------
    v : ndarray, shape (H, W)
        (and ``info`` if ``return_info``)

    Examples
    --------
    >>> import numpy as np
    >>> a = np.zeros((3, 4)); b = np.ones((3, 4))
    >>> v1 = solve_component(a, b, dt=0.5, lam=1.0, method="cg")
    >>> np.allclose(v1, 2.0)
    True
    """
    a = as_array(a, "a", ("H", "W"), allow_nan=True, copy=False)
    b = as_array(b, "b", ("H", "W"), allow_nan=True, copy=False)
    d, m, dt, lam, method, tol, max_iter = _prepare(
        a, b, dt, lam, mask, method, tol, max_iter, ("a", "b"), "(H, W)"
    )
    v, info = _solve_quadratic(d[..., None], m, lam / dt**2, method, tol, max_iter, return_info)
    v = v[..., 0]
    return (v, info) if return_info else v


def variational_scene_flow(
    X_t,
    X_t1,
    dt,
    lam,
    method="dct",
    mask=None,
    tol=1e-10,
    regularizer="quadratic",
    eps=1e-3,
    max_iter=None,
    irls_max_iter=50,
    irls_tol=1e-6,
    return_info=False,
):
    r"""Dense scene flow on the pixel grid by minimising the variational energy.

    Minimises :math:`E(v) = \sum_p m_p \|X_t(p) + v(p)\Delta t - X_{t+1}(p)\|^2 + \lambda
    \sum_{(p,q)} \|v(p) - v(q)\|^2` over 4-neighbour edges, i.e. solves
    :math:`(\Delta t^2 M + \lambda L_{\text{grid}})\, v_k = \Delta t\, M (X_{t+1} - X_t)_k` for
    :math:`k = 1, 2, 3` (see the module documentation for the derivation, the solvers, the
    agreement guarantee and the handling of invalid depth).

    Parameters
    ----------
    X_t, X_t1 : array_like, shape (H, W, 3)
        Point maps at t and t + dt (metres). NaN marks invalid depth (the pixel carries no data,
        its flow comes from the smoothness term); inf is rejected.
    dt : float
        Time step (> 0), seconds.
    lam : float
        Smoothness weight :math:`\lambda \ge 0`. ``lam = 0`` gives :math:`v = (X_{t+1} - X_t)/\Delta t`
        (NaN at pixels without data).
    method : {"dct", "cg", "gauss_seidel"}
        ``"dct"``: exact, full data term only (raises ``ValueError`` with a mask or NaN input);
        ``"cg"``: Jacobi-preconditioned CG; ``"gauss_seidel"``: red-black Gauss–Seidel.
    mask : array_like of bool, shape (H, W), optional
        Pixels whose data term is used (combined with "finite in both frames").
    tol : float
        Relative-residual tolerance :math:`\|B - AV\|_F / \|B\|_F` of the iterative solvers.
    regularizer : {"quadratic", "charbonnier"}
        Smoothness penalty; ``"charbonnier"`` uses :math:`\lambda \sum \psi(\|v_p - v_q\|^2)`,
        :math:`\psi(s^2) = 2\varepsilon^2(\sqrt{1 + s^2/\varepsilon^2} - 1)`, minimised by IRLS.
    eps : float
        Charbonnier scale :math:`\varepsilon > 0` (m/s): velocity jumps well above ``eps`` are
        treated as discontinuities.
    max_iter : int, optional
        Iteration cap of CG / Gauss–Seidel (see :func:`solve_component`).
    irls_max_iter : int
        Maximum number of IRLS reweightings (charbonnier only).
    irls_tol : float
        IRLS stops when :math:`\|v^{(k+1)} - v^{(k)}\|_F / \|v^{(k+1)}\|_F <` ``irls_tol``.
    return_info : bool
        Also return a dict with ``method``, ``iterations`` (CG iterations / GS sweeps; 0 for DCT),
        ``residual_history`` (relative residual after each iteration; for DCT the single final
        value), ``residual`` (final true relative residual), ``converged``, and for charbonnier
        ``irls_iterations``, ``irls_change``, ``irls_converged``, ``inner_iterations``,
        ``energy_history`` (:math:`E_\psi` after each IRLS step, non-increasing); there ``iterations``
        and ``residual*`` describe the first (quadratic) solve.

    Returns
    -------
    v : ndarray, shape (H, W, 3)
        Velocity at every pixel (and ``info`` if ``return_info``).

    Raises
    ------
    ValueError
        Wrong shapes, inf, ``dt <= 0``, ``lam < 0``, unknown ``method``/``regularizer``, a
        non-boolean ``mask``, ``method="dct"`` without a full data term, no data at all.

    Examples
    --------
    All three solvers agree (to ``tol`` level, see the module documentation):

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> X_t = rng.normal(size=(6, 7, 3)); X_t1 = X_t + 0.01 * rng.normal(size=(6, 7, 3))
    >>> v_dct = variational_scene_flow(X_t, X_t1, dt=0.1, lam=0.05)
    >>> v_cg = variational_scene_flow(X_t, X_t1, dt=0.1, lam=0.05, method="cg")
    >>> v_gs, info = variational_scene_flow(X_t, X_t1, dt=0.1, lam=0.05, method="gauss_seidel",
    ...                                     return_info=True)
    >>> bool(np.abs(v_cg - v_dct).max() < 1e-8 and np.abs(v_gs - v_dct).max() < 1e-8)
    True
    >>> info["residual"] < 1e-10
    True

    Invalid depth (NaN) needs an iterative method:

    >>> X_t[2, 3] = np.nan
    >>> variational_scene_flow(X_t, X_t1, dt=0.1, lam=0.05, method="cg").shape
    (6, 7, 3)
    """
    X_t = as_array(X_t, "X_t", ("H", "W", 3), allow_nan=True, copy=False)
    X_t1 = as_array(X_t1, "X_t1", ("H", "W", 3), allow_nan=True, copy=False)
    regularizer = _check_choice(regularizer, "regularizer", REGULARIZERS)
    d, m, dt, lam, method, tol, max_iter = _prepare(
        X_t, X_t1, dt, lam, mask, method, tol, max_iter, ("X_t", "X_t1"), "(H, W, 3)"
    )
    alpha = lam / dt**2
    if regularizer == "quadratic" or alpha == 0.0:
        v, info = _solve_quadratic(d, m, alpha, method, tol, max_iter, return_info)
        info["regularizer"] = regularizer
    else:
        eps = positive(eps, "eps")
        irls_max_iter = positive_int(irls_max_iter, "irls_max_iter")
        irls_tol = positive(irls_tol, "irls_tol")
        v, info = _solve_charbonnier(
            d, m, alpha, dt, lam, eps, method, tol, max_iter, irls_max_iter, irls_tol, return_info
        )
    return (v, info) if return_info else v


def variational_energy(v, X_t, X_t1, dt, lam, mask=None, regularizer="quadratic", eps=1e-3) -> float:
    r"""The energy minimised by :func:`variational_scene_flow`, evaluated at ``v``.

    .. math::  E(v) = \sum_p m_p \|X_t(p) + v(p)\Delta t - X_{t+1}(p)\|^2
               + \lambda \sum_{(p,q)} \rho(\|v(p) - v(q)\|^2),

    with :math:`\rho(s^2) = s^2` (quadratic) or :math:`\psi(s^2) = 2\varepsilon^2(\sqrt{1 +
    s^2/\varepsilon^2} - 1)` (charbonnier); ``m`` is the same effective mask (``mask`` and finite
    in both frames).

    Parameters
    ----------
    v : array_like, shape (H, W, 3)
        Velocity field (finite).
    X_t, X_t1, dt, lam, mask, regularizer, eps
        As in :func:`variational_scene_flow`.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> X = np.zeros((2, 2, 3)); v = np.zeros((2, 2, 3)); v[0, 0, 0] = 1.0
    >>> variational_energy(v, X, X, dt=1.0, lam=2.0)   # data 1 + 2 * (two edges of length 1)
    5.0
    """
    X_t = as_array(X_t, "X_t", ("H", "W", 3), allow_nan=True, copy=False)
    X_t1 = as_array(X_t1, "X_t1", ("H", "W", 3), allow_nan=True, copy=False)
    regularizer = _check_choice(regularizer, "regularizer", REGULARIZERS)
    v = as_array(v, "v", X_t.shape)
    d, m, dt, lam, *_ = _prepare(X_t, X_t1, dt, lam, mask, "cg", 0.5, None, ("X_t", "X_t1"), "(H, W, 3)")
    eps = positive(eps, "eps")
    return _energy(v, d, m, dt, lam, regularizer, eps)
