"""Running an attack suite in each isolation mode: :func:`use_sandbox_mode` (for pytest).

The sandbox's own attack suite (``grading_sandbox/tests``) and a grader's suites call it from a
``mode`` fixture, so that every attack runs under bubblewrap, the setpriv mode and the fallback.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from . import config
from .isolation import bwrap_status, choose_mode

__all__ = ["SANDBOX_MODES", "use_sandbox_mode"]

SANDBOX_MODES = ("bwrap", "fallback", "setpriv")


def use_sandbox_mode(mode: str, monkeypatch, tmp_path_factory=None) -> str:
    """Make the next :class:`~.sandbox.Sandbox` run in ``mode``; returns ``mode``.

    ``"bwrap"`` requires bubblewrap (the test fails without it); ``"fallback"`` forces the fallback;
    ``"setpriv"`` runs as a Gradescope container does: root, and a bubblewrap that cannot create
    namespaces (:data:`.config.ENV_BWRAP` points at a stub failing as bwrap does under Docker's
    default seccomp profile), so the sandbox picks the setpriv mode by itself (skipped when not
    root). ``monkeypatch`` is pytest's fixture; ``tmp_path_factory`` is not used (kept for callers
    that pass it).
    """
    if mode == "bwrap":
        ok, why = bwrap_status()
        assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
        monkeypatch.delenv(config.ENV_BWRAP, raising=False)
        monkeypatch.setenv(config.ENV_MODE, "bwrap")
    elif mode == "fallback":
        monkeypatch.setenv(config.ENV_MODE, "fallback")
    elif mode == "setpriv":
        if os.geteuid() != 0:
            import pytest

            pytest.skip("the setpriv mode needs root (as in a Gradescope container)")
        # where the probe's unprivileged uid can run it (pytest's own temporary folders are private)
        stub = Path(tempfile.gettempdir()) / f"{config.NAME}-test-failing-bwrap"
        if not stub.exists():
            tmp = stub.with_name(f"{stub.name}.{os.getpid()}")
            tmp.write_text(
                "#!/bin/sh\necho 'bwrap: No permissions to creating new namespace, likely because the "
                "kernel does not allow non-privileged user namespaces.' >&2\nexit 1\n"
            )
            tmp.chmod(0o755)
            os.replace(tmp, stub)
        monkeypatch.setenv(config.ENV_BWRAP, str(stub))
        monkeypatch.delenv(config.ENV_MODE, raising=False)
        chosen, why = choose_mode()
        assert chosen == "setpriv" and "namespace" in why, (chosen, why)
    else:
        raise ValueError(f"mode must be one of {', '.join(SANDBOX_MODES)}, got {mode!r}")
    return mode
