r"""sympy derivation of the turn-rate (coordinated-turn) track model of :mod:`flowtrack.motion`.

From first principles: a body moving in the plane :math:`z` = const whose velocity turns at the
constant rate :math:`\omega` obeys :math:`\dot v = \omega K v`, :math:`K = [e_z]_\times`, so
:math:`v(s) = e^{\omega s K} v_0` (the matrix exponential, computed by sympy) and
:math:`p(T) = p_0 + \int_0^T v(s)\,ds` (integrated by sympy); :math:`v_z` and :math:`\omega` are
constant. :func:`turn_rate_model` returns the state, :math:`f(x)` and the Jacobian
:math:`\partial f/\partial x` (``sympy.Matrix.jacobian``), and :func:`turn_rate_limits` the limits
:math:`\omega \to 0` of both (the constant-velocity model and its Jacobian, plus the
:math:`\partial p'/\partial\omega = \tfrac{T^2}{2} K v` column that keeps the yaw rate observable).

Examples
--------
>>> import sympy as sp
>>> x, f, J = turn_rate_model()
>>> f.shape, J.shape
((7, 1), (7, 7))
>>> fl, Jl = turn_rate_limits()
>>> T = sp.Symbol("T", positive=True)
>>> sp.simplify(fl[0] - (x[0] + T * x[3]))
0
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

__all__ = ["turn_rate_limits", "turn_rate_model", "turn_rate_model_numeric"]


@cache
def turn_rate_model():
    r"""State, transition and Jacobian of the turn-rate model about the z axis (3-D).

    Returns
    -------
    x : sympy.Matrix, shape (7, 1)
        ``[px, py, pz, vx, vy, vz, w]``.
    f : sympy.Matrix, shape (7, 1)
        :math:`f(x)` over the horizon ``T`` (symbol ``T``, positive).
    J : sympy.Matrix, shape (7, 7)
        :math:`\partial f/\partial x`.
    """
    px, py, pz, vx, vy, vz = sp.symbols("px py pz vx vy vz", real=True)
    w = sp.Symbol("w", real=True, nonzero=True)
    T, s = sp.symbols("T s", positive=True)
    G = sp.Matrix([[0, -1], [1, 0]])  # in-plane generator: [e_z]_x restricted to the plane
    E = sp.simplify((w * s * G).exp())  # e^{w s G}: the in-plane velocity rotation after s seconds
    v0 = sp.Matrix([vx, vy])
    v_s = E * v0
    v_T = v_s.subs(s, T)
    p_T = sp.Matrix([px, py]) + v_s.applyfunc(lambda e: sp.integrate(e, (s, 0, T)))
    x = sp.Matrix([px, py, pz, vx, vy, vz, w])
    f = sp.Matrix([p_T[0], p_T[1], pz + T * vz, v_T[0], v_T[1], vz, w]).applyfunc(sp.simplify)
    J = f.jacobian(x).applyfunc(sp.simplify)
    return x, f, J


@cache
def turn_rate_limits():
    r"""Limits :math:`\omega \to 0` of :math:`f` and :math:`J` from :func:`turn_rate_model`."""
    x, f, J = turn_rate_model()
    w = x[6]
    return f.applyfunc(lambda e: sp.limit(e, w, 0)), J.applyfunc(lambda e: sp.limit(e, w, 0))


@cache
def _numeric():
    x, f, J = turn_rate_model()
    T = sp.Symbol("T", positive=True)
    return sp.lambdify((list(x), T), f, "numpy"), sp.lambdify((list(x), T), J, "numpy")


def turn_rate_model_numeric(x, T):
    """``(f(x), J(x))`` lambdified from the derived expressions (axis z, 3-D, ``x[6] != 0``)."""
    ff, jf = _numeric()
    x = [float(v) for v in np.asarray(x, dtype=float)]
    return np.asarray(ff(x, float(T)), dtype=float).ravel(), np.asarray(jf(x, float(T)), dtype=float)
