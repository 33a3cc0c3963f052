r"""Symbolic derivations of lesson 7 (five languages): the orderings of the constant-velocity process
noise, :math:`Q_{1D}\otimes I_d` against the listings' :math:`\operatorname{blkdiag}(Q_{1D},\dots)`.

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

import sympy as sp

from .._validation import positive_int
from .filtering import white_noise_acceleration_Q
from .graph import commutation_matrix

__all__ = [
    "process_noise_orderings",
]


def process_noise_orderings(dim: int = 2, model: str = "discrete") -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    r"""The derived process noise in both state orders, and the permutation between them (§6, lesson 7).

    ``Q`` is :func:`white_noise_acceleration_Q` for the derivative-major order
    ``[p_1..p_d, v_1..v_d]`` (:math:`Q_{1D}\otimes I_d`); ``Q_axis`` is
    :math:`\operatorname{blkdiag}(Q_{1D},\dots,Q_{1D}) = I_d\otimes Q_{1D}` built from the derived
    one-axis :math:`Q_{1D}` = ``white_noise_acceleration_Q(1)``, the matrix for the axis-major order
    ``[p_1, v_1, p_2, v_2, ...]``; ``Pi`` = ``commutation_matrix(2, dim)`` maps the first order to the
    second, and :math:`\Pi Q \Pi^\top = Q_{axis}`.

    Returns
    -------
    (Q, Q_axis, Pi) : sympy.Matrix, each (2*dim, 2*dim)

    Examples
    --------
    >>> Q, Q_axis, Pi = process_noise_orderings(2)
    >>> Pi * Q * Pi.T == Q_axis, Q == Q_axis
    (True, False)
    """
    d = positive_int(dim, "dim")
    Q = white_noise_acceleration_Q(d, model)
    Q1d = white_noise_acceleration_Q(1, model)
    return Q, sp.diag(*([Q1d] * d)), commutation_matrix(2, d)
