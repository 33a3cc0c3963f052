r"""Motion clustering of a scene-flow field into objects (syllabus Problem 5).

Given points :math:`X_i` with velocities :math:`v_i`, build a spatial graph — an edge between
:math:`i` and :math:`j` when :math:`\|X_i - X_j\| \le r` (at most the ``k`` nearest neighbours of
each point, symmetrised) — with motion affinities

.. math::  w_{ij} = \exp\!\left(-\frac{\|v_i - v_j\|^2}{\sigma_v^2}\right),

and group the points whose motion is coherent:

* ``method="connected"``: keep the edges with :math:`w_{ij} \ge e^{-1}` (i.e.
  :math:`\|v_i - v_j\| \le \sigma_v`) and return the connected components.
* ``method="spectral"``: drop only the negligible edges (:math:`\|v_i - v_j\| > 3\sigma_v`,
  :math:`w_{ij} < e^{-9}`); every connected component of what remains is a natural cluster (the
  normalised Laplacian is block diagonal and each block contributes one zero eigenvalue). Inside a
  component, the eigenvalues :math:`0 = \lambda_1 \le \lambda_2 \le \dots` of
  :math:`L_\mathrm{sym} = I - D^{-1/2} W D^{-1/2}` decide whether to split it further: with
  ``n_clusters`` given, the ``n_clusters`` smallest eigenvalues over all components are used
  (exactly as spectral clustering of the whole graph would); with ``n_clusters=None`` a component
  is split into :math:`c` parts where :math:`c` is the largest index with a *relative eigengap*
  :math:`\lambda_c < \tfrac{1}{10}\,\lambda_{c+1}` (a weak motion cut gives a tiny
  :math:`\lambda_c` next to the geometric eigenvalues of a rigid piece, which grow slowly, so a
  rigid object is never split on shape alone). A split is done by k-means on the row-normalised
  first :math:`c` eigenvectors (Ng, Jordan & Weiss 2002).

In both methods components smaller than ``min_size`` (isolated noisy points) are not clusters of
their own: they join the cluster of their spatially nearest clustered point. Points slower than
``min_speed`` are static background, label ``-1``, and are left out of the graph.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import eigsh
from scipy.spatial import cKDTree

from ._graph import as_labels, knn_edges, laplacian
from ._validation import as_array, nonnegative, positive, positive_int

__all__ = ["cluster_motion", "drop_small_clusters", "motion_affinity_graph", "tracks_from_clusters"]

_METHODS = ("spectral", "connected")
_GAP_RATIO = 0.1
_MAX_SPLIT = 6


def _check_points_flow(points, flow) -> tuple[np.ndarray, np.ndarray]:
    P = as_array(points, "points", ("N", None))
    if P.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (N, 3) or (N, 2), got {P.shape}")
    V = as_array(flow, "flow", P.shape)
    return P, V


def motion_affinity_graph(points, flow, radius: float, sigma_v: float, k: int = 10) -> sp.csr_matrix:
    r"""Symmetric spatial graph with motion affinities :math:`\exp(-\|v_i - v_j\|^2/\sigma_v^2)`.

    Parameters
    ----------
    points : array_like, shape (N, D)
        Positions, D = 2 or 3.
    flow : array_like, shape (N, D)
        Velocities.
    radius : float, > 0
        Maximal edge length.
    sigma_v : float, > 0
        Velocity scale of the affinity.
    k : int, >= 1
        At most ``k`` nearest neighbours per point (before symmetrisation).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (N, N)
        :math:`W` with :math:`w_{ij} = w_{ji}` and a zero diagonal.

    Examples
    --------
    >>> W = motion_affinity_graph([[0, 0, 0], [0.1, 0, 0], [5, 0, 0]], [[0, 0, 0], [1, 0, 0], [0, 0, 0]],
    ...                           radius=0.5, sigma_v=1.0)
    >>> np.round(W.toarray(), 4)
    array([[0.    , 0.3679, 0.    ],
           [0.3679, 0.    , 0.    ],
           [0.    , 0.    , 0.    ]])
    """
    P, V = _check_points_flow(points, flow)
    radius = positive(radius, "radius")
    sigma_v = positive(sigma_v, "sigma_v")
    k = positive_int(k, "k")
    return _graph(P, V, radius, sigma_v, k)


def _graph(P: np.ndarray, V: np.ndarray, radius: float, sigma_v: float, k: int) -> sp.csr_matrix:
    n = P.shape[0]
    if n < 2:
        return sp.csr_matrix((n, n))
    rows, cols, _ = knn_edges(P, k, radius)
    w = np.exp(-np.sum((V[rows] - V[cols]) ** 2, axis=1) / sigma_v**2)
    W = sp.csr_matrix((w, (rows, cols)), shape=(n, n))
    return W.maximum(W.T).tocsr()


def _smallest_eigs(W: sp.csr_matrix, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``m`` smallest eigenpairs of L_sym = I - D^{-1/2} W D^{-1/2} (ascending)."""
    n = W.shape[0]
    L, v0 = laplacian(W, normed=True, return_diag=True)  # v0 = sqrt(degrees): L_sym v0 = 0
    m = min(m, n)
    if n <= 150 or m >= n - 1:
        lam, U = np.linalg.eigh(L.toarray())
        return np.maximum(lam[:m], 0.0), U[:, :m]
    # shift-invert Lanczos about a small negative shift: L_sym + 1e-3 I is positive definite, and
    # the wanted (smallest) eigenvalues become the largest of its inverse -> fast convergence
    L = L.tocsc()
    lam, U = eigsh(L, k=m, sigma=-1e-3, which="LM", v0=v0 / np.linalg.norm(v0), tol=1e-10)
    order = np.argsort(lam)
    return np.maximum(lam[order], 0.0), U[:, order]


def _split(U: np.ndarray, c: int, random_state: int) -> np.ndarray:
    from sklearn.cluster import KMeans

    Y = U[:, :c]
    Y = Y / np.maximum(np.linalg.norm(Y, axis=1, keepdims=True), 1e-300)
    return KMeans(n_clusters=c, n_init=10, random_state=random_state).fit_predict(Y)


def _relabel_by_size(lab: np.ndarray) -> np.ndarray:
    """Map labels >= 0 to 0..K-1 by decreasing size (ties: smaller old label first)."""
    out = np.full_like(lab, -1)
    ids, counts = np.unique(lab[lab >= 0], return_counts=True)
    order = np.lexsort((ids, -counts))
    for new, old in enumerate(ids[order]):
        out[lab == old] = new
    return out


def cluster_motion(
    points,
    flow,
    radius: float,
    sigma_v: float,
    n_clusters: int | None = None,
    min_speed: float | None = None,
    method: str = "spectral",
    k: int = 10,
    min_size: int | None = None,
    random_state: int = 0,
) -> np.ndarray:
    r"""Group points into rigidly moving clusters from their scene flow (Problem 5).

    Parameters
    ----------
    points : array_like, shape (N, D)
        Positions (D = 3, or 2 for planar problems).
    flow : array_like, shape (N, D)
        Velocity of each point.
    radius : float, > 0
        Neighbourhood radius of the spatial graph (same unit as ``points``).
    sigma_v : float, > 0
        Velocity scale of the affinity :math:`\exp(-\|v_i - v_j\|^2/\sigma_v^2)`.
    n_clusters : int or None
        Number of moving clusters; ``None`` chooses it (connected components, refined by the
        relative eigengap for ``"spectral"``; see the module docstring).
    min_speed : float or None, >= 0
        Points with :math:`\|v_i\| <` ``min_speed`` are static background: label ``-1``.
    method : {"spectral", "connected"}
    k : int, >= 1
        Cap on the neighbours per point.
    min_size : int or None
        Components smaller than this join their spatially nearest cluster; default
        :math:`\max(3, \lceil 0.002\,N_\text{moving} \rceil)`.
    random_state : int
        Seed of k-means (the result is deterministic).

    Returns
    -------
    ndarray, shape (N,) int
        ``0..K-1`` for the moving clusters, sorted by decreasing size; ``-1`` for static points.

    Raises
    ------
    ValueError, TypeError
        Bad shapes, NaN/inf, non-positive ``radius``/``sigma_v``, unknown ``method``.

    Examples
    --------
    Two 5×5 patches moving apart and a static one:

    >>> g = np.stack(np.meshgrid(np.arange(5), np.arange(5)), -1).reshape(-1, 2) * 0.01
    >>> P = np.vstack([g, g + [0.049, 0.0], g + [0.5, 0.5]])
    >>> V = np.vstack([np.tile([1.0, 0], (25, 1)), np.tile([-1.0, 0], (25, 1)), np.zeros((25, 2))])
    >>> lab = cluster_motion(P, V, radius=0.015, sigma_v=0.5, min_speed=0.1)
    >>> [sorted(set(lab[i:i + 25].tolist())) for i in (0, 25, 50)]
    [[0], [1], [-1]]
    """
    P, V = _check_points_flow(points, flow)
    radius = positive(radius, "radius")
    sigma_v = positive(sigma_v, "sigma_v")
    if n_clusters is not None:
        n_clusters = positive_int(n_clusters, "n_clusters")
    if min_speed is not None:
        min_speed = nonnegative(min_speed, "min_speed")
    if not isinstance(method, str) or method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    k = positive_int(k, "k")
    random_state = positive_int(random_state, "random_state", minimum=0)

    n = P.shape[0]
    labels = np.full(n, -1, dtype=np.int64)
    moving = np.ones(n, dtype=bool) if min_speed is None else np.linalg.norm(V, axis=1) >= min_speed
    idx = np.nonzero(moving)[0]
    nm = idx.size
    if nm == 0:
        return labels
    if min_size is None:
        min_size = max(3, int(np.ceil(0.002 * nm)))
    else:
        min_size = positive_int(min_size, "min_size")

    Pm, Vm = P[idx], V[idx]
    W = _graph(Pm, Vm, radius, sigma_v, k)
    thr = np.exp(-1.0) if method == "connected" else np.exp(-9.0)
    W.data[W.data < thr] = 0.0
    W.eliminate_zeros()
    n_comp, comp = connected_components(W, directed=False)
    sizes = np.bincount(comp, minlength=n_comp)
    big = np.nonzero(sizes >= min_size)[0]
    if big.size == 0:
        big = np.arange(n_comp)
    big = big[np.lexsort((big, -sizes[big]))]  # largest first
    if n_clusters is not None and big.size > n_clusters:
        big = big[:n_clusters]

    lab = np.full(nm, -1, dtype=np.int64)
    if method == "connected" or (n_clusters is not None and big.size == n_clusters):
        for new, c in enumerate(big):
            lab[comp == c] = new
    else:
        # spectral refinement inside each component
        members = [np.nonzero(comp == c)[0] for c in big]
        spectra = []
        for mem in members:
            if mem.size < 2 * min_size or mem.size < 3:
                spectra.append((np.zeros(1), None))
                continue
            Wc = W[mem][:, mem].tocsr()
            spectra.append(_smallest_eigs(Wc, min(_MAX_SPLIT + 1, mem.size - 1)))
        if n_clusters is None:
            n_split = []
            for lam, _ in spectra:
                c = 1
                for i in range(1, lam.size - 1):
                    if lam[i] < _GAP_RATIO * lam[i + 1]:
                        c = i + 1
                n_split.append(c)
        else:
            extra = [(lam[i], j) for j, (lam, _) in enumerate(spectra) for i in range(1, lam.size)]
            extra.sort(key=lambda t: (t[0], t[1]))
            n_split = [1] * len(members)
            for _, j in extra[: n_clusters - len(members)]:
                n_split[j] += 1
        nxt = 0
        for mem, (_lam, U), c in zip(members, spectra, n_split):
            if c == 1:
                lab[mem] = nxt
            else:
                lab[mem] = nxt + _split(U, c, random_state)
            nxt += c

    # small components join their spatially nearest cluster
    rest = lab < 0
    if rest.any() and (~rest).any():
        _, nn = cKDTree(Pm[~rest]).query(Pm[rest])
        lab[rest] = lab[~rest][nn]
    labels[idx] = _relabel_by_size(lab)
    return labels


def drop_small_clusters(labels, min_size: int) -> np.ndarray:
    """Send clusters with fewer than ``min_size`` points to the background (label ``-1``).

    Isolated groups of "moving" points inside static surfaces are usually flow noise, not objects:
    unlike ``cluster_motion(..., min_size=...)``, which merges them into a neighbouring cluster, this
    drops them. The remaining clusters are renumbered ``0..K-1`` by decreasing size.

    Parameters
    ----------
    labels : array_like of int, shape (N,)
        Cluster labels, ``-1`` for background.
    min_size : int >= 1

    Returns
    -------
    ndarray of int, shape (N,)

    Examples
    --------
    >>> drop_small_clusters([0, 0, 0, 1, 2, 2, -1], 2)
    array([ 0,  0,  0, -1,  1,  1, -1])
    """
    lab = as_labels(labels, "labels")
    min_size = positive_int(min_size, "min_size")
    ids, counts = np.unique(lab[lab >= 0], return_counts=True)
    lab[np.isin(lab, ids[counts < min_size])] = -1
    return _relabel_by_size(lab)


def tracks_from_clusters(points, flow, labels) -> list[tuple[np.ndarray, np.ndarray]]:
    r"""Initial track states from clusters: centroid and mean velocity of each (Problem 5, step 4).

    Parameters
    ----------
    points : array_like, shape (N, D)
    flow : array_like, shape (N, D)
    labels : array_like, shape (N,) int
        Cluster labels; ``-1`` (static) is ignored.

    Returns
    -------
    list of (ndarray (D,), ndarray (D,))
        ``(mean of X_i, mean of v_i)`` over each cluster, in increasing label order.

    Examples
    --------
    >>> tracks_from_clusters([[0, 0, 0], [2, 0, 0], [9, 9, 9]], [[1, 0, 0], [3, 0, 0], [0, 0, 0]], [0, 0, -1])
    [(array([1., 0., 0.]), array([2., 0., 0.]))]
    """
    P, V = _check_points_flow(points, flow)
    lab = as_labels(labels, "labels", P.shape[0], type_error=True, min_label=-1)
    out = []
    for c in np.unique(lab[lab >= 0]):
        m = lab == c
        out.append((P[m].mean(axis=0), V[m].mean(axis=0)))
    return out
