"""The names the sandbox reads from its surroundings: environment variables and folder names.

They are the package's whole configuration interface; nothing else of the host application is
read. The values below are the names the package has always answered to (the course it was made
for documents them to its instructors), so they stay as they are. A host application that wants
other names assigns these attributes once, before it creates its first sandbox.

===============  ===============================  ==============================================
attribute        environment variable             meaning
===============  ===============================  ==============================================
``ENV_MODE``     ``FLOWTRACK_SANDBOX``            ``bwrap``, ``setpriv``, ``fallback`` or
                                                  ``auto`` (:func:`~.isolation.choose_mode`)
``ENV_BWRAP``    ``FLOWTRACK_BWRAP``              the bubblewrap executable to use
``ENV_CACHE``    ``FLOWTRACK_SANDBOX_CACHE``      where the cache folder is made (:mod:`.cache`)
``ENV_SECCOMP``  ``FLOWTRACK_SANDBOX_SECCOMP``    ``0`` turns the seccomp filter off
``ENV_CGROUP``   ``FLOWTRACK_SANDBOX_CGROUP``     ``0`` turns the per-sandbox cgroups off
===============  ===============================  ==============================================

``NAME`` prefixes what the sandbox creates on the machine: the cache folder
``<tmp>/<NAME>-<uid>``, the cgroups ``<NAME>-<pid>-<n>`` and, inside bubblewrap, the read-only
mount point ``/opt/<NAME>`` of the runner, the exposed packages and the site-packages.
"""

from __future__ import annotations

import os

__all__ = ["ENV_BWRAP", "ENV_CACHE", "ENV_CGROUP", "ENV_MODE", "ENV_SECCOMP", "NAME", "env", "switched_off"]

ENV_MODE = "FLOWTRACK_SANDBOX"
ENV_BWRAP = "FLOWTRACK_BWRAP"
ENV_CACHE = "FLOWTRACK_SANDBOX_CACHE"
ENV_SECCOMP = "FLOWTRACK_SANDBOX_SECCOMP"
ENV_CGROUP = "FLOWTRACK_SANDBOX_CGROUP"
NAME = "flowtrack-sandbox"


def env(name: str) -> str:
    """The value of the environment variable ``name`` (``""`` when unset), read at each call so that
    a change of the environment takes effect at the next sandbox.

    >>> env("NO_SUCH_VARIABLE_SET_HERE")
    ''
    """
    return os.environ.get(name, "")


def switched_off(name: str) -> bool:
    """True when the environment variable ``name`` says ``0``, ``no`` or ``off``.

    >>> switched_off("NO_SUCH_VARIABLE_SET_HERE")
    False
    """
    return env(name).strip().lower() in ("0", "no", "off")
