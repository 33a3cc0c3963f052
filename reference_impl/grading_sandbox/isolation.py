"""Isolating a sandboxed child: bubblewrap (probed once per process) or the fallback, a fresh
unprivileged uid per sandbox when the grader is root, killing everything a sandbox started, measuring
and removing its directory.
"""

from __future__ import annotations

import functools
import itertools
import os
import shutil
import signal
import stat
import subprocess
import time
from pathlib import Path
from typing import NamedTuple

from . import config

__all__ = [
    "MAX_TREE_DEPTH",
    "SandboxUnavailable",
    "TreeUsage",
    "WORLD_WRITABLE",
    "bwrap_base",
    "bwrap_path",
    "bwrap_status",
    "choose_mode",
    "descendants",
    "disk_reserve_problem",
    "drop_to",
    "kill_uid",
    "mount_usage",
    "readable_by_sandbox",
    "remove_tree",
    "setpriv_command",
    "setpriv_status",
    "sandbox_uid",
    "signal_name",
    "tree_usage",
    "uid_has_processes",
    "uid_litter",
    "unlinked_bytes",
    "user_tasks",
]

_UID_BASE = 1_600_000_000
_uid_counter = itertools.count()


class SandboxUnavailable(RuntimeError):
    """A sandbox mode was forced (:data:`.config.ENV_MODE`) that cannot run here."""



# Launch modes


def sandbox_uid() -> int | None:
    """A fresh unprivileged uid for this sandbox when the grader is root, else None."""
    if os.geteuid() != 0:
        return None
    # The whole pid (pid_max <= 2**22) so that two grader processes never share a uid: closing one
    # student's sandbox kills every process of its uid.
    return _UID_BASE + os.getpid() * 64 + next(_uid_counter) % 64


def drop_to(uid: int | None) -> None:
    """Drop this process's groups, gid and uid to ``uid`` for good (nothing when ``None``)."""
    if uid is None:
        return
    os.setgroups([])
    os.setresgid(uid, uid, uid)
    os.setresuid(uid, uid, uid)


#: the JDK's configuration (java.security, jvm.cfg: Debian links them from /usr/lib/jvm into /etc),
#: read-only, so that Java programs can be compiled and run in the sandbox
JVM_CONFIG = ("/etc/java-17-openjdk", "/etc/java-21-openjdk")


def _bwrap_args(bwrap: str, extra: tuple[str, ...] = ()) -> list[str]:
    args = [bwrap, "--unshare-all", "--unshare-user", *extra, "--die-with-parent", "--new-session",
            "--uid", "65534", "--gid", "65534", "--ro-bind", "/usr", "/usr"]
    for top in ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"):
        if os.path.islink(top):
            args += ["--symlink", os.readlink(top), top]
        elif os.path.isdir(top):
            args += ["--ro-bind", top, top]
    for f in ("/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/alternatives",
              "/etc/localtime", *JVM_CONFIG):
        args += ["--ro-bind-try", f, f]
    args += ["--proc", "/proc", "--dev", "/dev"]
    return args


def bwrap_base(bwrap: str) -> list[str]:
    """The bubblewrap command line every sandboxed child starts with: all namespaces
    unshared, no further user namespace inside (``--disable-userns`` where this bubblewrap and
    kernel support it; the seccomp filter refuses new namespaces in any case), uid/gid 65534,
    ``/usr`` and the library folders read-only, the loader and JDK configuration, a fresh ``/proc``
    and ``/dev``."""
    return _bwrap_args(bwrap, _probe_bwrap(bwrap, os.geteuid() == 0)[2])


def bwrap_path() -> str | None:
    """The bubblewrap executable: the variable :data:`.config.ENV_BWRAP` when set (tests point it at a
    failing stub to run as under Docker's default seccomp profile), else ``bwrap`` on PATH."""
    return config.env(config.ENV_BWRAP) or shutil.which("bwrap")


@functools.lru_cache(maxsize=8)
def _probe_bwrap(bwrap: str | None, as_other_uid: bool) -> tuple[bool, str, tuple[str, ...]]:
    """``(usable, why not, extra options)``: bubblewrap runs ``true`` here, with
    ``--disable-userns`` when it can."""
    if bwrap is None:
        return False, "bubblewrap (bwrap) is not installed", ()
    true = shutil.which("true") or "/usr/bin/true"
    uid = sandbox_uid() if as_other_uid else None
    why = ""
    for extra in (("--disable-userns",), ()):
        try:
            r = subprocess.run([*_bwrap_args(bwrap, extra), true], preexec_fn=lambda: drop_to(uid),
                               capture_output=True, timeout=30, env={"PATH": "/usr/bin:/bin"})
        except (OSError, subprocess.SubprocessError) as exc:
            return False, f"bwrap could not run ({exc})", ()
        if r.returncode == 0:
            return True, "", extra
        lines = r.stderr.decode(errors="replace").strip().splitlines()
        why = why or f"bwrap cannot create namespaces here ({lines[-1] if lines else r.returncode})"
    return False, why, ()


def bwrap_status() -> tuple[bool, str]:
    """``(usable, why not)`` for bubblewrap on this machine (probed once per process and path)."""
    return _probe_bwrap(bwrap_path(), os.geteuid() == 0)[:2]


def setpriv_status() -> tuple[bool, str]:
    """``(usable, why not)`` for the ``setpriv`` mode: the grader is root and util-linux's
    ``setpriv`` exists (it switches the child to a fresh unprivileged uid, no namespaces needed)."""
    if os.geteuid() != 0:
        return False, "the setpriv mode needs the grader to run as root (it switches to an unprivileged uid)"
    if shutil.which("setpriv") is None:
        return False, "setpriv (util-linux) is not installed"
    return True, ""


def setpriv_command(uid: int) -> list[str]:
    """The prefix that runs a command as ``uid`` (group ``uid``, no supplementary groups), with no
    capabilities (inheritable, ambient and bounding sets emptied) and ``no_new_privs`` (no setuid
    binary can give privileges back)."""
    return [shutil.which("setpriv") or "setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups",
            "--inh-caps=-all", "--ambient-caps=-all", "--bounding-set=-all", "--no-new-privs", "--"]


_MODES = ("bwrap", "setpriv", "fallback")


def choose_mode() -> tuple[str, str]:
    """``(mode, why bubblewrap is not used)``.

    The variable :data:`.config.ENV_MODE` forces a mode (``bwrap``, ``setpriv``, ``fallback``; a
    forced one that cannot run raises :class:`SandboxUnavailable`); unset (or ``auto``): bubblewrap
    where it can create namespaces, else ``setpriv`` when the grader is root (a Gradescope container
    under Docker's seccomp profile), else the fallback.
    """
    var = config.ENV_MODE
    want = config.env(var).strip().lower()
    if want not in ("", "auto", *_MODES):
        raise SandboxUnavailable(f"{var} must be one of auto, {', '.join(_MODES)}; got {want!r}")
    if want == "fallback":
        return "fallback", f"{var}=fallback"
    if want == "setpriv":
        ok, why = setpriv_status()
        if not ok:
            raise SandboxUnavailable(f"{var}=setpriv but {why}")
        return "setpriv", f"{var}=setpriv"
    ok, why = bwrap_status()
    if ok:
        return "bwrap", ""
    if want == "bwrap":
        raise SandboxUnavailable(f"{var}=bwrap but {why}")
    if setpriv_status()[0]:
        return "setpriv", why
    return "fallback", why


def readable_by_sandbox(paths) -> list[str]:
    """The ``paths`` an unprivileged sandbox uid could open (read a file, list a folder).

    Tried for real: a forked process switches to a fresh sandbox uid and opens each. The ``setpriv``
    mode relies on file permissions, so a grader refuses to run it while its key, the submissions or
    its output folder are among these. Without root every path counts as readable.
    """
    paths = [str(p) for p in paths]
    if os.geteuid() != 0:
        return paths
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        try:
            os.close(r)
            drop_to(sandbox_uid())
            out = []
            for i, p in enumerate(paths):
                try:
                    if os.path.isdir(p):
                        os.listdir(p)
                    else:
                        os.close(os.open(p, os.O_RDONLY | os.O_NONBLOCK))
                    out.append(str(i))
                except OSError:
                    pass
            os.write(w, ",".join(out).encode())
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        data = fh.read().decode()
    os.waitpid(pid, 0)
    return [paths[int(i)] for i in data.split(",") if i]


# World-writable folders any uid can write without a mount namespace (the setpriv mode, the fallback
# as root): what a sandbox's uid leaves there is counted against its disk limit and removed with it.
WORLD_WRITABLE = ("/tmp", "/var/tmp", "/dev/shm", "/run/lock", "/dev/mqueue")


def uid_litter(uid: int, roots: tuple[str, ...] = WORLD_WRITABLE) -> list[Path]:
    """Top-level entries of the world-writable ``roots`` owned by ``uid`` (a per-sandbox uid, so only
    this student's)."""
    out = []
    for root in roots:
        try:
            with os.scandir(root) as it:
                for e in it:
                    try:
                        if e.stat(follow_symlinks=False).st_uid == uid:
                            out.append(Path(e.path))
                    except OSError:
                        continue
        except OSError:
            continue
    return out


def user_tasks() -> int:
    """The number of threads (tasks under ``/proc``) this process's uid is running."""
    uid = os.getuid()
    n = 0
    for p in Path("/proc").glob("[0-9]*"):
        try:
            st = p.stat()
            if st.st_uid == uid:
                n += len(os.listdir(p / "task"))
        except OSError:
            continue
    return n


def signal_name(sig: int) -> str:
    """The name of signal ``sig`` (``"SIGKILL"``), or ``"signal N"`` when it has none.

    Examples
    --------
    >>> signal_name(9)
    'SIGKILL'
    """
    try:
        return signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"



def kill_uid(uid: int) -> None:
    """SIGKILL every process of ``uid`` (a per-sandbox uid: only this student's processes)."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        try:
            drop_to(uid)
            for _ in range(50):  # repeated: a fork bomb may be forking while we kill
                os.kill(-1, signal.SIGKILL)
                time.sleep(0.001)
        except BaseException:
            pass
        os._exit(0)
    os.waitpid(pid, 0)
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and uid_has_processes(uid):
        time.sleep(0.02)


def uid_has_processes(uid: int) -> bool:
    """True while a live (not zombie) process of ``uid`` exists."""
    for p in Path("/proc").glob("[0-9]*"):
        try:
            if p.stat().st_uid == uid and (p / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                return True
        except (OSError, IndexError):
            continue
    return False


def _device(path) -> int | None:
    """``st_dev`` of ``path``, or of its nearest existing ancestor (None when nothing exists)."""
    for p in [Path(path), *Path(path).parents]:
        try:
            return os.stat(p).st_dev
        except OSError:
            continue
    return None


def disk_reserve_problem(writable, protected, students_max: int, reserve: int) -> str:
    """Why student code could leave the grader without disk space ("" when it cannot).

    Where students write to the host's filesystems (the setpriv mode and the fallback: their work
    area, the world-writable folders), the sandbox's meter stops each one at its disk limit, but
    ``students_max`` bytes (the students graded at once, each up to its limit plus what it writes
    between two measurements) may be taken before that. For each of the ``protected`` paths (the
    output folder, the grader's temporary folder) on a filesystem one of the ``writable`` paths is
    on, the grader must keep ``reserve`` bytes once the students took what they can: what an
    unprivileged user may write there (``f_bavail``; the sandbox runs as one) is what they can take,
    what the grader may write is ``f_bfree`` as root (the filesystem's root reservation is its
    alone) and ``f_bavail`` otherwise.

    Returns
    -------
    str
        A message naming the filesystem, the numbers and the remedies, or ``""``.
    """
    shared = {d for d in map(_device, writable) if d is not None}
    as_root = os.geteuid() == 0
    for path in protected:
        dev = _device(path)
        if dev is None or dev not in shared:
            continue
        p = next(q for q in [Path(path), *Path(path).parents] if q.exists())
        st = os.statvfs(p)
        user = st.f_bavail * st.f_frsize
        grader = st.f_bfree * st.f_frsize if as_root else user
        if grader - min(user, students_max) >= reserve:
            continue
        mib = 1 << 20
        return (
            f"the students' code can write to the filesystem of {path} (the sandbox's work area "
            "is there, or a world-writable folder is): it has "
            f"{user // mib} MiB free for them and {grader // mib} MiB for the grader, and the students "
            f"graded at once may write up to {students_max // mib} MiB before the sandbox stops them, "
            f"which would leave the grader less than its reserve of {reserve // mib} MiB for the "
            f"outputs. Put the sandbox's work area on another filesystem ({config.ENV_CACHE}, "
            "e.g. a tmpfs), free space, grade with fewer --jobs, or give root a reservation "
            f"the students cannot use (tune2fs -r) of at least {reserve // mib} MiB."
        )
    return ""


_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
# Deeper folders than this in a student's directory count as a violation of the disk limit: the meter
# holds one descriptor per level, and no exercise needs more than a few levels.
MAX_TREE_DEPTH = 64


class TreeUsage(NamedTuple):
    """What :func:`tree_usage` measured: bytes allocated, entries, and why it could not measure all
    (``""`` when it could)."""

    size: int
    entries: int
    problem: str


def tree_usage(root: Path, max_entries: int, max_depth: int = MAX_TREE_DEPTH) -> TreeUsage:
    """Bytes allocated and entries under ``root``, walked with directory descriptors.

    Each folder is opened relative to its parent's descriptor (``O_NOFOLLOW``), so no path is ever
    longer than one name: a chain of long names beyond ``PATH_MAX`` is measured like any other. A
    folder that cannot be opened or listed, or one deeper than ``max_depth``, is reported in
    ``problem`` (the caller treats it as a violation: what cannot be measured is not allowed).
    Stops once ``max_entries`` is exceeded.
    """
    size = entries = 0
    try:
        top = os.open(root, _DIR_FLAGS)
    except OSError as exc:
        return TreeUsage(0, 0, f"cannot open the sandbox's directory ({exc.strerror})")
    stack = [(top, 0)]
    problem = ""
    try:
        while stack and entries <= max_entries and not problem:
            fd, depth = stack.pop()
            try:
                with os.scandir(fd) as it:
                    names = []
                    for e in it:
                        entries += 1
                        st = e.stat(follow_symlinks=False)
                        size += st.st_blocks * 512
                        if stat.S_ISDIR(st.st_mode):
                            names.append(e.name)
                        if entries > max_entries:
                            break
                if names and depth + 1 > max_depth:
                    problem = f"created folders nested deeper than {max_depth} levels"
                    continue
                for name in names:
                    stack.append((os.open(name, _DIR_FLAGS, dir_fd=fd), depth + 1))
            except OSError as exc:
                problem = f"made part of its directory unreadable ({exc.strerror})"
            finally:
                os.close(fd)
    finally:
        for fd, _ in stack:
            os.close(fd)
    return TreeUsage(size, entries, problem)


def descendants(pid: int) -> list[int]:
    """``pid`` and every process below it (from ``/proc/<pid>/task/*/children``, iteratively)."""
    out, stack, seen = [], [pid], set()
    while stack:
        p = stack.pop()
        if p in seen:
            continue
        seen.add(p)
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                stack += [int(c) for c in (task / "children").read_text().split()]
            except (OSError, ValueError):
                continue
    return out


def unlinked_bytes(pids: list[int]) -> int:
    """Bytes held by deleted (unlinked) files that the processes ``pids`` still keep open.

    Such files are in no folder, so no walk finds them, but they occupy the disk (or, for memfd,
    RAM) until closed. Read through ``/proc/<pid>/fd``; processes or descriptors that vanish meanwhile
    are skipped.
    """
    total = 0
    seen: set[tuple[int, int]] = set()
    for pid in pids:
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                st = os.stat(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode) and st.st_nlink == 0 and (st.st_dev, st.st_ino) not in seen:
                seen.add((st.st_dev, st.st_ino))
                total += st.st_blocks * 512
    return total


def mount_usage(pid: int, path: str) -> tuple[int, int] | None:
    """``(bytes, inodes)`` in use on the filesystem mounted at ``path`` in the mount namespace of
    ``pid`` (``statvfs`` through ``/proc/<pid>/root``); None when it cannot be read (process gone,
    not yet set up, or not ours to inspect)."""
    try:
        st = os.statvfs(f"/proc/{pid}/root{path}")
    except OSError:
        return None
    return (st.f_blocks - st.f_bfree) * st.f_frsize, st.f_files - st.f_ffree


_MAX_OPEN = 64  # directory descriptors remove_tree holds at once while it descends


def remove_tree(path: Path) -> list[str]:
    """Delete the folder ``path`` and everything in it, however deep; returns the problems met.

    Iterative and descriptor-based, so neither the depth of the tree (a chain of thousands of
    folders, paths far beyond ``PATH_MAX``) nor symlinks can defeat it: it descends holding one
    descriptor per level and works relative to them (``unlink``/``rmdir`` with ``dir_fd``, symlinks
    removed, never followed); at :data:`_MAX_OPEN` levels the folders below are moved up to be
    direct children of ``path`` (``rename`` between two open descriptors) and emptied from there
    later, so the descriptors held stay bounded. A folder the student made unreadable is made
    accessible to its owner again (through its descriptor, or after ``lstat`` showed a real folder).
    Call it only once the processes that could write there are gone.

    Returns
    -------
    list of str
        One message per entry that could not be removed (empty when ``path`` is gone).
    """
    problems: list[str] = []
    try:
        root = os.open(path, _DIR_FLAGS)
    except FileNotFoundError:
        return problems
    except OSError as exc:
        return [f"cannot open {path}: {exc.strerror}"]
    counter = itertools.count()

    def open_at(parent: int, name: str) -> int:
        try:
            return os.open(name, _DIR_FLAGS, dir_fd=parent)
        except PermissionError:
            os.chmod(name, 0o700, dir_fd=parent)  # a real folder: lstat-ed by the caller
            return os.open(name, _DIR_FLAGS, dir_fd=parent)

    def fresh_name() -> str:
        while True:
            name = f".{config.NAME}-rm-{next(counter)}"
            try:
                os.lstat(name, dir_fd=root)
            except FileNotFoundError:
                return name

    def remove_dir(name: str, todo: list[str]) -> None:
        """Empty and remove the folder ``name`` of ``root``, depth first with bounded descriptors."""
        stack: list[list] = [[open_at(root, name), None, name]]  # [fd, subfolders left, name]
        try:
            while stack:
                top = stack[-1]
                fd = top[0]
                if top[1] is None:
                    try:
                        os.fchmod(fd, 0o700)  # a real folder (opened with O_NOFOLLOW)
                    except OSError:
                        pass
                    with os.scandir(fd) as it:
                        entries = [(e.name, e.is_dir(follow_symlinks=False)) for e in it]
                    top[1] = []
                    for child, is_dir in entries:
                        if not is_dir:
                            os.unlink(child, dir_fd=fd)
                        elif len(stack) >= _MAX_OPEN:  # deep enough: continue from the top later
                            moved = fresh_name()
                            os.rename(child, moved, src_dir_fd=fd, dst_dir_fd=root)
                            todo.append(moved)
                        else:
                            top[1].append(child)
                if top[1]:
                    child = top[1].pop()
                    stack.append([open_at(fd, child), None, child])
                    continue
                stack.pop()
                os.close(fd)
                parent = stack[-1][0] if stack else root
                os.rmdir(top[2], dir_fd=parent)
        finally:
            for entry in stack:
                os.close(entry[0])

    try:
        try:
            os.fchmod(root, 0o700)
        except OSError:
            pass
        with os.scandir(root) as it:
            todo = [e.name for e in it]
        while todo:
            name = todo.pop()
            try:
                st = os.lstat(name, dir_fd=root)
                if stat.S_ISDIR(st.st_mode):
                    remove_dir(name, todo)
                else:
                    os.unlink(name, dir_fd=root)
            except OSError as exc:
                problems.append(f"{name}: {exc.strerror or exc}")
                if len(problems) > 20:
                    problems.append("... (more entries could not be removed)")
                    break
    except OSError as exc:
        problems.append(f"{path}: {exc.strerror or exc}")
    finally:
        os.close(root)
    if not problems:
        try:
            os.rmdir(path)
        except OSError as exc:
            problems.append(f"{path}: {exc.strerror or exc}")
    return problems
