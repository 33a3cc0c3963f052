r"""Symbolic derivations of lesson 1 (camera geometry): the pinhole projection Jacobian (§2, Problem 1).

Part of :mod:`flowtrack.symbolic`, which re-exports every name.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from .._validation import as_array

__all__ = [
    "projection_jacobian",
    "projection_jacobian_numeric",
    "projection_symbols",
]


# --------------------------------------------------------------------------------------------------
# §2 / Problem 1: projection Jacobian
# --------------------------------------------------------------------------------------------------
def projection_symbols() -> tuple[sp.Symbol, ...]:
    """The symbols ``(X, Y, Z, fx, fy, cx, cy)`` used by :func:`projection_jacobian` (real; Z, fx, fy > 0)."""
    X, Y, cx, cy = sp.symbols("X Y c_x c_y", real=True)
    Z, fx, fy = sp.symbols("Z f_x f_y", positive=True)
    return X, Y, Z, fx, fy, cx, cy


def projection_jacobian() -> sp.Matrix:
    r"""Jacobian of the pinhole projection, derived by differentiation.

    .. math::

       \pi(X) = \begin{bmatrix} f_x X/Z + c_x \\ f_y Y/Z + c_y \end{bmatrix}, \qquad
       \frac{\partial\pi}{\partial X} =
       \begin{bmatrix} f_x/Z & 0 & -f_x X/Z^2 \\ 0 & f_y/Z & -f_y Y/Z^2 \end{bmatrix}.

    Returns
    -------
    sympy.Matrix, shape (2, 3)
        ``pi.jacobian([X, Y, Z])`` in the symbols of :func:`projection_symbols`.

    Examples
    --------
    >>> J = projection_jacobian()
    >>> J
    Matrix([
    [f_x/Z,     0, -X*f_x/Z**2],
    [    0, f_y/Z, -Y*f_y/Z**2]])
    """
    X, Y, Z, fx, fy, cx, cy = projection_symbols()
    pi = sp.Matrix([fx * X / Z + cx, fy * Y / Z + cy])
    return pi.jacobian(sp.Matrix([X, Y, Z]))


@cache
def _projection_fn():
    return sp.lambdify(projection_symbols(), projection_jacobian(), "numpy")


def projection_jacobian_numeric(X, cam) -> np.ndarray:
    """Evaluate the *derived* :func:`projection_jacobian` at points ``X (N, 3)`` for a camera.

    Parameters
    ----------
    X : array_like, shape (N, 3)
        Camera-frame points, Z > 0.
    cam : flowtrack.camera.PinholeCamera

    Returns
    -------
    ndarray, shape (N, 2, 3)

    Examples
    --------
    >>> from flowtrack.camera import PinholeCamera
    >>> projection_jacobian_numeric([[1.0, 2.0, 4.0]], PinholeCamera(100.0, 100.0, 0.0, 0.0))[0]
    array([[ 25.  ,   0.  ,  -6.25],
           [  0.  ,  25.  , -12.5 ]])
    """
    pts = as_array(X, "X", ("N", 3))
    if (pts[:, 2] <= 0).any():
        raise ValueError("X must have Z > 0 for every point")
    for attr in ("fx", "fy", "cx", "cy"):
        if not hasattr(cam, attr):
            raise TypeError(f"cam must be a PinholeCamera, got {type(cam).__name__}")
    f = _projection_fn()
    out = np.empty((pts.shape[0], 2, 3))
    for k, (x, y, z) in enumerate(pts):
        out[k] = f(x, y, z, cam.fx, cam.fy, cam.cx, cam.cy)
    return out
