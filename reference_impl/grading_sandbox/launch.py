"""What a new child sees and how it is started: the bubblewrap command line (a fresh root of
read-only binds and two bounded tmpfs) or the fallback's command and deny list; and the error of a
child whose view lacks what its allowlist names (:class:`SandboxConfigError`).

Both functions are pure: they turn a :class:`View` (what the sandbox holds for this exercise) into
the command and the init message the runner (``_child.py``) receives; :class:`~.sandbox.Sandbox`
starts the process.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import config
from .isolation import bwrap_base, setpriv_command
from .runtime import Runtime, package_entries, stub_dir

__all__ = ["HOME", "OPT", "SandboxConfigError", "View", "bwrap_command", "config_error", "fallback_command"]

#: the student's HOME (and cwd) inside bubblewrap
HOME = "/home/student"
#: where bubblewrap mounts the runner (``bin``), the exposed packages (``lib``) and site-packages
OPT = f"/opt/{config.NAME}"


@dataclass(frozen=True)
class View:
    """What a child is given.

    ``sites`` the site-packages folders (outside paths); ``in_view`` the top-level packages of the
    allowlist (None: every installed one); ``lib_root`` the folder of the filtered copies of the
    exposed packages in view (None when there are none); ``exposed`` the top-level names of every
    exposed package (never shown from site-packages: their copies stand in for them);
    ``blocked_locations`` the blocked modules outside the exposed packages (the private packages
    included) and where they are; ``hide`` the outside paths the fallback's audit hook refuses.
    """

    runtime: Runtime
    sites: tuple[str, ...]
    in_view: tuple[str, ...] | None
    lib_root: Path | None
    runner: Path
    exposed: tuple[str, ...]
    blocked_locations: tuple[tuple[str, Path], ...]
    hide: tuple[str, ...]


def bwrap_command(view: View, bwrap: str, env: dict[str, str], disk_bytes: int) -> tuple[list[str], dict]:
    """The bubblewrap command line and init message of a child (see the package's threat model)."""
    inner_sites = [f"{OPT}/site/{i}" for i in range(len(view.sites))]
    cmd = bwrap_base(bwrap)
    cmd += ["--ro-bind", view.runtime.source, view.runtime.prefix]
    for src, dst in zip(view.sites, inner_sites):
        if view.in_view is not None:  # only what the allowlist needs
            cmd += ["--dir", dst]
            for entry in package_entries(src, view.in_view):
                if entry not in view.exposed:  # exposed packages come from their filtered copy
                    cmd += ["--ro-bind", f"{src}/{entry}", f"{dst}/{entry}"]
            continue
        cmd += ["--ro-bind", src, dst]
        for name in view.exposed:  # a non-editable install: its filtered copy hides the real one
            if (Path(src) / name).exists() and view.lib_root is not None:
                cmd += ["--ro-bind", str(view.lib_root / name), f"{dst}/{name}"]
    if view.lib_root is not None:
        cmd += ["--ro-bind", str(view.lib_root), f"{OPT}/lib"]
    cmd += ["--ro-bind", str(view.runner), f"{OPT}/bin"]
    for name, loc in view.blocked_locations:
        if view.in_view is not None and name.split(".")[0] not in view.in_view:
            continue  # not in the sandbox at all
        inner = str(loc)
        for src, dst in zip(view.sites, inner_sites):
            if loc.is_relative_to(src):
                inner = dst + "/" + str(loc.relative_to(src))
        stub = stub_dir(name)
        cmd += ["--ro-bind", str(stub if loc.is_dir() else stub / "__init__.py"), inner]
    # The only writable places are two tmpfs, HOME and /tmp, each of Limits.disk_bytes: the
    # kernel bounds their size (unlinked files included), the grader's meter their sum.
    # They live in the sandbox's mount namespace (in its cgroup's memory when there is one)
    # and vanish with it: nothing a student writes reaches a disk of the host. bubblewrap's
    # own root and /dev are unbounded tmpfs, so they are made read-only once all is mounted.
    size = str(int(disk_bytes))
    cmd += ["--size", size, "--tmpfs", HOME, "--size", size, "--tmpfs", "/tmp",
            "--remount-ro", "/dev", "--remount-ro", "/", "--chdir", HOME, "--clearenv"]
    for k, v in {**env, "HOME": HOME, "TMPDIR": "/tmp"}.items():
        cmd += ["--setenv", k, v]
    rt = view.runtime
    exe = str(Path(rt.prefix) / Path(rt.executable).relative_to(rt.source))
    cmd += [exe, "-I", "-S", "-B", f"{OPT}/bin/_child.py"]
    paths = [f"{OPT}/lib"] * (view.lib_root is not None) + inner_sites
    return cmd, {"paths": paths, "deny_paths": [], "strict_audit": False}


def fallback_command(view: View, workdir: Path, uid: int | None, setpriv: bool,
                     stdlib: Sequence[str]) -> tuple[list[str], dict[str, Any]]:
    """The command (through ``setpriv`` when ``setpriv``) and init message of a child without
    namespaces: what its audit hook refuses (``deny_paths``) and allows, and where it may write."""
    deny = [*view.hide, *(str(loc) for _, loc in view.blocked_locations)]
    if view.in_view is not None:  # the packages the allowlist does not need
        for site in view.sites:
            keep = set(package_entries(site, view.in_view)) - set(view.exposed)
            deny += [os.path.join(site, e) for e in sorted(os.listdir(site)) if e not in keep]
    cmd = [view.runtime.executable, "-I", "-S", "-B", str(view.runner / "_child.py")]
    if setpriv:  # the uid switch, capabilities and no_new_privs: see setpriv_command
        assert uid is not None
        cmd = [*setpriv_command(uid), *cmd]
    lib = [str(view.lib_root)] if view.lib_root is not None else []
    init = {"paths": [*lib, *view.sites], "deny_paths": deny, "strict_audit": True,
            "write_root": str(workdir),
            "allow_paths": [*lib, *view.sites, *stdlib, str(view.runner)]}
    return cmd, init


class SandboxConfigError(RuntimeError):
    """The sandbox's Python cannot import numpy or a module its allowlist names.

    The child tries those imports before any student code runs, so this is never the student's
    doing: it is the grader's environment (a package the sandbox's view lacks, a library that does
    not load). A grader reports it once, with the fix in the message, instead of scoring the
    student. ``module`` is what failed to import, ``error`` the child's exception.
    """

    def __init__(self, message: str, module: str = "", error: str = "") -> None:
        super().__init__(message)
        self.module = module
        self.error = error


def config_error(reply: dict, isolation: str, as_root: bool, cache: Path) -> SandboxConfigError:
    """The :class:`SandboxConfigError` of a child's ``config-error`` reply, with the fix."""
    module = str(reply.get("module", ""))[:200] or "numpy"
    error = str(reply.get("error", ""))[:1500].strip()
    if as_root:
        fix = ("the grader runs as root, so student code runs as an unprivileged uid that sees a "
               "world-readable mirror of the packages it cannot read (in the sandbox cache, "
               f"{cache}). Make the Python environment readable by other users (chmod -R a+rX on the "
               "virtual environment, chmod o+x on the folders above it) or grade as an ordinary user; "
               "if it persists, delete the cache folder and report this message")
    else:
        fix = ("the sandbox's Python sees only the packages the allowlist needs, without .pth files "
               "(python -I -S): reinstall the package (pip install --force-reinstall), check that "
               f"`python -I -S -c 'import {module}'` works with site-packages on PYTHONPATH, and report "
               "this message if it persists")
    msg = (f"grader configuration error: the sandbox's Python cannot import {module} ({isolation} "
           f"sandbox), which the exercise allows: {error}. This is not the student's work (nothing of "
           f"it had run yet). Fix: {fix}.")
    return SandboxConfigError(msg, module, error)
