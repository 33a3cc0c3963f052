r"""Symbolic derivations of lesson 2 (variational scene flow): the Euler-Lagrange equation (§3, Problem 2).

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

import sympy as sp
from sympy.calculus.euler import euler_equations

__all__ = [
    "euler_lagrange_scene_flow",
    "scene_flow_lagrangian",
]


# --------------------------------------------------------------------------------------------------
# §3 / Problem 2: Euler-Lagrange equation of the quadratic scene-flow energy
# --------------------------------------------------------------------------------------------------
def scene_flow_lagrangian():
    r"""The integrand of the scalar scene-flow energy and its ingredients.

    .. math::  \mathcal{L} = (a + v\,\Delta t - b)^2 + \lambda\,(v_x^2 + v_y^2)

    Returns
    -------
    (L, v, a, b, (x, y), (dt, lam))
        ``v, a, b`` are sympy functions of ``(x, y)``; ``dt`` and ``lam`` positive symbols.
    """
    x, y = sp.symbols("x y", real=True)
    dt, lam = sp.symbols("Delta_t lambda", positive=True)
    v, a, b = (sp.Function(n)(x, y) for n in ("v", "a", "b"))
    L = (a + v * dt - b) ** 2 + lam * (sp.diff(v, x) ** 2 + sp.diff(v, y) ** 2)
    return L, v, a, b, (x, y), (dt, lam)


def euler_lagrange_scene_flow() -> sp.Eq:
    r"""Euler–Lagrange equation of :math:`E(v) = \int_\Omega (a + v\Delta t - b)^2 + \lambda\|\nabla v\|^2`.

    Derived with :func:`sympy.calculus.euler.euler_equations`, i.e.
    :math:`\partial\mathcal{L}/\partial v - \partial_x \partial\mathcal{L}/\partial v_x
    - \partial_y \partial\mathcal{L}/\partial v_y = 0`, which gives

    .. math::  2\Delta t\,(a + v\,\Delta t - b) - 2\lambda\,\Delta v = 0
       \iff \Delta t^2 v - \lambda \Delta v = \Delta t\,(b - a).

    Returns
    -------
    sympy.Eq
        ``Eq(lhs, 0)`` in the functions/symbols of :func:`scene_flow_lagrangian`.

    Examples
    --------
    >>> eq = euler_lagrange_scene_flow()
    >>> L, v, a, b, (x, y), (dt, lam) = scene_flow_lagrangian()
    >>> laplacian = sp.diff(v, x, 2) + sp.diff(v, y, 2)
    >>> sp.simplify(eq.lhs - (2 * dt * (a + v * dt - b) - 2 * lam * laplacian))
    0
    """
    L, v, _a, _b, (x, y), _ = scene_flow_lagrangian()
    (eq,) = euler_equations(L, [v], [x, y])
    return eq
