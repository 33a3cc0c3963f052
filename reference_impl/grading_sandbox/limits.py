"""Resource limits of one sandboxed child (:class:`Limits`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["GiB", "Limits", "MiB"]

GiB = 1 << 30
MiB = 1 << 20


@dataclass(frozen=True)
class Limits:
    """Resource limits of one sandboxed child.

    Attributes
    ----------
    cpu_seconds : float
        CPU time per batch of calls (RLIMIT_CPU soft limit, re-armed by the child before each
        batch; a lifetime ceiling of ``10 * cpu_seconds + 60`` s is the hard limit).
    wall_seconds : float
        Default wall-clock timeout of one batch (``Sandbox.run(timeout=...)`` overrides it).
    memory_bytes : int
        Address space per process (RLIMIT_AS); numpy with single-threaded OpenBLAS needs about
        0.5 GiB. Where the sandbox gets a cgroup (:mod:`.cgroups`), everything its
        processes hold together (forked children, memfd and shared memory, its tmpfs) is bounded
        by ``memory_bytes + 2 * disk_bytes``; otherwise only per process, and the seccomp filter
        (:mod:`.seccomp`) refuses memfd and System V shared memory, which no
        process's address space counts.
    processes : int
        Processes and threads (RLIMIT_NPROC) the sandbox may hold.
    open_files : int
        RLIMIT_NOFILE.
    output_bytes : int
        Reply bytes the grader reads per batch; more kills the child.
    file_size : int
        Largest file the child may write (RLIMIT_FSIZE).
    disk_bytes : int
        Bytes the child may keep in its writable places (HOME, which is its cwd, and ``/tmp``).
        Under bubblewrap each is a tmpfs of this size inside the sandbox (the kernel refuses writes
        beyond it, unlinked files included; nothing reaches the host's disks) and the grader kills
        the child when both together hold more. In the fallback they are folders of the host that
        the grader measures (walking with directory descriptors; deleted files the child keeps
        open included; a folder it cannot read or one nested deeper than
        :data:`.isolation.MAX_TREE_DEPTH` is a violation) while it waits for
        replies (every ``0.2`` s) and after each batch; the overshoot is bounded by what the child
        writes in 0.2 s.
    disk_files : int
        Files and directories the child may create there.
    """

    cpu_seconds: float = 20
    wall_seconds: float = 10
    memory_bytes: int = 2 * GiB
    processes: int = 64
    open_files: int = 64
    output_bytes: int = 1 * MiB
    file_size: int = 16 * MiB
    disk_bytes: int = 256 * MiB
    disk_files: int = 10_000

    def __post_init__(self) -> None:
        for name in ("cpu_seconds", "wall_seconds", "memory_bytes", "processes", "open_files",
                     "output_bytes", "file_size", "disk_bytes", "disk_files"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"Limits.{name} must be a positive number, got {v!r}")
        if self.processes < 4:
            raise ValueError("Limits.processes must be >= 4 (the sandbox itself needs a few)")
        if self.open_files < 16:
            raise ValueError("Limits.open_files must be >= 16 (Python needs a few)")
