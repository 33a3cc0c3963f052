"""Attacks on what outlives one exercise: the next exercise's (another student's) folders and
scheduling, state the kernel keeps after the sandbox, and the in-process guard switched off.

A :class:`SandboxPool` forks each exercise from a zygote that serves exercise after exercise (in
``flowtrack grade`` one student after another), so whatever one child leaves in the zygote or its
writable folders, the next one starts with. Oracles: a fresh sandbox of the same kind (what the next
exercise must see), and the kernel's own answers (errno) for what must be refused.
"""

from __future__ import annotations

import ctypes
import errno
import socket

import pytest

from grading_sandbox import Call, Limits, Sandbox, SandboxPool
from grading_sandbox.seccomp import seccomp_status
from grading_sandbox.testing import SANDBOX_MODES, use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

LIMITS = Limits(cpu_seconds=5, wall_seconds=10, memory_bytes=1 << 30, processes=16, disk_bytes=16 << 20)
needs_filter = pytest.mark.skipif(not seccomp_status()[0], reason=f"no seccomp filter: {seccomp_status()[1]}")


@pytest.fixture(params=SANDBOX_MODES)
def mode(request, monkeypatch, tmp_path_factory):
    return use_sandbox_mode(request.param, monkeypatch, tmp_path_factory)


PROBE = """
import os, resource, tempfile
def probe():
    home, tmp = os.environ["HOME"], tempfile.gettempdir()
    out = {"modes": [oct(os.stat(d).st_mode & 0o7777) for d in (home, tmp)]}
    try:
        out["xattrs"] = sorted(os.listxattr(home))
    except OSError:
        out["xattrs"] = []
    try:
        os.makedirs(os.path.join(home, "build"))  # what a language exercise's driver does first
        with open(os.path.join(tmp, "scratch"), "w") as fh:
            fh.write("x")
        out["write"] = "ok"
    except OSError as exc:
        out["write"] = exc.strerror
    out["nice"] = os.getpriority(os.PRIO_PROCESS, 0)
    out["policy"] = os.sched_getscheduler(0)
    out["affinity"] = sorted(os.sched_getaffinity(0))
    out["nofile"] = list(resource.getrlimit(resource.RLIMIT_NOFILE))
    return out
"""


def _fresh_probe() -> dict:
    """What the first exercise of a new sandbox sees (the oracle)."""
    with SandboxPool() as pool, pool([("p", PROBE)], limits=LIMITS) as box:
        (out,) = box.run([Call("probe")], timeout=20)
    assert out.ok, out
    return out.value


def _after(attack: str, call: str = "attack", spawn: bool = False) -> tuple[object, dict]:
    """The attack's outcome as one exercise of a pool, and what the pool's next exercise sees."""
    with SandboxPool() as pool:
        with pool([("a", attack)], limits=LIMITS, spawn=spawn) as box:
            (hit,) = box.run([Call(call)], timeout=20)
        with pool([("p", PROBE)], limits=LIMITS) as box:
            (out,) = box.run([Call("probe")], timeout=20)
    assert out.ok, out
    return hit, out.value


FOLDERS = """
import os, tempfile
def attack():
    home, tmp = os.environ["HOME"], tempfile.gettempdir()
    for d in (home, tmp):
        os.makedirs(os.path.join(d, "left", "behind"))
    try:
        os.setxattr(home, "user.leak", b"0.55")  # a value the next exercise could read
    except OSError:
        pass
    os.chmod(home, 0o555)
    os.chmod(tmp, 0o555)
    return "done"
"""

# the same as a C++ answer's static initialiser does it: system() in a program the exercise runs
SHELL = """
import os, tempfile
def attack():
    return os.system('rm -rf "$HOME"/* && chmod 555 "$HOME" "$TMPDIR" ' + tempfile.gettempdir())
"""


@pytest.mark.parametrize("attack, spawn", [(FOLDERS, False), (SHELL, True)], ids=["python", "system"])
def test_one_exercise_cannot_break_the_folders_of_the_next(mode, attack, spawn):
    fresh = _fresh_probe()
    hit, seen = _after(attack, spawn=spawn)
    assert hit.ok, hit  # the attack itself ran (its own folders are its own)
    assert seen["write"] == "ok", seen  # the next student's build can write its files
    assert seen["modes"] == fresh["modes"] and seen["xattrs"] == fresh["xattrs"] == [], (seen, fresh)


SCHEDULING = """
import os, resource
def attack():
    zygote = os.getppid()  # the process the next exercise's child is forked from
    done = []
    for what, act in [
        ("nice", lambda: os.setpriority(os.PRIO_PROCESS, zygote, 19)),
        ("group", lambda: os.setpriority(os.PRIO_PGRP, 0, 19)),
        ("idle", lambda: os.sched_setscheduler(zygote, os.SCHED_IDLE, os.sched_param(0))),
        ("affinity", lambda: os.sched_setaffinity(zygote, {0})),
        ("nofile", lambda: resource.prlimit(zygote, resource.RLIMIT_NOFILE, (16, 16))),
    ]:
        try:
            act()
            done.append(what)
        except OSError:
            pass
    os.nice(5)  # its own: allowed, and its own business
    return done
"""


def test_the_next_exercise_inherits_no_scheduling_nor_limits(mode):
    # a previous student's child renices, idles, pins or limits the zygote: the next child must start
    # with a fresh sandbox's values (the kernel refuses it; a zygote whose values changed anyway ends)
    fresh = _fresh_probe()
    hit, seen = _after(SCHEDULING)
    assert hit.ok, hit
    for key in ("nice", "policy", "affinity", "nofile"):
        assert seen[key] == fresh[key], (key, seen, fresh, hit.value)
    if seccomp_status()[0]:
        assert hit.value == [], hit  # refused outright, not only repaired


# the in-process audit hook of the setpriv mode and the fallback is a Python closure: switched off
# first, so that what these attacks meet is the kernel
DISARM = """
import gc, types
def disarm():
    # the in-process audit hook is a Python closure: find it and switch it off
    n = 0
    for obj in gc.get_objects():
        if isinstance(obj, types.FunctionType) and obj.__name__ == "audit" and obj.__closure__:
            for name, cell in zip(obj.__code__.co_freevars, obj.__closure__):
                if name == "strict":
                    cell.cell_contents = False
                    n += 1
                elif name == "denied_path":
                    cell.cell_contents = lambda p: False
                elif name == "allow_spawn":
                    cell.cell_contents = True
    return n
"""

NETWORK = DISARM + """
import os, socket, subprocess
def attack(port):
    out = {"disarmed": disarm()}
    try:
        s = socket.create_connection(("127.0.0.1", port), timeout=2)
        s.sendall(b"the hidden inputs")
        s.close()
        out["connect"] = "connected"
    except OSError as exc:
        out["connect"] = exc.errno
    try:
        pid = os.fork()
        if pid == 0:
            os._exit(0)
        os.waitpid(pid, 0)
        out["fork"] = "forked"
    except OSError as exc:
        out["fork"] = exc.errno
    try:
        subprocess.run(["true"], check=False)
        out["exec"] = "ran"
    except OSError as exc:
        out["exec"] = exc.errno
    return out
"""


@needs_filter
@pytest.mark.parametrize("mode", ["setpriv", "fallback"], indirect=True)
def test_switching_the_audit_hook_off_leaves_no_network_and_no_fork(mode):
    # without a network namespace the audit hook was the only thing between student code and the
    # network: with it switched off, the kernel must still refuse sockets, fork and exec
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(5)
    server.setblocking(False)
    try:
        with Sandbox([("a", NETWORK)], limits=LIMITS) as sb:
            (out,) = sb.run([Call("attack", (server.getsockname()[1],))], timeout=20)
        with pytest.raises(BlockingIOError):
            server.accept()  # nobody connected
    finally:
        server.close()
    assert out.ok and out.value["disarmed"] >= 1, out  # the hook was really switched off
    assert out.value["connect"] == errno.EPERM, out
    assert out.value["fork"] == out.value["exec"] == errno.EPERM, out


MQ = DISARM + """
import ctypes, os
NAME = b"/flowtrack-attack-queue"

def _libc():
    disarm()
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mq_open.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_uint, ctypes.c_void_p]
    libc.mq_send.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint]
    libc.mq_receive.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t, ctypes.c_void_p]
    return libc

def leave(secret):
    libc = _libc()
    q = libc.mq_open(NAME, os.O_CREAT | os.O_WRONLY, 0o666, None)
    if q < 0:
        return ctypes.get_errno()
    libc.mq_send(q, secret.encode(), len(secret), 0)
    return "sent"

def pick_up():
    libc = _libc()
    q = libc.mq_open(NAME, os.O_RDONLY | os.O_NONBLOCK, 0, None)
    if q < 0:
        return ctypes.get_errno()
    buf = ctypes.create_string_buffer(8192)
    n = libc.mq_receive(q, buf, 8192, None)
    return buf.raw[:n].decode() if n >= 0 else ctypes.get_errno()
"""


def _unlink_queue() -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mq_unlink(b"/flowtrack-attack-queue")


@needs_filter
def test_a_message_queue_cannot_carry_one_exercises_inputs_to_a_later_sandbox(mode):
    # one sandbox (an exercise with hidden inputs) leaves a POSIX queue; a later one (another uid in
    # the setpriv mode) reads it and prints it in a public test's message
    _unlink_queue()
    try:
        with Sandbox([("a", MQ)], limits=LIMITS) as sb:
            (left,) = sb.run([Call("leave", ("dt=0.731",))], timeout=20)
        with Sandbox([("b", MQ)], limits=LIMITS) as sb:
            (got,) = sb.run([Call("pick_up")], timeout=20)
    finally:
        _unlink_queue()
    assert left.ok and left.value == errno.EPERM, left
    assert got.ok and got.value == errno.EPERM, got


NESTED = DISARM + """
import ctypes, os
def attack(megabytes):
    disarm()
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(0x10000000 | 0x00020000) != 0:  # CLONE_NEWUSER | CLONE_NEWNS
        return ["unshare", ctypes.get_errno()]
    where = os.path.join(os.environ["HOME"], "mnt")
    os.mkdir(where)
    libc.mount.argtypes = [ctypes.c_char_p] * 4 + [ctypes.c_char_p]
    if libc.mount(b"none", where.encode(), b"tmpfs", 0, b"size=64g") != 0:
        return ["mount", ctypes.get_errno()]
    block = b"x" * (1 << 20)
    with open(os.path.join(where, "f"), "wb") as fh:
        for _ in range(megabytes):
            fh.write(block)
    return ["held", megabytes]
"""


@needs_filter
def test_a_nested_user_namespace_cannot_hold_memory_beyond_every_limit(mode, monkeypatch):
    # without a cgroup (an ordinary user without delegation) a tmpfs of a nested mount namespace is
    # RAM in no process's RLIMIT_AS and beyond the sandbox's disk limit (16 MiB here): 48 MiB stand
    # for the gigabytes such a mount could hold
    monkeypatch.setenv("FLOWTRACK_SANDBOX_CGROUP", "0")
    with Sandbox([("a", NESTED)], limits=LIMITS) as sb:
        (out,) = sb.run([Call("attack", (48,))], timeout=20)
    assert out.ok and out.value[0] == "unshare", out
    assert out.value[1] in (errno.EPERM, errno.ENOSPC), out  # the filter, or bubblewrap's --disable-userns
