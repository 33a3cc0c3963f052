"""A seccomp filter for the sandboxed child: system calls no exercise needs are refused with EPERM.

Why
---
Resource limits (``setrlimit``) are per process, and some memory belongs to no process at all:
pages of a ``memfd_create`` file and System V shared memory (``shmget``) count in nobody's
RLIMIT_AS. A cgroup bounds them (:mod:`.cgroups`), but where none can be
made (an ordinary user without delegation, a container) a student could hold gigabytes of the
machine's RAM through them, and the OOM killer might pick a grading worker. Worse, a System V
segment, message queue or semaphore set outlives its creator (outside bubblewrap's IPC namespace,
i.e. in the setpriv mode and the fallback): nothing of the sandbox's clean-up would remove it. So the
child never gets these calls at all. The filter also closes kernel interfaces that only an attacker
needs in a grading child:

============================  ===============================================================
``memfd_create``,             anonymous RAM outside RLIMIT_AS (``os.memfd_create``);
``memfd_secret``              the same, unswappable
System V IPC (``shm*``,       shared memory, message queues and semaphores: RAM outside
``msg*``, ``sem*``)           RLIMIT_AS that outlives the process
``userfaultfd``               pauses the kernel mid-copy: a classic exploit aid
``keyctl``, ``add_key``,      kernel keyrings: kernel memory per uid, kept after the process
``request_key``
``ptrace``,                   reading and writing other processes of the same uid (a zygote,
``process_vm_readv/writev``   the grader in the fallback as an ordinary user)
``perf_event_open``, ``bpf``  large kernel attack surface
``io_uring_setup``            its operations are not seen by seccomp at all
============================  ===============================================================

Each is answered ``EPERM`` (Python raises :class:`PermissionError`, libraries that probe for one of
them fall back as on a kernel without it); numpy, scipy, sympy and the exercises use none of them.

The program
-----------
A classic BPF program over ``struct seccomp_data`` (``nr`` at offset 0, ``arch`` at offset 4), built
by :func:`program` for the machine's architecture from :data:`SYSCALLS` (the numbers differ per
architecture; x86_64 from ``asm/unistd_64.h``, aarch64 from ``asm-generic/unistd.h``). For x86_64
(:func:`listing` prints it)::

     0  ld  [4]                         arch
     1  jeq #0xc000003e, 2, 30          a foreign ABI (i386 through int 0x80): kill the process
     2  ld  [0]                         nr
     3  jge #0x40000000, 30, 4          the x32 ABI's numbers (x86_64 only): kill
     4  jeq #29, 29, 5                  shmget: deny; else go on
    ..  ...                             one jeq per denied call, in increasing order
    23  jeq #319, 29, 24                memfd_create
    ..  ...
    27  jeq #447, 29, 28                memfd_secret
    28  ret #0x7fff0000                 SECCOMP_RET_ALLOW
    29  ret #0x00050001                 SECCOMP_RET_ERRNO | EPERM
    30  ret #0x80000000                 SECCOMP_RET_KILL_PROCESS

(jump targets are absolute here; in the program they are relative to the next instruction).

Checking ``arch`` first matters: the same number means another call in another ABI, so a filter
that only compared numbers could be walked around through the i386 entry point.

Where it is installed
---------------------
Under bubblewrap through ``bwrap --seccomp FD`` (bubblewrap loads it right before it executes the
child, after its own set-up); in the setpriv mode and the fallback by the grader's ``preexec_fn``
right before ``exec`` (:func:`preexec_installer`: ``prctl(PR_SET_NO_NEW_PRIVS)`` then
``prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER)``), so the whole child, its interpreter start-up
included, runs filtered; a filter is inherited over ``fork`` and ``exec`` and cannot be removed.
On another architecture, or a kernel without seccomp filters, :func:`seccomp_status` says why and
the sandbox runs without the filter (the cgroup, where there is one, still bounds memory).
The variable :data:`.config.ENV_SECCOMP` set to ``0`` turns it off.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import os
import platform
import struct

from . import config

__all__ = ["AUDIT_ARCH", "SYSCALLS", "listing", "preexec_installer", "program", "seccomp_status"]

#: ``AUDIT_ARCH_*`` of the supported machines (``linux/audit.h``: ELF machine | 64-bit | little-endian)
AUDIT_ARCH = {"x86_64": 0xC000003E, "aarch64": 0xC00000B7}

#: the denied system calls and their numbers per architecture
SYSCALLS: dict[str, dict[str, int]] = {
    "x86_64": {
        "memfd_create": 319, "memfd_secret": 447,
        "shmget": 29, "shmat": 30, "shmctl": 31, "shmdt": 67,
        "semget": 64, "semop": 65, "semctl": 66, "semtimedop": 220,
        "msgget": 68, "msgsnd": 69, "msgrcv": 70, "msgctl": 71,
        "userfaultfd": 323, "add_key": 248, "request_key": 249, "keyctl": 250,
        "ptrace": 101, "process_vm_readv": 310, "process_vm_writev": 311,
        "perf_event_open": 298, "bpf": 321, "io_uring_setup": 425,
    },
    "aarch64": {
        "memfd_create": 279, "memfd_secret": 447,
        "shmget": 194, "shmctl": 195, "shmat": 196, "shmdt": 197,
        "semget": 190, "semctl": 191, "semtimedop": 192, "semop": 193,
        "msgget": 186, "msgctl": 187, "msgrcv": 188, "msgsnd": 189,
        "userfaultfd": 282, "add_key": 217, "request_key": 218, "keyctl": 219,
        "ptrace": 117, "process_vm_readv": 270, "process_vm_writev": 271,
        "perf_event_open": 241, "bpf": 280, "io_uring_setup": 425,
    },
}

_X32_SYSCALL_BIT = 0x40000000
# classic BPF opcodes (linux/filter.h) and seccomp return values (linux/seccomp.h)
_LD_W_ABS = 0x20  # BPF_LD | BPF_W | BPF_ABS
_JEQ_K = 0x15  # BPF_JMP | BPF_JEQ | BPF_K
_JGE_K = 0x35  # BPF_JMP | BPF_JGE | BPF_K
_RET_K = 0x06  # BPF_RET | BPF_K
RET_ALLOW = 0x7FFF0000
RET_ERRNO = 0x00050000
RET_KILL_PROCESS = 0x80000000
_PR_SET_NO_NEW_PRIVS = 38
_PR_SET_SECCOMP = 22
_SECCOMP_MODE_FILTER = 2


def _instructions(machine: str) -> list[tuple[int, int, int, int]]:
    """``(code, jt, jf, k)`` of the filter for ``machine`` (see the module docstring)."""
    try:
        arch, numbers = AUDIT_ARCH[machine], SYSCALLS[machine]
    except KeyError:
        raise ValueError(f"machine: no seccomp table for {machine!r}; known: {sorted(SYSCALLS)}") from None
    nrs = sorted(set(numbers.values()))
    head: list[tuple[int, int, int, int]] = [
        (_LD_W_ABS, 0, 0, 4), (_JEQ_K, 0, -1, arch), (_LD_W_ABS, 0, 0, 0)]
    if machine == "x86_64":
        head.append((_JGE_K, -1, 0, _X32_SYSCALL_BIT))
    body = [(_JEQ_K, -2, 0, nr) for nr in nrs]
    prog = head + body + [(_RET_K, 0, 0, RET_ALLOW), (_RET_K, 0, 0, RET_ERRNO | errno.EPERM),
                          (_RET_K, 0, 0, RET_KILL_PROCESS)]
    deny, kill = len(prog) - 2, len(prog) - 1

    def target(i: int, j: int) -> int:  # -1: kill, -2: deny; jumps are relative to the next instruction
        return (kill if j == -1 else deny) - i - 1 if j < 0 else j

    return [(c, target(i, jt), target(i, jf), k) for i, (c, jt, jf, k) in enumerate(prog)]


def program(machine: str | None = None) -> bytes:
    """The filter as ``struct sock_filter[]`` bytes (8 per instruction, native byte order): what
    ``bwrap --seccomp FD`` reads and ``PR_SET_SECCOMP`` takes.

    Parameters
    ----------
    machine : str, optional
        ``"x86_64"`` or ``"aarch64"``; default: this machine (:func:`platform.machine`).

    Raises
    ------
    ValueError
        No table for ``machine``.

    Examples
    --------
    >>> prog = program("x86_64")
    >>> len(prog) % 8, len(prog) // 8 == 4 + len(set(SYSCALLS["x86_64"].values())) + 3
    (0, True)
    """
    machine = machine or platform.machine()
    return b"".join(struct.pack("=HBBI", *ins) for ins in _instructions(machine))


def listing(machine: str | None = None) -> str:
    """The filter as readable assembly, one instruction a line (``jeq #k, if equal, else`` with
    absolute instruction numbers).

    Examples
    --------
    >>> print(listing("aarch64").splitlines()[1])
       1  jeq #0xc00000b7, 2, 29
    """
    machine = machine or platform.machine()
    names = {v: k for k, v in SYSCALLS[machine].items()}
    lines = []
    for i, (code, jt, jf, k) in enumerate(_instructions(machine)):
        if code == _LD_W_ABS:
            text = f"ld  [{k}]"
        elif code == _RET_K:
            text = f"ret #{k:#010x}"
        else:
            op = "jeq" if code == _JEQ_K else "jge"
            arg = f"#{k:#x}" if k > 0xFFFF else f"#{k}"
            text = f"{op} {arg}, {i + 1 + jt}, {i + 1 + jf}"
            if code == _JEQ_K and k in names and i > 1:
                text += f"    {names[k]}"
        lines.append(f"{i:4d}  {text}")
    return "\n".join(lines)


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def preexec_installer(machine: str | None = None):
    """A function that installs the filter in the calling process (for ``preexec_fn``).

    Everything it needs (libc's ``prctl``, the program in a C buffer) is prepared here, in the
    parent, so that after ``fork`` it only makes two ``prctl`` calls. It raises :class:`OSError`
    when the kernel refuses (then ``subprocess`` fails to start the child: no unfiltered child).
    """
    data = program(machine)
    buf = ctypes.create_string_buffer(data, len(data))
    fprog = _SockFprog(len(data) // 8, ctypes.cast(buf, ctypes.c_void_p))
    libc = ctypes.CDLL(None, use_errno=True)
    prctl = libc.prctl
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong]
    prctl.restype = ctypes.c_int
    ref = ctypes.addressof(fprog)
    keep = (buf, fprog)

    def install() -> None:
        assert keep
        if prctl(_PR_SET_NO_NEW_PRIVS, 1, None, 0, 0) != 0:
            e = ctypes.get_errno()
            raise OSError(e, f"prctl(PR_SET_NO_NEW_PRIVS): {os.strerror(e)}")
        if prctl(_PR_SET_SECCOMP, _SECCOMP_MODE_FILTER, ref, 0, 0) != 0:
            e = ctypes.get_errno()
            raise OSError(e, f"prctl(PR_SET_SECCOMP): {os.strerror(e)}")

    return install


@functools.lru_cache(maxsize=1)
def _probe() -> tuple[bool, str]:
    machine = platform.machine()
    if machine not in SYSCALLS:
        return False, f"no seccomp table for this machine ({machine})"
    try:
        install = preexec_installer(machine)
    except (OSError, AttributeError) as exc:
        return False, f"prctl is not available ({exc})"
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        code = b"?"
        try:
            os.close(r)
            install()
            try:
                os.close(os.memfd_create("probe"))
                code = b"a"  # the filter did not refuse
            except PermissionError:
                code = b"k"
        except OSError:
            code = b"e"
        finally:
            os.write(w, code)
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        code = fh.read(1)
    os.waitpid(pid, 0)
    if code == b"k":
        return True, ""
    if code == b"e":
        return False, "the kernel refused to install a seccomp filter"
    return False, "a seccomp filter did not refuse memfd_create"


def seccomp_status() -> tuple[bool, str]:
    """``(usable, why not)``: whether the sandbox installs the filter (probed once per process, in
    a forked child that installs it and checks that ``memfd_create`` is refused).

    The variable :data:`.config.ENV_SECCOMP` set to ``0`` turns the filter off.
    """
    if config.switched_off(config.ENV_SECCOMP):
        return False, f"{config.ENV_SECCOMP}=0"
    return _probe()
