"""A control group per sandbox: memory and process limits the kernel enforces for the whole sandbox.

Resource limits (``setrlimit``) are per process: a student can fork children that each use the full
address space, and memory in ``memfd`` files or on a tmpfs belongs to no process at all. A cgroup
counts all of it (anonymous memory, page cache, shmem/tmpfs/memfd pages, kernel memory) for every
process of the sandbox, and the kernel's OOM killer then stays inside that group instead of picking
a grading worker. :class:`SandboxCgroup` makes one per sandbox, below the grader's own cgroup:

* **cgroup v2** (``/sys/fs/cgroup/cgroup.controllers``): ``memory.max``, ``memory.swap.max = 0``,
  ``memory.oom.group = 1`` (an OOM kills the whole sandbox), ``pids.max`` and, where the ``cpu``
  controller can be enabled, ``cpu.weight``; closed with ``cgroup.kill``. Needs the ``memory``
  and ``pids`` controllers enabled for children of the grader's cgroup (``cgroup.subtree_control``)
  and write access there: the case for root on a server, a systemd unit with ``Delegate=yes``, or
  ``systemd-run --user -p Delegate=yes``.
* **cgroup v1** (``/sys/fs/cgroup/memory`` and ``/sys/fs/cgroup/pids`` writable, as root in many
  containers and VMs): ``memory.limit_in_bytes`` (with ``memory.memsw.limit_in_bytes`` when swap
  accounting exists), ``pids.max`` and, where ``/sys/fs/cgroup/cpu`` is writable too,
  ``cpu.shares``.

The CPU share: the sandbox's processes and threads are scheduled as one group, with the default
weight (:data:`CPU_WEIGHT`), against the grader's other work. However many threads a student
starts, and whatever nice value or scheduling policy they give them (a process may change its own),
the sandbox gets one share of the CPU, and those settings act inside its group only; the seccomp
filter keeps them from changing any other process's (:mod:`.seccomp`).

When neither is available (an ordinary user without delegation, most laptops) the sandbox falls back
to its resource limits alone (RLIMIT_AS per process, RLIMIT_NPROC, a tmpfs bounded by size): memory
in forked children is then not counted together; memfd and System V shared memory, which no process's
RLIMIT_AS counts, are refused by the seccomp filter (:mod:`.seccomp`).
:func:`cgroup_status` says which case applies; the variable :data:`.config.ENV_CGROUP` set to ``0``
turns cgroups off.
"""

from __future__ import annotations

import itertools
import os
import signal
import time
from pathlib import Path

from . import config

__all__ = ["CPU_WEIGHT", "SandboxCgroup", "cgroup_status"]

#: the CPU weight of a sandbox's group (cgroup v2 ``cpu.weight``; v1 ``cpu.shares`` is 1024 / 100
#: times it): the kernel's default, the same as any other group's
CPU_WEIGHT = 100

_ROOT = Path("/sys/fs/cgroup")
_counter = itertools.count()


def _own_path(version: int, controller: str = "") -> str | None:
    """This process' cgroup path (v2: the ``0::`` line; v1: the line naming ``controller``)."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if version == 2 and parts[0] == "0" and parts[1] == "":
            return parts[2]
        if version == 1 and controller in parts[1].split(","):
            return parts[2]
    return None


def _v2_parent() -> Path | None:
    """Where per-sandbox v2 cgroups can be made (memory and pids delegated and writable), else None."""
    if not (_ROOT / "cgroup.controllers").is_file():
        return None
    own = _own_path(2)
    if own is None:
        return None
    base = _ROOT / own.lstrip("/")
    try:
        enabled = (base / "cgroup.subtree_control").read_text().split()
    except OSError:
        return None
    if not {"memory", "pids"} <= set(enabled):
        try:  # only possible where the grader's own cgroup holds no process (or is the root)
            (base / "cgroup.subtree_control").write_text("+memory +pids")
        except OSError:
            return None
    return base if os.access(base, os.W_OK) else None


def _v1_parents() -> tuple[Path, Path] | None:
    """``(memory, pids)`` v1 hierarchies' folders of this process where sub-cgroups can be made."""
    out = []
    for controller in ("memory", "pids"):
        own = _own_path(1, controller)
        root = _ROOT / controller
        if own is None or not (root / "cgroup.procs").is_file():
            return None
        base = root / own.lstrip("/")
        if not base.is_dir() or not os.access(base, os.W_OK):
            return None
        out.append(base)
    return out[0], out[1]


def _v2_cpu(base: Path) -> bool:
    """True when sub-cgroups of ``base`` get the ``cpu`` controller (enabled here if it can be)."""
    try:
        if "cpu" in (base / "cgroup.subtree_control").read_text().split():
            return True
        (base / "cgroup.subtree_control").write_text("+cpu")
        return True
    except OSError:
        return False


def _v1_cpu_parent() -> Path | None:
    """The v1 ``cpu`` hierarchy's folder of this process where sub-cgroups can be made, else None."""
    own = _own_path(1, "cpu")
    root = _ROOT / "cpu"
    if own is None or not (root / "cgroup.procs").is_file():
        return None
    base = root / own.lstrip("/")
    return base if base.is_dir() and os.access(base, os.W_OK) else None


def cgroup_status() -> tuple[str, str]:
    """``(kind, why)``: kind ``"v2"``, ``"v1"`` or ``""`` (none: rlimits only), and why not."""
    if config.switched_off(config.ENV_CGROUP):
        return "", f"{config.ENV_CGROUP}=0"
    if _v2_parent() is not None:
        return "v2", ""
    if _v1_parents() is not None:
        return "v1", ""
    return "", "no writable cgroup with the memory and pids controllers (not delegated to this user)"


class SandboxCgroup:
    """One sandbox's cgroup: made by :meth:`create`, entered by the child before it execs
    (:meth:`enter`, async-signal-safe enough for ``preexec_fn``: one ``write``), then
    :meth:`kill` and :meth:`remove`.

    ``memory_bytes`` bounds everything the sandbox's processes hold in RAM together, tmpfs and memfd
    pages included; ``processes`` the tasks (processes and threads); the CPU is shared with the
    weight :data:`CPU_WEIGHT` (where the ``cpu`` controller is available: :attr:`cpu`).
    """

    def __init__(self, kind: str, dirs: list[Path]) -> None:
        self.kind = kind
        self.dirs = dirs
        self._procs = [str(d / "cgroup.procs") for d in dirs]

    @classmethod
    def create(cls, memory_bytes: int, processes: int) -> SandboxCgroup | None:
        """A new cgroup with these limits, or None when cgroups are not available here."""
        kind, _ = cgroup_status()
        name = f"{config.NAME}-{os.getpid()}-{next(_counter)}"
        group: SandboxCgroup | None = None
        try:
            if kind == "v2":
                parent = _v2_parent()
                assert parent is not None
                d = parent / name
                d.mkdir()
                group = cls("v2", [d])
                (d / "memory.max").write_text(str(int(memory_bytes)))
                for f, v in (("memory.swap.max", "0"), ("memory.oom.group", "1")):
                    try:
                        (d / f).write_text(v)
                    except OSError:
                        pass
                (d / "pids.max").write_text(str(int(processes)))
                if _v2_cpu(parent):
                    try:
                        (d / "cpu.weight").write_text(str(CPU_WEIGHT))
                    except OSError:
                        pass
                return group
            if kind == "v1":
                parents = _v1_parents()
                assert parents is not None
                mem, pids = parents[0] / name, parents[1] / name
                mem.mkdir()
                group = cls("v1", [mem])
                pids.mkdir()
                group.dirs.append(pids)
                group._procs.append(str(pids / "cgroup.procs"))
                (mem / "memory.limit_in_bytes").write_text(str(int(memory_bytes)))
                if (mem / "memory.memsw.limit_in_bytes").exists():
                    try:
                        (mem / "memory.memsw.limit_in_bytes").write_text(str(int(memory_bytes)))
                    except OSError:
                        pass
                (pids / "pids.max").write_text(str(int(processes)))
                cpu_parent = _v1_cpu_parent()
                if cpu_parent is not None:
                    cpu = cpu_parent / name
                    try:
                        cpu.mkdir()
                    except OSError:
                        return group
                    group.dirs.append(cpu)
                    group._procs.append(str(cpu / "cgroup.procs"))
                    try:
                        (cpu / "cpu.shares").write_text(str(CPU_WEIGHT * 1024 // 100))
                    except OSError:
                        pass
                return group
        except OSError:
            if group is not None:
                group.remove()
            return None
        return None

    @property
    def cpu(self) -> bool:
        """True when the group has a CPU share of its own."""
        return any(d.name == self.dirs[0].name and d.parent.name == "cpu" for d in self.dirs[1:]) or (
            self.kind == "v2" and (self.dirs[0] / "cpu.weight").exists())

    def enter(self) -> None:
        """Move the calling process into the cgroup (call it in the child before ``exec``)."""
        for procs in self._procs:
            fd = os.open(procs, os.O_WRONLY)
            try:
                os.write(fd, b"0")
            finally:
                os.close(fd)

    def pids(self) -> list[int]:
        try:
            return [int(p) for p in Path(self._procs[0]).read_text().split()]
        except (OSError, ValueError):
            return []

    def oom_killed(self) -> bool:
        """True when the kernel killed a process of the sandbox for exceeding ``memory_bytes``."""
        events = "memory.events" if self.kind == "v2" else "memory.oom_control"
        try:
            for line in (self.dirs[0] / events).read_text().splitlines():
                key, _, value = line.partition(" ")
                if key == "oom_kill" and int(value) > 0:
                    return True
        except (OSError, ValueError):
            pass
        return False

    def kill(self) -> None:
        """SIGKILL every process in the cgroup (fork bombs included) and wait until it is empty."""
        if self.kind == "v2":
            try:
                (self.dirs[0] / "cgroup.kill").write_text("1")
            except OSError:
                pass
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            pids = self.pids()
            if not pids:
                return
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            time.sleep(0.01)

    def remove(self) -> None:
        """Remove the (empty) cgroup folders; kills what is left first."""
        if self.pids():
            self.kill()
        for d in self.dirs:
            for _ in range(50):
                try:
                    d.rmdir()
                    break
                except FileNotFoundError:
                    break
                except OSError:
                    time.sleep(0.02)
