r"""The ports' test vectors: ``cpp_java_matlab_ports/vectors/<problem>.json``, made by the reference.

Every problem is one file in the shared vectors format (:mod:`flowtrack_course.polyglot.vectors`)::

    {"problem": "<name>",
     "cases": [{"id": "<case id>", "input": {...}, "expected": {...}, "rtol": r, "atol": a}, ...]}

The problems, their conventions and their cases are defined once, in
:mod:`flowtrack_course.polyglot.problems` (the same definitions give the language grader its cases);
this module writes, reads and checks the files. They are generated, never edited by hand:
:func:`write_vectors` (``flowtrack ports --regenerate``) is deterministic (fixed seeds, JSON with
sorted keys, ``repr``-exact floats). Regenerating on the machine that wrote the files gives the same
bytes; on another CPU, BLAS, CHOLMOD, open3d or OpenCV build the floats may differ in their last
bits, so a test compares a regeneration with the committed files by :func:`vector_differences`
within :data:`REGENERATION_RTOL` (far below the ports' tolerances, far above rounding noise).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from ..course import ports_dir
from ..course import vectors_dir as _course_vectors
from ..polyglot.problems import VECTOR_PROBLEMS
from ..polyglot.vectors import dumps

__all__ = [
    "REGENERATION_RTOL",
    "dumps",
    "generate",
    "problem_names",
    "load_vectors",
    "vector_differences",
    "write_vectors",
]


def __getattr__(name: str) -> Path:
    """``PORTS_DIR`` (the course's ports folder: sources, ``vectors/``, the build cache ``build/``)
    and ``VECTORS_DIR``, looked up when read (``--course``/``$FLOWTRACK_COURSE``/the current folder,
    see :mod:`flowtrack_course.course`)."""
    if name == "PORTS_DIR":
        return ports_dir()
    if name == "VECTORS_DIR":
        return _course_vectors()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: Problem -> relative tolerance within which a regeneration must reproduce the committed file.
#: A float ``g`` regenerated for the committed ``e`` passes iff ``|g - e| <= rtol (|e| + s)``, with
#: ``s`` the largest magnitude of the same ``input``/``expected`` entry in that case (so a component
#: that is zero up to rounding is judged at the scale of its array, not by its own size). Each value
#: sits between two bounds: far above last-bit noise across machines (measured: 1e-16 to 3e-14
#: relative for CHOLMOD/BLAS and OpenCV-free rendering; closed forms stay within a few ulps) and far
#: below what a port is allowed (the case's ``rtol``/``atol``), so a real change of a committed value
#: (1e-5 relative, a test checks) is always caught.
REGENERATION_RTOL: dict[str, float] = {
    # 1000-step filter recursions with 4x4 BLAS products: noise ~1e-14; ports get 1e-9
    "kalman_cv2d": 1e-12,
    # closed-form polynomials in dt: a few ulps (1 ulp = 2.2e-16 relative); ports get 1e-12, so ~20 ulps
    "white_noise_q": 4e-15,
    # closed-form quotients: a few ulps; ports get 1e-12, so ~20 ulps
    "projection_jacobian": 4e-15,
    # 2x2 / 3x3 solves (LAPACK): ~1e-15; ports get 1e-10
    "mahalanobis_assignment": 2e-13,
    # sparse direct solve (SuperLU ordering/BLAS): measured up to 3e-14 across machines; ports get 1e-8
    "graph_scene_flow": 1e-11,
    # DCT (FFT) solves: ~1e-14 of the array scale; ports get 1e-8
    "variational_scene_flow": 1e-11,
    # open3d ICP (threaded reductions), T rounded to 12 significant digits: up to ~1e-12 from the
    # rounding alone; ports get 1e-4 absolute
    "rigid_icp": 1e-9,
    # exact projection differences of the rendered scene: measured 1.6e-13 across machines; ports get
    # 0.5 px absolute (about 1e-1 relative)
    "lucas_kanade": 1e-10,
    # closed-form scalar Riccati root (correctly rounded sqrt): a few ulps; ports get 1e-10
    "steady_state_scalar": 1e-13,
}


def vector_differences(committed: dict, regenerated: dict, rtol: float) -> list[str]:
    r"""What differs between two documents of one problem, numbers compared within ``rtol``.

    Structure (keys, list lengths, case ids), strings, booleans and integers must be equal; floats
    :math:`g` (regenerated) and :math:`e` (committed) must satisfy :math:`|g - e| \le
    \text{rtol}\,(|e| + s)`, :math:`s` the largest magnitude within the same top-level entry of
    the case's ``input`` or ``expected`` (or the value itself for scalars), so entries that are zero
    up to rounding are judged at the scale of their array. An integer may match a float of the same
    value (JSON writes ``1.0`` as ``1.0``, but a generator may produce either).

    Parameters
    ----------
    committed, regenerated : dict
        Problem documents (``json.loads`` of the files).
    rtol : float >= 0
        E.g. :data:`REGENERATION_RTOL` ``[problem]``.

    Returns
    -------
    list of str
        One line per difference (empty when the documents agree), naming the case and the path.

    Examples
    --------
    >>> a = {"problem": "p", "cases": [{"id": "c", "expected": {"x": [1.0, 1e-17]}}]}
    >>> b = {"problem": "p", "cases": [{"id": "c", "expected": {"x": [1.0 + 4e-16, -3e-17]}}]}
    >>> vector_differences(a, b, 1e-12)
    []
    >>> b["cases"][0]["expected"]["x"][0] = 1.00001
    >>> vector_differences(a, b, 1e-12)  # doctest: +ELLIPSIS
    ['case c: expected/x/0: 1.00001 regenerated vs 1.0 committed (...)']
    """
    if not (isinstance(rtol, (int, float)) and rtol >= 0):
        raise ValueError(f"rtol must be a number >= 0, got {rtol!r}")
    out: list[str] = []

    def scale(value) -> float:
        if isinstance(value, bool):
            return 0.0
        if isinstance(value, (int, float)):
            return abs(float(value))
        if isinstance(value, list):
            return max((scale(v) for v in value), default=0.0)
        if isinstance(value, dict):
            return max((scale(v) for v in value.values()), default=0.0)
        return 0.0

    def walk(e, g, path: str, where: str, s: float) -> None:
        if isinstance(e, bool) or isinstance(g, bool) or isinstance(e, str) or e is None:
            if type(e) is not type(g) or e != g:
                out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed")
            return
        if isinstance(e, (int, float)) and isinstance(g, (int, float)):
            if isinstance(e, int) and isinstance(g, int):
                if e != g:
                    out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed (integers differ)")
                return
            bound = rtol * (abs(e) + s)
            if not abs(g - e) <= bound:
                out.append(f"{where}: {path}: {g!r} regenerated vs {e!r} committed (|diff| "
                           f"{abs(g - e):.3g} > {bound:.3g})")
            return
        if isinstance(e, list) and isinstance(g, list):
            if len(e) != len(g):
                out.append(f"{where}: {path}: length {len(g)} regenerated vs {len(e)} committed")
                return
            for i, (a, b) in enumerate(zip(e, g)):
                walk(a, b, f"{path}/{i}" if path else str(i), where, s)
            return
        if isinstance(e, dict) and isinstance(g, dict):
            if set(e) != set(g):
                out.append(f"{where}: {path or 'keys'}: {sorted(g)} regenerated vs {sorted(e)} committed")
                return
            for key in sorted(e):
                walk(e[key], g[key], f"{path}/{key}" if path else key, where, s)
            return
        out.append(f"{where}: {path}: {type(g).__name__} regenerated vs {type(e).__name__} committed")

    head_e = {k: v for k, v in committed.items() if k != "cases"}
    head_g = {k: v for k, v in regenerated.items() if k != "cases"}
    walk(head_e, head_g, "", "document", 0.0)
    cases_e, cases_g = committed.get("cases", []), regenerated.get("cases", [])
    ids_e = [c.get("id") for c in cases_e]
    ids_g = [c.get("id") for c in cases_g]
    if ids_e != ids_g:
        return [*out, f"document: case ids {ids_g} regenerated vs {ids_e} committed"]
    for ce, cg in zip(cases_e, cases_g):
        where = f"case {ce.get('id')}"
        if set(ce) != set(cg):
            out.append(f"{where}: keys {sorted(cg)} regenerated vs {sorted(ce)} committed")
            continue
        for key in sorted(ce):
            if isinstance(ce[key], dict) and isinstance(cg[key], dict) and set(ce[key]) == set(cg[key]):
                for sub in sorted(ce[key]):  # one scale per top-level entry of input / expected
                    walk(ce[key][sub], cg[key][sub], f"{key}/{sub}", where, scale(ce[key][sub]))
            else:
                walk(ce[key], cg[key], key, where, scale(ce[key]))
    return out


def problem_names() -> list[str]:
    """Names of all problems with a vector file, sorted."""
    return sorted(VECTOR_PROBLEMS)


def generate(problem: str) -> dict:
    """Make the document of one problem.

    Parameters
    ----------
    problem : str
        One of :func:`problem_names`.

    Returns
    -------
    dict
        ``{"problem": problem, "cases": [...]}``.
    """
    if problem not in VECTOR_PROBLEMS:
        raise ValueError(f"problem must be one of {problem_names()}, got {problem!r}")
    return VECTOR_PROBLEMS[problem].vectors()


def write_vectors(
    out_dir: Path | str | None = None, problems: Iterable[str] | None = None, progress: bool = False
) -> list[Path]:
    """Write ``<out_dir>/<problem>.json`` for the given problems (default: all).

    Parameters
    ----------
    out_dir : path, optional
        Folder (created if missing; default: the course's ``cpp_java_matlab_ports/vectors``).
    problems : iterable of str, optional
        Subset of :func:`problem_names`.
    progress : bool
        Show a tqdm progress bar.

    Returns
    -------
    list of Path
        The files written.
    """
    names = problem_names() if problems is None else list(problems)
    for name in names:
        if name not in VECTOR_PROBLEMS:
            raise ValueError(f"problems must be among {problem_names()}, got {name!r}")
    out = Path(out_dir) if out_dir is not None else _course_vectors()
    out.mkdir(parents=True, exist_ok=True)
    written = []
    iterator: Iterable[str] = names
    if progress:
        from tqdm import tqdm

        iterator = tqdm(names, desc="vectors", unit="problem")
    for name in iterator:
        path = out / f"{name}.json"
        path.write_text(dumps(generate(name)), encoding="utf-8")
        written.append(path)
    return written


def load_vectors(vectors_dir: Path | str | None = None) -> dict[str, dict]:
    """Read every ``*.json`` problem document of a folder (default: the course's vectors) into
    ``{problem: doc}``."""
    d = Path(vectors_dir) if vectors_dir is not None else _course_vectors()
    if not d.is_dir():
        raise FileNotFoundError(f"vectors_dir {d} is not a folder (run `flowtrack ports --regenerate`)")
    return {p.stem: json.loads(p.read_text(encoding="utf-8")) for p in sorted(d.glob("*.json"))}
