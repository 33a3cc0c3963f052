"""The linearised RGB-D energy of one warp of :func:`flowtrack.rgbd_flow.rgbd_scene_flow` and its
numpy solver (block-Jacobi preconditioned conjugate gradients).

:class:`Linearised` holds the energy of the module documentation of :mod:`flowtrack.rgbd_flow` with
its data terms linearised around the warp's displacement: its value, exact gradient, IRLS weights and
the quadratic majoriser (the sparse system). :func:`pcg` solves that system with numpy;
:mod:`flowtrack._rgbd_kernels` does the same in compiled loops (the tests compare the two).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Linearised", "depth_sigma", "pcg", "rho", "rho_weight"]


def depth_sigma(Z, o):
    r"""The depth-noise scale (m) at depth ``Z``: :math:`\sqrt{\sigma_d^2 + (\sigma_{d2} Z^2)^2}` (the noise
    of a disparity-based sensor grows with :math:`Z^2`); ``o`` holds ``sigma_d`` and ``sigma_d_z2``."""
    if o["sigma_d_z2"] == 0.0:
        return o["sigma_d"]
    return np.sqrt(o["sigma_d"] ** 2 + (o["sigma_d_z2"] * np.asarray(Z) ** 2) ** 2)


def rho(x2, penalty):
    """Penalty of squared normalised residuals."""
    if penalty == "quadratic":
        return x2
    return 2.0 * (np.sqrt(1.0 + x2) - 1.0)


def rho_weight(x2, penalty):
    """d rho / d(x^2): the IRLS weight."""
    if penalty == "quadratic":
        return np.ones_like(x2)
    return 1.0 / np.sqrt(1.0 + x2)


class Linearised:
    """The energy of one warp with the data terms linearised around ``s0``.

    ``a_i, a_d`` (H, W, 3), ``r_i, r_d`` (H, W) residuals at ``s0``, ``m_i, m_d`` (H, W) 0/1 data
    masks, ``wv (H-1, W), wh (H, W-1)`` geometric edge weights, ``lam``, the scales and the penalty;
    optionally a match term: targets ``m_t`` (H, W, 3) with weights ``c_m`` (H, W) >= 0:

    E(s) = sum m_i rho((r_i + a_i.(s - s0)) / sigma_i) + m_d rho((r_d + a_d.(s - s0)) / sigma_d)
           + sum c_m rho(|s - m_t| / sigma_m) + lam sum_edges w rho(|s_p - s_q| / sigma_s).
    """

    def __init__(self, s0, a_i, r_i, m_i, a_d, r_d, m_d, wv, wh, lam, sigma_i, sigma_d, sigma_s, penalty,
                 m_t=None, c_m=None, sigma_m=1.0):
        self.s0, self.a_i, self.r_i, self.m_i = s0, a_i, r_i, m_i
        self.a_d, self.r_d, self.m_d = a_d, r_d, m_d
        self.wv, self.wh = wv, wh
        self.lam, self.sigma_i, self.sigma_d, self.sigma_s = lam, sigma_i, sigma_d, sigma_s
        self.penalty = penalty
        self.m_t, self.c_m, self.sigma_m = m_t, c_m, sigma_m

    def residuals(self, s):
        ds = s - self.s0
        return (self.r_i + np.sum(self.a_i * ds, axis=-1), self.r_d + np.sum(self.a_d * ds, axis=-1))

    def energy(self, s) -> float:
        ri, rd = self.residuals(s)
        pen = self.penalty
        data = np.sum(self.m_i * rho((ri / self.sigma_i) ** 2, pen))
        data += np.sum(self.m_d * rho((rd / self.sigma_d) ** 2, pen))
        if self.m_t is not None:
            data += np.sum(self.c_m * rho(np.sum(((s - self.m_t) / self.sigma_m) ** 2, axis=-1), pen))
        gv = np.sum((s[1:] - s[:-1]) ** 2, axis=-1) / self.sigma_s**2
        gh = np.sum((s[:, 1:] - s[:, :-1]) ** 2, axis=-1) / self.sigma_s**2
        smooth = np.sum(self.wv * rho(gv, pen)) + np.sum(self.wh * rho(gh, pen))
        return float(data + self.lam * smooth)

    def weights(self, s):
        """IRLS weights at ``s``: data (c_i, c_d) per pixel, smoothness (W_v, W_h) per edge."""
        ri, rd = self.residuals(s)
        pen = self.penalty
        c_i = self.m_i * rho_weight((ri / self.sigma_i) ** 2, pen) / self.sigma_i**2
        c_d = self.m_d * rho_weight((rd / self.sigma_d) ** 2, pen) / self.sigma_d**2
        gv = np.sum((s[1:] - s[:-1]) ** 2, axis=-1) / self.sigma_s**2
        gh = np.sum((s[:, 1:] - s[:, :-1]) ** 2, axis=-1) / self.sigma_s**2
        Wv = self.lam * self.wv * rho_weight(gv, pen) / self.sigma_s**2
        Wh = self.lam * self.wh * rho_weight(gh, pen) / self.sigma_s**2
        return c_i, c_d, Wv, Wh

    def match_weights(self, s):
        """IRLS weights of the match term at ``s`` per component (H, W, 3), or None without one."""
        if self.m_t is None:
            return None
        x2 = np.sum(((s - self.m_t) / self.sigma_m) ** 2, axis=-1)
        return (self.c_m * rho_weight(x2, self.penalty))[..., None] / self.sigma_m**2

    def add_match(self, M, rhs, s):
        """Add the match term's IRLS weights at ``s`` to the 6-entry blocks ``M`` (xx, xy, xz, yy, yz, zz)
        and to ``rhs`` (H, W, 3) of an assembled system without it (the compiled path)."""
        w = self.match_weights(s)
        if w is not None:
            M[..., 0] += w[..., 0]
            M[..., 3] += w[..., 1]
            M[..., 5] += w[..., 2]
            rhs += w * self.m_t

    def system(self, s):
        """The quadratic majoriser at ``s``: ``(N, rhs, Wv, Wh)`` with 0.5 grad = A s - rhs."""
        c_i, c_d, Wv, Wh = self.weights(s)
        a_i, a_d = self.a_i, self.a_d
        N = c_i[..., None, None] * a_i[..., :, None] * a_i[..., None, :]
        N += c_d[..., None, None] * a_d[..., :, None] * a_d[..., None, :]
        # residual r + a.(s - s0) = a.s + (r - a.s0): rhs = N s0 - (c_i r_i a_i + c_d r_d a_d)
        rhs = np.einsum("...ij,...j->...i", N, self.s0)
        rhs -= (c_i * self.r_i)[..., None] * a_i + (c_d * self.r_d)[..., None] * a_d
        c_m = self.match_weights(s)
        if c_m is not None:
            for k in range(3):
                N[..., k, k] += c_m[..., k]
            rhs += c_m * self.m_t
        return N, rhs, Wv, Wh

    def gradient(self, s):
        """Exact gradient of :meth:`energy` (the IRLS system at ``s`` touches E to first order)."""
        N, rhs, Wv, Wh = self.system(s)
        return 2.0 * (_apply(N, Wv, Wh, s) - rhs)


def _neighbour_weighted(s, Wv, Wh):
    """sum_q W_pq s_q for s (H, W, 3); Wv (H-1, W), Wh (H, W-1)."""
    out = np.zeros_like(s)
    t = Wv[..., None] * s[1:]
    out[:-1] += t
    t = Wv[..., None] * s[:-1]
    out[1:] += t
    t = Wh[..., None] * s[:, 1:]
    out[:, :-1] += t
    t = Wh[..., None] * s[:, :-1]
    out[:, 1:] += t
    return out


def _degree(Wv, Wh, shape):
    deg = np.zeros(shape)
    deg[:-1] += Wv
    deg[1:] += Wv
    deg[:, :-1] += Wh
    deg[:, 1:] += Wh
    return deg


def _apply(N, Wv, Wh, s):
    """A s with A = blockdiag(N_p) + (L_W kron I_3)."""
    deg = _degree(Wv, Wh, s.shape[:2])
    return np.einsum("...ij,...j->...i", N, s) + deg[..., None] * s - _neighbour_weighted(s, Wv, Wh)


def _inverse_sym3(M):
    """Inverses of symmetric positive definite 3×3 blocks (..., 3, 3) by the adjugate."""
    a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    d, e, f = M[..., 1, 1], M[..., 1, 2], M[..., 2, 2]
    A = d * f - e * e
    B = c * e - b * f
    C = b * e - c * d
    D = a * f - c * c
    E = b * c - a * e
    F = a * d - b * b
    det = a * A + b * B + c * C
    inv = np.empty_like(M)
    r = 1.0 / det
    inv[..., 0, 0] = A * r
    inv[..., 0, 1] = inv[..., 1, 0] = B * r
    inv[..., 0, 2] = inv[..., 2, 0] = C * r
    inv[..., 1, 1] = D * r
    inv[..., 1, 2] = inv[..., 2, 1] = E * r
    inv[..., 2, 2] = F * r
    return inv


def pcg(N, rhs, Wv, Wh, s, n_iter):
    """``n_iter`` block-Jacobi preconditioned CG iterations on A s = rhs (numpy); ``s`` updated in place."""
    deg = _degree(Wv, Wh, s.shape[:2])
    M = N.copy()
    for k in range(3):
        M[..., k, k] += deg
    Minv = _inverse_sym3(M)
    precond = lambda r: np.einsum("...ij,...j->...i", Minv, r)  # noqa: E731
    r = rhs - _apply(N, Wv, Wh, s)
    z = precond(r)
    p = z.copy()
    rz = float(np.sum(r * z))
    for _ in range(n_iter):
        if rz <= 0.0:
            break
        q = _apply(N, Wv, Wh, p)
        pq = float(np.sum(p * q))
        if pq <= 0.0:
            break
        alpha = rz / pq
        s += alpha * p
        r -= alpha * q
        z = precond(r)
        rz_new = float(np.sum(r * z))
        p = z + (rz_new / rz) * p
        rz = rz_new
    return s
