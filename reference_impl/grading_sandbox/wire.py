"""The one encoding of plain data between the grader and the sandboxed child, and the two records
that cross it: a :class:`Call` of a student function and its :class:`Outcome`.

Grader -> child: :func:`to_wire` turns call arguments into JSON data (a numpy array becomes
``{"__ndarray__": nested lists, "dtype", "shape"}`` with dtype bool, int64 or float64), which the child
(``_child.py``, standard library and numpy only, so it keeps its own copy of the decoder) rebuilds with
the same rule as :func:`from_wire`. Child -> grader: replies must be plain data (:func:`is_plain`):
``None``, ``bool``, ``int``, ``float``, ``str``, lists and dicts with str keys, nothing else.
:func:`plain_data` converts a returned value exactly as the child does before sending it (used by
the in-process path that the notebooks run).

Examples
--------
>>> import numpy as np
>>> wire = to_wire([np.arange(3), (1.5, "a")])
>>> wire[0]["dtype"], wire[0]["shape"], wire[1]
('int64', [3], [1.5, 'a'])
>>> from_wire(wire)[0].tolist(), is_plain(wire), is_plain((1, 2))
([0, 1, 2], True, False)
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Call", "NotPlainData", "Outcome", "as_child_receives", "from_wire", "is_plain", "plain_data",
           "to_wire"]


@dataclass(frozen=True)
class Call:
    """One call of a student function: ``function(*args, **kwargs)`` inside the child.

    ``args``/``kwargs`` hold plain data or numpy arrays (a bool, integer or float array is sent to
    the child as nested lists with its dtype and shape and rebuilt there as a bool, int64 or float64
    array, see :func:`to_wire`). ``post`` (plain data) asks the child to turn the result into data
    before it is sent: ``{"op": "formula", "symbols": [...], "points": [[...], ...]}`` parses a
    formula given as text and evaluates it at the points (:mod:`.formula`), so that the grader
    never parses student text.
    """

    function: str
    args: tuple[Any, ...] = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    post: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class Outcome:
    """What came back from one call: plain data only (never an object made by student code).

    ``ok`` is False when the call raised, timed out, crashed the child, exceeded a limit or returned
    something that is not plain data; ``error`` then says why.
    """

    ok: bool
    value: Any = None
    error: str = ""


def to_wire(x: Any, depth: int = 0) -> Any:
    """``x`` converted to plain data that crosses the boundary to the sandboxed child (arrays
    tagged with their dtype and shape).

    Raises
    ------
    TypeError
        ``x`` is nested more than 32 deep or holds a type that cannot cross.
    """
    if depth > 32:
        raise TypeError("Call arguments are nested too deeply")
    if x is None or isinstance(x, bool | int | float | str):
        return x
    if isinstance(x, np.ndarray):
        if x.dtype.kind == "b":
            dtype = "bool"
        elif x.dtype.kind in "iu":
            dtype = "int64"
        elif x.dtype.kind == "f":
            dtype = "float64"
        else:
            raise TypeError(f"Call arguments: arrays of dtype {x.dtype} cannot be sent to the sandbox")
        return {"__ndarray__": np.asarray(x, dtype=dtype).tolist(), "dtype": dtype, "shape": list(x.shape)}
    if isinstance(x, np.generic):
        return to_wire(x.item(), depth + 1)
    if isinstance(x, list | tuple):
        return [to_wire(v, depth + 1) for v in x]
    if isinstance(x, dict):
        if not all(isinstance(k, str) for k in x):
            raise TypeError("Call arguments: dict keys must be str")
        return {k: to_wire(v, depth + 1) for k, v in x.items()}
    raise TypeError(f"Call arguments of type {type(x).__name__} cannot be sent to the sandbox")


def is_plain(x: Any, depth: int = 0) -> bool:
    """True when ``x`` is plain data: ``None``, bool, int, float, str, and lists and
    str-keyed dicts of them (nested at most 64 deep).

    Examples
    --------
    >>> is_plain({"a": [1, 2.0, None]}), is_plain((1, 2))
    (True, False)
    """
    if depth > 64:
        return False
    t = type(x)
    if x is None or t in (bool, int, float, str):
        return True
    if t is list:
        return all(is_plain(v, depth + 1) for v in x)
    if t is dict:
        return all(type(k) is str and is_plain(v, depth + 1) for k, v in x.items())
    return False


def from_wire(x: Any) -> Any:
    """Rebuild what :func:`to_wire` made, as the child does (arrays of the sent dtype and shape)."""
    t = type(x)
    if t is dict:
        if "__ndarray__" in x:
            return np.array(x["__ndarray__"], dtype=x["dtype"]).reshape(x["shape"])
        return {k: from_wire(v) for k, v in x.items()}
    if t is list:
        return [from_wire(v) for v in x]
    return x


def as_child_receives(value: Any) -> Any:
    """A call argument as the sandboxed child receives it: encoded, sent as JSON and rebuilt (fresh
    bool/int64/float64 arrays, tuples as lists, copies of everything)."""
    return from_wire(json.loads(json.dumps(to_wire(value), allow_nan=True)))


class NotPlainData(TypeError):
    """A returned value that the child would refuse to send (not numbers, lists or numpy arrays)."""


def plain_data(value: Any, _depth: int = 0) -> Any:
    """Convert a returned value to plain JSON data as the sandboxed child does.

    numpy arrays -> nested lists (of the base-class data, so an ndarray subclass cannot lie about its
    values), numpy scalars -> Python scalars, tuples/lists -> lists (recursively), dicts with str
    keys -> dicts; ``int``/``float``/``bool``/``str``/``None`` stay; anything else raises
    :class:`NotPlainData` (a ``TypeError``).
    """
    if _depth > 16:
        raise NotPlainData("the result is nested too deeply")
    if value is None or type(value) in (bool, int, float, str):
        return value
    if isinstance(value, np.ndarray):
        arr = np.array(value, copy=True).view(np.ndarray)
        if arr.dtype == object:
            return [plain_data(v, _depth + 1) for v in arr.tolist()]
        if arr.dtype.kind not in "biuf":
            raise NotPlainData(f"an array of dtype {arr.dtype} is not numeric")
        return arr.tolist()
    if isinstance(value, np.generic) and value.dtype.kind in "biuf":
        return value.item()
    if type(value) in (list, tuple):
        return [plain_data(v, _depth + 1) for v in value]
    if type(value) is dict:
        if not all(type(k) is str for k in value):
            raise NotPlainData("dict keys must be strings")
        return {k: plain_data(v, _depth + 1) for k, v in value.items()}
    raise NotPlainData(f"returned a {type(value).__name__}, expected numbers, lists or numpy arrays")
