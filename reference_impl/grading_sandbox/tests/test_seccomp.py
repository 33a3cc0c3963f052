"""The sandbox's seccomp filter (:mod:`grading_sandbox.seccomp`).

Oracles: the system call numbers against libseccomp's own tables (``seccomp_syscall_resolve_name_arch``,
through ctypes) and the kernel headers; the program's meaning against a small classic-BPF interpreter
written here from ``linux/filter.h``; the kernel itself, in a child started with the filter
(``os.memfd_create`` and ``shmget`` refused, everything else working); and the course's solutions
graded with the filter on, which must keep full marks.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import json
import platform
import re
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from grading_sandbox import seccomp
from grading_sandbox.seccomp import (
    AUDIT_ARCH,
    CLONE_NAMESPACES,
    DENIED,
    SYSCALLS,
    install,
    no_spawn_program,
    preexec_installer,
    program,
    seccomp_status,
)

pytestmark = pytest.mark.xdist_group("sandbox")

needs_filter = pytest.mark.skipif(not seccomp_status()[0], reason=f"no seccomp filter: {seccomp_status()[1]}")


# -- the tables ------------------------------------------------------------------------------------


def _libseccomp():
    name = ctypes.util.find_library("seccomp")
    if name is None:
        pytest.skip("libseccomp is not installed (the independent table of syscall numbers)")
    lib = ctypes.CDLL(name)
    lib.seccomp_arch_resolve_name.argtypes = [ctypes.c_char_p]
    lib.seccomp_arch_resolve_name.restype = ctypes.c_uint32
    lib.seccomp_syscall_resolve_name_arch.argtypes = [ctypes.c_uint32, ctypes.c_char_p]
    lib.seccomp_syscall_resolve_name_arch.restype = ctypes.c_int
    return lib


@pytest.mark.parametrize("machine", sorted(SYSCALLS))
def test_syscall_numbers_and_arch_tokens_agree_with_libseccomp(machine):
    lib = _libseccomp()
    token = lib.seccomp_arch_resolve_name(machine.encode())
    assert token == AUDIT_ARCH[machine]  # libseccomp's arch tokens are the AUDIT_ARCH_* values
    for name, nr in SYSCALLS[machine].items():
        theirs = lib.seccomp_syscall_resolve_name_arch(token, name.encode())
        if theirs < 0:  # an older libseccomp that does not know a newer call
            continue
        assert theirs == nr, (machine, name, theirs, nr)


def test_syscall_numbers_agree_with_the_kernel_headers():
    headers = {"x86_64": Path("/usr/include/x86_64-linux-gnu/asm/unistd_64.h"),
               "aarch64": Path("/usr/include/asm-generic/unistd.h")}
    checked = 0
    for machine, header in headers.items():
        if not header.exists():
            continue
        defined = dict(re.findall(r"#define __NR_(\w+)\s+(\d+)\b", header.read_text()))
        for name, nr in SYSCALLS[machine].items():
            if name in defined:
                assert int(defined[name]) == nr, (machine, name)
                checked += 1
    if not checked:
        pytest.skip("no kernel headers installed")


# -- the program, read by an interpreter of classic BPF ------------------------------------------------


def _run_bpf(prog: bytes, nr: int, arch: int, args=(0, 0, 0, 0, 0, 0)) -> int:
    """Run a seccomp classic-BPF program on ``struct seccomp_data`` {nr, arch, ip=0, args}."""
    data = struct.pack("=iIQ6Q", nr, arch, 0, *args)
    ins = [struct.unpack("=HBBI", prog[i:i + 8]) for i in range(0, len(prog), 8)]
    acc, pc = 0, 0
    for _ in range(len(ins) + 1):
        code, jt, jf, k = ins[pc]
        if code == 0x20:  # ld [k]
            acc = struct.unpack_from("=I", data, k)[0]
            pc += 1
        elif code in (0x15, 0x35, 0x45):  # jeq / jge / jset #k
            hit = acc == k if code == 0x15 else (acc >= k if code == 0x35 else bool(acc & k))
            pc += 1 + (jt if hit else jf)
        elif code == 0x06:
            return k
        else:
            raise AssertionError(f"unexpected opcode {code:#x}")
    raise AssertionError("the program did not return")


EPERM_RET = 0x00050000 | errno.EPERM
ENOSYS_RET = 0x00050000 | errno.ENOSYS
ALLOW_RET = 0x7FFF0000
# (call, arguments, allowed?) of the conditional rules, beside the calls refused whatever their arguments
CLONE_NEWUSER, CLONE_NEWNS, CLONE_NEWTIME, CLONE_THREAD = 0x10000000, 0x00020000, 0x80, 0x00010000
CONDITIONS = [
    ("clone", (0x11,), True),  # fork(): SIGCHLD
    ("clone", (0x3D0F00,), True),  # a thread (CLONE_VM | CLONE_FS | ... | CLONE_THREAD | ...)
    ("clone", (CLONE_NEWUSER | 0x11,), False),
    ("clone", (CLONE_NEWNS,), False),
    ("clone", (0x40000000,), False),  # CLONE_NEWNET
    ("unshare", (0,), True),
    ("unshare", (0x400,), True),  # CLONE_FILES: no namespace
    ("unshare", (CLONE_NEWUSER | CLONE_NEWNS,), False),
    ("unshare", (CLONE_NEWTIME,), False),
    ("setpriority", (0, 0, 19), True),  # this process
    ("setpriority", (0, 4242, 19), False),  # another one (the zygote)
    ("setpriority", (1, 0, 19), False),  # PRIO_PGRP: the process group (the zygote's)
    ("setpriority", (2, 0, 19), False),  # PRIO_USER: every process of the uid
    ("sched_setscheduler", (0, 5, 0), True),
    ("sched_setscheduler", (4242, 5, 0), False),  # SCHED_IDLE for another process
    ("sched_setparam", (4242, 0), False),
    ("sched_setattr", (4242, 0, 0), False),
    ("sched_setaffinity", (4242, 8, 0), False),
    ("sched_setaffinity", (0, 8, 0), True),
    ("prlimit64", (0, 7, 0, 0), True),
    ("prlimit64", (4242, 7, 0, 0), False),  # another process's RLIMIT_NOFILE
    ("ioprio_set", (1, 0, 0), True),
    ("ioprio_set", (1, 4242, 0), False),
    ("ioprio_set", (3, 0, 0), False),  # IOPRIO_WHO_USER
    ("socket", (1, 1, 0), True),  # AF_UNIX
]


@pytest.mark.parametrize("machine", sorted(SYSCALLS))
def test_the_program_denies_exactly_its_table_and_kills_foreign_abis(machine):
    prog = program(machine)
    arch = AUDIT_ARCH[machine]
    numbers = SYSCALLS[machine]
    denied = {numbers[n] for n in DENIED}
    conditional = {numbers[n] for n, _, _ in CONDITIONS} | {numbers["ioprio_set"]}
    for nr in range(0, 600):
        if nr in conditional:
            continue
        want = EPERM_RET if nr in denied else ENOSYS_RET if nr == numbers["clone3"] else ALLOW_RET
        assert _run_bpf(prog, nr, arch) == want, nr
    for name, args, allowed in CONDITIONS:
        full = (*args, *[0] * (6 - len(args)))
        want = ALLOW_RET if allowed else EPERM_RET
        assert _run_bpf(prog, numbers[name], arch, full) == want, (name, args)
        # the kernel reads the low 32 bits of these arguments: high bits change nothing
        high = tuple(a | (0xDEAD << 32) for a in full)
        assert _run_bpf(prog, numbers[name], arch, high) == want, (name, args)
    # the same numbers through another ABI (i386 through int 0x80, 32-bit ARM): the process dies
    for foreign in (0x40000003, 0x40000028, *(a for m, a in AUDIT_ARCH.items() if m != machine)):
        assert _run_bpf(prog, SYSCALLS[machine]["memfd_create"], foreign) == 0x80000000
        assert _run_bpf(prog, 0, foreign) == 0x80000000
    if machine == "x86_64":  # the x32 ABI shares AUDIT_ARCH_X86_64, with bit 30 set in nr
        assert _run_bpf(prog, 0x40000000 | 319, arch) == 0x80000000
        assert _run_bpf(prog, 0x40000000, arch) == 0x80000000


@pytest.mark.parametrize("machine", sorted(SYSCALLS))
def test_without_a_network_namespace_only_unix_sockets(machine):
    numbers, arch = SYSCALLS[machine], AUDIT_ARCH[machine]
    closed = program(machine, network=False)
    for family, allowed in ((1, True), (2, False), (10, False), (16, False), (17, False), (0, False)):
        assert _run_bpf(closed, numbers["socket"], arch, (family, 1, 0, 0, 0, 0)) == (
            ALLOW_RET if allowed else EPERM_RET), family
        assert _run_bpf(program(machine), numbers["socket"], arch, (family, 1, 0, 0, 0, 0)) == ALLOW_RET
    # everything else is the same filter
    for nr in range(0, 600):
        if nr != numbers["socket"]:
            assert _run_bpf(closed, nr, arch) == _run_bpf(program(machine), nr, arch), nr


@pytest.mark.parametrize("machine", sorted(SYSCALLS))
def test_the_no_spawn_filter_refuses_new_processes_and_exec_but_not_threads(machine):
    prog, numbers, arch = no_spawn_program(machine), SYSCALLS[machine], AUDIT_ARCH[machine]
    refused = {numbers[n] for n in ("fork", "vfork", "execve", "execveat") if n in numbers}
    assert len(refused) == (4 if machine == "x86_64" else 2)  # aarch64 has no fork nor vfork
    for nr in range(0, 600):
        if nr == numbers["clone"]:
            continue
        want = EPERM_RET if nr in refused else ENOSYS_RET if nr == numbers["clone3"] else ALLOW_RET
        assert _run_bpf(prog, nr, arch) == want, nr
    assert _run_bpf(prog, numbers["clone"], arch, (0x11, 0, 0, 0, 0, 0)) == EPERM_RET  # fork()
    assert _run_bpf(prog, numbers["clone"], arch, (0x4111, 0, 0, 0, 0, 0)) == EPERM_RET  # vfork()
    assert _run_bpf(prog, numbers["clone"], arch, (0x3D0F00, 0, 0, 0, 0, 0)) == ALLOW_RET  # a thread
    assert _run_bpf(prog, numbers["memfd_create"], AUDIT_ARCH[machine]) == ALLOW_RET  # the base filter's
    assert _run_bpf(prog, 0, 0x40000003) == 0x80000000
    assert CLONE_NAMESPACES & CLONE_THREAD == 0


def test_program_names_the_machine_it_does_not_know():
    with pytest.raises(ValueError, match="machine"):
        program("mips")


# -- the kernel ------------------------------------------------------------------------------------

PROBE = r"""
import ctypes, json, os, socket, sys, threading, time
out = {}
try:
    os.memfd_create("x")
    out["memfd"] = "allowed"
except OSError as e:
    out["memfd"] = e.errno
libc = ctypes.CDLL(None, use_errno=True)
libc.shmget.argtypes = [ctypes.c_int, ctypes.c_size_t, ctypes.c_int]
r = libc.shmget(0, 16 << 20, 0o1600)  # IPC_PRIVATE, 16 MiB, IPC_CREAT | 0600
out["shmget"] = "allowed" if r >= 0 else ctypes.get_errno()
if r >= 0:
    libc.shmctl(r, 0, None)  # IPC_RMID
r = libc.syscall(323, 0) if os.uname().machine == "x86_64" else -1  # userfaultfd
out["userfaultfd"] = ctypes.get_errno() if r < 0 else "allowed"
libc.mq_open.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_uint, ctypes.c_void_p]
q = libc.mq_open(b"/ft-probe-%d" % os.getpid(), os.O_CREAT | os.O_RDWR, 0o600, None)
out["mq_open"] = ctypes.get_errno() if q < 0 else "allowed"
if q >= 0:
    libc.mq_unlink(b"/ft-probe-%d" % os.getpid())
out["unshare"] = ctypes.get_errno() if libc.unshare(0x10000000 | 0x00020000) != 0 else "allowed"
out["clone3"] = ctypes.get_errno() if libc.syscall(435, None, 0) < 0 else "allowed"
# another process's scheduling: a sibling of ours (never the test's own process)
sib = os.fork()
if sib == 0:
    time.sleep(30)
    os._exit(0)
try:
    os.setpriority(os.PRIO_PROCESS, sib, 19)
    out["renice_other"] = "allowed"
except OSError as e:
    out["renice_other"] = e.errno
os.kill(sib, 9)
os.waitpid(sib, 0)
out["nice_self"] = os.nice(1)
try:
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.close()
    out["inet"] = "allowed"
except OSError as e:
    out["inet"] = e.errno
a, b = socket.socketpair()
a.close(); b.close()
if len(sys.argv) > 1:  # the no-spawn filter on top
    sys.path.insert(0, sys.argv[1])
    from grading_sandbox.seccomp import install, no_spawn_program
    install(no_spawn_program())()
    import subprocess
    try:
        subprocess.run(["true"])
        out["spawn"] = "allowed"
    except OSError as e:
        out["spawn"] = e.errno
# what ordinary code does still works: files, pipes, threads, mmap, fork
import mmap, tempfile
with tempfile.TemporaryFile() as f:
    f.write(b"x" * 4096)
    f.flush()
    m = mmap.mmap(f.fileno(), 4096)
    out["mmap"] = m[:1].decode()
t = threading.Thread(target=lambda: out.setdefault("thread", True))
t.start(); t.join()
try:
    pid = os.fork()
    if pid == 0:
        os._exit(7)
    out["fork"] = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
except OSError as e:
    out["fork"] = -e.errno
import numpy as np
out["numpy"] = float(np.linalg.solve(np.eye(3) * 2, np.ones(3)).sum())
print(json.dumps(out))
"""


def _probe(*args, **kwargs):
    r = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=60,
                       **kwargs)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


@needs_filter
def test_a_child_with_the_filter_gets_eperm_for_memfd_shm_mq_and_namespaces_and_works_otherwise():
    out = _probe(preexec_fn=preexec_installer())
    assert out["memfd"] == out["shmget"] == out["mq_open"] == out["unshare"] == errno.EPERM, out
    assert out["renice_other"] == errno.EPERM and out["clone3"] == errno.ENOSYS, out
    if platform.machine() == "x86_64":
        assert out["userfaultfd"] == errno.EPERM, out
    assert out["inet"] == "allowed" and out["nice_self"] >= 1, out  # bubblewrap's filter: no socket rule
    assert out["mmap"] == "x" and out["thread"] is True and out["fork"] == 7 and out["numpy"] == 1.5
    # and without the filter the same probe is allowed memfd, queues and namespaces (the checks above
    # can fail)
    bare = _probe()
    assert bare["memfd"] == bare["mq_open"] == "allowed" and bare["clone3"] != errno.ENOSYS, bare


@needs_filter
def test_without_a_network_namespace_the_filter_refuses_inet_sockets():
    out = _probe(preexec_fn=preexec_installer(network=False))
    assert out["inet"] == errno.EPERM and out["fork"] == 7, out


@needs_filter
def test_the_no_spawn_filter_refuses_fork_and_exec_in_the_kernel():
    import grading_sandbox

    package = Path(grading_sandbox.__file__).resolve().parent
    where = str(package.parent)  # the folder the package is imported from
    out = _probe(where, preexec_fn=preexec_installer())
    assert out["spawn"] == out["unshare"] == errno.EPERM and out["fork"] == -errno.EPERM, out
    assert out["thread"] is True and out["numpy"] == 1.5, out
    assert install  # the function the child's own installation mirrors


def test_the_filter_can_be_turned_off(monkeypatch):
    monkeypatch.setenv("FLOWTRACK_SANDBOX_SECCOMP", "0")
    assert seccomp_status() == (False, "FLOWTRACK_SANDBOX_SECCOMP=0")
    assert "seccomp" in seccomp.__doc__


# -- the course's solutions still score full marks with the filter on ---------------------------------


