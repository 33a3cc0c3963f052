"""Input checks shared by the library and the tools built on it: the public names of
:mod:`flowtrack._validation`'s checks.

>>> positive(0.5, "dt"), positive_int(3, "jobs"), scalar(2, "lam")
(0.5, 3, 2.0)
"""

from ._validation import _scalar, positive, positive_int

__all__ = ["positive", "positive_int", "scalar"]


def scalar(value, name: str) -> float:
    """``value`` as a finite real ``float``; a ``TypeError`` or ``ValueError`` naming ``name`` when it
    is not one (see :mod:`flowtrack._validation`)."""
    return _scalar(value, name)
