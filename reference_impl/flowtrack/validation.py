"""Input checks shared by the library and the tools built on it: public names of
:mod:`flowtrack._validation`'s checks.

>>> positive(0.5, "dt"), positive_int(3, "jobs"), scalar(2, "lam")
(0.5, 3, 2.0)
"""

from ._validation import _scalar as scalar
from ._validation import positive, positive_int

__all__ = ["positive", "positive_int", "scalar"]
