"""Compiled (numba) inner loops of :mod:`flowtrack.rgbd_flow`.

Each kernel does exactly what the vectorised numpy code beside it in ``rgbd_flow.py`` does (the tests
compare the two), fused into one pass over the pixels so that no temporaries are made. Importing this
module raises ``ImportError`` when numba is missing; ``rgbd_flow`` then uses its numpy code.
"""

from __future__ import annotations

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True, fastmath=False)


@_jit
def sample(stack, x, y, out, inside):
    """Bilinear samples of ``stack (H, W, C)`` at ``(x, y)`` (h, w) into ``out (h, w, C)``."""
    H, W, C = stack.shape
    h, w = x.shape
    for i in range(h):
        for j in range(w):
            xi = x[i, j]
            yi = y[i, j]
            inside[i, j] = (xi >= 0.0) and (yi >= 0.0) and (xi <= W - 1) and (yi <= H - 1)
            xc = min(max(xi, 0.0), W - 1.0)
            yc = min(max(yi, 0.0), H - 1.0)
            x0 = min(int(np.floor(xc)), max(W - 2, 0))
            y0 = min(int(np.floor(yc)), max(H - 2, 0))
            ax = xc - x0
            ay = yc - y0
            x1 = min(x0 + 1, W - 1)
            y1 = min(y0 + 1, H - 1)
            for c in range(C):
                top = stack[y0, x0, c] * (1.0 - ax) + stack[y0, x1, c] * ax
                bot = stack[y1, x0, c] * (1.0 - ax) + stack[y1, x1, c] * ax
                out[i, j, c] = top * (1.0 - ay) + bot * ay


@_jit
def assemble(a_i, a_d, c_i, c_d, r_i, r_d, s0, Wv, Wh, M, rhs):
    """Per pixel: ``M`` (6 entries xx, xy, xz, yy, yz, zz) of N_p + deg_p I and ``rhs`` = N s0 - g."""
    H, W = c_i.shape
    for i in range(H):
        for j in range(W):
            deg = 0.0
            if i > 0:
                deg += Wv[i - 1, j]
            if i < H - 1:
                deg += Wv[i, j]
            if j > 0:
                deg += Wh[i, j - 1]
            if j < W - 1:
                deg += Wh[i, j]
            ci = c_i[i, j]
            cd = c_d[i, j]
            ai0, ai1, ai2 = a_i[i, j, 0], a_i[i, j, 1], a_i[i, j, 2]
            ad0, ad1, ad2 = a_d[i, j, 0], a_d[i, j, 1], a_d[i, j, 2]
            n00 = ci * ai0 * ai0 + cd * ad0 * ad0
            n01 = ci * ai0 * ai1 + cd * ad0 * ad1
            n02 = ci * ai0 * ai2 + cd * ad0 * ad2
            n11 = ci * ai1 * ai1 + cd * ad1 * ad1
            n12 = ci * ai1 * ai2 + cd * ad1 * ad2
            n22 = ci * ai2 * ai2 + cd * ad2 * ad2
            M[i, j, 0] = n00 + deg
            M[i, j, 1] = n01
            M[i, j, 2] = n02
            M[i, j, 3] = n11 + deg
            M[i, j, 4] = n12
            M[i, j, 5] = n22 + deg
            s00, s01, s02 = s0[i, j, 0], s0[i, j, 1], s0[i, j, 2]
            gi = ci * r_i[i, j]
            gd = cd * r_d[i, j]
            rhs[i, j, 0] = n00 * s00 + n01 * s01 + n02 * s02 - gi * ai0 - gd * ad0
            rhs[i, j, 1] = n01 * s00 + n11 * s01 + n12 * s02 - gi * ai1 - gd * ad1
            rhs[i, j, 2] = n02 * s00 + n12 * s01 + n22 * s02 - gi * ai2 - gd * ad2


@_jit
def sweeps(M, rhs, Wv, Wh, s, n_sweeps):
    """``n_sweeps`` red-black block Gauss–Seidel sweeps on A s = rhs, ``s (H, W, 3)`` in place."""
    H, W = Wh.shape[0], Wv.shape[1]
    for _ in range(n_sweeps):
        for colour in range(2):
            for i in range(H):
                for j in range((i + colour) % 2, W, 2):
                    b0 = rhs[i, j, 0]
                    b1 = rhs[i, j, 1]
                    b2 = rhs[i, j, 2]
                    if i > 0:
                        w = Wv[i - 1, j]
                        b0 += w * s[i - 1, j, 0]
                        b1 += w * s[i - 1, j, 1]
                        b2 += w * s[i - 1, j, 2]
                    if i < H - 1:
                        w = Wv[i, j]
                        b0 += w * s[i + 1, j, 0]
                        b1 += w * s[i + 1, j, 1]
                        b2 += w * s[i + 1, j, 2]
                    if j > 0:
                        w = Wh[i, j - 1]
                        b0 += w * s[i, j - 1, 0]
                        b1 += w * s[i, j - 1, 1]
                        b2 += w * s[i, j - 1, 2]
                    if j < W - 1:
                        w = Wh[i, j]
                        b0 += w * s[i, j + 1, 0]
                        b1 += w * s[i, j + 1, 1]
                        b2 += w * s[i, j + 1, 2]
                    a = M[i, j, 0]
                    b = M[i, j, 1]
                    c = M[i, j, 2]
                    d = M[i, j, 3]
                    e = M[i, j, 4]
                    f = M[i, j, 5]
                    A = d * f - e * e
                    B = c * e - b * f
                    C = b * e - c * d
                    D = a * f - c * c
                    E = b * c - a * e
                    F = a * d - b * b
                    r = 1.0 / (a * A + b * B + c * C)
                    s[i, j, 0] = (A * b0 + B * b1 + C * b2) * r
                    s[i, j, 1] = (B * b0 + D * b1 + E * b2) * r
                    s[i, j, 2] = (C * b0 + E * b1 + F * b2) * r


@_jit
def _apply(M, Wv, Wh, x, out):
    """out = A x with A = blockdiag(M_p) - (W off-diagonal), M_p = N_p + deg_p I (6 entries)."""
    H, W = Wh.shape[0], Wv.shape[1]
    for i in range(H):
        for j in range(W):
            x0, x1, x2 = x[i, j, 0], x[i, j, 1], x[i, j, 2]
            o0 = M[i, j, 0] * x0 + M[i, j, 1] * x1 + M[i, j, 2] * x2
            o1 = M[i, j, 1] * x0 + M[i, j, 3] * x1 + M[i, j, 4] * x2
            o2 = M[i, j, 2] * x0 + M[i, j, 4] * x1 + M[i, j, 5] * x2
            if i > 0:
                w = Wv[i - 1, j]
                o0 -= w * x[i - 1, j, 0]
                o1 -= w * x[i - 1, j, 1]
                o2 -= w * x[i - 1, j, 2]
            if i < H - 1:
                w = Wv[i, j]
                o0 -= w * x[i + 1, j, 0]
                o1 -= w * x[i + 1, j, 1]
                o2 -= w * x[i + 1, j, 2]
            if j > 0:
                w = Wh[i, j - 1]
                o0 -= w * x[i, j - 1, 0]
                o1 -= w * x[i, j - 1, 1]
                o2 -= w * x[i, j - 1, 2]
            if j < W - 1:
                w = Wh[i, j]
                o0 -= w * x[i, j + 1, 0]
                o1 -= w * x[i, j + 1, 1]
                o2 -= w * x[i, j + 1, 2]
            out[i, j, 0] = o0
            out[i, j, 1] = o1
            out[i, j, 2] = o2


@_jit
def _precondition(M, r, z):
    """z = blockdiag(M_p)^-1 r (each 3x3 block by its adjugate); returns r . z."""
    H, W = r.shape[0], r.shape[1]
    rz = 0.0
    for i in range(H):
        for j in range(W):
            a = M[i, j, 0]
            b = M[i, j, 1]
            c = M[i, j, 2]
            d = M[i, j, 3]
            e = M[i, j, 4]
            f = M[i, j, 5]
            A = d * f - e * e
            B = c * e - b * f
            C = b * e - c * d
            D = a * f - c * c
            E = b * c - a * e
            F = a * d - b * b
            q = 1.0 / (a * A + b * B + c * C)
            r0, r1, r2 = r[i, j, 0], r[i, j, 1], r[i, j, 2]
            z0 = (A * r0 + B * r1 + C * r2) * q
            z1 = (B * r0 + D * r1 + E * r2) * q
            z2 = (C * r0 + E * r1 + F * r2) * q
            z[i, j, 0] = z0
            z[i, j, 1] = z1
            z[i, j, 2] = z2
            rz += r0 * z0 + r1 * z1 + r2 * z2
    return rz


@_jit
def pcg(M, rhs, Wv, Wh, s, n_iter):
    """``n_iter`` block-Jacobi preconditioned CG iterations on A s = rhs from ``s`` (updated in place)."""
    r = np.empty_like(s)
    _apply(M, Wv, Wh, s, r)
    r[:] = rhs - r
    z = np.empty_like(s)
    rz = _precondition(M, r, z)
    p = z.copy()
    q = np.empty_like(s)
    for _ in range(n_iter):
        if rz <= 0.0:
            break
        _apply(M, Wv, Wh, p, q)
        pq = np.sum(p * q)
        if pq <= 0.0:
            break
        alpha = rz / pq
        s += alpha * p
        r -= alpha * q
        rz_new = _precondition(M, r, z)
        beta = rz_new / rz
        rz = rz_new
        p[:] = z + beta * p
    return s
