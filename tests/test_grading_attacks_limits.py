"""A resource attack on a class run: a student filling the disk (the sandbox's own resource attacks
are in ``reference_impl/grading_sandbox/tests/test_attacks_limits.py``).
"""

import json

import pytest

from flowtrack_course.grading.engine.jobs import ClassJob
from flowtrack_course.grading.grade import grade_class
from grading_helpers import get_exercise, source_notebook
from grading_sandbox import bwrap_status
from grading_sandbox.isolation import remove_tree, tree_usage

pytestmark = pytest.mark.xdist_group("sandbox")


def test_a_disk_filler_does_not_reach_the_host_or_the_next_student(tmp_path, monkeypatch):
    # The red team filled a disk shared with the output: the next students scored 0 ("No space left on
    # device") and grades.csv could not be written. Under bubblewrap a student writes only to the
    # sandbox's own tmpfs: the host's disks (output, cache) never see it.
    import shutil

    ok, why = bwrap_status()
    assert ok, why
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    ex = get_exercise("ex05_cv_model")
    subs = tmp_path / "subs"
    for name in ("ann", "mallory", "zoe"):
        (subs / name).mkdir(parents=True)
        shutil.copy(source_notebook(ex), subs / name / ex.notebook)
    nb = json.loads((subs / "mallory" / ex.notebook).read_text())
    filler = """
import os
for d in (".", "/tmp"):
    try:
        for i in range(100):  # files of 15 MiB (RLIMIT_FSIZE is 16 MiB) until the disk is full
            with open(os.path.join(d, f"fill{i}"), "wb") as f:
                f.write(b"x" * (15 << 20))
    except OSError:
        pass
"""
    cell = next(c for c in nb["cells"]
                if c.get("metadata", {}).get("nbgrader", {}).get("grade_id") == "cv_transition")
    cell["source"] = filler + "".join(cell["source"])
    (subs / "mallory" / ex.notebook).write_text(json.dumps(nb))
    from grading_sandbox import sandbox as sandbox_module

    on_host = []  # bytes each sandbox left in its folder of the host, measured just before removal

    def measured_remove(path):
        on_host.append(tree_usage(path, 100_000).size)
        return remove_tree(path)

    monkeypatch.setattr(sandbox_module, "remove_tree", measured_remove)
    job = ClassJob(subs, tmp_path / "out", exercises=(ex,), progress=False)
    rows = {r["student"]: r for r in grade_class(job)}
    assert rows["ann"]["score"] == rows["zoe"]["score"] == ex.max_score, rows
    assert "error" not in rows["mallory"]  # graded like anyone (killed by the meter, or ENOSPC)
    # whatever the filler wrote went to its sandbox's tmpfs (RAM, bounded): none of it to the host
    assert on_host and max(on_host) < 1 << 20, on_host
