"""The seccomp filters of the sandboxed child: system calls no exercise needs are refused by the kernel.

Why
---
Resource limits (``setrlimit``) are per process, and some memory belongs to no process at all:
pages of a ``memfd_create`` file and System V shared memory (``shmget``) count in nobody's
RLIMIT_AS. A cgroup bounds them (:mod:`.cgroups`), but where none can be
made (an ordinary user without delegation, a container) a student could hold gigabytes of the
machine's RAM through them, and the OOM killer might pick a grading worker. Worse, a System V
segment, a POSIX or System V message queue or a semaphore set outlives its creator (outside
bubblewrap's IPC namespace, i.e. in the setpriv mode and the fallback): nothing of the sandbox's
clean-up would remove it, and a later sandbox of another uid could read what it holds (a hidden
input of one exercise printed in the public output of the next). A nested user namespace hands
the student ``CAP_SYS_ADMIN`` over a mount namespace of its own, where a tmpfs of any size holds
memory outside every limit. So the child never gets these calls at all. The filter also closes
kernel interfaces that only an attacker needs in a grading child:

==============================  ===============================================================
``memfd_create``,               anonymous RAM outside RLIMIT_AS (``os.memfd_create``);
``memfd_secret``                the same, unswappable
System V IPC (``shm*``,         shared memory, message queues and semaphores: RAM outside
``msg*``, ``sem*``), POSIX      RLIMIT_AS that outlives the process (and the sandbox's uid)
queues (``mq_*``)
``unshare``, ``clone`` with     new namespaces (a user namespace: capabilities, mounts of any
a namespace flag, ``setns``     size); ``clone3`` answers ``ENOSYS`` (its flags are behind a
                                pointer seccomp cannot read), so the C library falls back to
                                ``clone``, whose flags it can
``mount`` and the new mount     what only a namespace's ``CAP_SYS_ADMIN`` could use
API (``open_tree``, ``fs*``,
``move_mount``, ...)
``setpriority``,                another process's nice value, scheduling policy, CPU affinity,
``sched_set*`` (scheduler,      I/O priority or resource limits (the zygote's, which the next
param, attr, affinity),         child would inherit: a student could slow down or starve the
``ioprio_set``, ``prlimit64``   students graded after them); the calling process's own stay allowed
``userfaultfd``                 pauses the kernel mid-copy: a classic exploit aid
``keyctl``, ``add_key``,        kernel keyrings: kernel memory per uid, kept after the process
``request_key``
``ptrace``,                     reading and writing other processes of the same uid (a zygote,
``process_vm_readv/writev``     the grader in the fallback as an ordinary user)
``perf_event_open``, ``bpf``    large kernel attack surface
``io_uring_setup``              its operations are not seen by seccomp at all
``socket`` (setpriv mode and    any family but ``AF_UNIX``: without a network namespace this
the fallback)                   is what keeps the child off the network (an audit hook is
                                Python code the student can switch off)
==============================  ===============================================================

Each is answered ``EPERM`` (Python raises :class:`PermissionError`, libraries that probe for one of
them fall back as on a kernel without it); numpy, scipy, sympy, the compilers, the JVM and the
exercises use none of them.

A second filter, :func:`no_spawn_program`, is added by the child itself for an exercise whose own
code starts no program (every notebook; not the answers in other languages, whose driver runs a
compiler, a JVM or Octave): ``fork``, ``vfork``, ``clone`` without ``CLONE_THREAD`` (a new process,
not a thread), ``execve`` and ``execveat`` are refused from then on, before any student code runs.
Filters stack and none can be removed, so the process cannot get them back.

The program
-----------
A classic BPF program over ``struct seccomp_data`` (``nr`` at offset 0, ``arch`` at offset 4, the
arguments as 64-bit words from offset 16; every condition here reads the low 32 bits of an argument,
which is all the kernel reads of an ``int`` or ``pid_t`` and where every flag tested lives), built by
:func:`program` for the machine's architecture from :data:`SYSCALLS` (the numbers differ per
architecture; x86_64 from ``asm/unistd_64.h``, aarch64 from ``asm-generic/unistd.h``). For x86_64
(:func:`listing` prints it)::

     0  ld  [4]                         arch
     1  jeq #0xc000003e, 2, KILL        a foreign ABI (i386 through int 0x80): kill the process
     2  ld  [0]                         nr
     3  jge #0x40000000, KILL, 4        the x32 ABI's numbers (x86_64 only): kill
     4  jeq #29, DENY, 5                shmget: deny; else go on
    ..  ...                             one jeq per denied call
    ..  jeq #435, ENOSYS, ..            clone3
    ..  jeq #56, +1, ..                 clone: then
    ..  ld  [16]                          its flags (low word)
    ..  jset #0x7e020000, DENY, ALLOW     a namespace flag: deny, else allow
    ..  ...
        ret #0x7fff0000                 ALLOW
        ret #0x00050001                 DENY: SECCOMP_RET_ERRNO | EPERM
        ret #0x00050026                 ENOSYS
        ret #0x80000000                 KILL: SECCOMP_RET_KILL_PROCESS

Checking ``arch`` first matters: the same number means another call in another ABI, so a filter
that only compared numbers could be walked around through the i386 entry point.

Where it is installed
---------------------
Under bubblewrap through ``bwrap --seccomp FD`` (bubblewrap loads it right before it executes the
child, after its own set-up); in the setpriv mode and the fallback by the grader's ``preexec_fn``
right before ``exec`` (:func:`preexec_installer`: ``prctl(PR_SET_NO_NEW_PRIVS)`` then
``prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER)``), so the whole child, its interpreter start-up
included, runs filtered; a filter is inherited over ``fork`` and ``exec`` and cannot be removed.
The no-spawn filter is sent to the child in its init message and installed the same way by the
child (:func:`install`'s two ``prctl`` calls) before it executes the first cell.
On another architecture, or a kernel without seccomp filters, :func:`seccomp_status` says why and
the sandbox runs without the filters (the cgroup, where there is one, still bounds memory).
The variable :data:`.config.ENV_SECCOMP` set to ``0`` turns them off.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import os
import platform
import struct

from . import config

__all__ = [
    "AUDIT_ARCH",
    "CLONE_NAMESPACES",
    "DENIED",
    "SYSCALLS",
    "install",
    "listing",
    "no_spawn_program",
    "preexec_installer",
    "program",
    "seccomp_status",
]

#: ``AUDIT_ARCH_*`` of the supported machines (``linux/audit.h``: ELF machine | 64-bit | little-endian)
AUDIT_ARCH = {"x86_64": 0xC000003E, "aarch64": 0xC00000B7}

#: the numbers of every system call the filters name, per architecture
SYSCALLS: dict[str, dict[str, int]] = {
    "x86_64": {
        "memfd_create": 319, "memfd_secret": 447,
        "shmget": 29, "shmat": 30, "shmctl": 31, "shmdt": 67,
        "semget": 64, "semop": 65, "semctl": 66, "semtimedop": 220,
        "msgget": 68, "msgsnd": 69, "msgrcv": 70, "msgctl": 71,
        "mq_open": 240, "mq_unlink": 241, "mq_timedsend": 242, "mq_timedreceive": 243,
        "mq_notify": 244, "mq_getsetattr": 245,
        "userfaultfd": 323, "add_key": 248, "request_key": 249, "keyctl": 250,
        "ptrace": 101, "process_vm_readv": 310, "process_vm_writev": 311,
        "perf_event_open": 298, "bpf": 321, "io_uring_setup": 425,
        "setns": 308, "mount": 165, "umount2": 166, "pivot_root": 155, "open_tree": 428,
        "move_mount": 429, "fsopen": 430, "fsconfig": 431, "fsmount": 432, "fspick": 433,
        "mount_setattr": 442,
        "clone3": 435, "clone": 56, "unshare": 272, "fork": 57, "vfork": 58, "execve": 59,
        "execveat": 322,
        "setpriority": 141, "sched_setparam": 142, "sched_setscheduler": 144, "sched_setaffinity": 203,
        "sched_setattr": 314, "ioprio_set": 251, "prlimit64": 302, "socket": 41,
    },
    "aarch64": {
        "memfd_create": 279, "memfd_secret": 447,
        "shmget": 194, "shmctl": 195, "shmat": 196, "shmdt": 197,
        "semget": 190, "semctl": 191, "semtimedop": 192, "semop": 193,
        "msgget": 186, "msgctl": 187, "msgrcv": 188, "msgsnd": 189,
        "mq_open": 180, "mq_unlink": 181, "mq_timedsend": 182, "mq_timedreceive": 183,
        "mq_notify": 184, "mq_getsetattr": 185,
        "userfaultfd": 282, "add_key": 217, "request_key": 218, "keyctl": 219,
        "ptrace": 117, "process_vm_readv": 270, "process_vm_writev": 271,
        "perf_event_open": 241, "bpf": 280, "io_uring_setup": 425,
        "setns": 268, "mount": 40, "umount2": 39, "pivot_root": 41, "open_tree": 428,
        "move_mount": 429, "fsopen": 430, "fsconfig": 431, "fsmount": 432, "fspick": 433,
        "mount_setattr": 442,
        "clone3": 435, "clone": 220, "unshare": 97, "execve": 221, "execveat": 281,
        "setpriority": 140, "sched_setparam": 118, "sched_setscheduler": 119, "sched_setaffinity": 122,
        "sched_setattr": 274, "ioprio_set": 30, "prlimit64": 261, "socket": 198,
    },
}

#: the calls the base filter refuses whatever their arguments
DENIED = (
    "memfd_create", "memfd_secret", "shmget", "shmat", "shmctl", "shmdt", "semget", "semop", "semctl",
    "semtimedop", "msgget", "msgsnd", "msgrcv", "msgctl", "mq_open", "mq_unlink", "mq_timedsend",
    "mq_timedreceive", "mq_notify", "mq_getsetattr", "userfaultfd", "add_key", "request_key", "keyctl",
    "ptrace", "process_vm_readv", "process_vm_writev", "perf_event_open", "bpf", "io_uring_setup",
    "setns", "mount", "umount2", "pivot_root", "open_tree", "move_mount", "fsopen", "fsconfig",
    "fsmount", "fspick", "mount_setattr",
)

#: CLONE_NEWNS | CLONE_NEWCGROUP | CLONE_NEWUTS | CLONE_NEWIPC | CLONE_NEWUSER | CLONE_NEWPID |
#: CLONE_NEWNET (``linux/sched.h``); ``unshare`` also takes CLONE_NEWTIME (0x80, which in
#: ``clone``'s flags is part of the exit signal)
CLONE_NAMESPACES = 0x00020000 | 0x02000000 | 0x04000000 | 0x08000000 | 0x10000000 | 0x20000000 | 0x40000000
_CLONE_NEWTIME = 0x00000080
_CLONE_THREAD = 0x00010000
_AF_UNIX = 1
_IOPRIO_WHO_PROCESS = 1

_X32_SYSCALL_BIT = 0x40000000
# classic BPF opcodes (linux/filter.h) and seccomp return values (linux/seccomp.h)
_LD_W_ABS = 0x20  # BPF_LD | BPF_W | BPF_ABS
_JEQ_K = 0x15  # BPF_JMP | BPF_JEQ | BPF_K
_JGE_K = 0x35  # BPF_JMP | BPF_JGE | BPF_K
_JSET_K = 0x45  # BPF_JMP | BPF_JSET | BPF_K
_RET_K = 0x06  # BPF_RET | BPF_K
RET_ALLOW = 0x7FFF0000
RET_ERRNO = 0x00050000
RET_KILL_PROCESS = 0x80000000
_PR_SET_NO_NEW_PRIVS = 38
_PR_SET_SECCOMP = 22
_SECCOMP_MODE_FILTER = 2

# symbolic jump targets of the builder (the program's last four instructions)
_ALLOW, _DENY, _ENOSYS, _KILL = "ALLOW", "DENY", "ENOSYS", "KILL"
_NEXT = 0


def _arg(i: int) -> int:
    """Offset of the low 32 bits of argument ``i`` in ``struct seccomp_data`` (little-endian)."""
    return 16 + 8 * i


def _only_self(nr: int, *args: int) -> list[tuple]:
    """``nr`` is allowed when each argument ``args[k]`` (an argument's index) is 0 (the calling
    process), else denied."""
    block: list[tuple] = [(_JEQ_K, _NEXT, ("skip", 2 * len(args)), nr)]
    for k, i in enumerate(args):
        last = k == len(args) - 1
        block += [(_LD_W_ABS, 0, 0, _arg(i)), (_JEQ_K, _ALLOW if last else _NEXT, _DENY, 0)]
    return block


def _body(numbers: dict[str, int], *, network: bool, spawn: bool, base: bool) -> list[tuple]:
    """The rules after the architecture check: ``(code, jt, jf, k)`` with symbolic targets."""
    out: list[tuple] = []
    if base:
        for nr in sorted({numbers[n] for n in DENIED}):
            out.append((_JEQ_K, _DENY, _NEXT, nr))
    out.append((_JEQ_K, _ENOSYS, _NEXT, numbers["clone3"]))
    # clone: a namespace flag is denied; without spawn, so is a new process (no CLONE_THREAD)
    clone_ok = _ALLOW if spawn else _NEXT
    clone = [(_LD_W_ABS, 0, 0, _arg(0))]
    if base:
        clone.append((_JSET_K, _DENY, clone_ok, CLONE_NAMESPACES))
    if not spawn:
        clone.append((_JSET_K, _ALLOW, _DENY, _CLONE_THREAD))
    out.append((_JEQ_K, _NEXT, ("skip", len(clone)), numbers["clone"]))
    out += clone
    if not spawn:
        for name in ("fork", "vfork", "execve", "execveat"):
            if name in numbers:
                out.append((_JEQ_K, _DENY, _NEXT, numbers[name]))
    if base:
        out += [(_JEQ_K, _NEXT, ("skip", 2), numbers["unshare"]), (_LD_W_ABS, 0, 0, _arg(0)),
                (_JSET_K, _DENY, _ALLOW, CLONE_NAMESPACES | _CLONE_NEWTIME)]
        for name in ("sched_setscheduler", "sched_setparam", "sched_setattr", "sched_setaffinity",
                     "prlimit64"):
            out += _only_self(numbers[name], 0)
        # setpriority(PRIO_PROCESS = 0, who = 0, prio): this process only (not its group, its uid)
        out += _only_self(numbers["setpriority"], 0, 1)
        out += [(_JEQ_K, _NEXT, ("skip", 4), numbers["ioprio_set"]), (_LD_W_ABS, 0, 0, _arg(0)),
                (_JEQ_K, _NEXT, _DENY, _IOPRIO_WHO_PROCESS), (_LD_W_ABS, 0, 0, _arg(1)),
                (_JEQ_K, _ALLOW, _DENY, 0)]
        if not network:
            out += [(_JEQ_K, _NEXT, ("skip", 2), numbers["socket"]), (_LD_W_ABS, 0, 0, _arg(0)),
                    (_JEQ_K, _ALLOW, _DENY, _AF_UNIX)]
    return out


def _instructions(machine: str, *, network: bool = True, spawn: bool = True,
                  base: bool = True) -> list[tuple[int, int, int, int]]:
    """``(code, jt, jf, k)`` of a filter for ``machine`` (see the module docstring): the base filter
    (``base``; ``network=False`` adds the socket rule), or the no-spawn filter (``base=False,
    spawn=False``)."""
    try:
        arch, numbers = AUDIT_ARCH[machine], SYSCALLS[machine]
    except KeyError:
        raise ValueError(f"machine: no seccomp table for {machine!r}; known: {sorted(SYSCALLS)}") from None
    prog: list[tuple] = [(_LD_W_ABS, 0, 0, 4), (_JEQ_K, _NEXT, _KILL, arch), (_LD_W_ABS, 0, 0, 0)]
    if machine == "x86_64":
        prog.append((_JGE_K, _KILL, _NEXT, _X32_SYSCALL_BIT))
    prog += _body(numbers, network=network, spawn=spawn, base=base)
    ends = {_ALLOW: len(prog), _DENY: len(prog) + 1, _ENOSYS: len(prog) + 2, _KILL: len(prog) + 3}
    prog += [(_RET_K, 0, 0, RET_ALLOW), (_RET_K, 0, 0, RET_ERRNO | errno.EPERM),
             (_RET_K, 0, 0, RET_ERRNO | errno.ENOSYS), (_RET_K, 0, 0, RET_KILL_PROCESS)]

    def target(i: int, j) -> int:
        """A jump of instruction ``i`` relative to the next instruction (classic BPF only jumps
        forward, by at most 255)."""
        if isinstance(j, tuple):  # ("skip", n): over the n instructions of a rule's block
            rel = j[1]
        elif isinstance(j, str):
            rel = ends[j] - i - 1
        else:
            rel = j
        if not 0 <= rel <= 255:
            raise ValueError(f"the filter is too long for a classic BPF jump ({rel}) at instruction {i}")
        return rel

    return [(c, target(i, jt), target(i, jf), k) if c not in (_LD_W_ABS, _RET_K) else (c, 0, 0, k)
            for i, (c, jt, jf, k) in enumerate(prog)]


def _pack(ins: list[tuple[int, int, int, int]]) -> bytes:
    return b"".join(struct.pack("=HBBI", *i) for i in ins)


def program(machine: str | None = None, *, network: bool = True) -> bytes:
    """The base filter as ``struct sock_filter[]`` bytes (8 per instruction, native byte order): what
    ``bwrap --seccomp FD`` reads and ``PR_SET_SECCOMP`` takes.

    Parameters
    ----------
    machine : str, optional
        ``"x86_64"`` or ``"aarch64"``; default: this machine (:func:`platform.machine`).
    network : bool
        False adds the socket rule (only ``AF_UNIX``): the setpriv mode and the fallback, which have no
        network namespace of their own.

    Raises
    ------
    ValueError
        No table for ``machine``.

    Examples
    --------
    >>> prog = program("x86_64")
    >>> len(prog) % 8, len(prog) < len(program("x86_64", network=False))
    (0, True)
    """
    return _pack(_instructions(machine or platform.machine(), network=network))


def no_spawn_program(machine: str | None = None) -> bytes:
    """The filter an exercise's child adds when its exercise starts no programs: no new process
    (``fork``, ``vfork``, ``clone`` without ``CLONE_THREAD``) and no ``execve``/``execveat``; threads
    stay allowed.

    Examples
    --------
    >>> len(no_spawn_program("aarch64")) % 8
    0
    """
    return _pack(_instructions(machine or platform.machine(), spawn=False, base=False))


def listing(machine: str | None = None, *, network: bool = True, spawn: bool = True,
            base: bool = True) -> str:
    """A filter as readable assembly, one instruction a line (``jeq #k, if equal, else`` with
    absolute instruction numbers).

    Examples
    --------
    >>> print(listing("aarch64").splitlines()[1].split(",")[0])
       1  jeq #0xc00000b7
    """
    machine = machine or platform.machine()
    names = {v: k for k, v in SYSCALLS[machine].items()}
    ins = _instructions(machine, network=network, spawn=spawn, base=base)
    lines = []
    for i, (code, jt, jf, k) in enumerate(ins):
        if code == _LD_W_ABS:
            text = f"ld  [{k}]"
        elif code == _RET_K:
            text = f"ret #{k:#010x}"
        else:
            op = {_JEQ_K: "jeq", _JGE_K: "jge", _JSET_K: "jset"}[code]
            arg = f"#{k:#x}" if k > 0xFFFF else f"#{k}"
            text = f"{op} {arg}, {i + 1 + jt}, {i + 1 + jf}"
            after_arg = ins[i - 1][0] == _LD_W_ABS and ins[i - 1][3] >= 16  # compares an argument
            if code == _JEQ_K and k in names and i > 1 and not after_arg:
                text += f"    {names[k]}"
        lines.append(f"{i:4d}  {text}")
    return "\n".join(lines)


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def install(data: bytes):
    """A function that installs the filter ``data`` (:func:`program` bytes) in the calling process.

    Everything it needs (libc's ``prctl``, the program in a C buffer) is prepared here, so that the
    returned function only makes two ``prctl`` calls (what a ``preexec_fn`` may do after ``fork``).
    It raises :class:`OSError` when the kernel refuses.
    """
    buf = ctypes.create_string_buffer(bytes(data), len(data))
    fprog = _SockFprog(len(data) // 8, ctypes.cast(buf, ctypes.c_void_p))
    libc = ctypes.CDLL(None, use_errno=True)
    prctl = libc.prctl
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong]
    prctl.restype = ctypes.c_int
    ref = ctypes.addressof(fprog)
    keep = (buf, fprog)

    def installer() -> None:
        assert keep
        if prctl(_PR_SET_NO_NEW_PRIVS, 1, None, 0, 0) != 0:
            e = ctypes.get_errno()
            raise OSError(e, f"prctl(PR_SET_NO_NEW_PRIVS): {os.strerror(e)}")
        if prctl(_PR_SET_SECCOMP, _SECCOMP_MODE_FILTER, ref, 0, 0) != 0:
            e = ctypes.get_errno()
            raise OSError(e, f"prctl(PR_SET_SECCOMP): {os.strerror(e)}")

    return installer


def preexec_installer(machine: str | None = None, *, network: bool = True):
    """A function that installs the base filter in the calling process (for ``preexec_fn``;
    ``subprocess`` then fails to start the child when the kernel refuses: no unfiltered child)."""
    return install(program(machine, network=network))


@functools.lru_cache(maxsize=1)
def _probe() -> tuple[bool, str]:
    machine = platform.machine()
    if machine not in SYSCALLS:
        return False, f"no seccomp table for this machine ({machine})"
    try:
        installer = preexec_installer(machine)
    except (OSError, AttributeError) as exc:
        return False, f"prctl is not available ({exc})"
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        code = b"?"
        try:
            os.close(r)
            installer()
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
    """``(usable, why not)``: whether the sandbox installs the filters (probed once per process, in
    a forked child that installs the base filter and checks that ``memfd_create`` is refused).

    The variable :data:`.config.ENV_SECCOMP` set to ``0`` turns the filters off.
    """
    if config.switched_off(config.ENV_SECCOMP):
        return False, f"{config.ENV_SECCOMP}=0"
    return _probe()
