"""Shared test doubles for the grader's tests."""

from __future__ import annotations

from typing import ClassVar

from flowtrack_course.grading.exercises import plain_data
from flowtrack_course.grading.spec import Outcome


class StandInSandbox:
    """Base of the sandbox stand-ins for ``run_exercise``: no process, no student code run.

    Subclasses set :attr:`isolation` and define ``run(calls, timeout) -> list[Outcome]``; the
    constructor takes the answer cells (``[(grade_id, source), ...]``) and ignores the limits.
    """

    isolation = "stand-in"

    def __init__(self, cells, **kwargs):
        self.cells = list(cells)
        self.cell_errors: dict[str, str] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class RecordingSandbox(StandInSandbox):
    """Sandbox stand-in for ``run_exercise``: records the calls it is sent and echoes their argument.

    ``sent`` holds ``(function, plain data of the arguments)`` of every call since the caller last
    emptied it; nothing of the student's code is run (what is checked is the inputs sent).
    """

    sent: ClassVar[list[tuple[str, list]]] = []
    isolation = "recording"

    def run(self, calls, timeout):
        self.sent.extend((c.function, plain_data(list(c.args))) for c in calls)
        return [Outcome(True, plain_data(c.args[0])) for c in calls]


SANDBOX_MODES = ("bwrap", "fallback", "setpriv")


def use_sandbox_mode(mode: str, monkeypatch, tmp_path_factory) -> str:
    """Make the next Sandbox run in ``mode``; the attack suites' ``mode`` fixtures call this.

    ``"bwrap"`` requires bubblewrap (``make test`` installs it); ``"fallback"`` forces the fallback;
    ``"setpriv"`` runs as a Gradescope container does: root, and a bubblewrap that cannot create
    namespaces (``$FLOWTRACK_BWRAP`` points at a stub failing as bwrap does under Docker's default
    seccomp profile), so the grader picks the setpriv mode by itself (skipped when not root).
    """
    import os
    import tempfile
    from pathlib import Path

    from flowtrack_course.grading.isolation import bwrap_status, choose_mode

    if mode == "bwrap":
        ok, why = bwrap_status()
        assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
        monkeypatch.delenv("FLOWTRACK_BWRAP", raising=False)
        monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    elif mode == "fallback":
        monkeypatch.setenv("FLOWTRACK_SANDBOX", "fallback")
    elif mode == "setpriv":
        if os.geteuid() != 0:
            import pytest

            pytest.skip("the setpriv mode needs root (as in a Gradescope container)")
        # where the probe's unprivileged uid can run it (pytest's own temporary folders are private)
        stub = Path(tempfile.gettempdir()) / "flowtrack-test-failing-bwrap"
        if not stub.exists():
            tmp = stub.with_name(f"{stub.name}.{os.getpid()}")
            tmp.write_text(
                "#!/bin/sh\necho 'bwrap: No permissions to creating new namespace, likely because the "
                "kernel does not allow non-privileged user namespaces.' >&2\nexit 1\n"
            )
            tmp.chmod(0o755)
            os.replace(tmp, stub)
        monkeypatch.setenv("FLOWTRACK_BWRAP", str(stub))
        monkeypatch.delenv("FLOWTRACK_SANDBOX", raising=False)
        chosen, why = choose_mode()
        assert chosen == "setpriv" and "namespace" in why, (chosen, why)
    else:  # pragma: no cover
        raise ValueError(mode)
    return mode
