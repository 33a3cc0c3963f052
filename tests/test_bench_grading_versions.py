"""``benchmarks/bench_grading_versions.py``: which exercises the old and new graders are timed on.

Only exercises whose notebooks are byte for byte the same in both trees may be used: a notebook that
changed may have gained graded questions, and the two graders would then not do the same work.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

COURSE = Path(__file__).resolve().parents[1]


def _bench(monkeypatch):
    # the script imports its neighbours (bench_grading, _results) as top-level modules
    monkeypatch.syspath_prepend(str(COURSE / "benchmarks"))
    spec = importlib.util.spec_from_file_location(
        "bench_grading_versions", COURSE / "benchmarks" / "bench_grading_versions.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_only_exercises_with_identical_notebooks_are_selected(tmp_path, monkeypatch):
    bench = _bench(monkeypatch)
    new, old = tmp_path / "new", tmp_path / "old"
    files = {
        "ex01": (b'{"cells": []}\n', b'{"cells": []}\n'),  # the same
        "ex02": (b'{"cells": [1]}\n', b'{"cells": []}\n'),  # a question added
        "ex03": (b'{"cells": []}\n', b'{"cells": []} \n'),  # one byte of white space
        "ex04": (b'{"cells": []}\n', None),  # not in the old tree
        "ex05": (None, b'{"cells": []}\n'),  # gone from the new tree
    }
    rel = {}
    for ex, (a, b) in files.items():
        rel[ex] = Path("exercises") / ex / f"{ex}.ipynb"
        for root, data in ((new, a), (old, b)):
            if data is not None:
                (root / rel[ex]).parent.mkdir(parents=True, exist_ok=True)
                (root / rel[ex]).write_bytes(data)
    used, left_out = bench.select_exercises(new, old, rel)
    assert used == ["ex01"]
    assert sorted(left_out) == ["ex02", "ex03", "ex04", "ex05"]
    assert "changed" in left_out["ex02"] and "changed" in left_out["ex03"]
    assert "old tree" in left_out["ex04"] and "checkout" in left_out["ex05"]


def test_the_course_copy_keeps_only_the_selected_exercises(tmp_path, monkeypatch):
    bench = _bench(monkeypatch)
    tree = tmp_path / "tree"
    for name in ("ex01_a", "ex02_b", "ex10_c", "languages"):
        (tree / "exercises" / name).mkdir(parents=True)
        (tree / "exercises" / name / "f.txt").write_text(name)
    (tree / "exercises" / "README.md").write_text("readme")
    course = bench.course_copy(tree, tmp_path / "course", {"ex02_b"})
    kept = sorted(p.name for p in (course / "exercises").iterdir())
    assert kept == ["README.md", "ex02_b", "languages"]
    assert (course / "exercises" / "ex02_b" / "f.txt").read_text() == "ex02_b"
