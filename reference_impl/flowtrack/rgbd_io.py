r"""Reading real RGB-D sequences: the TUM RGB-D layout, and stereo pairs with disparity.

**TUM RGB-D layout** (Sturm et al., 2012, the format of the TUM benchmark)::

    DIR/rgb/<timestamp>.png      8-bit colour images
    DIR/depth/<timestamp>.png    16-bit depth, Z = value / depth_scale metres (5000 for TUM), 0 = none
    DIR/rgb.txt, DIR/depth.txt   "timestamp filename" lines, '#' starts a comment
    DIR/intrinsics.txt           optional: "fx fy cx cy" (or the 9 entries of K, row by row)

Colour and depth frames come from different clocks; :func:`associate` pairs them as TUM's
``associate.py`` does: among all pairs with :math:`|t_a - (t_b + \text{offset})| <` ``max_difference``
the closest pairs are taken first, greedily, each frame at most once. Without ``rgb.txt`` and
``depth.txt`` the PNGs are paired in name order, so both folders must hold the same number.

**Stereo layout**::

    DIR/left/*.png               rectified left images (the reference view)
    DIR/right/*.png              optional, rectified right images (not needed when disparity is given)
    DIR/disparity/*.pfm | *.png  disparity of the left view: PFM (float, pixels) or 16-bit PNG
                                 (pixels = value / disparity_scale; KITTI uses 256)

Depth from disparity :math:`d` (pixels) with focal length :math:`f` (pixels) and baseline :math:`B`
(metres) is :math:`Z = f B / (d + d_\text{offs})` (:math:`d_\text{offs}`: the principal points'
column difference, 0 for most rigs; Middlebury lists it as ``doffs``), computed by
:func:`flowtrack.camera.depth_from_disparity`. Depth 0 (none) where the disparity is NaN or inf (a
PFM's "unknown", Middlebury 2014 uses inf), where :math:`d + d_\text{offs} \le 0`, and where a
16-bit PNG holds 0 (KITTI's "no measurement", whatever :math:`d_\text{offs}`).

Intrinsics are never guessed: give them as ``"fx,fy,cx,cy"``, a file, a preset name of
:data:`INTRINSICS_PRESETS` or an ``intrinsics.txt`` next to the frames.

Examples
--------
>>> parse_intrinsics("525,525,319.5,239.5").K.tolist()
[[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]]
>>> associate([1.00, 1.10, 1.20], [1.01, 1.12, 1.50], max_difference=0.03)
[(0, 0), (1, 1)]
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._validation import positive, positive_int, scalar
from .camera import PinholeCamera, depth_from_disparity

__all__ = [
    "INTRINSICS_PRESETS",
    "RGBDSequence",
    "associate",
    "load_rgbd",
    "load_stereo_sequence",
    "load_tum_sequence",
    "parse_intrinsics",
    "read_depth_png",
    "read_file_list",
    "read_pfm",
    "read_rgb_png",
    "write_pfm",
    "write_tum_sequence",
]

#: Published intrinsics (fx, fy, cx, cy) of the TUM RGB-D cameras and the ROS default.
INTRINSICS_PRESETS = {
    "tum-fr1": (517.3, 516.5, 318.6, 255.3),
    "tum-fr2": (520.9, 521.0, 325.1, 249.7),
    "tum-fr3": (535.4, 539.2, 320.1, 247.6),
    "ros-default": (525.0, 525.0, 319.5, 239.5),
}
_INTRINSICS_FILES = ("intrinsics.txt", "camera.txt")


@dataclass
class RGBDSequence:
    """Registered colour and metric depth frames of one camera.

    Attributes
    ----------
    camera : PinholeCamera
        Intrinsics, with ``width`` and ``height``.
    rgb : list of ndarray, shape (H, W, 3) uint8
    depth : list of ndarray, shape (H, W) float
        Depth Z in metres, 0 where there is none.
    timestamps : ndarray, shape (n,)
        Seconds (of the depth frames for TUM).
    source : str
        Where the frames came from.
    files : list of tuple of str
        The file names of each frame, for messages.
    indices : list of int
        Index of each frame in the input (TUM: among the associated colour/depth pairs; stereo: among
        the left images) before ``step`` and ``max_frames`` chose some; empty means 0, 1, 2, ...
    """

    camera: PinholeCamera
    rgb: list
    depth: list
    timestamps: np.ndarray
    source: str = ""
    files: list = field(default_factory=list)
    indices: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.depth)

    @property
    def dt(self) -> float:
        """Median time between frames (s); 0.1 for a single frame."""
        if len(self.timestamps) < 2:
            return 0.1
        d = float(np.median(np.diff(self.timestamps)))
        if not d > 0:
            raise ValueError(f"timestamps must increase, got a median step of {d} s in {self.source}")
        return d


# ------------------------------------------------------------------------------------------------
# intrinsics
# ------------------------------------------------------------------------------------------------
def _numbers(text: str) -> list[float]:
    text = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
    out = []
    for tok in re.split(r"[\s,;=]+", text.strip()):
        if not tok:
            continue
        try:
            out.append(float(tok))
        except ValueError:
            continue  # labels such as "fx" or "K"
    return out


def parse_intrinsics(spec, width: int | None = None, height: int | None = None) -> PinholeCamera:
    """A pinhole camera from ``"fx,fy,cx,cy"``, a file, a preset name, 4 numbers or a camera.

    Parameters
    ----------
    spec : str, path, sequence of 4 floats or PinholeCamera
        ``"fx,fy,cx,cy"`` (commas or spaces); a name of :data:`INTRINSICS_PRESETS`; a text file
        holding ``fx fy cx cy`` or the 9 entries of :math:`K` row by row (``#`` comments and labels
        such as ``fx:`` are ignored).
    width, height : int, optional
        Image size stored in the camera.

    Returns
    -------
    PinholeCamera

    Raises
    ------
    ValueError
        Not 4 (or 9) numbers, a non-positive focal length, or a K that is not upper triangular
        with last row ``0 0 1``.
    FileNotFoundError
        ``spec`` names a file that does not exist.

    Examples
    --------
    >>> cam = parse_intrinsics("tum-fr1", width=640, height=480)
    >>> (cam.fx, cam.cy, cam.width)
    (517.3, 255.3, 640)
    """
    if isinstance(spec, PinholeCamera):
        vals = [spec.fx, spec.fy, spec.cx, spec.cy]
    elif isinstance(spec, (str, Path)):
        text = str(spec).strip()
        if text.lower() in INTRINSICS_PRESETS:
            vals = list(INTRINSICS_PRESETS[text.lower()])
        else:
            vals = _numbers(text)
            if not re.fullmatch(r"[\d\s,.;eE+-]+", text):
                path = Path(text)
                if not path.is_file():
                    raise FileNotFoundError(
                        f"intrinsics must be 'fx,fy,cx,cy', a preset ({', '.join(INTRINSICS_PRESETS)}) or an "
                        f"existing file; {text!r} is none of these"
                    )
                vals = _numbers(path.read_text())
                if len(vals) == 9:
                    K = np.array(vals).reshape(3, 3)
                    if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0 or K[0, 1] != 0:
                        raise ValueError(
                            f"intrinsics file {path} must hold K = [[fx,0,cx],[0,fy,cy],[0,0,1]]"
                        )
                    vals = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    else:
        try:
            vals = [float(v) for v in spec]
        except TypeError:
            raise TypeError(
                f"intrinsics must be a string, a path or 4 numbers, got {type(spec).__name__}"
            ) from None
    if len(vals) != 4:
        raise ValueError(
            f"intrinsics must be 4 numbers fx,fy,cx,cy (or a 3x3 K in a file), got {len(vals)}: {vals}"
        )
    fx, fy, cx, cy = (float(v) for v in vals)
    if not (fx > 0 and fy > 0) or not np.isfinite([fx, fy, cx, cy]).all():
        raise ValueError(f"intrinsics need finite fx > 0 and fy > 0, got fx={fx}, fy={fy}, cx={cx}, cy={cy}")
    return PinholeCamera(fx, fy, cx, cy, width=width, height=height)


def _resolve_intrinsics(intrinsics, root: Path, width: int, height: int) -> PinholeCamera:
    if intrinsics is None:
        for name in _INTRINSICS_FILES:
            if (root / name).is_file():
                return parse_intrinsics(root / name, width, height)
        raise ValueError(
            f"intrinsics missing for {root}: pass intrinsics (--intrinsics fx,fy,cx,cy, a file or a preset "
            f"such as {', '.join(INTRINSICS_PRESETS)}) or put an intrinsics.txt with 'fx fy cx cy' "
            "in the folder"
        )
    return parse_intrinsics(intrinsics, width, height)


# ------------------------------------------------------------------------------------------------
# file lists and association (TUM's associate.py)
# ------------------------------------------------------------------------------------------------
def read_file_list(path) -> list[tuple[float, list[str]]]:
    """Parse a TUM list file (``rgb.txt``, ``depth.txt``): ``timestamp data...`` per line.

    Returns
    -------
    list of (float, list of str)
        In file order; comment (``#``) and empty lines are skipped.

    Raises
    ------
    FileNotFoundError, ValueError
        Missing file; a line whose first field is not a number.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found")
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        fields = [f for f in re.split(r"[\s,]+", line.strip()) if f]
        if not fields or fields[0].startswith("#"):
            continue
        try:
            stamp = float(fields[0])
        except ValueError:
            raise ValueError(f"{path}:{n}: expected 'timestamp filename', got {line!r}") from None
        out.append((stamp, fields[1:]))
    return out


def associate(first, second, offset: float = 0.0, max_difference: float = 0.02) -> list[tuple[int, int]]:
    r"""Pair two lists of timestamps as TUM's ``associate.py`` does.

    Every pair :math:`(a, b)` with :math:`|a - (b + \text{offset})| <` ``max_difference`` is a
    candidate; candidates are taken in order of increasing difference (ties: smaller ``a``, then
    smaller ``b``), skipping those whose ``a`` or ``b`` is already used.

    Parameters
    ----------
    first, second : array_like, shape (n,), (m,)
        Timestamps in seconds (need not be sorted).
    offset : float
        Added to ``second`` (a known clock offset).
    max_difference : float, > 0

    Returns
    -------
    list of (int, int)
        Index pairs into ``first`` and ``second``, sorted by ``first``'s timestamp.

    Examples
    --------
    >>> associate([0.0, 0.1], [0.09, 0.11, 0.5], max_difference=0.05)
    [(1, 1)]
    """
    a = np.asarray(first, dtype=np.float64).reshape(-1)
    b = np.asarray(second, dtype=np.float64).reshape(-1) + float(offset)
    max_difference = positive(max_difference, "max_difference")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("timestamps must be finite")
    order_b = np.argsort(b, kind="stable")
    bs = b[order_b]
    cand = []
    for i, t in enumerate(a):
        lo = np.searchsorted(bs, t - max_difference, side="left")
        hi = np.searchsorted(bs, t + max_difference, side="right")
        for j in order_b[lo:hi]:
            d = abs(t - b[j])
            if d < max_difference:
                cand.append((d, a[i], b[j] - offset, i, int(j)))
    cand.sort()
    used_a, used_b, pairs = set(), set(), []
    for _, _, _, i, j in cand:
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((i, j))
    pairs.sort(key=lambda p: (a[p[0]], p[0]))
    return pairs


# ------------------------------------------------------------------------------------------------
# images
# ------------------------------------------------------------------------------------------------
def _open_image(path: Path, what: str):
    from PIL import Image, UnidentifiedImageError

    if not path.is_file():
        raise FileNotFoundError(f"{what} image {path} not found")
    try:
        img = Image.open(path)
        img.load()
    except (UnidentifiedImageError, OSError, SyntaxError) as exc:
        raise ValueError(f"unreadable {what} PNG {path}: {exc}") from None
    return img


def read_rgb_png(path) -> np.ndarray:
    """A colour image as ``(H, W, 3) uint8`` (grey images are repeated into 3 channels).

    Raises
    ------
    FileNotFoundError, ValueError
        Missing or unreadable file (the message names it).
    """
    img = _open_image(Path(path), "rgb")
    if img.mode in ("I;16", "I;16B", "I;16L", "I"):
        a = np.asarray(img, dtype=np.float64)
        a = np.clip(a * 255.0 / max(a.max(), 1.0), 0, 255).astype(np.uint8)
        return np.repeat(a[..., None], 3, axis=2)
    return np.asarray(img.convert("RGB"), dtype=np.uint8).copy()


def read_depth_png(path, depth_scale: float = 5000.0) -> np.ndarray:
    """A 16-bit depth PNG as metres: ``Z = value / depth_scale``, 0 = no depth.

    Parameters
    ----------
    path : path
    depth_scale : float, > 0
        Raw units per metre (5000 for TUM RGB-D, 1000 for many RealSense/Kinect v2 recordings).

    Returns
    -------
    ndarray, shape (H, W) float64

    Raises
    ------
    FileNotFoundError, ValueError
        Missing, unreadable or not 16-bit (an 8-bit PNG cannot hold metric depth).
    """
    depth_scale = positive(depth_scale, "depth_scale")
    path = Path(path)
    img = _open_image(path, "depth")
    if img.mode not in ("I;16", "I;16B", "I;16L", "I"):
        raise ValueError(f"depth PNG {path} must be a 16-bit single-channel image, got PIL mode {img.mode!r}")
    return np.asarray(img, dtype=np.float64) / depth_scale


def read_pfm(path) -> np.ndarray:
    """Read a PFM image (``Pf`` grey or ``PF`` colour) top row first, as float64.

    PFM stores rows bottom to top, after a header ``Pf``/``PF``, ``width height`` and a scale
    whose sign gives the byte order (negative: little-endian).

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3)

    Raises
    ------
    FileNotFoundError, ValueError
        Missing file, bad header or truncated data.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"PFM file {path} not found")
    data = path.read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        start = pos
        while pos < len(data) and not data[pos : pos + 1].isspace():
            pos += 1
        if start == pos:
            raise ValueError(f"unreadable PFM {path}: truncated header")
        tokens.append(data[start:pos].decode("ascii", "replace"))
    pos += 1  # the single whitespace after the scale
    kind = tokens[0]
    if kind not in ("PF", "Pf"):
        raise ValueError(f"unreadable PFM {path}: header must start with 'PF' or 'Pf', got {kind!r}")
    try:
        w, h, scale = int(tokens[1]), int(tokens[2]), float(tokens[3])
    except ValueError:
        raise ValueError(f"unreadable PFM {path}: bad header {tokens}") from None
    ch = 3 if kind == "PF" else 1
    dtype = "<f4" if scale < 0 else ">f4"
    n = w * h * ch
    if len(data) - pos < 4 * n:
        raise ValueError(f"unreadable PFM {path}: {w}x{h}x{ch} floats expected, file is too short")
    a = np.frombuffer(data, dtype=dtype, count=n, offset=pos).astype(np.float64)
    a = a.reshape(h, w, ch) if ch == 3 else a.reshape(h, w)
    return a[::-1].copy()


def write_pfm(path, image) -> None:
    """Write a ``(H, W)`` or ``(H, W, 3)`` float image as little-endian PFM (rows bottom to top)."""
    a = np.asarray(image, dtype="<f4")
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3):
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got {a.shape}")
    kind = "PF" if a.ndim == 3 else "Pf"
    header = f"{kind}\n{a.shape[1]} {a.shape[0]}\n-1.0\n".encode("ascii")
    Path(path).write_bytes(header + np.ascontiguousarray(a[::-1]).tobytes())


# ------------------------------------------------------------------------------------------------
# sequences
# ------------------------------------------------------------------------------------------------
def _pngs(folder: Path, exts=(".png",)) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in exts)


def _require_dir(path: Path, what: str) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{what} {path} not found")
    if not path.is_dir():
        raise ValueError(f"{what} {path} is not a folder")


def _select(n: int, max_frames, step) -> range:
    step = positive_int(step, "step")
    idx = range(0, n, step)
    if max_frames is not None:
        idx = idx[: positive_int(max_frames, "max_frames")]
    return idx


def _stamp_from_name(p: Path) -> float | None:
    try:
        return float(p.stem)
    except ValueError:
        return None


def load_tum_sequence(
    root,
    intrinsics=None,
    depth_scale: float = 5000.0,
    max_difference: float = 0.02,
    max_frames: int | None = None,
    step: int = 1,
    dt: float | None = None,
) -> RGBDSequence:
    """Load a sequence in the TUM RGB-D layout (see the module docstring).

    Parameters
    ----------
    root : path
        The folder holding ``rgb/`` and ``depth/`` (and ideally ``rgb.txt``, ``depth.txt``).
    intrinsics : see :func:`parse_intrinsics`, optional
        Required unless ``root/intrinsics.txt`` exists.
    depth_scale : float, > 0
        Raw depth units per metre (TUM: 5000).
    max_difference : float, > 0
        Largest colour/depth timestamp difference of an associated pair (s; TUM's default 0.02).
    max_frames : int, optional
        Keep at most this many frames (after ``step``).
    step : int, >= 1
        Keep every ``step``-th associated frame.
    dt : float, optional
        Frame interval used when the file names carry no timestamps (default 1/30 s).

    Returns
    -------
    RGBDSequence
        Timestamps are those of the depth frames.

    Raises
    ------
    FileNotFoundError
        ``root``, ``rgb/``, ``depth/`` or a listed image is missing.
    ValueError
        Unreadable or non-16-bit PNGs, unequal image sizes, mismatched frame counts (no lists and a
        different number of PNGs in ``rgb/`` and ``depth/``), no associated pairs, missing intrinsics.
    """
    root = Path(root)
    _require_dir(root, "input folder")
    for sub in ("rgb", "depth"):
        _require_dir(root / sub, f"{sub}/ folder of")
    depth_scale = positive(depth_scale, "depth_scale")
    lists = [root / "rgb.txt", root / "depth.txt"]
    if all(p.is_file() for p in lists):
        rgb_list, depth_list = read_file_list(lists[0]), read_file_list(lists[1])
        for name, lst in (("rgb.txt", rgb_list), ("depth.txt", depth_list)):
            if not lst or any(not f for _, f in lst):
                raise ValueError(f"{root / name} must list 'timestamp filename' lines, found none")
        pairs = associate([s for s, _ in rgb_list], [s for s, _ in depth_list], max_difference=max_difference)
        if not pairs:
            raise ValueError(
                f"mismatched frame counts: none of the {len(rgb_list)} rgb.txt and {len(depth_list)} "
                f"depth.txt timestamps in {root} are within max_difference={max_difference} s of each other"
            )
        files = [(root / rgb_list[i][1][0], root / depth_list[j][1][0]) for i, j in pairs]
        stamps = [depth_list[j][0] for _, j in pairs]
    elif any(p.is_file() for p in lists):
        have, missing = (lists[0], lists[1]) if lists[0].is_file() else (lists[1], lists[0])
        raise FileNotFoundError(f"{have.name} is present but {missing} is missing; give both or neither")
    else:
        rgbs, depths = _pngs(root / "rgb"), _pngs(root / "depth")
        if len(rgbs) != len(depths):
            raise ValueError(
                f"mismatched frame counts: {root / 'rgb'} holds {len(rgbs)} PNGs but {root / 'depth'} holds "
                f"{len(depths)}; without rgb.txt/depth.txt they are paired in name order, so the counts "
                "must match"
            )
        files = list(zip(rgbs, depths))
        names = [_stamp_from_name(d) for _, d in files]
        if files and all(s is not None for s in names) and len(set(names)) == len(names):
            stamps = names
        else:
            step_s = positive(dt, "dt") if dt is not None else 1.0 / 30.0
            stamps = [i * step_s for i in range(len(files))]
    if not files:
        raise ValueError(f"no frames found in {root}: rgb/ and depth/ hold no PNGs")
    sel = _select(len(files), max_frames, step)
    files = [files[i] for i in sel]
    stamps = np.array([stamps[i] for i in sel], dtype=np.float64)
    rgb, depth = [], []
    for rgb_path, depth_path in files:
        c = read_rgb_png(rgb_path)
        d = read_depth_png(depth_path, depth_scale)
        if c.shape[:2] != d.shape:
            raise ValueError(f"rgb {rgb_path} is {c.shape[1]}x{c.shape[0]} but depth {depth_path} is "
                             f"{d.shape[1]}x{d.shape[0]}; they must be registered to the same size")
        if depth and d.shape != depth[0].shape:
            raise ValueError(f"depth {depth_path} is {d.shape[1]}x{d.shape[0]}, the first frame "
                             f"{depth[0].shape[1]}x{depth[0].shape[0]}: every frame must have the same size")
        rgb.append(c)
        depth.append(d)
    H, W = depth[0].shape
    cam = _resolve_intrinsics(intrinsics, root, W, H)
    return RGBDSequence(cam, rgb, depth, stamps, source=str(root), files=[(str(a), str(b)) for a, b in files],
                        indices=list(sel))


def load_stereo_sequence(
    root,
    intrinsics=None,
    baseline: float | None = None,
    disparity_scale: float = 256.0,
    doffs: float = 0.0,
    max_frames: int | None = None,
    step: int = 1,
    dt: float = 0.1,
) -> RGBDSequence:
    r"""Load rectified stereo frames with disparity maps as an RGB-D sequence (left view).

    Parameters
    ----------
    root : path
        Folder with ``left/``, ``disparity/`` and optionally ``right/`` (see the module docstring).
    intrinsics : optional
        Left camera; see :func:`parse_intrinsics` (``fx`` is the focal length of :math:`Z = fB/d`).
    baseline : float, > 0
        Distance between the two camera centres (m). Required.
    disparity_scale : float, > 0
        For 16-bit PNG disparity maps: raw units per pixel (KITTI: 256); a raw 0 means no
        measurement. PFM maps are in pixels, NaN or inf for unknown.
    doffs : float
        Added to the disparity before the division (Middlebury's ``doffs``); finite.
    max_frames, step : see :func:`load_tum_sequence`
    dt : float, > 0
        Frame interval (s).

    Returns
    -------
    RGBDSequence
        Depth from :func:`flowtrack.camera.depth_from_disparity`, 0 at invalid disparities.

    Raises
    ------
    FileNotFoundError, ValueError
        As :func:`load_tum_sequence`; also a missing ``baseline`` or a non-finite ``doffs``.
    """
    root = Path(root)
    _require_dir(root, "input folder")
    if baseline is None:
        raise ValueError("baseline missing: a stereo input needs the baseline in metres (--baseline)")
    baseline = positive(baseline, "baseline")
    disparity_scale = positive(disparity_scale, "disparity_scale")
    doffs = scalar(doffs, "doffs")
    dt = positive(dt, "dt")
    _require_dir(root / "left", "left/ folder of")
    _require_dir(root / "disparity", "disparity/ folder of")
    lefts = _pngs(root / "left")
    disps = _pngs(root / "disparity", (".png", ".pfm"))
    if len(lefts) != len(disps):
        raise ValueError(f"mismatched frame counts: {root / 'left'} holds {len(lefts)} PNGs but "
                         f"{root / 'disparity'} holds {len(disps)} disparity maps")
    if (root / "right").is_dir():
        rights = _pngs(root / "right")
        if len(rights) != len(lefts):
            raise ValueError(f"mismatched frame counts: {root / 'left'} holds {len(lefts)} PNGs but "
                             f"{root / 'right'} holds {len(rights)}")
    if not lefts:
        raise ValueError(f"no frames found in {root}: left/ holds no PNGs")
    sel = _select(len(lefts), max_frames, step)
    rgb, depth, files = [], [], []
    cam = None
    for i in sel:
        c = read_rgb_png(lefts[i])
        if disps[i].suffix.lower() == ".pfm":
            d = read_pfm(disps[i])
            if d.ndim != 2:
                raise ValueError(f"disparity {disps[i]} must be a single-channel PFM ('Pf')")
        else:
            img = _open_image(disps[i], "disparity")
            if img.mode not in ("I;16", "I;16B", "I;16L", "I"):
                raise ValueError(f"disparity PNG {disps[i]} must be 16-bit, got PIL mode {img.mode!r}")
            raw = np.asarray(img, dtype=np.float64)
            d = np.where(raw > 0, raw / disparity_scale, np.nan)  # raw 0: no measurement, even if doffs > 0
        if c.shape[:2] != d.shape:
            raise ValueError(f"left {lefts[i]} is {c.shape[1]}x{c.shape[0]} but disparity {disps[i]} is "
                             f"{d.shape[1]}x{d.shape[0]}")
        if cam is None:
            cam = _resolve_intrinsics(intrinsics, root, d.shape[1], d.shape[0])
        rgb.append(c)
        depth.append(depth_from_disparity(d, cam.fx, baseline, doffs))
        files.append((str(lefts[i]), str(disps[i])))
    stamps = np.array(list(sel), dtype=np.float64) * dt  # with step, frames are step * dt apart
    return RGBDSequence(cam, rgb, depth, stamps, source=str(root), files=files, indices=list(sel))


def load_rgbd(root, stereo: bool = False, **kwargs) -> RGBDSequence:
    """:func:`load_stereo_sequence` if ``stereo`` else :func:`load_tum_sequence` (same keywords)."""
    return load_stereo_sequence(root, **kwargs) if stereo else load_tum_sequence(root, **kwargs)


def write_tum_sequence(root, rgb: Sequence, depth: Sequence, timestamps, depth_scale: float = 5000.0,
                       camera: PinholeCamera | None = None, depth_delay: float = 0.0) -> Path:
    """Write frames in the TUM RGB-D layout (e.g. a synthetic scene, to try ``--input``).

    Depth is stored as ``round(Z * depth_scale)`` in 16-bit PNGs (so it round-trips to
    ``1 / depth_scale`` m, clipped at 65535 units); ``depth_delay`` shifts the depth timestamps, to
    mimic the two clocks of a real sensor. With ``camera`` an ``intrinsics.txt`` is written too.

    Returns
    -------
    Path
        ``root``.
    """
    from PIL import Image

    root = Path(root)
    depth_scale = positive(depth_scale, "depth_scale")
    if len(rgb) != len(depth) or len(depth) != len(timestamps):
        raise ValueError(f"rgb, depth and timestamps must have the same length, got "
                         f"{len(rgb)}, {len(depth)}, {len(timestamps)}")
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    (root / "depth").mkdir(parents=True, exist_ok=True)
    rgb_lines = ["# color images", "# timestamp filename"]
    depth_lines = ["# depth maps", "# timestamp filename"]
    for c, d, t in zip(rgb, depth, timestamps):
        tr, td = float(t), float(t) + depth_delay
        Image.fromarray(np.asarray(c, dtype=np.uint8)).save(root / "rgb" / f"{tr:.6f}.png")
        raw = np.clip(np.rint(np.nan_to_num(np.asarray(d, dtype=np.float64)) * depth_scale), 0, 65535)
        Image.fromarray(raw.astype(np.uint16)).save(root / "depth" / f"{td:.6f}.png")
        rgb_lines.append(f"{tr:.6f} rgb/{tr:.6f}.png")
        depth_lines.append(f"{td:.6f} depth/{td:.6f}.png")
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    if camera is not None:
        c = camera
        (root / "intrinsics.txt").write_text(f"# fx fy cx cy\n{c.fx} {c.fy} {c.cx} {c.cy}\n")
    return root
