r"""Scene flow on point clouds: graph-regularised (syllabus section 4), rigid ICP (section 8), metrics.

Graph scene flow
----------------
Given points :math:`X_i \in \mathbb{R}^3` at time :math:`t` and correspondences :math:`Y_i` at
:math:`t + \Delta t` (e.g. :func:`nearest_neighbor_targets`), the velocities :math:`v_i` minimise

.. math::  E(v) = \sum_i \lVert X_i + v_i \Delta t - Y_i \rVert^2
           + \lambda \sum_{i<j} w_{ij} \lVert v_i - v_j \rVert^2 .

With the graph Laplacian :math:`L = D - W` (:math:`D = \operatorname{diag}(\sum_j w_{ij})`) the
smoothness term is :math:`\sum_c v_{:,c}^\top L\, v_{:,c}`, so :math:`\nabla E = 0` splits into three
independent :math:`N \times N` systems that share one matrix,

.. math::  (\Delta t^2 I + \lambda L)\, V = \Delta t\, (Y - X), \qquad V \in \mathbb{R}^{N \times 3},

which is the syllabus' :math:`(A^\top A + \lambda L \otimes I_3) v = A^\top b` with :math:`A = \Delta t
I_{3N}` written without the Kronecker product. The matrix is symmetric positive definite (eigenvalues in
:math:`[\Delta t^2, \Delta t^2 + 2 \lambda d_{max}]` by Gershgorin, :math:`d_{max}` the largest degree)
and diagonally dominant; :func:`graph_scene_flow` factorises it once (CHOLMOD when scikit-sparse is
importable, else SuperLU) or runs a block CG (Jacobi or, with pyamg, algebraic-multigrid preconditioned),
whichever a cost model fed by CHOLMOD's symbolic analysis (the fill of the factor) predicts fastest
(see :func:`graph_scene_flow`, Notes; measured in ``benchmarks/results/graphflow.md``). The solvers,
the cost model and the ctypes binding to CHOLMOD's column counts live in the helper module
``flowtrack._graph_solver``.

Rigid scene flow
----------------
The syllabus' Open3D sketch: ICP registers the cloud at :math:`t` onto the cloud at :math:`t+\Delta t`
and every point gets :math:`v = (T x - x) / \Delta t` (:func:`rigid_scene_flow`), once for the whole
scene or once per motion cluster (:func:`rigid_flow_per_cluster`).

Metrics
-------
:func:`scene_flow_metrics` follows FlowNet3D (Liu et al., CVPR 2019): EPE3D and the fractions of
points that are accurate / outliers by absolute or relative end-point error.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from . import _graph_solver
from ._graph import apply_transform, as_labels, knn_edges, laplacian
from ._graph_solver import SOLVERS, spd_solver
from ._validation import as_array, nonnegative, positive, positive_int
from .rgbd_flow import rgbd_scene_flow
from .variational import variational_scene_flow

__all__ = [
    "variational_scene_flow",
    "rgbd_scene_flow",
    "knn_graph",
    "graph_laplacian",
    "check_affinity",
    "graph_scene_flow",
    "nearest_neighbor_targets",
    "iterative_graph_scene_flow",
    "rigid_scene_flow",
    "rigid_flow_per_cluster",
    "scene_flow_metrics",
    "HAVE_CHOLMOD",
    "HAVE_PYAMG",
]

#: True when scikit-sparse's CHOLMOD could be imported (used by ``solver="auto"``).
HAVE_CHOLMOD = _graph_solver.HAVE_CHOLMOD
#: True when pyamg could be imported (``solver="amg"``, and ``"auto"`` on ill-conditioned systems).
HAVE_PYAMG = _graph_solver.HAVE_PYAMG


# ----------------------------------------------------------------------------------------------
# graph construction
# ----------------------------------------------------------------------------------------------
def knn_graph(points, k: int = 8, sigma=None) -> sp.csr_matrix:
    r"""Symmetric Gaussian affinities on the k-nearest-neighbour graph of a point cloud.

    Every point is joined to its ``k`` nearest other points (``scipy.spatial.cKDTree``, all cores);
    the edge set is symmetrised by union and weighted

    .. math::  w_{ij} = \exp\!\left(-\lVert X_i - X_j \rVert^2 / \sigma^2\right),

    which is symmetric by construction (an edge found from both ends gets the same, i.e. the max,
    weight). The diagonal is zero.

    Parameters
    ----------
    points : array_like, shape (N, D)
        The cloud (D = 3 for scene flow; any D >= 1 works).
    k : int, 1 <= k < N
        Neighbours per point before symmetrisation (a point ends with between k and N-1 edges).
    sigma : float > 0, optional
        Length scale. Default: the median of the N·k nearest-neighbour distances, so that a typical
        edge has weight :math:`e^{-1}` whatever the sampling density (if that median is 0 because of
        duplicated points, the smallest positive distance, and 1.0 if every distance is 0).

    Returns
    -------
    W : scipy.sparse.csr_matrix, shape (N, N)
        Symmetric, non-negative, zero diagonal, entries in (0, 1].

    Raises
    ------
    ValueError
        ``points`` not 2-D, empty, NaN/inf; ``k >= N``; ``sigma <= 0``.

    Examples
    --------
    >>> X = np.array([[0.0, 0, 0], [1, 0, 0], [3, 0, 0]])
    >>> W = knn_graph(X, k=1, sigma=1.0)
    >>> np.round(W.toarray(), 4)   # 0-1 (both ends) and 2-1 (from 2's end) are edges
    array([[0.    , 0.3679, 0.    ],
           [0.3679, 0.    , 0.0183],
           [0.    , 0.0183, 0.    ]])
    """
    X = as_array(points, "points", ("N", "D"), min_rows=1)
    n = X.shape[0]
    k = positive_int(k, "k")
    if k >= n:
        raise ValueError(f"k must be < N (number of points in points, shape {X.shape}), got k={k}")
    if sigma is not None:
        sigma = positive(sigma, "sigma")
    # k edges per point, never to itself (also with duplicated points)
    rows, cols, dist = knn_edges(X, k)
    if sigma is None:
        sigma = float(np.median(dist))
        if sigma <= 0.0:
            pos = dist[dist > 0]
            sigma = float(pos.min()) if pos.size else 1.0
    w = np.exp(-((dist / sigma) ** 2))
    W = sp.csr_matrix((w, (rows, cols)), shape=(n, n))
    W = W.maximum(W.T).tocsr()  # union of the directed kNN edges; self-pairs were dropped above
    W.eliminate_zeros()  # weights that underflowed to 0
    W.sort_indices()
    return W


def check_affinity(W, name: str = "W", n: int | None = None) -> sp.csr_matrix:
    """Validate an affinity matrix (dense or sparse): square, finite, non-negative, symmetric.

    The check :func:`graph_laplacian` and :func:`graph_scene_flow` apply to their ``W``.

    Parameters
    ----------
    W : array_like or scipy.sparse matrix, shape (N, N)
        Real affinities.
    name : str
        The argument's name, used in error messages.
    n : int, optional
        Required size ``N`` (e.g. the number of points).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (N, N)
        A float64 copy.

    Raises
    ------
    TypeError
        Non-numeric or complex entries.
    ValueError
        Not square, wrong size, NaN/inf, negative entries, not symmetric (relative tolerance 1e-12).

    Examples
    --------
    >>> check_affinity([[0.0, 1.0], [2.0, 0.0]])
    Traceback (most recent call last):
    ...
    ValueError: W must be symmetric (W == W.T)
    """
    if sp.issparse(W):
        if W.ndim != 2 or W.shape[0] != W.shape[1]:
            raise ValueError(f"{name} must be a square (N, N) matrix, got shape {W.shape}")
        if np.iscomplexobj(W.data) or not np.issubdtype(W.dtype, np.number):
            raise TypeError(f"{name} must be a real numeric matrix, got dtype {W.dtype}")
        W = sp.csr_matrix(W, dtype=np.float64, copy=True)
        if not np.isfinite(W.data).all():
            raise ValueError(f"{name} contains NaN or inf")
    else:
        W = as_array(W, name, ("N", "N"))
        if W.shape[0] != W.shape[1]:
            raise ValueError(f"{name} must be a square (N, N) matrix, got shape {W.shape}")
        W = sp.csr_matrix(W)
    if n is not None and W.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}) to match the points, got {W.shape}")
    if W.nnz and W.data.min() < 0:
        raise ValueError(f"{name} must be non-negative (affinities), smallest entry {W.data.min():.3g}")
    scale = float(np.abs(W.data).max()) if W.nnz else 0.0
    if W.nnz and abs(W - W.T).max() > 1e-12 * scale:
        raise ValueError(f"{name} must be symmetric (W == W.T)")
    return W


def graph_laplacian(W) -> sp.csr_matrix:
    r"""Combinatorial graph Laplacian :math:`L = D - W`, :math:`D = \operatorname{diag}(W \mathbf{1})`.

    For every vector :math:`x`, :math:`x^\top L x = \sum_{i<j} w_{ij} (x_i - x_j)^2 \ge 0`, so L is
    symmetric positive semi-definite with :math:`L \mathbf{1} = 0` (rows sum to zero). Self-loops
    :math:`w_{ii}` cancel and do not change L.

    Parameters
    ----------
    W : array_like or scipy.sparse matrix, shape (N, N)
        Symmetric, non-negative, finite affinities.

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (N, N)

    Raises
    ------
    ValueError
        Not square, not symmetric, negative entries, NaN/inf.

    Examples
    --------
    >>> graph_laplacian(np.array([[0.0, 2.0], [2.0, 0.0]])).toarray()
    array([[ 2., -2.],
           [-2.,  2.]])
    """
    return laplacian(check_affinity(W, "W"))


# ----------------------------------------------------------------------------------------------
# graph scene flow
# ----------------------------------------------------------------------------------------------
def _graph_system(n: int, W: sp.csr_matrix, dt: float, lam: float) -> tuple[sp.csr_matrix, float]:
    """The matrix ``dt² I + lam L`` of graph scene flow and its Gershgorin condition bound."""
    L = laplacian(W)  # W was validated (given) or is symmetric by construction
    A = (lam * L + sp.diags(np.full(n, dt * dt))).tocsr()
    kappa = 1.0 + 2.0 * lam * float(L.diagonal().max()) / (dt * dt)
    return A, kappa


def graph_scene_flow(
    points_t,
    targets,
    dt,
    lam,
    k: int = 8,
    sigma=None,
    W=None,
    *,
    solver: str = "auto",
    tol: float = 1e-8,
) -> np.ndarray:
    r"""Graph-regularised scene flow on a point cloud (syllabus section 4).

    Minimises

    .. math::  E(v) = \sum_i \lVert X_i + v_i \Delta t - Y_i \rVert^2
               + \lambda \sum_{i<j} w_{ij} \lVert v_i - v_j \rVert^2

    by solving :math:`(\Delta t^2 I + \lambda L)\, V = \Delta t (Y - X)` for the three columns of
    :math:`V` with one factorisation (or one block CG run), :math:`L` from :func:`graph_laplacian`
    of :func:`knn_graph` ``(points_t, k, sigma)`` unless ``W`` is given. ``lam = 0`` gives
    :math:`V = (Y - X)/\Delta t` without building a graph.

    Parameters
    ----------
    points_t : array_like, shape (N, 3)
        Points :math:`X` at time t.
    targets : array_like, shape (N, 3)
        Their estimated positions :math:`Y` at t + dt (e.g. :func:`nearest_neighbor_targets`).
    dt : float > 0
        Time step (s).
    lam : float >= 0
        Smoothness weight :math:`\lambda` (units of :math:`\Delta t^2`: the smoothing strength is
        :math:`\lambda / \Delta t^2`).
    k : int
        Neighbours per point of the kNN graph (ignored when ``W`` is given).
    sigma : float > 0, optional
        Affinity length scale (see :func:`knn_graph`; ignored when ``W`` is given).
    W : array_like or sparse, shape (N, N), optional
        Precomputed symmetric non-negative affinities; skips the graph construction.
    solver : {"auto", "cholmod", "splu", "cg", "amg"}, keyword-only
        ``"cholmod"``: sparse Cholesky (scikit-sparse, simplicial :math:`LDL^\top`), ``"splu"``:
        SuperLU (scipy), ``"cg"``: Jacobi-preconditioned CG on the three columns at once, ``"amg"``:
        the same CG preconditioned by one V-cycle of a smoothed-aggregation multigrid hierarchy
        (pyamg), built once for the three columns. ``"auto"`` picks the one a cost model predicts
        fastest, deciding from the fill of the factor (see Notes).
    tol : float > 0, keyword-only
        For CG (default 1e-8; measured errors against CHOLMOD are 1e-9 to 1e-12, see
        ``benchmarks/results/graphflow.md``): the relative error of each column is at most ``tol``, by
        iterating to a relative residual :math:`\le` ``tol / kappa`` (floored at
        :math:`8 \epsilon \kappa`, the reach of double precision, which for very ill-conditioned systems
        gives a weaker bound). Direct solvers ignore it.

    Returns
    -------
    V : ndarray, shape (N, 3)
        Velocities (units of points per second).

    Raises
    ------
    ValueError
        Wrong shapes, empty clouds, NaN/inf, ``dt <= 0``, ``lam < 0``, ``k >= N`` (when a graph is
        built, i.e. ``lam > 0`` and no ``W``), bad ``W`` or ``solver`` (or a solver whose package is
        missing); the message names the argument.

    Notes
    -----
    **How** ``solver="auto"`` **chooses.** Costs are counted in units of one Jacobi-CG iteration
    on the three columns (a sparse product :math:`A B`, :math:`B \in \mathbb{R}^{N \times 3}`, and the
    vector updates; :math:`\propto N` as kNN rows hold about :math:`k` non-zeros), with constants
    measured in ``benchmarks/bench_graphflow.py`` as ratios of times in one run.

    - Jacobi CG: with the Gershgorin bound :math:`\kappa = 1 + 2 \lambda d_{max} / \Delta t^2` on the
      condition number, CG needs :math:`O(\sqrt\kappa)` iterations; measured to ``tol`` = 1e-8:
      :math:`T_{cg} \approx 8 \sqrt{\kappa}`.
    - AMG-CG (pyamg importable): multigrid removes most of the :math:`\kappa` dependence (10, 20 and
      30–44 iterations at :math:`\kappa` = 20, 200, 2000), at about 4 CG iterations per V-cycle after
      a set-up of about 35: :math:`T_{amg} \approx 35 + 16\,\kappa^{0.3}`.
    - CHOLMOD: the cost is set by the fill, which the geometry decides and :math:`\kappa` does not
      see. A kNN graph of a *surface* (one depth camera) behaves like a 2-D mesh: nested-dissection
      separators of :math:`O(\sqrt N)` points, :math:`\operatorname{nnz}(L) = O(N \log N)`, work
      :math:`O(N^{3/2})`. A *volumetric* cloud (LiDAR sweeps, merged views, samples of a solid)
      behaves like a 3-D mesh: separators of :math:`O(N^{2/3})`, :math:`\operatorname{nnz}(L) =
      O(N^{4/3})`, work :math:`O(N^2)` — at N = 100k about 7 times the non-zeros and 85 times the
      work of a surface. CHOLMOD's symbolic analysis measures it before any numeric work: the AMD
      ordering :math:`P`, the elimination tree of :math:`P A P^\top` and the column counts
      :math:`c_j` of its factor (``cholmod_rowcolcounts``, :math:`O(\operatorname{nnz}(A))`). The
      simplicial :math:`LDL^\top` costs about :math:`\sum_j c_j^2` multiply-adds and the three
      solves :math:`6 \sum_j c_j`, so :math:`T_{chol} \approx \sum_j c_j^2 / (200 N) + \sum_j c_j /
      (20 N)`, after an analysis of :math:`T_{an} \approx 15`.

    The analysis is itself part of the call, so it runs only when the cheaper iterative method is
    predicted at more than :math:`4 T_{an} = 60` (below that, even a free factorisation could not
    win enough to pay for it). Then the smallest of :math:`T_{cg}, T_{amg}, T_{chol}` wins, and CHOLMOD's
    numeric factorisation reuses the analysis it was chosen from. Without the column counts (libcholmod
    not loadable through ctypes) the rule falls back to :math:`\kappa \le 18 (N / 20000)^{0.8}` for
    CG, then AMG, then CHOLMOD/SuperLU. ``benchmarks/results/graphflow.md`` shows the choice against
    every solver on surface and volumetric clouds.

    Examples
    --------
    A two-point graph with one edge of weight 1 pulls the raw velocities (2, 0) together:
    :math:`(0.01 I + 0.01 L) V = 0.1 (Y - X)` gives :math:`v_1 + v_2 = 2` and
    :math:`0.03 (v_1 - v_2) = 0.02`, i.e. :math:`v_{1,2} = 1 \pm 1/3`.

    >>> X = np.zeros((2, 3))
    >>> Y = np.array([[0.2, 0, 0], [0.0, 0, 0]])
    >>> V = graph_scene_flow(X, Y, dt=0.1, lam=0.01, W=np.array([[0.0, 1.0], [1.0, 0.0]]))
    >>> np.allclose(V[:, 0], [1 + 1 / 3, 1 - 1 / 3])
    True
    """
    X = as_array(points_t, "points_t", ("N", 3), min_rows=1)
    Y = as_array(targets, "targets", ("N", 3), min_rows=1)
    if Y.shape != X.shape:
        raise ValueError(f"targets must have shape {X.shape} like points_t, got {Y.shape}")
    dt = positive(dt, "dt")
    lam = nonnegative(lam, "lam")
    tol = positive(tol, "tol")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
    n = X.shape[0]
    if W is not None:
        Wm = check_affinity(W, "W", n)
    else:
        k = positive_int(k, "k")
        if sigma is not None:
            sigma = positive(sigma, "sigma")
        # lam = 0 needs no graph, so k >= N is only an error when one is built.
        Wm = knn_graph(X, k=k, sigma=sigma) if lam > 0.0 else None
    B = dt * (Y - X)
    if lam == 0.0 or Wm is None or Wm.nnz == 0:
        return B / (dt * dt)
    A, kappa = _graph_system(n, Wm, dt, lam)
    return spd_solver(A, solver, kappa, tol)(B)


def nearest_neighbor_targets(points_t, points_t1) -> np.ndarray:
    r"""The syllabus' correspondence step: the nearest point of the t+1 cloud for each point at t.

    :math:`Y_i = \operatorname{argmin}_{Z \in \mathcal{X}^{t+1}} \lVert Z - X_i \rVert` (cKDTree,
    all cores; ties go to the lower index). The clouds may have different sizes.

    Parameters
    ----------
    points_t : array_like, shape (N, 3)
    points_t1 : array_like, shape (M, 3)

    Returns
    -------
    Y : ndarray, shape (N, 3)
        Rows of ``points_t1``.

    Examples
    --------
    >>> nearest_neighbor_targets([[0.0, 0, 0], [1, 1, 1]], [[0.9, 1, 1], [0.1, 0, 0], [5, 5, 5]])
    array([[0.1, 0. , 0. ],
           [0.9, 1. , 1. ]])
    """
    X = as_array(points_t, "points_t", ("N", 3), min_rows=1)
    Z = as_array(points_t1, "points_t1", ("M", 3), min_rows=1)
    _, idx = cKDTree(Z).query(X, k=1, workers=-1)
    return Z[idx]


def iterative_graph_scene_flow(
    points_t,
    points_t1,
    dt,
    lam,
    k: int = 8,
    sigma=None,
    *,
    iterations: int = 5,
    tol: float = 1e-4,
    return_passes: bool = False,
):
    r"""Graph scene flow with re-matched correspondences (a non-rigid ICP).

    Nearest-neighbour targets only see the motion *normal* to a surface: a face sliding along itself
    matches its own neighbours. Alternating the two steps of the syllabus fixes much of that bias,

    .. math::  Y^{(s)}_i = \operatorname{NN}_{t+1}\big(X_i + v^{(s)}_i \Delta t\big), \qquad
               v^{(s+1)} = \operatorname{argmin}_v E(v; Y^{(s)}),

    starting from :math:`v^{(0)} = 0` (the first pass is exactly :func:`graph_scene_flow` on
    :func:`nearest_neighbor_targets`): the smoothness term carries the normal components of
    differently oriented faces of one object across it, and the re-matching then looks for partners
    where the object has moved to. The graph and the system matrix are built, and factorised, once.

    Parameters
    ----------
    points_t : array_like, shape (N, 3)
    points_t1 : array_like, shape (M, 3)
    dt : float > 0
    lam : float >= 0
    k, sigma
        As in :func:`knn_graph`.
    iterations : int >= 1
        Maximum number of passes.
    tol : float > 0
        Stop when no displacement :math:`v_i \Delta t` changed by more than ``tol`` (units of the
        points) in a pass.
    return_passes : bool
        Also return the list of every pass's velocities; ``passes[0]`` is exactly
        :func:`graph_scene_flow` on :func:`nearest_neighbor_targets`, so a caller wanting both needs
        only this call.

    Returns
    -------
    V : ndarray, shape (N, 3)
    passes : list of ndarray, shape (N, 3), only with ``return_passes=True``

    Examples
    --------
    A floor patch sliding by 0.7 grid spacings along itself (nearest neighbours see a slide of −0.3
    spacings) attached to a wall that moves with it along its normal: one pass averages the two
    (wrong) answers, the iteration recovers the slide exactly.

    >>> g = np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2) * 0.01
    >>> floor = np.column_stack([g, np.zeros(100)])
    >>> wall = np.column_stack([np.zeros(100), g[:, 0], g[:, 1] + 0.01])
    >>> X = np.vstack([floor, wall])
    >>> Y = X + [0.007, 0.0, 0.0]
    >>> v1 = graph_scene_flow(X, nearest_neighbor_targets(X, Y), 0.1, 1.0)
    >>> v5 = iterative_graph_scene_flow(X, Y, 0.1, 1.0, iterations=10)
    >>> round(float(v1[:, 0].mean()), 6), round(float(v5[:, 0].mean()), 6)
    (0.025, 0.07)
    """
    X = as_array(points_t, "points_t", ("N", 3), min_rows=1)
    Z = as_array(points_t1, "points_t1", ("M", 3), min_rows=1)
    dt = positive(dt, "dt")
    lam = nonnegative(lam, "lam")
    iterations = positive_int(iterations, "iterations")
    tol = positive(tol, "tol")
    solve = None  # lam = 0: no graph, v = (Y - X) / dt
    if lam > 0:
        k = positive_int(k, "k")
        W = knn_graph(X, k=k, sigma=None if sigma is None else positive(sigma, "sigma"))
        if W.nnz:
            A, kappa = _graph_system(X.shape[0], W, dt, lam)
            solve = spd_solver(A, "auto", kappa, 1e-8)  # one factorisation for every pass
    tree = cKDTree(Z)
    V = np.zeros_like(X)
    passes = []
    for _ in range(iterations):
        _, idx = tree.query(X + V * dt, k=1, workers=-1)
        B = dt * (Z[idx] - X)
        V_new = B / (dt * dt) if solve is None else solve(B)
        change = float(np.abs(V_new - V).max()) * dt
        V = V_new
        passes.append(V)
        if change <= tol:
            break
    return (V, passes) if return_passes else V


# ----------------------------------------------------------------------------------------------
# rigid scene flow (ICP)
# ----------------------------------------------------------------------------------------------
def _check_rigid(T, name: str) -> np.ndarray:
    T = as_array(T, name, (4, 4))
    R = T[:3, :3]
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ValueError(f"{name} must be a rigid (4, 4) transform with last row [0, 0, 0, 1], got {T[3]}")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
        raise ValueError(f"{name} must be a rigid (4, 4) transform: its (3, 3) block must be a rotation")
    return T


def _o3d():
    try:
        import open3d as o3d
    except ImportError as exc:  # the student install leaves open3d out: say what to install
        raise ImportError(
            "rigid (ICP) scene flow needs open3d, which this install does not have: "
            "python -m pip install open3d (or install flowtrack with the 'pipeline' extra)"
        ) from exc

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    return o3d


def _icp(X: np.ndarray, Z: np.ndarray, threshold: float, init: np.ndarray, method: str, max_iter: int):
    o3d = _o3d()
    reg = o3d.pipelines.registration
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(X))
    dst = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(Z))
    if method == "point_to_plane":
        dst.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=min(20, len(Z))))
        estimation = reg.TransformationEstimationPointToPlane()
    else:
        estimation = reg.TransformationEstimationPointToPoint()
    criteria = reg.ICPConvergenceCriteria(relative_fitness=1e-12, relative_rmse=1e-12, max_iteration=max_iter)
    result = reg.registration_icp(src, dst, threshold, init, estimation, criteria)
    return np.array(result.transformation, dtype=np.float64)


_METHODS = ("point_to_point", "point_to_plane")


def rigid_scene_flow(
    points_t, points_t1, dt, threshold, init=None, method: str = "point_to_point", max_iter: int = 50
) -> tuple[np.ndarray, np.ndarray]:
    r"""One rigid motion for the whole cloud by ICP (the syllabus' Open3D sketch, section 8).

    ``open3d.pipelines.registration.registration_icp`` finds :math:`T = [R\,|\,t]` aligning
    ``points_t`` to ``points_t1`` (pairs farther apart than ``threshold`` are ignored) and every
    point gets

    .. math::  v(x) = (T x - x) / \Delta t = \big((R - I) x + t\big) / \Delta t .

    Parameters
    ----------
    points_t : array_like, shape (N, 3), N >= 3
    points_t1 : array_like, shape (M, 3), M >= 3
    dt : float > 0
    threshold : float > 0
        Maximal correspondence distance (m).
    init : array_like, shape (4, 4), optional
        Initial rigid transform (identity by default).
    method : {"point_to_point", "point_to_plane"}
        ICP error; for point-to-plane the normals of ``points_t1`` are estimated from their 20
        nearest neighbours.
    max_iter : int >= 1
        ICP iterations (convergence tolerances 1e-12 relative fitness and RMSE).

    Returns
    -------
    flow : ndarray, shape (N, 3)
    T : ndarray, shape (4, 4)
        Rigid transform from t to t + dt.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-0.1, 0.1, size=(200, 3))
    >>> flow, T = rigid_scene_flow(X, X + [0.01, 0.0, 0.0], dt=0.1, threshold=0.05)
    >>> np.allclose(flow, [0.1, 0.0, 0.0], atol=1e-8), np.allclose(T[:3, 3], [0.01, 0, 0], atol=1e-9)
    (True, True)
    """
    X = as_array(points_t, "points_t", ("N", 3), min_rows=3)
    Z = as_array(points_t1, "points_t1", ("M", 3), min_rows=3)
    dt = positive(dt, "dt")
    threshold = positive(threshold, "threshold")
    init = np.eye(4) if init is None else _check_rigid(init, "init")
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    max_iter = positive_int(max_iter, "max_iter")
    T = _icp(X, Z, threshold, init, method, max_iter)
    return (apply_transform(T, X) - X) / dt, T


def rigid_flow_per_cluster(
    points_t,
    points_t1,
    labels,
    dt,
    threshold,
    *,
    labels_t1=None,
    method: str = "point_to_point",
    max_iter: int = 50,
    return_transforms: bool = False,
):
    r"""Rigid ICP flow per motion cluster: one :math:`T_\ell` for the points with label :math:`\ell`.

    For every label :math:`\ell \ge 0`, :func:`rigid_scene_flow` registers
    :math:`\{X_i : \ell_i = \ell\}` onto ``points_t1`` (or onto the points of ``points_t1`` with the
    same label when ``labels_t1`` is given), starting from the translation between the cluster's
    centroid and the centroid of its nearest neighbours at t + dt, and those points get
    :math:`v_i = (T_\ell X_i - X_i)/\Delta t`. Negative labels (the static background of
    :func:`flowtrack.clustering.cluster_motion`) get zero flow. A cluster of fewer than 3 points gets
    the mean nearest-neighbour displacement (a pure translation).

    Parameters
    ----------
    points_t : array_like, shape (N, 3)
    points_t1 : array_like, shape (M, 3)
    labels : array_like of int, shape (N,)
    dt : float > 0
    threshold : float > 0
        ICP correspondence distance (m).
    labels_t1 : array_like of int, shape (M,), optional, keyword-only
        Labels of ``points_t1`` consistent with ``labels`` (e.g. ground truth).
    method, max_iter
        As in :func:`rigid_scene_flow`.
    return_transforms : bool, keyword-only
        Also return ``{label: T (4, 4)}``.

    Returns
    -------
    flow : ndarray, shape (N, 3)
    transforms : dict[int, ndarray (4, 4)]
        Only when ``return_transforms`` is true.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> X = np.vstack([rng.uniform(0, 0.1, (100, 3)), rng.uniform(0.5, 0.6, (100, 3))])
    >>> lab = np.repeat([0, 1], 100)
    >>> Y = X + np.where(lab[:, None] == 0, [0.005, 0, 0], [0, -0.005, 0])
    >>> V = rigid_flow_per_cluster(X, Y, lab, dt=0.1, threshold=0.02)
    >>> np.allclose(V[:100], [0.05, 0, 0], atol=1e-8), np.allclose(V[100:], [0, -0.05, 0], atol=1e-8)
    (True, True)
    """
    X = as_array(points_t, "points_t", ("N", 3), min_rows=1)
    Z = as_array(points_t1, "points_t1", ("M", 3), min_rows=1)
    lab = as_labels(labels, "labels", X.shape[0], integral_floats=True)
    lab1 = None if labels_t1 is None else as_labels(labels_t1, "labels_t1", Z.shape[0], integral_floats=True)
    dt = positive(dt, "dt")
    threshold = positive(threshold, "threshold")
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    max_iter = positive_int(max_iter, "max_iter")
    flow = np.zeros_like(X)
    transforms: dict[int, np.ndarray] = {}
    for ell in np.unique(lab):
        if ell < 0:
            continue
        sel = lab == ell
        Xs = X[sel]
        Zs = Z if lab1 is None else Z[lab1 == ell]
        if len(Zs) == 0:
            Zs = Z
        _, nn = cKDTree(Zs).query(Xs, k=1, workers=-1)
        T = np.eye(4)
        T[:3, 3] = (Zs[nn] - Xs).mean(axis=0)
        if len(Xs) >= 3 and len(Zs) >= 3:
            T = _icp(Xs, Zs, threshold, T, method, max_iter)
        flow[sel] = (apply_transform(T, Xs) - Xs) / dt
        transforms[int(ell)] = T
    return (flow, transforms) if return_transforms else flow


# ----------------------------------------------------------------------------------------------
# metrics
# ----------------------------------------------------------------------------------------------
def scene_flow_metrics(pred, gt, mask=None, *, dt=None, eps: float = 0.0) -> dict:
    r"""FlowNet3D scene-flow metrics.

    With the end-point error :math:`e_i = \lVert \hat f_i - f_i \rVert` and the relative error
    :math:`r_i = e_i / \lVert f_i \rVert`:

    - ``epe3d`` = :math:`\operatorname{mean}_i e_i`,
    - ``acc3d_strict`` = fraction with :math:`e_i < 0.05` m **or** :math:`r_i < 5\,\%`,
    - ``acc3d_relax`` = fraction with :math:`e_i < 0.1` m **or** :math:`r_i < 10\,\%`,
    - ``outliers`` = fraction with :math:`e_i > 0.3` m **or** :math:`r_i > 10\,\%`,
    - ``n`` = number of points evaluated.

    Zero ground truth: where :math:`\lVert f_i \rVert = 0` the relative error is 0 if
    :math:`e_i = 0` and :math:`+\infty` otherwise (such a point is judged by the absolute error for
    accuracy, and is an outlier as soon as it is wrong at all). ``eps > 0`` uses
    :math:`r_i = e_i / (\lVert f_i \rVert + \epsilon)` instead; ``eps=1e-4`` reproduces the FlowNet3D
    reference code.

    The thresholds are in metres, i.e. for per-frame displacements. Velocities (m/s) can be passed
    with ``dt``: both are then multiplied by ``dt`` first (this changes ``epe3d`` and the absolute
    tests, not the relative ones).

    Parameters
    ----------
    pred, gt : array_like, shape (N, 3)
    mask : array_like of bool, shape (N,), optional
        Points to evaluate. With no point selected every fraction and ``epe3d`` is NaN, ``n`` = 0.
    dt : float > 0, optional, keyword-only
    eps : float >= 0, keyword-only

    Returns
    -------
    dict
        ``epe3d``, ``acc3d_strict``, ``acc3d_relax``, ``outliers`` (floats) and ``n`` (int).

    Examples
    --------
    >>> gt = np.array([[1.0, 0, 0], [1.0, 0, 0], [0.0, 0, 0], [2.0, 0, 0]])
    >>> pred = gt + [[0.04, 0, 0], [0.08, 0, 0], [0.0, 0, 0], [0.4, 0, 0]]
    >>> m = scene_flow_metrics(pred, gt)
    >>> float(m["epe3d"]), m["acc3d_strict"], m["acc3d_relax"], m["outliers"], m["n"]
    (0.13, 0.5, 0.75, 0.25, 4)
    """
    P = as_array(pred, "pred", ("N", 3))
    G = as_array(gt, "gt", ("N", 3))
    if P.shape != G.shape:
        raise ValueError(f"gt must have shape {P.shape} like pred, got {G.shape}")
    if dt is not None:
        dt = positive(dt, "dt")
        P, G = P * dt, G * dt
    eps = nonnegative(eps, "eps")
    if mask is not None:
        m = np.asarray(mask)
        if m.dtype != np.bool_:
            raise ValueError(f"mask must be a boolean array of shape ({P.shape[0]},), got dtype {m.dtype}")
        if m.shape != (P.shape[0],):
            raise ValueError(f"mask must have shape ({P.shape[0]},), got {m.shape}")
        P, G = P[m], G[m]
    n = int(P.shape[0])
    if n == 0:
        nan = float("nan")
        return {"epe3d": nan, "acc3d_strict": nan, "acc3d_relax": nan, "outliers": nan, "n": 0}
    err = np.linalg.norm(P - G, axis=1)
    gnorm = np.linalg.norm(G, axis=1) + eps
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(gnorm > 0, err / np.where(gnorm > 0, gnorm, 1.0), np.where(err > 0, np.inf, 0.0))
    return {
        "epe3d": float(err.mean()),
        "acc3d_strict": float(np.mean((err < 0.05) | (rel < 0.05))),
        "acc3d_relax": float(np.mean((err < 0.1) | (rel < 0.1))),
        "outliers": float(np.mean((err > 0.3) | (rel > 0.1))),
        "n": n,
    }
