r"""The RGB-D scene-flow energy of :mod:`flowtrack.rgbd_flow` in sympy: data term, Euler–Lagrange equations.

With the displacement field :math:`s(x, y) = (s_1, s_2, s_3)` (metres per frame) and the data terms
linearised about :math:`s = 0` (:mod:`flowtrack.rgbd_flow`, "Linearisation"), the quadratic energy
density is

.. math::

    \mathcal L = c_I\,(r_I + a_I^\top s)^2 + c_D\,(r_D + a_D^\top s)^2
                 + \lambda\, w \sum_{k=1}^3 \lVert \nabla s_k \rVert^2 ,

with :math:`a_I = J^\top \nabla I`, :math:`a_D = J^\top \nabla D - e_z` and every coefficient a
function of :math:`(x, y)`. Its Euler–Lagrange equations (:func:`rgbd_euler_lagrange`) are, for each
component :math:`k`,

.. math::

    c_I\, a_{I,k} (r_I + a_I^\top s) + c_D\, a_{D,k} (r_D + a_D^\top s)
    - \lambda\, \nabla\cdot(w\, \nabla s_k) = 0

(times 2): the pixel's 3×3 normal matrix :math:`N = c_I a_I a_I^\top + c_D a_D a_D^\top` coupled to
its neighbours by the weighted Laplacian. :func:`pixel_data_term` derives :math:`a_I, a_D` from the
projection and shows that :math:`\det N = 0` identically (rank at most 2) with the null vector
:math:`a_I \times a_D`.

The tests compare these equations with the discrete operator of :mod:`flowtrack.rgbd_flow`
(``tests/test_rgbd_flow.py``): on a grid of spacing :math:`h` its gradient divided by :math:`h^2` agrees
with the left-hand side to :math:`O(h^2)`.
"""

from __future__ import annotations

import sympy as sp
from sympy.calculus.euler import euler_equations

__all__ = ["pixel_data_term", "rgbd_energy_density", "rgbd_euler_lagrange"]


def rgbd_energy_density():
    """The energy density :math:`\\mathcal L` and its symbols.

    Returns
    -------
    L : sympy.Expr
    symbols : dict
        ``x, y`` (coordinates), ``s`` (list of 3 functions of x, y), ``a_I, a_D`` (lists of 3 functions),
        ``r_I, r_D, c_I, c_D, w`` (functions) and ``lam`` (a positive symbol).

    Examples
    --------
    >>> L, S = rgbd_energy_density()
    >>> sorted(str(f.func) for f in S["s"])
    ['s_1', 's_2', 's_3']
    """
    x, y = sp.symbols("x y", real=True)
    lam = sp.Symbol("lambda", positive=True)
    s = [sp.Function(f"s_{k}")(x, y) for k in (1, 2, 3)]
    a_I = [sp.Function(f"a_I{k}")(x, y) for k in (1, 2, 3)]
    a_D = [sp.Function(f"a_D{k}")(x, y) for k in (1, 2, 3)]
    r_I, r_D, c_I, c_D, w = (sp.Function(n)(x, y) for n in ("r_I", "r_D", "c_I", "c_D", "w"))
    res_I = r_I + sum(a * v for a, v in zip(a_I, s))
    res_D = r_D + sum(a * v for a, v in zip(a_D, s))
    smooth = sum(sp.diff(v, x) ** 2 + sp.diff(v, y) ** 2 for v in s)
    L = c_I * res_I**2 + c_D * res_D**2 + lam * w * smooth
    return L, {"x": x, "y": y, "s": s, "a_I": a_I, "a_D": a_D, "r_I": r_I, "r_D": r_D, "c_I": c_I,
               "c_D": c_D, "w": w, "lam": lam}


def rgbd_euler_lagrange():
    r"""The three Euler–Lagrange equations of :func:`rgbd_energy_density`.

    Returns
    -------
    eqs : list of sympy.Expr
        Left-hand sides :math:`\partial\mathcal L/\partial s_k - \partial_x(\partial\mathcal L/\partial
        s_{k,x}) - \partial_y(\partial\mathcal L/\partial s_{k,y})` (each = 0), from
        :func:`sympy.calculus.euler.euler_equations`.
    symbols : dict
        As in :func:`rgbd_energy_density`.

    Examples
    --------
    The equations are twice "data gradient minus weighted Laplacian":

    >>> eqs, S = rgbd_euler_lagrange()
    >>> x, y, s, w, lam = S["x"], S["y"], S["s"], S["w"], S["lam"]
    >>> aI, aD = S["a_I"], S["a_D"]
    >>> rI = S["r_I"] + sum(a * v for a, v in zip(aI, s))
    >>> rD = S["r_D"] + sum(a * v for a, v in zip(aD, s))
    >>> div = sp.diff(w * sp.diff(s[0], x), x) + sp.diff(w * sp.diff(s[0], y), y)
    >>> sp.simplify(eqs[0] - 2 * (S["c_I"] * aI[0] * rI + S["c_D"] * aD[0] * rD - lam * div))
    0
    """
    L, S = rgbd_energy_density()
    eqs = euler_equations(L, S["s"], [S["x"], S["y"]])
    return [sp.expand(e.lhs - e.rhs) for e in eqs], S


def pixel_data_term():
    r"""One pixel's linearised data term from the projection: :math:`a_I, a_D`, :math:`N`, its null vector.

    :math:`J = \partial\pi/\partial X` at :math:`X = (X, Y, Z)` with focal lengths :math:`f_x, f_y`;
    :math:`a_I = J^\top (I_x, I_y)^\top`, :math:`a_D = J^\top (D_x, D_y)^\top - e_z`,
    :math:`N = c_I a_I a_I^\top + c_D a_D a_D^\top`.

    Returns
    -------
    dict
        ``J`` (2×3), ``a_I``, ``a_D`` (3×1), ``N`` (3×3), ``null`` (:math:`a_I \times a_D`, 3×1) and the
        symbols.

    Examples
    --------
    :math:`\det N = 0` and :math:`N (a_I \times a_D) = 0` identically:

    >>> d = pixel_data_term()
    >>> sp.simplify(d["N"].det()), sp.simplify(d["N"] * d["null"]).T
    (0, Matrix([[0, 0, 0]]))
    """
    X, Y = sp.symbols("X Y", real=True)
    Z, fx, fy = sp.symbols("Z f_x f_y", positive=True)
    Ix, Iy, Dx, Dy = sp.symbols("I_x I_y D_x D_y", real=True)
    cI, cD = sp.symbols("c_I c_D", nonnegative=True)
    P = sp.Matrix([X, Y, Z])
    pi = sp.Matrix([fx * X / Z, fy * Y / Z])
    J = pi.jacobian(P)
    a_I = J.T * sp.Matrix([Ix, Iy])
    a_D = J.T * sp.Matrix([Dx, Dy]) - sp.Matrix([0, 0, 1])
    N = cI * a_I * a_I.T + cD * a_D * a_D.T
    return {"J": J, "a_I": a_I, "a_D": a_D, "N": N, "null": a_I.cross(a_D),
            "symbols": (X, Y, Z, fx, fy, Ix, Iy, Dx, Dy, cI, cD)}
