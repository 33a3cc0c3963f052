r"""The Kalman filter for ``M`` independent tracks at once, stored as packed stacked arrays.

:class:`BatchKalmanFilter` runs the recursion of :class:`flowtrack.kalman.KalmanFilter` for every
track of a multi-object tracker in a few batched array operations (no Python loop over tracks):
covariances are stored component-major with only their upper triangles, innovation covariances are
inverted in closed form (``m <= 3``) or by an unrolled batched Cholesky factorisation
(:mod:`flowtrack._batch_kernels`). It is re-exported by :mod:`flowtrack.kalman`.
"""

from __future__ import annotations

import numpy as np

from ._batch_kernels import GEMM_SINGLE_THREAD_WORK, gemm_over_columns, spd_inverse_cm
from ._linear_gaussian import LOG_2PI, check_model
from ._validation import as_array, check_psd

__all__ = ["BatchKalmanFilter"]


def _model_property(name: str, doc: str) -> property:
    """Property ``F``/``H``/``Q``/``R`` of :class:`BatchKalmanFilter`.

    Reads give the stored read-only array; an assignment is validated like the constructor's
    argument (same dimensions) and recomputes the model's operators.
    """

    def fget(self):
        return getattr(self, "_" + name)

    def fset(self, value):
        mats = {k: getattr(self, "_" + k) for k in "FHQR"}
        mats[name] = as_array(value, name, mats[name].shape)  # the filter's dimensions are fixed
        self._set_model(*check_model(*mats.values()))

    return property(fget, fset, doc=doc + " Read-only array; assign a new one to change the model.")


class BatchKalmanFilter:
    r"""``M`` independent Kalman filters sharing ``(F, H, Q, R)``, stored as stacked arrays.

    Every step is a handful of batched ``matmul``/``solve`` calls over the track axis (no Python
    loop over tracks); the maths is that of :class:`KalmanFilter` track by track. Tracks can be
    added with :meth:`append` and removed with :meth:`keep`, as a multi-object tracker needs.

    Parameters
    ----------
    F, H, Q, R : array_like
        Shapes ``(n, n)``, ``(m, n)``, ``(n, n)``, ``(m, m)`` as for :class:`KalmanFilter`.
    x0 : array_like, shape (M, n)
        Initial means (``M = 0`` is allowed: start empty, :meth:`append` later).
    P0 : array_like, shape (M, n, n) or (n, n)
        Initial covariances; one ``(n, n)`` matrix is shared by all tracks (copied).

    Attributes
    ----------
    F, H, Q, R : ndarray
        The model, as validated (``Q``, ``R`` symmetrised); read-only arrays, since the filter
        precomputes operators from them: assign a new matrix (same shape) to change one.
    x : ndarray, shape (M, n)
    P : ndarray, shape (M, n, n)
    innovation : ndarray, shape (M, m) or None
        Innovations of the last :meth:`update`; NaN rows for tracks that were not updated.
    S : ndarray, shape (M, m, m) or None
        Innovation covariances ``H P⁻ Hᵀ + R`` at the last :meth:`update` (all tracks).
    log_likelihood : ndarray, shape (M,) or None
        Per-track log-likelihood of the last update (0 for tracks not updated). ``innovation``,
        ``S`` and ``log_likelihood`` are reset to ``None`` by :meth:`append`/:meth:`keep`.

    Examples
    --------
    >>> from flowtrack.kalman import constant_velocity_model
    >>> F, H, Q, R = constant_velocity_model(1.0, 0.0, 1.0, dim=1)
    >>> bkf = BatchKalmanFilter(F, H, Q, R, x0=[[0.0, 1.0], [5.0, 0.0]], P0=np.eye(2))
    >>> bkf.predict()
    >>> bkf.x
    array([[1., 1.],
           [5., 0.]])
    >>> bkf.update([[1.0], [9.0]], mask=[True, False])   # second track missed
    >>> bkf.x[1]
    array([5., 0.])
    >>> idx = bkf.append([2.0, 0.0])                      # a third track, P0 = the first P0
    >>> len(bkf), idx
    (3, array([2]))
    >>> bkf.keep([0, 2]); len(bkf)
    2
    """

    def __init__(self, F, H, Q, R, x0, P0):
        F, H, Q, R = check_model(F, H, Q, R)
        self.dim_x = n = F.shape[0]
        self.dim_z = H.shape[0]
        iu, ju = np.triu_indices(n)
        self._iu_ju = iu * n + ju                                  # flat index of upper entry (i, j), i <= j
        self._ju_iu = ju * n + iu                                  # ... and of its mirror (j, i)
        pos = np.empty((n, n), dtype=np.intp)
        pos[iu, ju] = np.arange(iu.size)
        pos[ju, iu] = pos[iu, ju]
        self._mirror = pos.ravel()                                 # full entry -> its packed slot
        self._x_cache: np.ndarray | None = None                    # x, P, _hph(): see _state_changed
        self._P_cache: np.ndarray | None = None
        self._hph_cache: tuple[np.ndarray, np.ndarray] | None = None
        self._set_model(F, H, Q, R)
        x0 = as_array(x0, "x0", ("M", n))
        self._P0_default: np.ndarray | None = None
        self._xc = np.ascontiguousarray(x0.T)
        self._Pu = self._pack(self._covariances(P0, "P0", x0.shape[0]))
        self._Pu_spare: np.ndarray | None = None                   # the other buffer of predict
        self._buf: np.ndarray | None = None                        # scratch of update
        self._reset_last()

    def _covariances(self, P0, name: str, M: int) -> np.ndarray:
        n = self.dim_x
        P0 = as_array(P0, name)
        if P0.shape == (n, n):
            check_psd(P0, name)
            P0 = 0.5 * (P0 + P0.T)
            if self._P0_default is None:
                self._P0_default = P0.copy()
            return np.broadcast_to(P0, (M, n, n)).copy()
        if P0.shape != (M, n, n):
            raise ValueError(f"{name} must have shape ({M}, {n}, {n}) or ({n}, {n}), got {P0.shape}")
        if M:
            check_psd(P0, name)
        return 0.5 * (P0 + np.swapaxes(P0, -1, -2))

    def _pack(self, P: np.ndarray) -> np.ndarray:
        """Symmetric ``(k, n, n)`` stack -> packed component-major ``(n(n+1)/2, k)`` (upper triangles)."""
        k, n = P.shape[0], self.dim_x
        return np.ascontiguousarray(P.reshape(k, n * n)[:, self._iu_ju].T)

    def _reset_last(self) -> None:
        self._yc: np.ndarray | None = None
        self._sel = None
        self._Sc: np.ndarray | None = None
        self._y_cache: np.ndarray | None = None
        self._S_cache: np.ndarray | None = None
        self.log_likelihood: np.ndarray | None = None

    def _state_changed(self) -> None:
        """Drop everything derived from the state (``x``, ``P``, ``H P Hᵀ + R``): call after every change."""
        self._x_cache = None
        self._P_cache = None
        self._hph_cache = None

    @property
    def M(self) -> int:
        """Number of tracks."""
        return self._xc.shape[1]

    def __len__(self) -> int:
        return self.M

    # -- public arrays -------------------------------------------------------------------------------
    #
    # Internally the state is component-major (see "Layout" below): ``_xc (n, M)`` and the upper
    # triangles of the covariances packed as ``_Pu (n(n+1)/2, M)``. The usual ``x (M, n)`` and
    # ``P (M, n, n)`` are built on access and cached until the next step or track change; they are
    # copies, so write them back by assignment (``bkf.P = ...``), not by item assignment.
    @property
    def x(self) -> np.ndarray:
        """Means, shape ``(M, n)``."""
        if self._x_cache is None:
            self._x_cache = np.ascontiguousarray(self._xc.T)
            self._x_cache.flags.writeable = False  # an in-place edit would not reach the filter
        return self._x_cache

    @x.setter
    def x(self, value) -> None:
        value = as_array(value, "x", (self.M, self.dim_x))
        self._xc = np.ascontiguousarray(value.T)
        self._state_changed()

    @property
    def P(self) -> np.ndarray:
        """Covariances, shape ``(M, n, n)`` (exactly symmetric)."""
        if self._P_cache is None:
            n = self.dim_x
            self._P_cache = np.ascontiguousarray(self._Pu[self._mirror].T).reshape(self.M, n, n)
            self._P_cache.flags.writeable = False  # assign the whole array instead
        return self._P_cache

    @P.setter
    def P(self, value) -> None:
        n = self.dim_x
        value = as_array(value, "P", (self.M, n, n))
        self._Pu = self._pack(0.5 * (value + np.swapaxes(value, -1, -2)))
        self._state_changed()

    @property
    def innovation(self) -> np.ndarray | None:
        """Innovations of the last :meth:`update`, shape ``(M, m)``; NaN rows for tracks not updated."""
        if self._y_cache is None and self._yc is not None:
            y = np.ascontiguousarray(self._yc.T)
            if self._sel is not None:
                y[~self._sel] = np.nan
            self._y_cache = y
        return self._y_cache

    @property
    def S(self) -> np.ndarray | None:
        """Innovation covariances ``H P⁻ Hᵀ + R`` of the last :meth:`update`, shape ``(M, m, m)``."""
        if self._S_cache is None and self._Sc is not None:
            m = self.dim_z
            self._S_cache = np.ascontiguousarray(self._Sc.reshape(m * m, -1).T).reshape(-1, m, m)
        return self._S_cache

    # -- track management ----------------------------------------------------------------------------
    def append(self, x0, P0=None) -> np.ndarray:
        """Add tracks; return their indices.

        Parameters
        ----------
        x0 : array_like, shape (k, n) or (n,)
            Means of the new tracks.
        P0 : array_like, shape (k, n, n) or (n, n), optional
            Their covariances; default: the ``(n, n)`` ``P0`` given to the constructor (an error
            if there was none).

        Returns
        -------
        indices : ndarray of int, shape (k,)
        """
        n = self.dim_x
        x0 = as_array(x0, "x0")
        if x0.shape == (n,):
            x0 = x0[None, :]
        if x0.ndim != 2 or x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (k, {n}) or ({n},), got {x0.shape}")
        k = x0.shape[0]
        if P0 is None:
            if self._P0_default is None:
                raise ValueError("P0 is required: the constructor was not given a shared (n, n) P0")
            P0 = self._P0_default
        P0 = self._covariances(P0, "P0", k)
        start = self.M
        self._xc = np.concatenate([self._xc, x0.T], axis=1)
        self._Pu = np.concatenate([self._Pu, self._pack(P0)], axis=1)
        self._state_changed()
        self._reset_last()
        return np.arange(start, start + k)

    def keep(self, indices) -> None:
        """Keep only the tracks selected by ``indices`` (int array, in that order, or bool mask (M,))."""
        idx = np.asarray(indices)
        if idx.dtype == bool:
            if idx.shape != (self.M,):
                raise ValueError(f"indices as a mask must have shape ({self.M},), got {idx.shape}")
        elif idx.size == 0:
            idx = np.zeros(0, dtype=int)
        elif not np.issubdtype(idx.dtype, np.integer) or idx.ndim != 1:
            raise ValueError(f"indices must be a 1-D int array or a bool mask of shape ({self.M},)")
        elif idx.min() < -self.M or idx.max() >= self.M:
            raise ValueError(f"indices out of range for {self.M} tracks")
        self._xc = np.ascontiguousarray(self._xc[:, idx])
        self._Pu = np.ascontiguousarray(self._Pu[:, idx])
        self._state_changed()
        self._reset_last()

    # -- steps ---------------------------------------------------------------------------------------
    #
    # Layout. A stack of M tiny matrices (M, 4, 4) is the worst case for numpy: a stacked ``matmul``
    # costs ~100 ns per 4x4 product and elementwise ops with an inner axis of length 4 run far below
    # memory speed. So the state is kept in the *component-major* ("structure of arrays") layout: a
    # ``(k, M)`` array whose row ``r`` is one matrix entry for all tracks; of each symmetric ``P``
    # only the upper triangle is stored (``n(n+1)/2`` rows), so ``P`` is exactly symmetric by
    # construction.
    #   * every product with a shared matrix (F, H) is one GEMM with a Kronecker matrix folded onto
    #     the packed triangle, e.g. vec(F P Fᵀ) = (F ⊗ F) vec(P) (row-major vec), for all tracks;
    #     when H selects entries (each row one 1), P Hᵀ and H P Hᵀ are a row gather instead;
    #   * every per-track product (K y, K S, D Kᵀ) is one broadcast multiply and a sum over the tiny
    #     m axis on contiguous length-M rows;
    #   * S⁻¹ for m <= 3 is closed form (adjugate / determinant, PD checked by leading minors).
    def _set_model(self, F, H, Q, R) -> None:
        """Store the validated model read-only and precompute its operators on the packed layout.

        ``F, H, Q, R`` are read-only (an in-place edit would bypass the operators); assigning one
        (``bkf.Q = ...``) validates it and comes back here.
        """
        for A in (F, H, Q, R):
            A.flags.writeable = False
        self._F, self._H, self._Q, self._R = F, H, Q, R
        n, m = self.dim_x, self.dim_z
        up, lo = self._iu_ju, self._ju_iu
        off = (up != lo)[None, :]

        def fold(A):  # A (r, n²) acting on vec(P) -> (r, n(n+1)/2) acting on the packed P
            return np.ascontiguousarray(A[:, up] + np.where(off, A[:, lo], 0.0))

        FF = np.einsum("ik,jl->ijkl", F, F).reshape(n * n, n * n)          # vec(F P Fᵀ) = FF vec(P)
        IH = np.einsum("ik,jl->ijkl", np.eye(n), H).reshape(n * m, n * n)  # vec(P Hᵀ)
        HH = np.einsum("ik,jl->ijkl", H, H).reshape(m * m, n * n)          # vec(H P Hᵀ)
        G = np.vstack([IH, HH])                  # vec(P) -> [vec(P Hᵀ); vec(H P Hᵀ)], component-major
        # H a selection matrix: every row of G picks one entry of P, a gather of packed rows
        take = None
        if np.array_equal(np.count_nonzero(G, axis=1), np.ones(len(G))) and (G.max(axis=1) == 1).all():
            take = self._mirror[np.argmax(G, axis=1)]
        cols = np.argmax(H, axis=1)
        if not np.array_equal(H, np.eye(n)[cols]):
            cols = None
        self._FFp = fold(FF[up])                           # (n(n+1)/2)² : packed F P Fᵀ
        self._Qu = Q.ravel()[up][:, None].copy()           # packed Q, a column
        self._take = take                                  # packed rows of [P Hᵀ; H P Hᵀ], or None
        self._G = fold(G)                                  # ... else this operator on the packed P
        self._Rcol = R.reshape(m * m, 1).copy()
        self._cols = cols                                  # H x = x[cols] if H selects, else None
        self._state_changed()

    F = _model_property("F", "State transition, shape ``(n, n)``.")
    H = _model_property("H", "Measurement matrix, shape ``(m, n)``.")
    Q = _model_property("Q", "Process noise covariance, shape ``(n, n)``.")
    R = _model_property("R", "Measurement noise covariance, shape ``(m, m)``.")

    def _hph(self):
        """Component-major ``P Hᵀ (n, m, M)`` and ``S = H P Hᵀ + R (m, m, M)`` (exactly symmetric).

        Cached until the state changes (:meth:`_state_changed`): the tracker's gating
        (:meth:`predicted_measurements`) and the :meth:`update` that follows share one build. The
        arrays are shared, so callers must not write into them.
        """
        c = self._hph_cache
        if c is None:
            M, n, m = self.M, self.dim_x, self.dim_z
            take = self._take
            if take is not None:
                Y = self._Pu.take(take, axis=0)
            else:
                Y = gemm_over_columns(self._G, self._Pu)
            S = Y[n * m:]
            S += self._Rcol
            S = S.reshape(m, m, M)
            if take is None:
                for i in range(m):
                    for j in range(i + 1, m):
                        S[j, i] = S[i, j]
            c = self._hph_cache = (Y[:n * m].reshape(n, m, M), S)
        return c

    def predict(self) -> None:
        r"""Time update of every track: :math:`x_i \leftarrow F x_i`, :math:`P_i \leftarrow F P_i F^\top + Q`.

        One GEMM gives the (packed) upper triangle of every :math:`F P_i F^\top`, so ``P`` stays
        exactly symmetric.
        """
        FFp = self._FFp
        self._xc = gemm_over_columns(self._F, self._xc)
        Pu, spare = self._Pu, self._Pu_spare
        if spare is None or spare.shape != Pu.shape or Pu.shape[1] * FFp.size > GEMM_SINGLE_THREAD_WORK:
            spare = gemm_over_columns(FFp, Pu)
        else:
            np.matmul(FFp, Pu, out=spare)
        spare += self._Qu
        self._Pu, self._Pu_spare = spare, Pu
        self._state_changed()

    def predicted_measurements(self):
        """Predicted measurements and innovation covariances of all tracks, for gating.

        Returns
        -------
        z_pred : ndarray, shape (M, m)
            :math:`H x_i`.
        S : ndarray, shape (M, m, m)
            :math:`H P_i H^\\top + R`.
        """
        M, m = self.M, self.dim_z
        cols = self._cols
        _, S = self._hph()
        z = self._xc[cols] if cols is not None else self._H @ self._xc
        # a copy, always (for M = 1 the transpose is already contiguous): S stays cached for update
        return np.ascontiguousarray(z.T), S.reshape(m * m, M).T.copy().reshape(M, m, m)

    def update(self, Z, mask=None) -> None:
        r"""Joseph-form measurement update of the tracks with ``mask[i]`` True.

        Per track, with :math:`S = HPH^\top + R`: :math:`K = P H^\top S^{-1}`,
        :math:`x \leftarrow x + K y`, and the Joseph form
        :math:`P \leftarrow (I - KH) P (I - KH)^\top + K R K^\top`, evaluated as
        :math:`P + D K^\top + K D^\top` with :math:`D = \tfrac12 K S - P H^\top` (the same
        polynomial in ``K`` expanded, so it keeps the Joseph form's property that an error
        :math:`\delta K` in the gain changes ``P`` only by :math:`\delta K\, S\, \delta K^\top`);
        only the upper triangle is computed and stored, so ``P`` is exactly symmetric.
        :math:`S^{-1}` is closed form for ``m <= 3`` (adjugate over determinant; positive
        definiteness checked through the leading principal minors) and from a Cholesky
        factorisation otherwise. Tracks with ``mask`` False get
        a zero gain, so their ``x`` and (symmetric) ``P`` are left bit-for-bit unchanged.

        Parameters
        ----------
        Z : array_like, shape (M, m)
            One measurement per track; rows with ``mask`` False are ignored and may be NaN.
        mask : array_like of bool, shape (M,), optional
            Which tracks have a measurement (default: all).
        """
        M, n, m = self.M, self.dim_x, self.dim_z
        Z = as_array(Z, "Z", (M, m), allow_nan=True)
        if mask is None:
            sel = None
        else:
            sel = np.asarray(mask)
            if sel.dtype != bool or sel.shape != (M,):
                raise ValueError(f"mask must be a bool array of shape ({M},), got {sel.dtype} {sel.shape}")
            if sel.all():
                sel = None
        cols = self._cols
        PHt, S = self._hph()                                               # (n, m, M), (m, m, M)
        xc = self._xc
        y = Z.T - (xc[cols] if cols is not None else self._H @ xc)         # (m, M), NaN if unmeasured
        if sel is not None:
            y = np.where(sel, y, 0.0)
        if np.isnan(y).any():  # Z is finite or NaN (as_array), x finite: a NaN in a measured row
            raise ValueError("Z contains NaN in a row that is to be updated (mask True)")
        Si, logdet = spd_inverse_cm(S, sel)                               # (m, m, M), zero if unmeasured
        # K = P Hᵀ S⁻¹, the Joseph factor D = K S / 2 - P Hᵀ, K y, S⁻¹ y: sums over the tiny m axis,
        # unrolled (K, D, D Kᵀ) or one broadcast product and a sum; D Kᵀ in reused scratch buffers
        K = PHt[:, 0, None] * Si[0]                                        # (n, m, M)
        D = np.empty_like(K)
        for k in range(1, m):
            np.multiply(PHt[:, k, None], Si[k], out=D)
            K += D
        np.multiply(K[:, 0, None], S[0], out=D)
        for k in range(1, m):
            D += K[:, k, None] * S[k]
        D *= 0.5
        D -= PHt
        self._xc = xc + (K * y).sum(axis=1)
        # Joseph form (I - KH) P (I - KH)ᵀ + K R Kᵀ = P + D Kᵀ + K Dᵀ  (for any gain K), upper triangle
        buf = self._buf
        if buf is None or buf.shape[1] != n * n * M:
            buf = self._buf = np.empty((2, n * n * M))
        T = buf[0].reshape(n, n, M)                                        # (D Kᵀ)[i, j]
        tmp = buf[1].reshape(n, n, M)
        np.multiply(D[:, None, 0], K[None, :, 0], out=T)
        for k in range(1, m):
            np.multiply(D[:, None, k], K[None, :, k], out=tmp)
            T += tmp
        T = T.reshape(n * n, M)
        Pu = self._Pu
        Pu += T.take(self._iu_ju, axis=0)
        Pu += T.take(self._ju_iu, axis=0)
        quad = (y * (y[:, None] * Si).sum(axis=0)).sum(axis=0)
        ll = quad
        ll += logdet
        ll += m * LOG_2PI
        ll *= -0.5
        if sel is not None:
            ll[~sel] = 0.0
        self._state_changed()
        self._reset_last()
        self._yc, self._sel, self._Sc, self.log_likelihood = y, sel, S, ll

    def __repr__(self) -> str:
        return f"BatchKalmanFilter(M={self.M}, dim_x={self.dim_x}, dim_z={self.dim_z})"
