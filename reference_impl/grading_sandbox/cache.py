"""The sandbox cache: prepared copies kept between runs, built atomically, pruned when stale.

What the sandbox reads is prepared once and kept in ``<tmp>/<NAME>-<uid>/`` (:data:`.config.NAME`;
``<tmp>`` is the folder the variable :data:`.config.ENV_CACHE` names if set, else the temporary
directory, or ``/tmp`` when root's temporary directory is private), a directory of this uid that
nobody else can write: ``pkg/<key>`` filtered copies of the exposed packages, ``python/<key>`` the
mirrored runtime and ``site/<key>`` mirrored site-packages (root only), ``bin/<key>`` the runner,
``stubs/`` the stubs of blocked packages and ``work/`` the students' temporary directories. A copy's
``key`` is a fingerprint of what it was made from, so an upgrade of an exposed package or of the
Python packages makes new copies. Each start of a child sets the mtime
of the copies it uses to now (under a shared ``flock`` of ``<kind>/.lock``). Whenever a new copy of
``pkg``, ``python``, ``site`` or ``bin`` is created, the other copies of that kind whose mtime is more
than a day old (:data:`PRUNE_AFTER`) are removed, under the exclusive lock: renamed out of the way, then
deleted without following symlinks. A copy in use was touched when its child started, minutes ago at
most (in the grader a child serves one student's tests), so it is never that old; one removed while a
process still remembered it is rebuilt at that process's next start. ``stubs`` (one per blocked
package, not versioned) and ``work`` are not pruned.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import shutil
import stat
import tempfile
import time
from pathlib import Path

from . import config

__all__ = ["PRUNE_AFTER", "atomic_dir", "cache_root", "link_or_copy", "live_copy", "mark_used", "prune_stale",
           "world_readable"]

# A cached copy (filtered packages, mirrored runtime or site-packages, runner) not used for this long
# is removed when a newer copy of its kind is made. Far longer than a child lives (minutes), short
# enough that upgrades do not pile up copies.
PRUNE_AFTER = 24 * 3600.0
# What the cache's kind directories hold: fingerprints, builds in progress (or crashed) and copies
# being deleted; anything else is left alone.
_CACHE_ENTRY = re.compile(r"[0-9a-f]{16,64}|\.build-[^/]+|\.trash-[^/]+")


def cache_root() -> Path:
    """The sandbox cache folder ``<NAME>-<uid>`` (created, mode 0755, with its sub-folders) under the
    folder :data:`.config.ENV_CACHE` names, else the temporary directory (a shared one when root's
    own is not reachable by the sandbox's uid).

    Raises
    ------
    RuntimeError
        The folder exists but is not a private directory of this user.
    FileNotFoundError
        :data:`.config.ENV_CACHE` names a folder that does not exist (said with the variable's name).
    """
    explicit = config.env(config.ENV_CACHE)
    base = Path(explicit or tempfile.gettempdir())
    if explicit and not base.is_dir():
        raise FileNotFoundError(
            f"{config.ENV_CACHE}={explicit}: no such folder; create it (mkdir -p) or unset the variable "
            "to use the temporary directory"
        )
    if os.geteuid() == 0 and not explicit and not world_readable(base, read=False):
        # root with a private TMPDIR (e.g. /root/tmp): the sandbox's unprivileged uid could not
        # reach its files there; use the machine's shared temporary directory instead.
        shared = [Path(d) for d in ("/tmp", "/var/tmp") if world_readable(Path(d), read=False)]
        base = shared[0] if shared else base
    root = base / f"{config.NAME}-{os.geteuid()}"
    try:
        root.mkdir(mode=0o755)
    except FileExistsError:
        pass
    st = os.lstat(root)
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid() or st.st_mode & 0o022:
        raise RuntimeError(f"the sandbox cache {root} is not a private directory of this user")
    os.chmod(root, 0o755)
    for sub in ("work", "pkg", "stubs", "python", "bin", "site"):
        d = root / sub
        d.mkdir(mode=0o755, exist_ok=True)
        os.chmod(d, 0o711 if sub == "work" else 0o755)
    return root


def world_readable(path: Path, read: bool = True) -> bool:
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


def atomic_dir(final: Path, build, *, prune: bool = False) -> Path:
    """Build a directory with ``build(tmp)`` and rename it into place (first writer wins).

    An existing ``final`` is only marked as used (:func:`mark_used`). With ``prune``, making a new
    ``final`` also removes its kind's stale copies (:func:`prune_stale`).
    """
    if mark_used(final):
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
        prune_stale(final.parent, keep=final.name)
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


def mark_used(copy: Path) -> bool:
    """Set the mtime of the cached ``copy`` to now; False when it does not exist (not built yet, or
    pruned since a caller remembered it).

    Done under the shared lock of its kind, so a concurrent :func:`prune_stale` either sees the new
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


def live_copy(make, *args, where=lambda path: path):
    """``make(*args)``, an lru-cached maker of a cached copy, with the copy (``where(value)``, None for
    no copy) marked as used; made afresh when the copy it remembered is gone (pruned meanwhile)."""
    value = make(*args)
    path = where(value)
    if path is not None and not mark_used(path):
        make.cache_clear()
        value = make(*args)
    return value


def prune_stale(kind_dir: Path, keep: str, max_age: float = PRUNE_AFTER) -> list[str]:
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


def link_or_copy(src: Path, dst: Path) -> None:
    """Hard-link ``src`` to ``dst`` when others may read it, else copy it (mode 0755 if ``src`` is
    executable, else 0644).

    A hard link shares the file's inode and so its mode: a file made under ``umask 077`` (a virtual
    environment created by root with a private umask) would stay unreadable to the sandbox's uid
    through its link, so it is copied instead."""
    mode = os.stat(src).st_mode
    executable = bool(mode & stat.S_IXUSR)
    if mode & stat.S_IROTH and (not executable or mode & stat.S_IXOTH):
        try:
            os.link(src, dst)
            return
        except OSError:
            pass
    shutil.copy2(src, dst)
    os.chmod(dst, 0o755 if executable else 0o644)

