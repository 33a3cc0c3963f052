"""Three boxes on a table, rendered as an RGB-D sequence in the TUM layout by code that shares nothing
with flowtrack (numpy and PIL only): the stand-in for "a sequence no one here made".

flowtrack's own scenes (``flowtrack.synth``) come from the same hands as the pipeline that tracks
them; this renderer does not: its own ray caster (a slab test per box, two planes), its own camera
(TUM fr1 intrinsics, 640x480, a camera 0.65 m above the table looking down at it), its own textures
(bilinear colour noise; ``plain=True``: one flat colour per box, shading only, like cardboard),
its own Kinect-like depth model (noise ``0.0012 + 0.0019 (z - 0.4)^2`` m, disparity rounded to 1/8
px with f = 580 px and a 7.5 cm baseline, half the pixels next to a depth step over 3 cm dropped,
grazing surfaces and 1 % of all pixels dropped, nothing nearer than 0.4 m), and the colour and depth
clocks of a real sensor (depth 6 ms late, ±2 ms jitter). The boxes: one slides left to right in
front, one right to left behind it (the two cross and the far one is partly hidden), one turns on an
arc (yaw follows the heading). ``objects.csv`` holds the ground truth: per associated frame, each
box's centre in that frame's camera frame (metres) and its visible pixel count.

Used by ``benchmarks/bench_tum_input.py`` and ``tests/test_tum_input.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

#: TUM fr1 intrinsics at 640x480 (fx, fy, cx, cy)
TUM_FR1 = (517.3, 516.5, 318.6, 255.3)
HALF_SIZES = (np.array([0.07, 0.05, 0.06]), np.array([0.06, 0.06, 0.09]), np.array([0.09, 0.045, 0.05]))


def _look_at(eye, target, up=(0.0, 0.0, 1.0)):
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z]), eye  # rows: world -> camera


def _sample(tex, u, v):
    n = tex.shape[0]
    u = np.mod(u, 1.0) * (n - 1)
    v = np.mod(v, 1.0) * (n - 1)
    i0, j0 = np.floor(u).astype(int), np.floor(v).astype(int)
    i1, j1 = np.minimum(i0 + 1, n - 1), np.minimum(j0 + 1, n - 1)
    a, b = (u - i0)[:, None], (v - j0)[:, None]
    return (tex[i0, j0] * (1 - a) * (1 - b) + tex[i1, j0] * a * (1 - b) + tex[i0, j1] * (1 - a) * b
            + tex[i1, j1] * a * b)


def _yaw(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _render(poses, Rcw, eye, texs, K, size, rng):
    fx, fy, cx, cy = K
    H, W = size
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    d_w = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones_like(u)], -1).reshape(-1, 3) @ Rcw
    n = len(d_w)
    best = np.full(n, np.inf)
    lab = np.full(n, -1)
    col = np.zeros((n, 3))
    nrm = np.zeros((n, 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        # the table z = 0 (|x| < 0.8, -0.5 < y < 1) and the wall y = 1 behind it
        for plane, tex_i in ((2, 0), (1, 1)):
            off = 0.0 if plane == 2 else 1.0
            t = (off - eye[plane]) / d_w[:, plane]
            P = eye + t[:, None] * d_w
            if plane == 2:
                ok = (np.abs(P[:, 0]) < 0.8) & (P[:, 1] > -0.5) & (P[:, 1] < 1.0)
                uv = (P[:, 0] * 2.5, P[:, 1] * 2.5)
                normal = (0.0, 0.0, 1.0)
            else:
                ok = (np.abs(P[:, 0]) < 1.5) & (P[:, 2] > -0.01) & (P[:, 2] < 1.5)
                uv = (P[:, 0] * 2.0, P[:, 2] * 2.0)
                normal = (0.0, -1.0, 0.0)
            hit = ok & (t > 0) & (t < best)
            best[hit] = t[hit]
            lab[hit] = 0
            col[hit] = 0.3 + 0.5 * _sample(texs[tex_i], uv[0][hit], uv[1][hit])
            nrm[hit] = normal
        for k, (hs, (R, c)) in enumerate(zip(HALF_SIZES, poses)):
            o, dd = (eye - c) @ R, d_w @ R  # the ray in the box's frame
            t1, t2 = (-hs - o) / dd, (hs - o) / dd
            tn, tf = np.minimum(t1, t2), np.maximum(t1, t2)
            near, far, face = tn.max(1), tf.min(1), tn.argmax(1)
            hit = (near <= far) & (near > 0) & (near < best)
            best[hit] = near[hit]
            lab[hit] = k + 1
            Pb = o[None] + near[:, None] * dd
            idx = np.flatnonzero(hit)
            for f in range(3):
                m = idx[face[idx] == f]
                a, b = ((1, 2), (0, 2), (0, 1))[f]
                side = np.sign(Pb[m, f])
                col[m] = _sample(texs[2 + k], Pb[m, a] * 4 + (side > 0) * 0.5, Pb[m, b] * 4 + f * 0.33)
                nb = np.zeros((len(m), 3))
                nb[:, f] = side
                nrm[m] = nb @ R.T
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    shade = 0.45 + 0.55 * np.clip(np.abs(nrm @ light), 0, 1)
    rgb = np.clip(col * shade[:, None] * 255 + rng.normal(0, 2.0, (n, 3)), 0, 255).astype(np.uint8)
    z = best.reshape(H, W)  # the camera ray has z = 1, so its parameter is the depth
    z[~np.isfinite(z)] = 0.0
    cos_incidence = np.abs(np.sum(nrm * d_w / np.linalg.norm(d_w, axis=1, keepdims=True), 1)).reshape(H, W)
    return z, rgb.reshape(H, W, 3), lab.reshape(H, W), cos_incidence


def _kinect(z, cos_incidence, rng):
    H, W = z.shape
    out = z + rng.normal(0, 1, z.shape) * (0.0012 + 0.0019 * (z - 0.4) ** 2)
    fb = 580.0 * 0.075
    out = fb / (np.round(fb / np.maximum(out, 1e-3) * 8) / 8)
    zz = np.pad(z, 1, mode="edge")
    step = np.zeros(z.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0), (2, 1), (1, 2)):
        step |= np.abs(zz[dy:dy + H, dx:dx + W] - z) > 0.03
    drop = (step & (rng.random(z.shape) < 0.5)) | (cos_incidence < 0.12) | (rng.random(z.shape) < 0.01)
    out[drop | (z <= 0)] = 0.0
    out[(out > 8.0) | (out < 0.4)] = 0.0
    return out


def render_sequence(root, *, seed: int = 0, n_frames: int = 90, rate_hz: float = 30.0, plain: bool = False,
                    size: tuple[int, int] = (480, 640), duration: float = 3.0, first: int = 0) -> dict:
    """Write the three-box sequence to ``root`` (TUM layout: rgb/, depth/, rgb.txt, depth.txt, plus
    objects.csv); return ``{"intrinsics": "fx,fy,cx,cy", "truth": {frame: {box: centre}}}``.

    The motions span ``duration`` seconds whatever the frame count, so ``n_frames`` frames at
    ``rate_hz`` show the part of them that fits, from frame ``first`` on (its frame 0 is the motions'
    frame ``first``). ``size`` (H, W) scales the TUM fr1 intrinsics.
    """
    root = Path(root)
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    (root / "depth").mkdir(exist_ok=True)
    rng = np.random.default_rng(seed)
    s = size[1] / 640.0
    K = (TUM_FR1[0] * s, TUM_FR1[1] * s, (TUM_FR1[2] + 0.5) * s - 0.5, (TUM_FR1[3] + 0.5) * s - 0.5)
    Rcw, eye = _look_at((0.0, -0.45, 0.65), (0.0, 0.35, 0.0))
    texs = [rng.uniform(0, 1, (24, 24, 3)), rng.uniform(0, 1, (24, 24, 3))]
    for _ in range(3):
        texs.append(np.broadcast_to(rng.uniform(0.3, 0.9, 3), (6, 6, 3)).copy() if plain
                    else rng.uniform(0, 1, (6, 6, 3)))

    def poses(t):
        a = t / duration
        th = -0.5 + 1.6 * a
        return [(_yaw(0.3), np.array([-0.35 + 0.6 * a, 0.15, HALF_SIZES[0][2]])),
                (_yaw(-0.2 + 0.5 * a), np.array([0.30 - 0.6 * a, 0.40, HALF_SIZES[1][2]])),
                (_yaw(th), np.array([0.05 - 0.22 * np.sin(th), 0.33 + 0.22 * np.cos(th), HALF_SIZES[2][2]]))]

    rgb_lines, depth_lines, rows = ["# rgb"], ["# depth"], ["frame,id,x,y,z,visible_pixels"]
    truth: dict[int, dict[int, np.ndarray]] = {}
    t0 = 1311868164.0
    for i in range(n_frames):
        t = i / rate_hz
        P = poses(t + first / rate_hz)
        z, rgb, lab, cosi = _render(P, Rcw, eye, texs, K, size, rng)
        depth = _kinect(z, cosi, rng)
        ts_rgb = t0 + t + rng.uniform(-0.002, 0.002)
        ts_depth = t0 + t + 0.006 + rng.uniform(-0.002, 0.002)
        Image.fromarray(rgb).save(root / "rgb" / f"{ts_rgb:.6f}.png")
        Image.fromarray(np.round(depth * 5000).astype(np.uint16)).save(root / "depth" / f"{ts_depth:.6f}.png")
        rgb_lines.append(f"{ts_rgb:.6f} rgb/{ts_rgb:.6f}.png")
        depth_lines.append(f"{ts_depth:.6f} depth/{ts_depth:.6f}.png")
        truth[i] = {}
        for k, (_, c) in enumerate(P):
            cc = Rcw @ (c - eye)
            truth[i][k + 1] = cc
            rows.append(f"{i},{k + 1},{cc[0]:.6f},{cc[1]:.6f},{cc[2]:.6f},{int((lab == k + 1).sum())}")
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (root / "objects.csv").write_text("\n".join(rows) + "\n")
    return {"intrinsics": ",".join(f"{v:.4f}" for v in K), "truth": truth}
