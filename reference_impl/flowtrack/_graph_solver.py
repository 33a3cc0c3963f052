r"""The solvers of graph scene flow's linear system, and the cost model that picks one.

Graph scene flow (:func:`flowtrack.sceneflow.graph_scene_flow`) solves, for the three columns of
:math:`V` at once,

.. math::  A\,V = B, \qquad A = \Delta t^2 I + \lambda L ,

with :math:`A` sparse, symmetric positive definite and diagonally dominant, its condition number at
most the Gershgorin bound :math:`\kappa = 1 + 2 \lambda d_{max} / \Delta t^2`. :func:`spd_solver`
returns ``solve(B)`` for one of four methods; a direct one factorises :math:`A` once for every
right-hand side:

- ``"cholmod"``: sparse Cholesky, scikit-sparse's simplicial :math:`LDL^\top` (optional dependency);
- ``"splu"``: scipy's SuperLU with a COLAMD ordering;
- ``"cg"``: block conjugate gradients with a Jacobi preconditioner, iterated to a relative
  residual of ``tol / kappa`` so that the relative error of each column is at most ``tol``;
- ``"amg"``: the same CG preconditioned by one V-cycle of pyamg's smoothed-aggregation hierarchy
  (:func:`amg_preconditioner`, optional dependency).

``"auto"`` (:func:`auto_choice`) predicts each method's cost in units of one Jacobi-CG iteration:
:math:`T_{cg} \approx 8 \sqrt\kappa`, :math:`T_{amg} \approx 35 + 16\,\kappa^{0.3}` and, from the
column counts :math:`c_j` of the Cholesky factor after an AMD ordering, :math:`T_{chol} \approx
\sum_j c_j^2 / (200 N) + \sum_j c_j / (20 N)`; it picks the cheapest. The column counts come from
CHOLMOD's symbolic analysis without any numeric work; scikit-sparse does not expose them, so
:class:`CholmodCounts` calls libcholmod through ctypes. The derivation and the measurements behind
the constants are in :func:`flowtrack.sceneflow.graph_scene_flow` (Notes) and
``benchmarks/results/graphflow.md``.

A helper module of :mod:`flowtrack.sceneflow`, which re-exports :data:`HAVE_CHOLMOD` and
:data:`HAVE_PYAMG`.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._graph import block_pcg

try:  # optional: CHOLMOD (scikit-sparse <= 0.4.x builds against SuiteSparse 5; 0.5 needs SuiteSparse 7)
    from sksparse.cholmod import analyze as _cholmod_analyze
    from sksparse.cholmod import cholesky as _cholmod_cholesky
except Exception:  # pragma: no cover - depends on the environment
    _cholmod_cholesky = _cholmod_analyze = None

try:  # optional: algebraic multigrid preconditioner for CG
    import pyamg as _pyamg
except Exception:  # pragma: no cover - depends on the environment
    _pyamg = None

__all__ = [
    "HAVE_CHOLMOD",
    "HAVE_PYAMG",
    "SOLVERS",
    "CholmodCounts",
    "amg_preconditioner",
    "auto_choice",
    "cg_kappa_limit",
    "cholmod_counts",
    "predicted_costs",
    "spd_solver",
]

#: True when scikit-sparse's CHOLMOD could be imported (used by ``solver="auto"``).
HAVE_CHOLMOD = _cholmod_cholesky is not None
#: True when pyamg could be imported (``solver="amg"``, and ``"auto"`` on ill-conditioned systems).
HAVE_PYAMG = _pyamg is not None

#: The ``solver`` choices of :func:`spd_solver` (and of :func:`flowtrack.sceneflow.graph_scene_flow`).
SOLVERS = ("auto", "cholmod", "splu", "cg", "amg")

# solver="auto" cost model (see graph_scene_flow's docstring). Unit: one Jacobi block-CG iteration on
# the N points (a 3-column mat-vec and the vector updates; ~ N, as kNN rows have ~k non-zeros).
# Constants measured with benchmarks/bench_graphflow.py on 20k and 100k surface and volumetric clouds
# as ratios of times in one run, so the machine's speed cancels.
_CG_ITERS_PER_SQRT_KAPPA = 8.0  # Jacobi CG iterations to tol = 1e-8: 6.4-9.2 sqrt(kappa) measured
_AMG_SETUP = 35.0  # pyamg smoothed-aggregation hierarchy, in CG iterations (26-40 measured)
_AMG_PER_ITER = 4.0  # one V-cycle per column + mat-vec, in CG iterations (3.3-6 measured)
_AMG_ITERS_SCALE, _AMG_ITERS_EXPONENT = 4.0, 0.3  # AMG-CG iterations ~ 4 kappa^0.3 (10 / 20 / 30-44)
_ANALYSIS = 15.0  # AMD ordering + elimination tree + column counts, in CG iterations (10-19 measured)
_FLOPS_PER_ITER_POINT = 200.0  # factorisation multiply-adds costing one CG iteration, per point
_SOLVE_NNZ_PER_ITER_POINT = 20.0  # non-zeros of L whose 3-column substitutions cost one CG iteration
# Run the symbolic analysis only when the cheaper iterative method is predicted to cost more than this
# many analyses: below it the analysis alone would eat the margin a direct solve could win.
_ANALYSE_ABOVE = 4.0
# Without CHOLMOD's column counts (libcholmod not loadable by ctypes) the older rule: CG when the
# Gershgorin bound kappa is at most 18 (N / 20k)^0.8 (crossover measured on depth-camera clouds) ...
_CG_KAPPA_WITH_CHOLMOD = 18.0
_CG_KAPPA_N_REF = 20_000
_CG_KAPPA_N_EXPONENT = 0.8
# ... and without CHOLMOD this fixed limit (SuperLU's fill-in grows fast, CG's cost only with sqrt(kappa)).
_CG_KAPPA_WITHOUT_CHOLMOD = 1.0e3


class CholmodCounts:
    """CHOLMOD's symbolic column counts through ctypes (scikit-sparse 0.4 does not expose them).

    ``colcounts(A, perm)`` returns the number of non-zeros of every column of the Cholesky factor
    of ``A[perm][:, perm]`` (diagonal included), computed by libcholmod's own ``cholmod_etree``,
    ``cholmod_postorder`` and ``cholmod_rowcolcounts`` (Gilbert, Ng & Peyton: O(nnz(A)) time, no
    numeric work) on the library scikit-sparse is linked with. The first use checks the binding on
    two matrices with known fill (a path: 2n - 1; a dense 5 x 5: 15); if that fails or the library
    cannot be loaded, ``ok`` is False and ``solver="auto"`` falls back to the condition-bound rule.
    """

    def __init__(self):
        self.ok = False
        try:
            self._bind()
            n = 10
            path = sp.diags([np.full(n - 1, -1.0), np.full(n, 3.0), np.full(n - 1, -1.0)], [-1, 0, 1])
            dense = sp.csc_matrix(np.ones((5, 5)) + 5.0 * np.eye(5))
            self.ok = True
            ok_path = int(self.colcounts(path, np.arange(n)).sum()) == 2 * n - 1
            ok_dense = int(self.colcounts(dense, np.arange(5)).sum()) == 15
            self.ok = ok_path and ok_dense
        except Exception:  # pragma: no cover - depends on the environment
            self.ok = False

    def _bind(self) -> None:
        import ctypes
        import ctypes.util

        class Sparse(ctypes.Structure):  # cholmod_sparse (SuiteSparse 4-7)
            _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t), ("nzmax", ctypes.c_size_t),
                        ("p", ctypes.c_void_p), ("i", ctypes.c_void_p), ("nz", ctypes.c_void_p),
                        ("x", ctypes.c_void_p), ("z", ctypes.c_void_p), ("stype", ctypes.c_int),
                        ("itype", ctypes.c_int), ("xtype", ctypes.c_int), ("dtype", ctypes.c_int),
                        ("sorted", ctypes.c_int), ("packed", ctypes.c_int)]

        lib = None
        for name in ("libcholmod.so.3", ctypes.util.find_library("cholmod")):
            if name:
                try:
                    lib = ctypes.CDLL(name)
                    break
                except OSError:
                    continue
        if lib is None:
            raise OSError("libcholmod not found")
        vp = ctypes.c_void_p
        lib.cholmod_start.argtypes = lib.cholmod_finish.argtypes = [vp]
        lib.cholmod_etree.argtypes = [ctypes.POINTER(Sparse), vp, vp]
        lib.cholmod_postorder.argtypes = [vp, ctypes.c_size_t, vp, vp, vp]
        lib.cholmod_postorder.restype = ctypes.c_long
        lib.cholmod_rowcolcounts.argtypes = [ctypes.POINTER(Sparse), vp, ctypes.c_size_t, vp, vp, vp, vp,
                                             vp, vp, vp]
        self._lib, self._Sparse, self._ctypes = lib, Sparse, ctypes

    def colcounts(self, A: sp.spmatrix, perm: np.ndarray) -> np.ndarray:
        if not self.ok:
            raise RuntimeError("CHOLMOD column counts unavailable")
        ct, lib = self._ctypes, self._lib
        n = A.shape[0]
        C = sp.csr_matrix(A)[perm][:, perm]
        keep = []

        def pattern(M, stype):  # CHOLMOD_INT indices, CHOLMOD_PATTERN, sorted, packed
            M = M.tocsc()
            M.sort_indices()
            ip = np.ascontiguousarray(M.indptr, dtype=np.int32)
            ii = np.ascontiguousarray(M.indices, dtype=np.int32)
            keep.append((ip, ii))
            return self._Sparse(n, n, len(ii), ip.ctypes.data, ii.ctypes.data, None, None, None, stype,
                                0, 0, 0, 1, 1)

        upper, lower = pattern(sp.triu(C), 1), pattern(sp.tril(C), -1)
        common = ct.create_string_buffer(1 << 16)  # > sizeof(cholmod_common) in every release
        parent, post, count, first, level = (np.empty(n, dtype=np.int32) for _ in range(5))
        lib.cholmod_start(common)
        try:
            ok = lib.cholmod_etree(ct.byref(upper), parent.ctypes.data, common)
            ok = ok and lib.cholmod_postorder(parent.ctypes.data, n, None, post.ctypes.data, common) == n
            ok = ok and lib.cholmod_rowcolcounts(ct.byref(lower), None, 0, parent.ctypes.data,
                                                 post.ctypes.data, None, count.ctypes.data,
                                                 first.ctypes.data, level.ctypes.data, common)
        finally:
            lib.cholmod_finish(common)
        if not ok:
            raise RuntimeError("cholmod_rowcolcounts failed")
        return count.astype(np.int64)


_COUNTS: list = []  # the one CholmodCounts, made on first use


def cholmod_counts():
    """The process's one :class:`CholmodCounts` (made on first use), or None when it cannot work."""
    if not HAVE_CHOLMOD:
        return None
    if not _COUNTS:
        _COUNTS.append(CholmodCounts() if HAVE_CHOLMOD else None)
    c = _COUNTS[0]
    return c if c is not None and c.ok else None


def amg_preconditioner(A: sp.csr_matrix):
    r"""One symmetric V-cycle of pyamg's smoothed-aggregation hierarchy on (N, C) blocks.

    The hierarchy (aggregates, prolongators, Galerkin coarse matrices) is built once by
    :func:`pyamg.smoothed_aggregation_solver` and reused for every column and every CG iteration. The
    cycle runs on all columns at once: two damped-Jacobi sweeps (:math:`\omega = 2/3`) before and
    after the coarse correction, a sparse LU on the coarsest level; pre- and post-smoothing are
    adjoint, so the cycle is a symmetric positive definite :math:`M^{-1}` as CG needs.
    """
    ml = _pyamg.smoothed_aggregation_solver(A, symmetry="symmetric", improve_candidates=None)
    levels = ml.levels
    dinv = [(2.0 / 3.0) / lv.A.diagonal() for lv in levels]
    coarse = spla.splu(levels[-1].A.tocsc())

    def cycle(lvl: int, B: np.ndarray) -> np.ndarray:
        if lvl == len(levels) - 1:
            return coarse.solve(B)
        Al, w = levels[lvl].A, dinv[lvl][:, None]
        X = w * B
        X += w * (B - Al @ X)
        X += levels[lvl].P @ cycle(lvl + 1, levels[lvl].R @ (B - Al @ X))
        X += w * (B - Al @ X)
        X += w * (B - Al @ X)
        return X

    return lambda R: cycle(0, np.ascontiguousarray(R))


def predicted_costs(A: sp.csr_matrix, kappa: float) -> dict:
    """Iterative costs of the cost model, in Jacobi-CG iterations (see graph_scene_flow, Notes)."""
    costs = {"cg": _CG_ITERS_PER_SQRT_KAPPA * np.sqrt(kappa)}
    if HAVE_PYAMG:
        costs["amg"] = _AMG_SETUP + _AMG_PER_ITER * _AMG_ITERS_SCALE * kappa**_AMG_ITERS_EXPONENT
    return costs


def auto_choice(A: sp.csr_matrix, kappa: float) -> tuple[str, object]:
    """``solver="auto"``: the method the fill-based cost model predicts fastest, and its analysis.

    Returns ``(solver, factor)``; ``factor`` is scikit-sparse's symbolic factor (AMD ordering) when the
    analysis was run and CHOLMOD chosen, so the numeric factorisation reuses it, else None.
    """
    iterative = predicted_costs(A, kappa)
    best_iter = min(iterative, key=iterative.get)
    counts = cholmod_counts()
    if counts is None:  # no column counts: the condition-bound rule (and AMG beyond it if available)
        if kappa <= cg_kappa_limit(A.shape[0]):
            return "cg", None
        if HAVE_PYAMG and iterative["amg"] < iterative["cg"]:
            return "amg", None
        return ("cholmod" if HAVE_CHOLMOD else "splu"), None
    if iterative[best_iter] <= _ANALYSE_ABOVE * _ANALYSIS:
        return best_iter, None
    factor = _cholmod_analyze(A.tocsc(), mode="simplicial", ordering_method="amd")
    c = counts.colcounts(A, factor.P()).astype(np.float64)
    n = float(A.shape[0])
    direct = float(c @ c) / (_FLOPS_PER_ITER_POINT * n) + float(c.sum()) / (_SOLVE_NNZ_PER_ITER_POINT * n)
    if direct < iterative[best_iter]:
        return "cholmod", factor
    return best_iter, None


def spd_solver(A: sp.csr_matrix, solver: str, kappa: float, tol: float):
    """Return ``solve(B)`` for ``A X = B``, SPD sparse A; a direct method factorises A once here.

    ``solver`` as in :func:`graph_scene_flow`; several right-hand sides (or several calls, as in
    :func:`iterative_graph_scene_flow`) share the one factorisation (or AMG hierarchy).
    """
    if solver == "auto":
        solver, factor = auto_choice(A, kappa)
        if factor is not None:  # numeric factorisation on the analysis the choice was made from
            factor.cholesky_inplace(A.tocsc())
            return factor
    if solver == "cholmod":
        if not HAVE_CHOLMOD:
            raise ValueError("solver='cholmod' needs scikit-sparse (sksparse.cholmod), not importable")
        # Simplicial (column by column) LDL': these graphs fill in too little for the supernodal
        # BLAS kernels to pay off; measured 1.4-1.9x faster for N = 5k-100k with 1 or 2 BLAS threads.
        return _cholmod_cholesky(A.tocsc(), mode="simplicial")
    if solver == "splu":
        return spla.splu(A.tocsc(), permc_spec="COLAMD").solve
    precond = None
    if solver == "amg":
        if not HAVE_PYAMG:
            raise ValueError("solver='amg' needs pyamg, not importable (pip install pyamg)")
        precond = amg_preconditioner(A)
    direct = []  # built only if CG ever fails

    def cg_solve(B: np.ndarray) -> np.ndarray:
        # ||x - x*|| / ||x*|| <= cond(A) ||r|| / ||b||, so a residual of tol / kappa bounds the error
        # by tol; the floor keeps the target above what rounding lets the true residual reach.
        rtol = max(tol / kappa, 8.0 * np.finfo(float).eps * kappa)
        maxiter = 1000 if precond is not None else max(1000, 50 * int(np.sqrt(kappa)) + 100)
        X, _, ok = block_pcg(A, B, rtol, maxiter=maxiter, precond=precond)
        if ok:
            return X
        warnings.warn(
            "graph_scene_flow: CG did not reach its tolerance; falling back to a direct solve",
            RuntimeWarning,
            stacklevel=3,
        )
        if not direct:
            direct.append(spd_solver(A, "cholmod" if HAVE_CHOLMOD else "splu", kappa, tol))
        return direct[0](B)

    return cg_solve


def cg_kappa_limit(n: int) -> float:
    """Largest condition bound for which the fallback rule (no column counts) picks block CG."""
    if not HAVE_CHOLMOD:
        return _CG_KAPPA_WITHOUT_CHOLMOD
    return _CG_KAPPA_WITH_CHOLMOD * (n / _CG_KAPPA_N_REF) ** _CG_KAPPA_N_EXPONENT
