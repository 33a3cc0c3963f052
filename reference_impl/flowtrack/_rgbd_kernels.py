"""Compiled (numba) inner loops of :mod:`flowtrack.rgbd_flow`.

Each kernel does exactly what the vectorised numpy code beside it does (``rgbd_flow.py``,
``_rgbd_energy.py``; the geodesic sweeps: ``_rgbd_match.geodesic_nearest_numpy``; the tests compare
the two), fused into passes over the pixels so that no temporaries are made. Importing this module
raises ``ImportError`` when numba is missing; ``rgbd_flow`` then uses the numpy code.
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
def _apply_dot(M, Wv, Wh, x, out):
    """out = A x, A = blockdiag(M_p) - (W off-diagonal), M_p = N_p + deg_p I (6 entries); returns x . out."""
    H, W = Wh.shape[0], Wv.shape[1]
    dot = 0.0
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
            dot += x0 * o0 + x1 * o1 + x2 * o2
    return dot


@_jit
def _block_inverses(M):
    """The 6 entries of each symmetric 3x3 block's inverse (adjugate / determinant)."""
    H, W = M.shape[0], M.shape[1]
    Minv = np.empty_like(M)
    for i in range(H):
        for j in range(W):
            a, b, c = M[i, j, 0], M[i, j, 1], M[i, j, 2]
            d, e, f = M[i, j, 3], M[i, j, 4], M[i, j, 5]
            A = d * f - e * e
            B = c * e - b * f
            C = b * e - c * d
            q = 1.0 / (a * A + b * B + c * C)
            Minv[i, j, 0] = A * q
            Minv[i, j, 1] = B * q
            Minv[i, j, 2] = C * q
            Minv[i, j, 3] = (a * f - c * c) * q
            Minv[i, j, 4] = (b * c - a * e) * q
            Minv[i, j, 5] = (a * d - b * b) * q
    return Minv


@_jit
def _update(s, r, p, q, z, Minv, alpha):
    """s += alpha p, r -= alpha q, z = Minv r; returns r . z."""
    H, W = s.shape[0], s.shape[1]
    rz = 0.0
    for i in range(H):
        for j in range(W):
            for k in range(3):
                s[i, j, k] += alpha * p[i, j, k]
                r[i, j, k] -= alpha * q[i, j, k]
            r0, r1, r2 = r[i, j, 0], r[i, j, 1], r[i, j, 2]
            z0 = Minv[i, j, 0] * r0 + Minv[i, j, 1] * r1 + Minv[i, j, 2] * r2
            z1 = Minv[i, j, 1] * r0 + Minv[i, j, 3] * r1 + Minv[i, j, 4] * r2
            z2 = Minv[i, j, 2] * r0 + Minv[i, j, 4] * r1 + Minv[i, j, 5] * r2
            z[i, j, 0] = z0
            z[i, j, 1] = z1
            z[i, j, 2] = z2
            rz += r0 * z0 + r1 * z1 + r2 * z2
    return rz


@_jit
def pcg(M, rhs, Wv, Wh, s, n_iter):
    """``n_iter`` block-Jacobi preconditioned CG iterations on A s = rhs from ``s`` (updated in place)."""
    Minv = _block_inverses(M)
    r = np.empty_like(s)
    _apply_dot(M, Wv, Wh, s, r)
    for i in range(s.shape[0]):
        for j in range(s.shape[1]):
            for k in range(3):
                r[i, j, k] = rhs[i, j, k] - r[i, j, k]
    z = np.zeros_like(s)
    p = np.zeros_like(s)
    q = np.zeros_like(s)
    rz = _update(s, r, p, q, z, Minv, 0.0)  # z = Minv r
    p[:] = z
    for _ in range(n_iter):
        if rz <= 0.0:
            break
        pq = _apply_dot(M, Wv, Wh, p, q)
        if pq <= 0.0:
            break
        alpha = rz / pq
        rz_new = _update(s, r, p, q, z, Minv, alpha)
        beta = rz_new / rz
        rz = rz_new
        for i in range(s.shape[0]):
            for j in range(s.shape[1]):
                for k in range(3):
                    p[i, j, k] = z[i, j, k] + beta * p[i, j, k]
    return s




@_jit
def geodesic_nearest(cost_h, cost_v, known, passes):
    """Index (row * W + col) of the geodesically nearest known pixel of every pixel (-1: none), and the
    geodesic distance to it (inf: none).

    ``cost_h (H, W-1)``, ``cost_v (H-1, W)``: the length of each horizontal / vertical step (> 0).
    Each pass sweeps every row left to right and back, then every column down and up (the numpy
    fallback in ``rgbd_flow`` does the same sweeps, so both give the same indices).
    """
    H, W = known.shape
    dist = np.full((H, W), np.inf)
    src = np.full((H, W), -1, dtype=np.int64)
    for i in range(H):
        for j in range(W):
            if known[i, j]:
                dist[i, j] = 0.0
                src[i, j] = i * W + j
    for _ in range(passes):
        for i in range(H):
            for j in range(1, W):
                c = dist[i, j - 1] + cost_h[i, j - 1]
                if c < dist[i, j]:
                    dist[i, j] = c
                    src[i, j] = src[i, j - 1]
            for j in range(W - 2, -1, -1):
                c = dist[i, j + 1] + cost_h[i, j]
                if c < dist[i, j]:
                    dist[i, j] = c
                    src[i, j] = src[i, j + 1]
        for j in range(W):
            for i in range(1, H):
                c = dist[i - 1, j] + cost_v[i - 1, j]
                if c < dist[i, j]:
                    dist[i, j] = c
                    src[i, j] = src[i - 1, j]
            for i in range(H - 2, -1, -1):
                c = dist[i + 1, j] + cost_v[i, j]
                if c < dist[i, j]:
                    dist[i, j] = c
                    src[i, j] = src[i + 1, j]
    return src, dist
