"""The scalar validators of :mod:`flowtrack`, for code built on the library.

Every public function of the library checks its scalar arguments with these, so that a wrong value is
reported with the argument's name and what was expected: ``TypeError`` for something that is not a
number of the right kind (bools are not numbers here), ``ValueError`` for NaN, inf or a value out
of range. Code built on the library (the course tooling, a student's own helpers) uses the same
validators to give the same messages. Each returns the value converted (``float`` or ``int``).

- :func:`scalar`: a finite real number;
- :func:`positive`: a finite real number > 0;
- :func:`nonnegative`: a finite real number >= 0;
- :func:`positive_int`: an integer >= ``minimum`` (1 unless given).

The implementation, and the array validators the library uses internally, are in the helper module
``flowtrack._validation``.

Examples
--------
>>> positive(0.5, "dt"), positive_int(3, "jobs"), scalar(-2, "offset"), nonnegative(0, "lam")
(0.5, 3, -2.0, 0.0)
>>> positive(0.0, "dt")
Traceback (most recent call last):
...
ValueError: dt must be > 0, got 0.0
>>> positive_int(2.0, "jobs")
Traceback (most recent call last):
...
TypeError: jobs must be an integer, got float
>>> scalar(float("nan"), "min")
Traceback (most recent call last):
...
ValueError: min must be finite, got nan
"""

from __future__ import annotations

from ._validation import nonnegative, positive, positive_int, scalar

__all__ = ["nonnegative", "positive", "positive_int", "scalar"]
