"""Independent numerical oracles shared by the tests (never the code under test)."""

import numpy as np


def central_difference_jacobian(f, X, h=1e-6):
    """Per-point Jacobian of ``f: (N, d) -> (N, m)`` by central differences, shape (N, m, d)."""
    X = np.asarray(X, dtype=float)
    cols = []
    for j in range(X.shape[1]):
        e = np.zeros(X.shape[1])
        e[j] = h
        cols.append((f(X + e) - f(X - e)) / (2 * h))
    return np.stack(cols, axis=-1)


def assert_same_run(a, b, rtol: float, path: str = "") -> None:
    """Two results of the same computation agree: structure, text and integers exactly, floats to rtol.

    For reruns (same seed, same machine or not): discrete outcomes (counts, ids, labels, strings) must
    be identical, while floats may differ in their last bits where BLAS/LAPACK, FFT, CHOLMOD or open3d
    reduce in a build- or alignment-dependent order, so they are compared as
    ``|x - y| <= rtol * max(|x|, |y|)`` (``rtol`` chosen per problem by the caller). NaN equals NaN.
    """
    where = path or "<root>"
    if isinstance(a, dict) and isinstance(b, dict):
        assert set(a) == set(b), f"{where}: keys {sorted(a)} vs {sorted(b)}"
        for k in a:
            assert_same_run(a[k], b[k], rtol, f"{path}/{k}")
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        assert len(a) == len(b), f"{where}: length {len(a)} vs {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_run(x, y, rtol, f"{path}/{i}")
    elif isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, (int, float)) and isinstance(b, (int, float)), f"{where}: {a!r} vs {b!r}"
        if np.isnan(a) and np.isnan(b):
            return
        assert abs(a - b) <= rtol * max(abs(a), abs(b)), f"{where}: {a!r} vs {b!r} (rtol {rtol:g})"
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} vs {b!r}"


def assert_same_text_numbers(a: str, b: str, path: str = "text") -> None:
    """Two rendered reports agree: the words exactly, each printed number to one unit of its last digit.

    A float that differs in its last bits can round to a neighbouring printed value when it sits on a
    rounding boundary, so a rerun's table is compared number by number, not byte by byte.
    """
    import re

    num = re.compile(r"[-+]?\d+(?:\.(\d+))?(?:[eE][-+]?\d+)?")
    assert num.sub("#", a) == num.sub("#", b), f"{path}: the text around the numbers differs"
    for x, y in zip(num.finditer(a), num.finditer(b)):
        digits = max(len(x.group(1) or ""), len(y.group(1) or ""))
        exp = re.search(r"[eE]([-+]?\d+)$", x.group(0))
        unit = 10.0 ** (-digits + (int(exp.group(1)) if exp else 0))
        assert abs(float(x.group(0)) - float(y.group(0))) <= unit * (1 + 1e-9), (
            f"{path}: {x.group(0)} vs {y.group(0)}"
        )
