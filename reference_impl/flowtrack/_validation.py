"""Input validation shared by every public function of :mod:`flowtrack`.

Every public entry point turns its array arguments into ``float64`` arrays with
:func:`as_array` and checks scalars with :func:`positive` / :func:`nonnegative`,
so a wrong shape, a NaN or a non-positive time step is reported with the name of
the offending argument and the shape that was expected.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np

__all__ = [
    "as_array",
    "scalar",
    "positive",
    "nonnegative",
    "positive_int",
    "probability",
    "spatial_dim",
    "check_psd",
    "check_square",
    "check_symmetric",
    "cholesky",
    "not_positive_definite",
]


def _shape_str(shape: Sequence[int | str | None]) -> str:
    inner = ", ".join("*" if s is None else str(s) for s in shape)
    return "(" + inner + ("," if len(shape) == 1 else "") + ")"


def as_array(
    value,
    name: str,
    shape: Sequence[int | str | None] | None = None,
    *,
    finite: bool = True,
    allow_nan: bool = False,
    min_rows: int = 0,
    dtype=np.float64,
    copy: bool = True,
) -> np.ndarray:
    """Convert ``value`` to a float64 array and check its shape and values.

    Parameters
    ----------
    value : array_like
        The argument to check.
    name : str
        The argument's name, used in error messages.
    shape : sequence of int, str or None, optional
        Expected shape. ``None`` or a string entry is a free dimension; a string
        (e.g. ``"N"``) names it in the message.
    finite : bool
        Reject NaN and inf (default). With ``allow_nan=True`` NaN is accepted but
        inf is still rejected.
    min_rows : int
        Minimum length of the first axis (e.g. 1 for "non-empty cloud").
    copy : bool
        Always return a new array (default). ``False`` returns ``value`` itself when it already is
        an array of ``dtype``; callers that pass ``False`` must never write into the result.

    Raises
    ------
    TypeError
        If ``value`` is not numeric (strings, objects, ``None``).
    ValueError
        Wrong number of dimensions, wrong size, too few rows, NaN or inf.
    """
    if value is None:
        raise TypeError(f"{name} must be an array, got None")
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a numeric array, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{name} could not be converted to an array: {exc}") from None
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.bool_)
    ):
        raise TypeError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if np.iscomplexobj(arr):
        raise TypeError(f"{name} must be real, got complex dtype {arr.dtype}")
    arr = np.array(arr, dtype=dtype, copy=True) if copy else np.asarray(arr, dtype=dtype)
    if shape is not None:
        expected = _shape_str(shape)
        if arr.ndim != len(shape):
            raise ValueError(f"{name} must have shape {expected}, got {arr.shape}")
        for got, want in zip(arr.shape, shape):
            if isinstance(want, numbers.Integral) and got != want:
                raise ValueError(f"{name} must have shape {expected}, got {arr.shape}")
    if min_rows and (arr.ndim == 0 or arr.shape[0] < min_rows):
        raise ValueError(f"{name} must have at least {min_rows} row(s), got shape {arr.shape}")
    if finite:
        if allow_nan:
            if np.isinf(arr).any():
                raise ValueError(f"{name} contains inf")
        elif not np.isfinite(arr).all():
            raise ValueError(f"{name} contains NaN or inf")
    return arr


def scalar(value, name: str) -> float:
    """Return ``value`` as float, raising unless it is a finite real number.

    ``TypeError`` (naming ``name``) for anything but a real number or a 0-d numeric array (bools
    included), ``ValueError`` for NaN or inf.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        if isinstance(value, np.ndarray) and value.ndim == 0 and np.issubdtype(value.dtype, np.number):
            value = value.item()
        else:
            raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    v = float(value)
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def positive(value, name: str) -> float:
    """Return ``value`` as float, raising ``ValueError`` unless it is finite and > 0."""
    v = scalar(value, name)
    if v <= 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    return v


def nonnegative(value, name: str) -> float:
    """Return ``value`` as float, raising ``ValueError`` unless it is finite and >= 0."""
    v = scalar(value, name)
    if v < 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    return v


def positive_int(value, name: str, minimum: int = 1) -> int:
    """Return ``value`` as int, raising unless it is an integer >= ``minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    v = int(value)
    if v < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {v}")
    return v


def probability(value, name: str) -> float:
    """Return ``value`` as float, raising unless it is a real number with ``0 < value < 1``.

    ``TypeError`` for a non-real value (bools included), ``ValueError`` for NaN, inf or a value
    outside the open interval.
    """
    p = scalar(value, name)
    if not 0.0 < p < 1.0:
        raise ValueError(f"{name} must satisfy 0 < {name} < 1, got {p}")
    return p


def spatial_dim(value, name: str = "dim") -> int:
    """Return ``value`` as int, raising unless it is a number of spatial axes: 1, 2 or 3."""
    d = positive_int(value, name)
    if d > 3:
        raise ValueError(f"{name} must be 1, 2 or 3, got {d}")
    return d


def check_square(mat: np.ndarray, name: str, n: int | None = None) -> np.ndarray:
    """Check that the last two axes of ``mat`` are square (and of size ``n`` if given)."""
    if mat.ndim < 2 or mat.shape[-1] != mat.shape[-2]:
        raise ValueError(f"{name} must be square (..., n, n), got shape {mat.shape}")
    if n is not None and mat.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}, {n}), got {mat.shape}")
    return mat


def _scale(mat: np.ndarray) -> float:
    return max(1.0, float(np.abs(mat).max(initial=0.0)))


def check_symmetric(mat: np.ndarray, name: str, *, atol: float = 1e-10) -> np.ndarray:
    """Check that one square matrix or a stack of them is symmetric, ``ValueError`` otherwise.

    Tolerance: relative ``1e-8`` plus absolute ``atol * max(1, max|mat|)``.

    Examples
    --------
    >>> check_symmetric(np.array([[2.0, 1.0], [1.0, 2.0]]), "S").shape
    (2, 2)
    >>> check_symmetric(np.array([[2.0, 1.0], [0.0, 2.0]]), "S")
    Traceback (most recent call last):
    ...
    ValueError: S must be symmetric
    """
    check_square(mat, name)
    if not np.allclose(mat, np.swapaxes(mat, -1, -2), rtol=1e-8, atol=atol * _scale(mat)):
        raise ValueError(f"{name} must be symmetric")
    return mat


def not_positive_definite(name: str, hint: str | None = None) -> ValueError:
    """The ``ValueError`` "<name> must be positive definite[; <hint>]" (for code that checks itself)."""
    return ValueError(f"{name} must be positive definite" + (f"; {hint}" if hint else ""))


def cholesky(mat: np.ndarray, name: str, *, hint: str | None = None) -> np.ndarray:
    """Lower Cholesky factor(s) ``L`` with ``mat = L Lᵀ``, of one matrix or a stack ``(..., n, n)``.

    Only the lower triangle of ``mat`` is read (check symmetry first with :func:`check_symmetric`
    where it matters).

    Raises
    ------
    ValueError
        "<name> must be positive definite" (plus ``hint``) if a matrix is not positive definite.

    Examples
    --------
    >>> cholesky(np.array([[4.0, 2.0], [2.0, 2.0]]), "S")
    array([[2., 0.],
           [1., 1.]])
    >>> cholesky(np.array([[1.0, 2.0], [2.0, 1.0]]), "S")
    Traceback (most recent call last):
    ...
    ValueError: S must be positive definite
    """
    try:
        return np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        raise not_positive_definite(name, hint) from None


def check_psd(mat: np.ndarray, name: str, *, strict: bool = False, atol: float = 1e-9) -> np.ndarray:
    """Check symmetry and positive (semi-)definiteness of one matrix or a stack of them.

    Symmetry is checked to a relative tolerance (:func:`check_symmetric`); definiteness through
    the smallest eigenvalue (``> 0`` if ``strict`` else ``>= -atol * scale``). An empty stack (shape
    ``(0, n, n)``) passes.
    """
    check_symmetric(mat, name)
    if mat.size == 0:  # an empty stack (a frame without detections) has no matrix to fail
        return mat
    scale = _scale(mat)
    eig = np.linalg.eigvalsh(0.5 * (mat + np.swapaxes(mat, -1, -2)))
    lo = eig.min()
    if strict and lo <= 0:
        raise ValueError(f"{name} must be positive definite (smallest eigenvalue {lo:.3g})")
    if lo < -atol * scale:
        raise ValueError(f"{name} must be positive semi-definite (smallest eigenvalue {lo:.3g})")
    return mat
