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

__all__ = ["SandboxUnavailable", "bwrap_base", "bwrap_status", "choose_mode", "drop_to", "kill_uid",
           "remove_tree", "sandbox_uid", "signal_name", "tree_usage", "uid_has_processes", "user_tasks"]

_UID_BASE = 1_600_000_000
_uid_counter = itertools.count()


class SandboxUnavailable(RuntimeError):
    """``FLOWTRACK_SANDBOX=bwrap`` was requested but bubblewrap cannot run here."""



# Launch modes


def sandbox_uid() -> int | None:
    """A fresh unprivileged uid for this sandbox when the grader is root, else None."""
    if os.geteuid() != 0:
        return None
    # The whole pid (pid_max <= 2**22) so that two grader processes never share a uid: closing one
    # student's sandbox kills every process of its uid.
    return _UID_BASE + os.getpid() * 64 + next(_uid_counter) % 64


def drop_to(uid: int | None) -> None:
    if uid is None:
        return
    os.setgroups([])
    os.setresgid(uid, uid, uid)
    os.setresuid(uid, uid, uid)


#: hook (issue 19): the JDK's configuration (java.security, jvm.cfg: Debian links them from /usr/lib/jvm
#: into /etc), read-only, so that Java answers can be compiled and run in the sandbox
JVM_CONFIG = ("/etc/java-17-openjdk", "/etc/java-21-openjdk")


def bwrap_base(bwrap: str) -> list[str]:
    args = [bwrap, "--unshare-all", "--unshare-user", "--die-with-parent", "--new-session",
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


@functools.lru_cache(maxsize=2)
def _probe_bwrap(as_other_uid: bool) -> tuple[bool, str]:
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        return False, "bubblewrap (bwrap) is not installed"
    true = shutil.which("true") or "/usr/bin/true"
    uid = sandbox_uid() if as_other_uid else None
    try:
        r = subprocess.run([*bwrap_base(bwrap), true], preexec_fn=lambda: drop_to(uid),
                           capture_output=True, timeout=30, env={"PATH": "/usr/bin:/bin"})
    except (OSError, subprocess.SubprocessError) as exc:
        return False, f"bwrap could not run ({exc})"
    if r.returncode != 0:
        why = r.stderr.decode(errors="replace").strip().splitlines()
        return False, f"bwrap cannot create namespaces here ({why[-1] if why else r.returncode})"
    return True, ""


def bwrap_status() -> tuple[bool, str]:
    """``(usable, why not)`` for bubblewrap on this machine (probed once per process)."""
    return _probe_bwrap(os.geteuid() == 0)


def choose_mode() -> tuple[str, str]:
    want = os.environ.get("FLOWTRACK_SANDBOX", "").strip().lower()
    if want == "fallback":
        return "fallback", "FLOWTRACK_SANDBOX=fallback"
    ok, why = bwrap_status()
    if ok:
        return "bwrap", ""
    if want == "bwrap":
        raise SandboxUnavailable(f"FLOWTRACK_SANDBOX=bwrap but {why}")
    return "fallback", why


def user_tasks() -> int:
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


def tree_usage(root: Path, max_entries: int) -> tuple[int, int]:
    """``(bytes allocated, entries)`` under ``root`` without following symlinks; stops counting
    entries once ``max_entries`` is exceeded."""
    size, entries, stack = 0, 0, [str(root)]
    while stack and entries <= max_entries:
        try:
            it = os.scandir(stack.pop())
        except OSError:
            continue
        with it:
            for e in it:
                entries += 1
                try:
                    st = e.stat(follow_symlinks=False)
                except OSError:
                    continue
                size += st.st_blocks * 512
                if stat.S_ISDIR(st.st_mode):
                    stack.append(e.path)
                if entries > max_entries:
                    break
    return size, entries


def remove_tree(path: Path) -> None:
    def onerror(func, p, exc_info):  # a student may have chmod-ed things
        try:
            # Never chmod through a symlink the student planted (it may point at a grader's file);
            # only real directories of the tree are made writable again.
            parent = os.path.dirname(p)
            if not os.path.islink(parent) and os.path.isdir(parent):
                os.chmod(parent, 0o700)
            if not os.path.islink(p) and os.path.isdir(p):
                os.chmod(p, 0o700)
            func(p)
        except OSError:
            pass

    shutil.rmtree(path, onerror=onerror)
    if path.exists():
        shutil.rmtree(path, ignore_errors=True)
