"""Resource attacks on the sandbox: deep trees, paths beyond PATH_MAX, open-but-unlinked
files, memfd and forked children's memory.

Each attack must score as an honest wrong answer or 0, leave the run whole (a later call in a fresh
child works) and leave nothing outside (the student's folder is gone after ``close``). The memory
attacks need a cgroup (v2 delegated, or v1 writable as root); they are skipped where the sandbox
falls back to resource limits alone (see :mod:`grading_sandbox.cgroups`). Without any cgroup
(``FLOWTRACK_SANDBOX_CGROUP=0``) the seccomp filter (:mod:`grading_sandbox.seccomp`) refuses
memfd and System V shared memory, whose pages count in no process's RLIMIT_AS.
"""

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from grading_sandbox import Call, Limits, Sandbox, SandboxPool, bwrap_status
from grading_sandbox.cgroups import cgroup_status
from grading_sandbox.isolation import remove_tree, tree_usage
from grading_sandbox.testing import SANDBOX_MODES, use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

MiB = 1 << 20
HONEST = "import numpy as np\ndef mul(a, b):\n    return np.asarray(a) * b\n"
needs_cgroup = pytest.mark.skipif(not cgroup_status()[0], reason=f"no cgroup: {cgroup_status()[1]}")


@pytest.fixture(params=SANDBOX_MODES)
def mode(request, monkeypatch, tmp_path_factory):
    return use_sandbox_mode(request.param, monkeypatch, tmp_path_factory)


def _chain(root: Path, depth: int, name: str = "d") -> None:
    """A chain of ``depth`` nested folders under ``root``, made relative to open descriptors."""
    fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
    try:
        for _ in range(depth):
            os.mkdir(name, dir_fd=fd)
            nxt = os.open(name, os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
            os.close(fd)
            fd = nxt
        with open(os.open("leaf", os.O_WRONLY | os.O_CREAT, 0o600, dir_fd=fd), "w") as f:
            f.write("x")
    finally:
        os.close(fd)


NEXT = """
import os, tempfile
def probe():
    return [sorted(os.listdir(".")), sorted(os.listdir(tempfile.gettempdir()))]
"""


def _run_attack(mode, cell, call, limits, expect_gone=True, spawn=False):
    """The attack's outcome; then an honest call in the same Sandbox; then nothing left outside.

    Also as one exercise of a SandboxPool (zygote), whose next exercise must start clean; both runs
    must agree on whether the attack's call failed. The plain run's outcome is returned. ``spawn``:
    as an exercise whose own code starts programs (the kernel then lets the child fork).
    """
    with Sandbox([("a", HONEST + cell)], limits=limits, spawn=spawn) as sb:
        (out,) = sb.run([call], timeout=limits.wall_seconds)
        workdir = sb._workdir
        x = np.arange(4.0)
        (after,) = sb.run([Call("mul", (x, 2.0))], timeout=20)
        assert after.ok and after.value == (2 * x).tolist(), after
    assert workdir is None or not workdir.exists(), f"left behind: {workdir}"
    assert sb.cleanup_problems == []
    with SandboxPool() as pool:
        with pool([("a", HONEST + cell)], limits=limits, spawn=spawn) as lease:
            (pooled,) = lease.run([call], timeout=limits.wall_seconds)
            (after,) = lease.run([Call("mul", (x, 2.0))], timeout=20)
            assert after.ok and after.value == (2 * x).tolist(), after
        with pool([("next", NEXT)], limits=limits) as nxt:
            (probe,) = nxt.run([Call("probe")], timeout=20)
        assert probe.ok and probe.value == [[], []], probe
        boxes = list(pool._boxes.values())
    assert all(b._workdir is None and b.cleanup_problems == [] for b in boxes)
    assert pooled.ok == out.ok, (out, pooled)
    return out


# -- cleanup ------------------------------------------------------------------------------------------


def test_removing_a_5000_level_tree_with_an_unreadable_folder(tmp_path):
    # shutil.rmtree recurses per level (RecursionError past ~1000) and walks full paths (ENAMETOOLONG
    # past PATH_MAX); remove_tree moves folders up between descriptors instead.
    root = tmp_path / "work"
    root.mkdir()
    _chain(root, 5000, name="n" * 200)  # 5000 x 201 bytes: a path of 1 MB
    (root / "side").mkdir()
    (root / "side" / "f").write_text("x")
    (root / "side" / "link").symlink_to(tmp_path)  # removed, never followed
    os.chmod(root / "side", 0)
    assert remove_tree(root) == []
    assert not root.exists() and tmp_path.is_dir()


def test_remove_tree_reports_instead_of_raising(tmp_path):
    assert remove_tree(tmp_path / "missing") == []
    f = tmp_path / "file"
    f.write_text("x")
    problems = remove_tree(f)  # not a folder: reported, nothing raised
    assert problems and f.exists()


def test_the_meter_walks_beyond_path_max_and_refuses_what_it_cannot_read(tmp_path):
    root = tmp_path / "w"
    root.mkdir()
    _chain(root, 20, name="n" * 250)  # > 4096 bytes of path: os.scandir(<full path>) fails there
    fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
    try:
        for _ in range(20):
            nxt = os.open("n" * 250, os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
            os.close(fd)
            fd = nxt
        with open(os.open("big", os.O_WRONLY | os.O_CREAT, 0o600, dir_fd=fd), "wb") as f:
            f.write(os.urandom(3 * MiB))
    finally:
        os.close(fd)
    size, entries, problem = tree_usage(root, 10_000)
    assert problem == "" and entries == 22 and size >= 3 * MiB
    assert tree_usage(root, 10_000, max_depth=10).problem  # deeper than allowed: a violation
    if os.geteuid() != 0:  # root reads every folder
        os.chmod(root / ("n" * 250), 0)
        assert tree_usage(root, 10_000).problem
        os.chmod(root / ("n" * 250), stat.S_IRWXU)


def test_a_student_making_a_5000_level_tree(mode):
    cell = """
import os
def attack():
    for _ in range(5000):
        os.mkdir("d")
        os.chdir("d")
    return [[0.0, 2.0, 4.0, 6.0]]
"""
    limits = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30, processes=16)
    out = _run_attack(mode, cell, Call("attack"), limits)
    if mode in ("fallback", "setpriv"):  # deeper than the meter's limit: a violation of the disk limit
        assert not out.ok and "disk limit" in out.error, out


# -- disk -------------------------------------------------------------------------------------------


def test_data_beyond_path_max(mode):
    # 20 levels of 250-character names, then 12 files of 8 MiB (96 MiB) against a 32 MiB limit.
    cell = """
import os, time
def attack():
    for _ in range(20):
        os.mkdir("n" * 250)
        os.chdir("n" * 250)
    written = 0
    try:
        for i in range(12):
            with open(f"f{i}", "wb") as f:
                f.write(b"x" * (8 << 20))
            written += 8 << 20
    except OSError:
        pass
    time.sleep(1.5)  # the grader measures while it waits
    return written
"""
    limits = Limits(cpu_seconds=10, wall_seconds=10, memory_bytes=1 << 30, processes=16,
                    disk_bytes=32 * MiB, file_size=16 * MiB)
    out = _run_attack(mode, cell, Call("attack"), limits)
    # stopped by the meter, or the kernel refused the writes beyond the limit
    assert not out.ok or out.value <= 32 * MiB, out


def test_open_but_unlinked_files(mode):
    cell = """
import os, time
KEEP = []
def attack():
    written = 0
    try:
        for i in range(6):
            f = open(f"f{i}", "wb")
            os.unlink(f"f{i}")  # in no folder: a walk never sees it
            KEEP.append(f)
            f.write(b"x" * (15 << 20))
            f.flush()
            written += 15 << 20
    except OSError:
        pass
    time.sleep(1.5)
    return written
"""
    limits = Limits(cpu_seconds=10, wall_seconds=10, memory_bytes=1 << 30, processes=16,
                    disk_bytes=32 * MiB, file_size=16 * MiB)
    out = _run_attack(mode, cell, Call("attack"), limits)
    assert not out.ok or out.value <= 32 * MiB, out
    if not out.ok:
        assert "disk limit" in out.error, out


# -- memory ------------------------------------------------------------------------------------------


@needs_cgroup
def test_memfd_memory_counts(mode, monkeypatch):
    # 48 memfds of 24 MiB (1.1 GiB) under 768 MiB + 32 MiB: memfd pages are in no process' size.
    # The cgroup on its own (the seccomp filter, which refuses memfd_create, is tested below).
    monkeypatch.setenv("FLOWTRACK_SANDBOX_SECCOMP", "0")
    cell = """
import os
KEEP = []
def attack():
    for i in range(48):
        fd = os.memfd_create(f"m{i}")
        KEEP.append(fd)
        os.write(fd, b"x" * (24 << 20))
    return len(KEEP)
"""
    limits = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=768 * MiB, processes=16,
                    disk_bytes=32 * MiB, file_size=32 * MiB, open_files=64)
    out = _run_attack(mode, cell, Call("attack"), limits)
    assert not out.ok, out
    if mode == "bwrap":  # the fallback's audit hook may refuse memfd_create first
        assert "memory" in out.error, out


@needs_cgroup
def test_forked_children_memory_counts(bwrap_or_skip):
    # 4 children x 300 MiB under 1 GiB + 32 MiB: each is within its own address-space limit
    cell = """
import os, time
def attack():
    kids = []
    for _ in range(4):
        pid = os.fork()
        if pid == 0:
            block = bytearray(b"x") * (300 << 20)
            time.sleep(2)
            os._exit(0)
        kids.append(pid)
    return sum(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) == 0 for pid in kids)
"""
    limits = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=1 << 30, processes=16, disk_bytes=32 * MiB)
    out = _run_attack("bwrap", cell, Call("attack"), limits, spawn=True)  # (else fork is refused)
    # the kernel stops the sandbox as a whole (cgroup v2: memory.oom.group) or its largest
    # processes (v1): never do all four children hold their memory
    assert (not out.ok and "memory" in out.error) or (out.ok and out.value < 4), out


MEMFD = """
import os
KEEP = []
def attack():
    for i in range(24):  # 24 x 16 MiB = 384 MiB, in no process's address space
        fd = os.memfd_create(f"m{i}")
        KEEP.append(fd)
        os.write(fd, b"x" * (16 << 20))
    return len(KEEP)
"""

SYSV_SHM = """
import ctypes
KEEP = []
def attack():
    libc = ctypes.CDLL(None, use_errno=True)
    libc.shmget.argtypes = [ctypes.c_int, ctypes.c_size_t, ctypes.c_int]
    libc.shmat.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
    libc.shmat.restype = ctypes.c_void_p
    for i in range(24):  # 24 segments of 16 MiB, each kept after the process is gone (no IPC_RMID)
        sid = libc.shmget(0, 16 << 20, 0o1600)  # IPC_PRIVATE, IPC_CREAT | 0600
        if sid < 0:
            raise OSError(ctypes.get_errno(), "shmget refused")
        addr = libc.shmat(sid, None, 0)
        ctypes.memset(addr, 1, 16 << 20)
        KEEP.append(sid)
    return len(KEEP)
"""


def _sysv_shm_segments() -> int:
    """System V shared memory segments of the machine's IPC namespace (the grader's)."""
    try:
        return len(Path("/proc/sysvipc/shm").read_text().splitlines()) - 1
    except OSError:
        return 0


@pytest.mark.parametrize("cell", [MEMFD, SYSV_SHM], ids=["memfd", "sysv_shm"])
def test_memory_outside_rlimit_as_without_any_cgroup(mode, cell, monkeypatch):
    from grading_sandbox.seccomp import seccomp_status

    ok, why = seccomp_status()
    if not ok:
        pytest.skip(f"no seccomp filter here: {why}")
    monkeypatch.setenv("FLOWTRACK_SANDBOX_CGROUP", "0")  # as for an ordinary user without delegation
    assert cgroup_status()[0] == ""
    limits = Limits(cpu_seconds=10, wall_seconds=20, memory_bytes=768 * MiB, processes=16,
                    disk_bytes=32 * MiB, file_size=32 * MiB, open_files=64)
    before = _sysv_shm_segments()
    out = _run_attack(mode, cell, Call("attack"), limits)
    # refused by the seccomp filter (or, in the fallback, its audit hook refusing ctypes first)
    assert not out.ok and ("PermissionError" in out.error or "not permitted" in out.error), out
    assert _sysv_shm_segments() == before  # nothing of it outlives the sandbox
    if mode == "bwrap" and cell is MEMFD:  # the attack is real: with neither defence it holds 384 MiB
        monkeypatch.setenv("FLOWTRACK_SANDBOX_SECCOMP", "0")
        with Sandbox([("a", cell)], limits=limits) as sb:
            (held,) = sb.run([Call("attack")], timeout=20)
            assert not sb.seccomp
        assert held.ok and held.value == 24, held


@pytest.fixture
def bwrap_or_skip(monkeypatch):
    ok, why = bwrap_status()
    assert ok, why
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")  # the fallback refuses fork anyway



