"""The course's solutions keep full marks with the sandbox's seccomp filter on (the filter itself is
tested in ``reference_impl/grading_sandbox/tests/test_seccomp.py``).
"""

from __future__ import annotations

import pytest

from flowtrack_course.grading.engine.jobs import ClassJob
from flowtrack_course.grading.grade import grade_class
from grading_helpers import EXERCISES, source_notebook, use_sandbox_mode
from grading_sandbox import sandbox as sandbox_mod
from grading_sandbox.seccomp import seccomp_status

pytestmark = pytest.mark.xdist_group("sandbox")

needs_filter = pytest.mark.skipif(not seccomp_status()[0], reason=f"no seccomp filter: {seccomp_status()[1]}")


@needs_filter
@pytest.mark.parametrize("mode", ["bwrap", "setpriv"])
def test_the_solutions_keep_full_marks_under_the_filter(mode, monkeypatch, tmp_path_factory, tmp_path):
    import shutil

    use_sandbox_mode(mode, monkeypatch, tmp_path_factory)
    filtered = []
    real = sandbox_mod.Sandbox._launch

    def recording(self, *a, **k):
        out = real(self, *a, **k)
        filtered.append(self.seccomp)
        return out

    monkeypatch.setattr(sandbox_mod.Sandbox, "_launch", recording)
    subs = tmp_path / "subs"
    (subs / "sol").mkdir(parents=True)
    for ex in EXERCISES:
        shutil.copy(source_notebook(ex), subs / "sol" / ex.notebook)
    out = tmp_path / "out"
    if mode == "setpriv":  # the setpriv mode refuses to grade while its uid could read these
        for p in (subs, out, tmp_path):
            p.mkdir(exist_ok=True)
            p.chmod(0o700)
    (row,) = grade_class(ClassJob(subs, out, exercises=EXERCISES, progress=False))
    assert "error" not in row, row
    assert filtered and all(filtered), filtered
    want = {ex.id: ex.max_score for ex in EXERCISES}
    assert row["exercises"] == pytest.approx(want), row
