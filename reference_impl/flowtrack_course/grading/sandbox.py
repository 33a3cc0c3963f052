"""The sandbox that runs a student's notebook cells for the grader.

Threat model
------------
The student controls the code of the graded cells and wants a higher score than their answer earns
(or to learn the hidden tests, read other students' work, or damage the grading machine). The
grader controls everything else. Defences, outermost first, and what each one stops:

1. **Separate process, data-only protocol.** The grader never imports, compiles or executes
   student code. A fresh ``python -I -S`` child runs :mod:`flowtrack_course.grading._child`, receives the
   cells and the inputs (length-prefixed JSON on stdin) and sends back plain data (length-prefixed
   JSON on a dedicated pipe). Expected values never leave the grader; the grader decodes at most
   ``Limits.output_bytes`` per batch with :func:`json.loads` and compares with its own numpy
   (:func:`flowtrack_course.grading.spec.compare_arrays`). This stops monkeypatching numpy / numpy.testing,
   objects whose ``__eq__`` lies, lying ndarray subclasses (only the raw buffer is serialised, and
   the grader re-checks exact JSON types), ``sys.exit``/``os._exit`` (the batch's unanswered calls
   fail; the next batch gets a fresh child) and forged result files (scores never come from exit
   codes, printed text or files).
2. **bubblewrap** (``isolation == "bwrap"``): new user, mount, pid, network, ipc, uts and cgroup
   namespaces; ``--die-with-parent``, ``--new-session``; a fresh root holding only read-only binds of
   ``/usr`` (and the ``/lib*`` links), the Python runtime, the virtual environment's
   site-packages, a *filtered copy* of flowtrack (blocked modules replaced by stubs that raise
   ``ImportError``, ``flowtrack_course.grading`` and the course tooling removed) and the runner. The
   student's empty temporary directory is the only writable place: its ``home`` is bound at cwd
   and HOME, its ``tmp`` at ``/tmp``; bubblewrap's own root and ``/dev`` (tmpfs, i.e. RAM that no
   rlimit covers) are remounted read-only, and the grader measures the directory while it waits
   (``Limits.disk_bytes``/``disk_files``), so neither the disk nor the RAM of the machine can be
   filled. Nothing of the course (repository, exercises, solutions, grader output, gradebook) exists
   inside. Blocked third-party packages (e.g. ``scipy.optimize``) have a stub directory bound over
   them, so even loading their files by path fails. No network interfaces but loopback of the new
   namespace (so no connection to the host). When the grader runs as root it switches, before
   starting bubblewrap, to a per-sandbox unprivileged uid (RLIMIT_NPROC is then enforced and
   private to this student); a Python runtime that uid cannot read (e.g. pyenv under ``/root``) is
   mirrored once, by hard links, into a world-readable cache.
3. **Resource limits** (``setrlimit`` before exec, RLIMIT_NPROC also in the child): CPU time,
   address space (memory bombs fail with MemoryError), processes (fork bombs), open files, file
   size, no core files; the grader enforces a wall-clock timeout per batch and output size per
   batch, and on any violation kills the whole sandbox (process group; bubblewrap's pid namespace;
   as root also every process of the sandbox uid), so nothing outlives it.
4. **Inside the child** (a second line, never the only one): a ``sys.meta_path`` blocker and an
   audit hook refusing blocked imports and opening protected paths; fd 1/2 point at /dev/null and
   ``print`` goes to a capped buffer, so student output cannot mix with replies.

Fallback (``isolation == "fallback: <why>"``): when bubblewrap is missing or namespaces are not
allowed (a student's laptop running ``flowtrack check``), the child is a plain subprocess with the
same limits, an empty temporary cwd, ``-I -S``, the filtered flowtrack copy, and (as root) a
per-sandbox uid. The audit hook additionally refuses the repository, the real flowtrack sources,
blocked packages, ``hidden_paths``, sockets and process spawning. This is best effort: a determined
student can get around an in-process hook (e.g. through ctypes), which is why ``flowtrack grade``
warns when it is not running under bubblewrap. ``FLOWTRACK_SANDBOX=fallback`` forces the fallback,
``FLOWTRACK_SANDBOX=bwrap`` requires bubblewrap.

Cache
-----
What the sandbox reads is prepared once and kept in ``<tmp>/flowtrack-sandbox-<uid>/`` (``<tmp>`` is
``$FLOWTRACK_SANDBOX_CACHE`` if set, else the temporary directory, or ``/tmp`` when root's temporary
directory is private), a directory of this uid that nobody else can write: ``ft/<key>`` filtered
flowtrack copies, ``python/<key>`` the mirrored runtime and ``site/<key>`` mirrored site-packages
(root only), ``bin/<key>`` the runner, ``stubs/`` the stubs of blocked packages and ``work/`` the
students' temporary directories. A copy's ``key`` is a fingerprint of what it was made from, so an
upgrade of flowtrack or of the Python packages makes new copies. Each start of a child sets the mtime
of the copies it uses to now (under a shared ``flock`` of ``<kind>/.lock``). Whenever a new copy of
``ft``, ``python``, ``site`` or ``bin`` is created, the other copies of that kind whose mtime is more
than a day old (``_PRUNE_AFTER``) are removed, under the exclusive lock: renamed out of the way, then
deleted without following symlinks. A copy in use was touched when its child started, minutes ago at
most (in the grader a child serves one student's tests), so it is never that old; one removed while a
process still remembered it is rebuilt at that process's next start. ``stubs`` (one per blocked
package, not versioned) and ``work`` are not pruned.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import itertools
import json
import math
import os
import re
import resource
import select
import shutil
import signal
import stat
import struct
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import flowtrack

from .spec import Call, Outcome

__all__ = ["Limits", "Sandbox", "SandboxUnavailable", "bwrap_status"]

GiB = 1 << 30
MiB = 1 << 20
# the library package the sandbox copies (the course tooling, flowtrack_course, is blocked whole)
_FLOWTRACK_DIR = Path(flowtrack.__file__).resolve().parent
# Removed from the sandbox's copy of flowtrack: the grader itself and course tooling.
_ALWAYS_REMOVED = ("grading", "ports", "cli", "book", "notebooks")
_UID_BASE = 1_600_000_000
_uid_counter = itertools.count()
_SANDBOX_HOME = "/home/student"
_OPT = "/opt/flowtrack-sandbox"
_DISK_POLL = 0.2  # seconds between measurements of the child's directory while waiting for it
# A cached copy (filtered flowtrack, mirrored runtime or site-packages, runner) not used for this long
# is removed when a newer copy of its kind is made. Far longer than a child lives (minutes), short
# enough that upgrades do not pile up copies.
_PRUNE_AFTER = 24 * 3600.0
# What the cache's kind directories hold: fingerprints, builds in progress (or crashed) and copies
# being deleted; anything else is left alone.
_CACHE_ENTRY = re.compile(r"[0-9a-f]{16,64}|\.build-[^/]+|\.trash-[^/]+")


class SandboxUnavailable(RuntimeError):
    """``FLOWTRACK_SANDBOX=bwrap`` was requested but bubblewrap cannot run here."""


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
        Address space (RLIMIT_AS); numpy with single-threaded OpenBLAS needs about 0.5 GiB.
    processes : int
        Processes and threads (RLIMIT_NPROC) the sandbox may hold.
    open_files : int
        RLIMIT_NOFILE.
    output_bytes : int
        Reply bytes the grader reads per batch; more kills the child.
    file_size : int
        Largest file the child may write (RLIMIT_FSIZE).
    disk_bytes : int
        Bytes the child may keep in its temporary directory (its only writable place: HOME, cwd and
        ``/tmp`` all live there). The grader measures it while it waits for replies (every
        ``0.2`` s) and after each batch, and kills the child when it is exceeded, so a student
        cannot fill the grading machine's disk (the overshoot is bounded by what the child writes
        in 0.2 s).
    disk_files : int
        Files and directories the child may create there (bounds the cost of measuring).
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


# --------------------------------------------------------------------------------------------------
# Cached, trusted preparation: cache dir, Python runtime, filtered flowtrack, stubs, the runner.


def _cache_root() -> Path:
    base = Path(os.environ.get("FLOWTRACK_SANDBOX_CACHE") or tempfile.gettempdir())
    explicit = bool(os.environ.get("FLOWTRACK_SANDBOX_CACHE"))
    if os.geteuid() == 0 and not explicit and not _world_readable(base, read=False):
        # root with a private TMPDIR (e.g. /root/tmp): the sandbox's unprivileged uid could not
        # reach its files there; use the machine's shared temporary directory instead.
        shared = [Path(d) for d in ("/tmp", "/var/tmp") if _world_readable(Path(d), read=False)]
        base = shared[0] if shared else base
    root = base / f"flowtrack-sandbox-{os.geteuid()}"
    try:
        root.mkdir(mode=0o755)
    except FileExistsError:
        pass
    st = os.lstat(root)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid() or st.st_mode & 0o022:
        raise RuntimeError(f"the sandbox cache {root} is not a private directory of this user")
    os.chmod(root, 0o755)
    for sub in ("work", "ft", "stubs", "python", "bin", "site"):
        d = root / sub
        d.mkdir(mode=0o755, exist_ok=True)
        os.chmod(d, 0o711 if sub == "work" else 0o755)
    return root


def _world_readable(path: Path, read: bool = True) -> bool:
    """True when ``path`` and its ancestors are traversable by others (and ``path`` readable)."""
    path = Path(path).resolve()
    try:
        for p in [path, *path.parents]:
            mode = os.stat(p).st_mode
            if stat.S_ISDIR(mode) and not mode & stat.S_IXOTH:
                return False
        return not read or bool(os.stat(path).st_mode & stat.S_IROTH)
    except OSError:
        return False


def _atomic_dir(final: Path, build, *, prune: bool = False) -> Path:
    """Build a directory with ``build(tmp)`` and rename it into place (first writer wins).

    An existing ``final`` is only marked as used (:func:`_mark_used`). With ``prune``, making a new
    ``final`` also removes its kind's stale copies (:func:`_prune_stale`).
    """
    if _mark_used(final):
        return final
    tmp = Path(tempfile.mkdtemp(prefix=".build-", dir=final.parent))
    created = False
    try:
        build(tmp)
        os.chmod(tmp, 0o755)
        try:
            os.rename(tmp, final)
            created = True
        except OSError:
            if not final.is_dir():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    if created and prune:
        _prune_stale(final.parent, keep=final.name)
    return final


@contextlib.contextmanager
def _kind_lock(kind_dir: Path, exclusive: bool):
    """``flock`` of ``kind_dir/.lock``: shared to mark a copy used, exclusive to prune."""
    fd = os.open(kind_dir / ".lock", os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        yield
    finally:
        os.close(fd)  # releases the lock


def _mark_used(copy: Path) -> bool:
    """Set the mtime of the cached ``copy`` to now; False when it does not exist (not built yet, or
    pruned since a caller remembered it).

    Done under the shared lock of its kind, so a concurrent :func:`_prune_stale` either sees the new
    mtime and keeps the copy, or has already moved it away and this returns False.
    """
    if not copy.parent.is_dir():  # the whole cache was removed (e.g. by a /tmp cleaner)
        return False
    with _kind_lock(copy.parent, exclusive=False):
        try:
            st = os.lstat(copy)
        except FileNotFoundError:
            return False
        if not stat.S_ISDIR(st.st_mode):
            return False
        try:
            os.utime(copy)
        except OSError:
            pass
        return True


def _live(make, *args, where=lambda path: path):
    """``make(*args)``, an lru-cached maker of a cached copy, with the copy (``where(value)``, None for
    no copy) marked as used; made afresh when the copy it remembered is gone (pruned meanwhile)."""
    value = make(*args)
    path = where(value)
    if path is not None and not _mark_used(path):
        make.cache_clear()
        value = make(*args)
    return value


def _prune_stale(kind_dir: Path, keep: str, max_age: float = _PRUNE_AFTER) -> list[str]:
    """Remove the cached copies in ``kind_dir`` other than ``keep`` unused for ``max_age`` seconds.

    Only directories of this uid whose names look like cache entries (:data:`_CACHE_ENTRY`) inside
    a ``kind_dir`` and cache root of this uid that nobody else can write are considered; symlinks
    are never followed (nor removed). Under the exclusive lock of the kind each stale copy (and a
    ``.build-`` left by a crashed build, equally old) is renamed to ``.trash-...``, so no key ever
    names a half-deleted copy; the renamed trees (and any ``.trash-`` left by an interrupted prune)
    are deleted after the lock is released.

    Returns
    -------
    list of str
        The names of the copies removed.
    """
    uid = os.geteuid()
    try:
        for d in (kind_dir.parent, kind_dir):
            st = os.lstat(d)
            if not stat.S_ISDIR(st.st_mode) or st.st_uid != uid or st.st_mode & 0o022:
                return []
    except OSError:
        return []
    removed: list[str] = []
    trash: list[str] = []
    with _kind_lock(kind_dir, exclusive=True):
        now = time.time()
        with os.scandir(kind_dir) as entries:
            for e in entries:
                if e.name == keep or not _CACHE_ENTRY.fullmatch(e.name):
                    continue
                try:
                    st = e.stat(follow_symlinks=False)
                except OSError:
                    continue
                if not stat.S_ISDIR(st.st_mode) or st.st_uid != uid:
                    continue
                if e.name.startswith(".trash-"):
                    trash.append(e.path)
                    continue
                if now - st.st_mtime < max_age:
                    continue
                dst = os.path.join(kind_dir, f".trash-{os.getpid()}-{time.monotonic_ns()}")
                try:
                    os.rename(e.path, dst)
                except OSError:
                    continue
                trash.append(dst)
                removed.append(e.name)
    for path in trash:
        shutil.rmtree(path, ignore_errors=True)  # fd-based on Linux: never follows a symlink
    return removed


def _link_or_copy(src: Path, dst: Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)
        os.chmod(dst, 0o755 if os.access(src, os.X_OK) else 0o644)


@dataclass(frozen=True)
class _Runtime:
    executable: str  # path of the python binary (outside)
    prefix: str  # base prefix as seen inside bwrap (original path)
    source: str  # directory bound at ``prefix`` inside bwrap
    stdlib: tuple[str, ...]  # stdlib dirs (outside paths)
    lib_dir: str | None  # LD_LIBRARY_PATH for the fallback when mirrored


@functools.lru_cache(maxsize=4)
def _python_runtime(need_world_readable: bool) -> _Runtime:
    prefix = Path(sys.base_prefix)
    ver = f"{sys.version_info.major}.{sys.version_info.minor}"
    exe = prefix / "bin" / f"python{ver}"
    if not exe.exists():
        exe = Path(getattr(sys, "_base_executable", sys.executable)).resolve()
    stdlib = Path(sysconfig.get_paths(vars={"installed_base": str(prefix), "base": str(prefix)})["stdlib"])
    real_prefix = prefix.resolve()
    stdlib_dirs = tuple(
        p
        for p in sys.path
        if p and "site-packages" not in p and Path(p).is_dir()
        and Path(p).resolve().is_relative_to(real_prefix)
    ) or (str(stdlib),)
    if not need_world_readable or (_world_readable(prefix) and _world_readable(exe)):
        return _Runtime(str(exe), str(prefix), str(prefix), stdlib_dirs, None)
    key = hashlib.sha256(f"{prefix}\0{sys.version}".encode()).hexdigest()[:16]
    skip = {"site-packages", "test", "idlelib", "tkinter", "turtledemo", "lib2to3", "ensurepip"}

    def build(tmp: Path) -> None:
        (tmp / "bin").mkdir(mode=0o755)
        _link_or_copy(exe, tmp / "bin" / exe.name)
        (tmp / "lib").mkdir(mode=0o755)
        for lib in (prefix / "lib").glob("libpython*"):
            if lib.is_file():
                _link_or_copy(lib, tmp / "lib" / lib.name)
        src_std = prefix / "lib" / f"python{ver}"
        for dirpath, dirnames, filenames in os.walk(src_std):
            rel = Path(dirpath).relative_to(src_std)
            if rel == Path("."):
                dirnames[:] = [d for d in dirnames if d not in skip]
            out = tmp / "lib" / f"python{ver}" / rel
            out.mkdir(mode=0o755, parents=True, exist_ok=True)
            for f in filenames:
                if not os.path.islink(os.path.join(dirpath, f)):
                    _link_or_copy(Path(dirpath) / f, out / f)

    mirror = _atomic_dir(_cache_root() / "python" / key, build, prune=True)
    mirror_std = tuple(str(mirror / Path(p).resolve().relative_to(prefix.resolve())) for p in stdlib_dirs)
    return _Runtime(str(mirror / "bin" / exe.name), str(prefix), str(mirror), mirror_std, str(mirror / "lib"))


def _site_dirs() -> list[str]:
    import site

    dirs = []
    for d in site.getsitepackages():
        if Path(d).is_dir() and d not in dirs:
            dirs.append(d)
    return dirs


def _mirror_site(site: Path) -> Path:
    """A world-readable mirror (hard links, else copies) of a site-packages folder the sandbox's
    unprivileged uid cannot reach (e.g. a virtual environment under ``/root``); rebuilt when a
    package is added, removed or replaced. flowtrack itself is left out (the sandbox gets its
    filtered copy)."""
    h = hashlib.sha256(f"{site.resolve()}\0{sys.version}".encode())
    for e in sorted(os.scandir(site), key=lambda e: e.name):
        h.update(f"{e.name}\0{e.stat(follow_symlinks=False).st_mtime_ns}\n".encode())
    key = h.hexdigest()[:20]

    def build(tmp: Path) -> None:
        for dirpath, dirnames, filenames in os.walk(site):
            rel = Path(dirpath).relative_to(site)
            if rel == Path("."):
                dirnames[:] = [d for d in dirnames if d not in ("flowtrack", "flowtrack_course")]
            dirnames[:] = [d for d in dirnames if d != "__pycache__"]
            out = tmp / rel
            out.mkdir(mode=0o755, parents=True, exist_ok=True)
            os.chmod(out, 0o755)
            for f in filenames:
                src = Path(dirpath) / f
                if src.is_symlink():
                    os.symlink(os.readlink(src), out / f)
                else:
                    _link_or_copy(src, out / f)

    return _atomic_dir(_cache_root() / "site" / key, build, prune=True)


def _flowtrack_signature() -> str:
    """Names, sizes and mtimes of the files the filtered copy takes (an edit of the grader itself,
    which the copy leaves out, does not rebuild it)."""
    h = hashlib.sha256()
    for p in sorted(_FLOWTRACK_DIR.rglob("*")):
        top = p.relative_to(_FLOWTRACK_DIR).parts[0].removesuffix(".py")
        if "__pycache__" in p.parts or not p.is_file() or top in _ALWAYS_REMOVED:
            continue
        st = p.stat()
        h.update(f"{p.relative_to(_FLOWTRACK_DIR)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def _stub_source(name: str) -> str:
    return f"raise ImportError({name + ' is not available in this exercise'!r})\n"


@functools.lru_cache(maxsize=64)
def _filtered_flowtrack(blocked: tuple[str, ...]) -> Path:
    """A read-only copy of flowtrack with blocked modules replaced by stubs; returns its sys.path root."""
    mods = sorted({b.split(".")[1] for b in blocked if b.startswith("flowtrack.")})
    key = hashlib.sha256(f"{_flowtrack_signature()}\0{','.join(mods)}".encode()).hexdigest()[:20]

    def build(tmp: Path) -> None:
        dst = tmp / "flowtrack"

        def ignore(d: str, names: list[str]) -> list[str]:
            out = [n for n in names if n == "__pycache__" or n.endswith(".pyc")]
            if Path(d).resolve() == _FLOWTRACK_DIR:
                out += [n for n in names if n.removesuffix(".py") in _ALWAYS_REMOVED]
            return out

        shutil.copytree(_FLOWTRACK_DIR, dst, ignore=ignore)
        for m in mods:
            if (dst / m).is_dir():
                shutil.rmtree(dst / m)
                (dst / m).mkdir()
                (dst / m / "__init__.py").write_text(_stub_source(f"flowtrack.{m}"))
            else:
                (dst / f"{m}.py").write_text(_stub_source(f"flowtrack.{m}"))
        for dirpath, _dirnames, filenames in os.walk(tmp):
            os.chmod(dirpath, 0o755)
            for f in filenames:
                os.chmod(os.path.join(dirpath, f), 0o644)

    return _atomic_dir(_cache_root() / "ft" / key, build, prune=True)


def _stub_dir(name: str) -> Path:
    key = hashlib.sha256(name.encode()).hexdigest()[:16]

    def build(tmp: Path) -> None:
        (tmp / "__init__.py").write_text(_stub_source(name))
        os.chmod(tmp / "__init__.py", 0o644)

    return _atomic_dir(_cache_root() / "stubs" / key, build)


@functools.lru_cache(maxsize=1)
def _runner_dir() -> Path:
    src = (Path(__file__).parent / "_child.py").read_bytes()
    key = hashlib.sha256(src).hexdigest()[:16]

    def build(tmp: Path) -> None:
        (tmp / "_child.py").write_bytes(src)
        os.chmod(tmp / "_child.py", 0o644)

    return _atomic_dir(_cache_root() / "bin" / key, build, prune=True)


def _locate_module(name: str, roots: Sequence[str]) -> Path | None:
    """Where ``name`` (dotted) lives under one of ``roots`` (a package dir or a module file)."""
    parts = name.split(".")
    for root in roots:
        base = Path(root, *parts[:-1])
        if not base.is_dir():
            continue
        cand = base / parts[-1]
        if cand.is_dir():
            return cand
        for f in sorted(base.glob(parts[-1] + ".*")):
            if f.is_file() and (f.suffix == ".py" or f.suffix == ".so" or f.name.endswith(".pyd")):
                return f
    return None


# --------------------------------------------------------------------------------------------------
# Launch modes


def _sandbox_uid() -> int | None:
    """A fresh unprivileged uid for this sandbox when the grader is root, else None."""
    if os.geteuid() != 0:
        return None
    # The whole pid (pid_max <= 2**22) so that two grader processes never share a uid: closing one
    # student's sandbox kills every process of its uid.
    return _UID_BASE + os.getpid() * 64 + next(_uid_counter) % 64


def _drop_to(uid: int | None) -> None:
    if uid is None:
        return
    os.setgroups([])
    os.setresgid(uid, uid, uid)
    os.setresuid(uid, uid, uid)


def _bwrap_base(bwrap: str) -> list[str]:
    args = [bwrap, "--unshare-all", "--unshare-user", "--die-with-parent", "--new-session",
            "--uid", "65534", "--gid", "65534", "--ro-bind", "/usr", "/usr"]
    for top in ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"):
        if os.path.islink(top):
            args += ["--symlink", os.readlink(top), top]
        elif os.path.isdir(top):
            args += ["--ro-bind", top, top]
    for f in ("/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/alternatives",
              "/etc/localtime"):
        args += ["--ro-bind-try", f, f]
    args += ["--proc", "/proc", "--dev", "/dev"]
    return args


@functools.lru_cache(maxsize=2)
def _probe_bwrap(as_other_uid: bool) -> tuple[bool, str]:
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        return False, "bubblewrap (bwrap) is not installed"
    true = shutil.which("true") or "/usr/bin/true"
    uid = _sandbox_uid() if as_other_uid else None
    try:
        r = subprocess.run([*_bwrap_base(bwrap), true], preexec_fn=lambda: _drop_to(uid),
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


def _choose_mode() -> tuple[str, str]:
    want = os.environ.get("FLOWTRACK_SANDBOX", "").strip().lower()
    if want == "fallback":
        return "fallback", "FLOWTRACK_SANDBOX=fallback"
    ok, why = bwrap_status()
    if ok:
        return "bwrap", ""
    if want == "bwrap":
        raise SandboxUnavailable(f"FLOWTRACK_SANDBOX=bwrap but {why}")
    return "fallback", why


def _user_tasks() -> int:
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


def _signal_name(sig: int) -> str:
    try:
        return signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"


# --------------------------------------------------------------------------------------------------
# Encoding of grader-side arguments


def _to_wire(x: Any, depth: int = 0) -> Any:
    if depth > 32:
        raise TypeError("Call arguments are nested too deeply")
    if x is None or isinstance(x, bool | int | float | str):
        return x
    if isinstance(x, np.ndarray):
        if x.dtype.kind == "b":
            dtype = "bool"
        elif x.dtype.kind in "iu":
            dtype = "int64"
        elif x.dtype.kind == "f":
            dtype = "float64"
        else:
            raise TypeError(f"Call arguments: arrays of dtype {x.dtype} cannot be sent to the sandbox")
        return {"__ndarray__": np.asarray(x, dtype=dtype).tolist(), "dtype": dtype, "shape": list(x.shape)}
    if isinstance(x, np.generic):
        return _to_wire(x.item(), depth + 1)
    if isinstance(x, list | tuple):
        return [_to_wire(v, depth + 1) for v in x]
    if isinstance(x, dict):
        if not all(isinstance(k, str) for k in x):
            raise TypeError("Call arguments: dict keys must be str")
        return {k: _to_wire(v, depth + 1) for k, v in x.items()}
    raise TypeError(f"Call arguments of type {type(x).__name__} cannot be sent to the sandbox")


def _plain(x: Any, depth: int = 0) -> bool:
    if depth > 64:
        return False
    t = type(x)
    if x is None or t in (bool, int, float, str):
        return True
    if t is list:
        return all(_plain(v, depth + 1) for v in x)
    if t is dict:
        return all(type(k) is str and _plain(v, depth + 1) for k, v in x.items())
    return False


class _ChildGone(Exception):
    """The child cannot answer any more; ``args[0]`` is the message for the unanswered calls."""


# --------------------------------------------------------------------------------------------------


class Sandbox:
    """Run one student's cells of one exercise in an isolated child and call their functions.

    Parameters
    ----------
    cells : sequence of (str, str)
        ``(grade_id, source)`` of the answer cells, executed in order in one namespace
        (see :func:`flowtrack_course.grading.notebook.extract_cells`).
    blocked : sequence of str
        Modules the student may not import, e.g. ``"flowtrack.camera"`` or ``"scipy.optimize"``.
    limits : Limits
        Resource limits of the child.
    workdir_parent : Path, optional
        Where the student's temporary directory is created (must be traversable by other users
        when grading as root); default: a private cache directory.
    hidden_paths : sequence of Path, optional
        Extra paths the fallback's audit hook refuses (bubblewrap never shows them anyway).

    Attributes
    ----------
    cell_errors : dict of str to str
        ``grade_id -> error text`` of cells that raised when executed (known after the first start).
    isolation : str
        ``"bwrap"`` or ``"fallback: <why>"``.
    stdout : str
        What the student's code printed during the last batch (truncated; never used for scores).

    Examples
    --------
    >>> from flowtrack_course.grading.spec import Call
    >>> with Sandbox([("a", "def add(a, b):\\n    return a + b\\n")]) as sb:
    ...     [o.value for o in sb.run([Call("add", (1, 2)), Call("add", ([1.5], [2.0]))], timeout=30)]
    [3, [1.5, 2.0]]
    """

    def __init__(
        self,
        cells: Sequence[tuple[str, str]],
        *,
        blocked: Sequence[str] = (),
        limits: Limits = Limits(),  # a frozen dataclass: immutable
        workdir_parent: Path | None = None,
        hidden_paths: Sequence[str | Path] = (),
    ) -> None:
        if isinstance(cells, str | bytes) or not all(
            isinstance(c, tuple | list) and len(c) == 2 and all(isinstance(s, str) for s in c) for c in cells
        ):
            raise TypeError("cells must be a sequence of (grade_id, source) pairs of str")
        if isinstance(blocked, str) or not all(
            isinstance(b, str) and b and all(p.isidentifier() for p in b.split(".")) for b in blocked
        ):
            raise TypeError("blocked must be a sequence of dotted module names such as 'scipy.optimize'")
        if not isinstance(limits, Limits):
            raise TypeError("limits must be a Limits")
        self.cells = [(str(g), str(s)) for g, s in cells]
        self.blocked = tuple(dict.fromkeys([*blocked, "flowtrack_course"]))
        self.limits = limits
        self.hidden_paths = tuple(str(Path(p).resolve()) for p in hidden_paths)
        self.cell_errors: dict[str, str] = {}
        self.stdout = ""
        self._mode, why = _choose_mode()
        self.isolation = "bwrap" if self._mode == "bwrap" else f"fallback: {why}"
        self._cache = _cache_root()
        self._workdir_parent = Path(workdir_parent) if workdir_parent is not None else self._cache / "work"
        if not self._workdir_parent.is_dir():
            raise ValueError(f"workdir_parent {self._workdir_parent} is not a directory")
        self._uid: int | None = None  # a fresh unprivileged uid per child when grading as root
        if os.geteuid() == 0 and not _world_readable(self._workdir_parent, read=False):
            raise ValueError(
                f"workdir_parent {self._workdir_parent} must be traversable by other users when "
                "grading as root (the sandbox runs as an unprivileged uid)"
            )
        self._proc: subprocess.Popen | None = None
        self._reply_fd: int | None = None
        self._stderr = None
        self._workdir: Path | None = None
        self._next_disk_check = 0.0
        self._cpu_used = 0.0
        self._cpu_ceiling = int(10 * limits.cpu_seconds + 60)

    # -- context manager ---------------------------------------------------------------------------
    def __enter__(self) -> Sandbox:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    def close(self) -> None:
        """Kill the child (and everything it started) and delete its temporary directory."""
        self._kill()

    # -- launching ---------------------------------------------------------------------------------
    def _blocked_locations(self, roots: Sequence[str]) -> list[tuple[str, Path]]:
        out = []
        for b in self.blocked:
            if b == "flowtrack" or b.startswith("flowtrack."):
                continue
            loc = _locate_module(b, roots)
            if loc is not None:
                out.append((b, loc))
        return out

    def _command(self) -> tuple[list[str], dict[str, str], dict[str, Any], Path]:
        self._uid = _sandbox_uid()
        # the cached copies are marked as used at every start (see "Cache" in the module docstring)
        runtime = _live(_python_runtime, self._uid is not None,
                        where=lambda r: Path(r.source) if r.lib_dir is not None else None)
        sites = _site_dirs()
        if self._uid is not None:
            sites = [d if _world_readable(Path(d)) else str(_mirror_site(Path(d))) for d in sites]
            unreadable = [d for d in sites if not _world_readable(Path(d))]
            if unreadable:
                raise RuntimeError(
                    f"the sandbox's unprivileged uid cannot read the Python packages in {unreadable[0]} "
                    "(a folder on the way is not readable by other users): make it readable, e.g. "
                    f"chmod -R a+rX {unreadable[0]} and chmod o+x on its parent folders"
                )
        ft_blocked = tuple(sorted(b for b in self.blocked if b.startswith("flowtrack.")))
        ft_root = _live(_filtered_flowtrack, ft_blocked)
        runner = _live(_runner_dir)
        workdir = Path(tempfile.mkdtemp(prefix="student-", dir=self._workdir_parent))
        # workdir/home is the student's HOME and cwd, workdir/tmp its /tmp: together the only places
        # it can write (measured as one tree, see Limits.disk_bytes).
        home, tmp = workdir / "home", workdir / "tmp"
        for d in (home, tmp):
            d.mkdir(mode=0o700)
            if self._uid is not None:
                os.chown(d, self._uid, self._uid)
        os.chmod(workdir, 0o711)
        env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1", "LANG": "C.UTF-8",
               "PATH": "/usr/bin:/bin"}
        stdlib = runtime.stdlib if self._mode == "fallback" else _python_runtime(False).stdlib
        roots = [*stdlib, *sites]
        blocked_locs = self._blocked_locations(roots)
        if self._mode == "bwrap":
            inner_sites = [f"{_OPT}/site/{i}" for i in range(len(sites))]
            cmd = _bwrap_base(shutil.which("bwrap") or "bwrap")
            cmd += ["--ro-bind", runtime.source, runtime.prefix]
            for src, dst in zip(sites, inner_sites):
                cmd += ["--ro-bind", src, dst]
                if (Path(src) / "flowtrack").exists():  # a non-editable install: hide the real one
                    cmd += ["--ro-bind", str(ft_root / "flowtrack"), f"{dst}/flowtrack"]
            cmd += ["--ro-bind", str(ft_root), f"{_OPT}/lib", "--ro-bind", str(runner), f"{_OPT}/bin"]
            for name, loc in blocked_locs:
                inner = str(loc)
                for src, dst in zip(sites, inner_sites):
                    if loc.is_relative_to(src):
                        inner = dst + "/" + str(loc.relative_to(src))
                stub = _stub_dir(name)
                cmd += ["--ro-bind", str(stub if loc.is_dir() else stub / "__init__.py"), inner]
            # The student's directory is the only writable place (HOME and /tmp; measured by the
            # grader, see Limits.disk_bytes); bubblewrap's own root and /dev are tmpfs in RAM that
            # no limit covers, so they are made read-only once everything is mounted.
            cmd += ["--bind", str(home), _SANDBOX_HOME, "--bind", str(tmp), "/tmp",
                    "--remount-ro", "/dev", "--remount-ro", "/", "--chdir", _SANDBOX_HOME, "--clearenv"]
            for k, v in {**env, "HOME": _SANDBOX_HOME, "TMPDIR": "/tmp"}.items():
                cmd += ["--setenv", k, v]
            exe = str(Path(runtime.prefix) / Path(runtime.executable).relative_to(runtime.source))
            cmd += [exe, "-I", "-S", "-B", f"{_OPT}/bin/_child.py"]
            init = {"paths": [f"{_OPT}/lib", *inner_sites], "deny_paths": [], "strict_audit": False}
        else:
            env.update(HOME=str(home), TMPDIR=str(tmp))
            if runtime.lib_dir:
                env["LD_LIBRARY_PATH"] = runtime.lib_dir
            deny = [str(_FLOWTRACK_DIR), str(self._cache / "ft"), str(self._cache / "stubs"),
                    *self.hidden_paths, *(str(loc) for _, loc in blocked_locs)]
            repo = _FLOWTRACK_DIR.parent.parent
            in_site = any(_FLOWTRACK_DIR.is_relative_to(s) for s in sites)
            if not in_site and (repo / "pyproject.toml").exists():
                deny.append(str(repo))
            cmd = [runtime.executable, "-I", "-S", "-B", str(runner / "_child.py")]
            init = {"paths": [str(ft_root), *sites], "deny_paths": deny, "strict_audit": True,
                    "write_root": str(workdir),
                    "allow_paths": [str(ft_root), *sites, *runtime.stdlib, str(runner)]}
        return cmd, env, init, workdir

    def _preexec(self, nproc_outer: int | None):
        lim = self.limits
        uid = self._uid
        cpu = math.ceil(lim.cpu_seconds) + 2  # + import of numpy and the cells

        def fn() -> None:
            rl = resource
            rl.setrlimit(rl.RLIMIT_CORE, (0, 0))
            rl.setrlimit(rl.RLIMIT_CPU, (cpu, self._cpu_ceiling))
            rl.setrlimit(rl.RLIMIT_AS, (lim.memory_bytes, lim.memory_bytes))
            rl.setrlimit(rl.RLIMIT_NOFILE, (lim.open_files, lim.open_files))
            rl.setrlimit(rl.RLIMIT_FSIZE, (lim.file_size, lim.file_size))
            if nproc_outer is not None:
                rl.setrlimit(rl.RLIMIT_NPROC, (nproc_outer, nproc_outer))
            _drop_to(uid)

        return fn

    def start(self, timeout: float | None = None) -> None:
        """Start the child and execute the cells (``run`` does this lazily); fills ``cell_errors``."""
        if self._proc is not None:
            return
        timeout = self.limits.wall_seconds if timeout is None else float(timeout)
        cmd, env, init, workdir = self._command()
        self._workdir = workdir
        r, w = os.pipe()
        os.set_inheritable(w, True)
        if self._uid is not None:
            nproc_outer = self.limits.processes  # a fresh uid: the count is the sandbox's own
            nproc_child = self.limits.processes
        elif self._mode == "bwrap":
            nproc_outer = None  # counted per user namespace once the child lowers it
            nproc_child = self.limits.processes
        else:
            nproc_outer = None
            nproc_child = _user_tasks() + self.limits.processes
        init.update(op="init", nproc=nproc_child, blocked=list(self.blocked), cells=self.cells)
        self._stderr = tempfile.TemporaryFile()
        try:
            self._proc = subprocess.Popen(
                [*cmd, str(w)], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._stderr,
                pass_fds=(w,), env=env, cwd=str(workdir / "home"), start_new_session=True,
                preexec_fn=self._preexec(nproc_outer),
            )
        finally:
            os.close(w)
        self._reply_fd = r
        self._cpu_used = 0.0
        deadline = time.monotonic() + timeout
        try:
            self._send(init, deadline)
            reply = self._recv(deadline, self.limits.output_bytes, timeout, starting=True)
        except _ChildGone:
            self._kill()
            raise
        errors = reply.get("cell_errors") if isinstance(reply, dict) else None
        if not isinstance(errors, dict) or reply.get("op") != "ready":
            self._kill()
            raise _ChildGone("the sandbox sent an invalid start-up reply")
        self.cell_errors = {str(k): str(v)[:2000] for k, v in errors.items() if isinstance(k, str)}

    # -- I/O -----------------------------------------------------------------------------------------
    def _send(self, msg: dict, deadline: float) -> None:
        data = json.dumps(msg, allow_nan=True).encode("utf-8")
        buf = memoryview(struct.pack(">I", len(data)) + data)
        assert self._proc is not None and self._proc.stdin is not None
        fd = self._proc.stdin.fileno()
        while buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise _ChildGone("timed out")
            _, writable, _ = select.select([], [fd], [], min(left, _DISK_POLL))
            self._check_disk()
            if not writable:
                continue
            try:
                n = os.write(fd, buf[: 1 << 16])
            except (BrokenPipeError, OSError):
                raise _ChildGone(self._death_message()) from None
            buf = buf[n:]

    def _read(self, n: int, deadline: float) -> bytes:
        chunks, got = [], 0
        while got < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise _ChildGone("timed out")
            readable, _, _ = select.select([self._reply_fd], [], [], min(left, _DISK_POLL))
            self._check_disk()
            if not readable:
                continue
            b = os.read(self._reply_fd, min(n - got, 1 << 20))
            if not b:
                raise _ChildGone(self._death_message())
            chunks.append(b)
            got += len(b)
        return b"".join(chunks)

    def _recv(self, deadline: float, budget: int, timeout: float, starting: bool = False) -> Any:
        try:
            (n,) = struct.unpack(">I", self._read(4, deadline))
            if n + 4 > budget:
                limit = self.limits.output_bytes
                raise _ChildGone(f"the result is larger than the output limit ({limit} bytes)")
            data = self._read(n, deadline)
        except _ChildGone as gone:
            msg = gone.args[0]
            if msg == "timed out":
                msg = f"timed out after {timeout:g} s"
            if starting:
                msg += " (while running the notebook cells)"
            raise _ChildGone(msg) from None
        self._budget_used = n + 4
        try:
            value = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            raise _ChildGone("the sandbox sent a reply that is not valid data") from None
        if not _plain(value):
            raise _ChildGone("the sandbox sent a reply that is not plain data")
        return value

    def _check_disk(self) -> None:
        """Raise _ChildGone when the child's directory holds more than the disk limits allow."""
        now = time.monotonic()
        if self._workdir is None or now < self._next_disk_check:
            return
        self._next_disk_check = now + _DISK_POLL
        lim = self.limits
        size, files = _tree_usage(self._workdir, lim.disk_files)
        if files > lim.disk_files:
            raise _ChildGone(f"created more than {lim.disk_files} files (the disk limit)")
        if size > lim.disk_bytes:
            raise _ChildGone(f"wrote more than {lim.disk_bytes} bytes to disk (the disk limit)")

    def _death_message(self) -> str:
        p = self._proc
        if p is None:
            return "the sandbox is not running"
        try:
            rc = p.wait(timeout=2)
        except subprocess.TimeoutExpired:
            return "the process closed its reply channel"
        sig = -rc if rc < 0 else (rc - 128 if self._mode == "bwrap" and 128 < rc < 160 else 0)
        if sig == signal.SIGXCPU:
            return f"used more than {self.limits.cpu_seconds:g} s of CPU time"
        if sig == signal.SIGXFSZ:
            return f"wrote a file larger than the limit ({self.limits.file_size} bytes)"
        if sig == signal.SIGKILL:
            return "was killed (it ran out of memory or exceeded a limit)"
        if sig:
            return f"crashed ({_signal_name(sig)})"
        tail = self._stderr_tail()
        if tail.startswith("bwrap:"):
            return f"the sandbox could not start: {tail}"
        return "the process exited (sys.exit / os._exit)" + (f" with status {rc}" if rc else "")

    def _stderr_tail(self) -> str:
        if self._stderr is None:
            return ""
        try:
            self._stderr.seek(0)
            return self._stderr.read(4096).decode(errors="replace").strip()[:300]
        except (OSError, ValueError):
            return ""

    # -- calls ---------------------------------------------------------------------------------------
    def run(self, calls: Sequence[Call], timeout: float | None = None) -> list[Outcome]:
        """Make ``calls`` in the child (starting it when needed); one :class:`Outcome` per call.

        Parameters
        ----------
        calls : sequence of Call
            The calls of one test; sent to the child together.
        timeout : float, optional
            Wall-clock seconds for the batch (default ``limits.wall_seconds``); the start of a
            fresh child (interpreter, numpy, the cells) gets its own budget of the same length.

        Returns
        -------
        list of Outcome
            ``ok=False`` with a message for calls that raised, returned something that is not plain
            data, or were not answered because the child crashed, timed out or exceeded a limit. In
            the last case the child is killed and the next ``run`` starts a fresh one.
        """
        calls = list(calls)
        if not all(isinstance(c, Call) for c in calls):
            raise TypeError("calls must be a sequence of Call")
        timeout = self.limits.wall_seconds if timeout is None else timeout
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not timeout > 0:
            raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
        wire = [{"function": c.function, "args": _to_wire(list(c.args)), "kwargs": _to_wire(dict(c.kwargs))}
                for c in calls]
        self.stdout = ""
        outcomes: list[Outcome] = []
        if not calls:
            return outcomes
        if self._proc is not None and self._cpu_used > self._cpu_ceiling - self.limits.cpu_seconds - 5:
            self._kill()  # its lifetime CPU budget is nearly spent: start afresh
        try:
            if self._proc is None:
                self.start(timeout)
            deadline = time.monotonic() + timeout
            self._send({"op": "calls", "calls": wire, "cpu": self.limits.cpu_seconds}, deadline)
            budget = self.limits.output_bytes
            printed = []
            for _ in calls:
                reply = self._recv(deadline, budget, timeout)
                budget -= self._budget_used
                if not isinstance(reply, dict) or type(reply.get("ok")) is not bool:
                    raise _ChildGone("the sandbox sent a reply that is not plain data")
                if isinstance(reply.get("printed"), str):
                    printed.append(reply["printed"])
                cpu = reply.get("cpu")
                if type(cpu) in (int, float):
                    self._cpu_used = max(self._cpu_used, float(cpu))
                if reply["ok"]:
                    outcomes.append(Outcome(ok=True, value=reply.get("value")))
                else:
                    err = reply.get("error")
                    outcomes.append(Outcome(ok=False, error=str(err)[:2000] if err else "the call failed"))
            self.stdout = "".join(printed)[:8192]
            self._next_disk_check = 0.0
            try:
                self._check_disk()
            except _ChildGone:
                self._kill()  # the answers stand; the next batch gets a fresh, empty directory
        except _ChildGone as gone:
            self._kill()
            msg = str(gone.args[0])
            outcomes += [Outcome(ok=False, error=msg) for _ in range(len(calls) - len(outcomes))]
        return outcomes

    # -- teardown ------------------------------------------------------------------------------------
    def _kill(self) -> None:
        p, self._proc = self._proc, None
        if p is not None:
            # Kill bubblewrap's children first (the pid namespace's init: its death kills the whole
            # namespace) so that bubblewrap reaps them; killing bubblewrap first leaves zombies for
            # whatever init the machine has.
            try:
                kids = Path(f"/proc/{p.pid}/task/{p.pid}/children").read_text().split()
            except OSError:
                kids = []
            for kid in kids:
                try:
                    os.kill(int(kid), signal.SIGKILL)
                except (ProcessLookupError, PermissionError, ValueError):
                    pass
            if kids:
                try:
                    p.wait(timeout=2)
                except subprocess.TimeoutExpired:
                    pass
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            try:
                p.kill()
            except ProcessLookupError:
                pass
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:  # pragma: no cover
                pass
            if p.stdin is not None:
                try:
                    p.stdin.close()
                except OSError:
                    pass
        if self._uid is not None and p is not None:
            _kill_uid(self._uid)
        if self._reply_fd is not None:
            os.close(self._reply_fd)
            self._reply_fd = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        if self._workdir is not None:
            _rmtree(self._workdir)
            self._workdir = None


def _kill_uid(uid: int) -> None:
    """SIGKILL every process of ``uid`` (a per-sandbox uid: only this student's processes)."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        try:
            _drop_to(uid)
            for _ in range(50):  # repeated: a fork bomb may be forking while we kill
                os.kill(-1, signal.SIGKILL)
                time.sleep(0.001)
        except BaseException:
            pass
        os._exit(0)
    os.waitpid(pid, 0)
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and _uid_has_processes(uid):
        time.sleep(0.02)


def _uid_has_processes(uid: int) -> bool:
    """True while a live (not zombie) process of ``uid`` exists."""
    for p in Path("/proc").glob("[0-9]*"):
        try:
            if p.stat().st_uid == uid and (p / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                return True
        except (OSError, IndexError):
            continue
    return False


def _tree_usage(root: Path, max_entries: int) -> tuple[int, int]:
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


def _rmtree(path: Path) -> None:
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
