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
   ``/usr`` (and the ``/lib*`` links), the Python runtime, the packages of the exercise's
   allowlist (``allowed``: e.g. numpy and scipy and nothing else of the environment; without an
   allowlist the virtual environment's site-packages and a *filtered copy* of flowtrack, blocked
   modules replaced by stubs that raise ``ImportError``) and the runner. Two tmpfs of
   ``Limits.disk_bytes`` each, HOME (the cwd) and ``/tmp``, are the only writable places: the
   kernel bounds their size, they vanish with the sandbox, and the grader reads their use with
   ``statvfs`` (bytes and files, ``disk_bytes``/``disk_files``); bubblewrap's own root and ``/dev``
   (tmpfs, i.e. RAM) are remounted read-only, so neither the disk nor the RAM of the machine can
   be filled. Nothing of the course (repository, exercises, solutions, grader output, gradebook) exists
   inside. Blocked third-party packages (e.g. ``scipy.optimize``) have a stub directory bound over
   them, so even loading their files by path fails. No network interfaces but loopback of the new
   namespace (so no connection to the host). When the grader runs as root it switches, before
   starting bubblewrap, to a per-sandbox unprivileged uid (RLIMIT_NPROC is then enforced and
   private to this student); a Python runtime that uid cannot read (e.g. pyenv under ``/root``) is
   mirrored once, by hard links, into a world-readable cache.
3. **Resource limits**: a cgroup per sandbox where one can be made (:mod:`flowtrack_course.grading.cgroups`:
   memory of all its processes together, memfd, shared memory and its tmpfs included, and
   processes), and ``setrlimit`` before exec (RLIMIT_NPROC also in the child): CPU time,
   address space (memory bombs fail with MemoryError), processes (fork bombs), open files, file
   size, no core files; the grader enforces a wall-clock timeout per batch and output size per
   batch, and on any violation kills the whole sandbox (process group; bubblewrap's pid namespace;
   as root also every process of the sandbox uid), so nothing outlives it. A seccomp filter
   (:mod:`flowtrack_course.grading.seccomp`, every mode) refuses ``memfd_create``, System V shared
   memory and IPC and a few kernel interfaces no exercise needs: memory that is in no process's
   RLIMIT_AS cannot be had even where no cgroup can be made.
4. **Inside the child** (a second line, never the only one): a ``sys.meta_path`` blocker and an
   audit hook refusing blocked imports, imports outside the allowlist (with a message naming it)
   and opening protected paths; fd 1/2 point at /dev/null and
   ``print`` goes to a capped buffer, so student output cannot mix with replies.

setpriv (``isolation == "setpriv"``): where bubblewrap cannot create namespaces (Docker's default
seccomp profile: a Gradescope container) and the grader is root, the child is started through
util-linux's ``setpriv`` as a fresh unprivileged uid of its own (group of the same number, no
supplementary groups, empty capability sets, ``no_new_privs``), with the fallback's limits, folder
and in-process guard on top. What protects the grader is then the kernel's permission checks, so
the key, the tests, the submissions and the grader's output must not be readable by other users:
``flowtrack grade`` and the Gradescope runner check that for real
(:func:`~flowtrack_course.grading.isolation.readable_by_sandbox`) and refuse to grade otherwise; the
Gradescope ``setup.sh``/``run_autograder`` set the modes. The uid cannot signal or ptrace the grader
(another uid), cannot write anywhere but its folder and the machine's world-writable folders, whose
entries of its uid are counted against the disk limit and removed with the sandbox. Unlike
bubblewrap it can see the machine's other world-readable files and its network.
``FLOWTRACK_SANDBOX=setpriv`` forces it; ``FLOWTRACK_BWRAP`` names the bubblewrap binary (tests point
it at a failing stub to run as Gradescope does).

Zygotes (:class:`SandboxPool`, what ``flowtrack grade`` uses): starting a sandboxed interpreter and
numpy costs ~0.3 s, more than most exercises take. A pool keeps one sandbox per kind of exercise
(:attr:`Sandbox.key`: the same file system view, limits and hidden paths) whose process, the zygote,
imported numpy and the allowlists' modules of its view (under the children's import rule: nothing
blocked, nothing outside the allowlist, is ever imported there) before any student
code existed, and forks a child per exercise that installs that exercise's import guard and audit
hook and runs its cells: each exercise starts from the same clean state as a fresh sandbox, and
scores the same. The zygote never reads student data (each child reads its cells and calls from
pipes of its own, passed over a control socket), is not dumpable (its children cannot ptrace it or
open its memory), and after each child it kills every other process of the sandbox, checks that
none survived, and empties HOME and ``/tmp``; a child that crashes or exceeds a limit takes the
zygote down with it, and the next exercise starts a new sandbox. In ``flowtrack grade`` a worker's
zygotes serve its students one after the other. A child per exercise, not one per student: a fork
and the clean-up after it cost about 1 to 10 ms of CPU (the more the zygote imported), some 5 % of
grading a student, and they keep each exercise's import guard, namespace and limits its own (a
crash, ``sys.exit`` or a monkeypatched numpy in one exercise cannot change another one's score).

Fallback (``isolation == "fallback: <why>"``): when bubblewrap is missing or namespaces are not
allowed (a student's laptop running ``flowtrack check``), the child is a plain subprocess with the
same limits, an empty temporary cwd, ``-I -S``, the filtered flowtrack copy, and (as root) a
per-sandbox uid; its folder on the host is measured by walking it with directory descriptors
(deleted files still open counted). The audit hook additionally refuses the repository, the real
flowtrack sources, blocked packages and those outside the allowlist, ``hidden_paths`` (``flowtrack
grade`` passes the submissions, its output folder and the key file), sockets and process spawning.
This is best effort: a determined student can get around an in-process hook (e.g. through ctypes),
which is why ``flowtrack grade`` refuses the fallback unless ``--allow-unsafe-sandbox`` is given
(``flowtrack check``, a student's own run, falls back with a warning).
``FLOWTRACK_SANDBOX=fallback`` forces the fallback, ``FLOWTRACK_SANDBOX=bwrap`` requires bubblewrap;
unset, the sandbox uses bubblewrap, else setpriv (as root), else the fallback.

The prepared copies the sandbox reads are kept between runs in a cache
(:mod:`flowtrack_course.grading.cache`); :mod:`flowtrack_course.grading.runtime` makes them,
:mod:`flowtrack_course.grading.isolation` starts and ends the
child's isolation, :mod:`flowtrack_course.grading.wire` encodes the data both ways.
"""

from __future__ import annotations

import json
import math
import os
import resource
import select
import signal
import socket
import struct
import subprocess
import tempfile
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .cache import cache_root, live_copy, world_readable
from .cgroups import SandboxCgroup
from .isolation import (
    WORLD_WRITABLE,
    SandboxUnavailable,
    bwrap_base,
    bwrap_path,
    bwrap_status,
    choose_mode,
    descendants,
    drop_to,
    kill_uid,
    mount_usage,
    remove_tree,
    sandbox_uid,
    setpriv_command,
    signal_name,
    tree_usage,
    uid_litter,
    unlinked_bytes,
    user_tasks,
)
from .runtime import (
    FLOWTRACK_DIR,
    allowed_packages,
    filtered_flowtrack,
    locate_module,
    mirror_site,
    package_entries,
    python_runtime,
    runner_dir,
    site_dirs,
    stub_dir,
)
from .seccomp import preexec_installer, seccomp_status
from .seccomp import program as seccomp_program
from .spec import Call, Outcome
from .wire import is_plain, to_wire

__all__ = ["Limits", "Sandbox", "SandboxPool", "SandboxUnavailable", "bwrap_status"]

GiB = 1 << 30
MiB = 1 << 20
_SANDBOX_HOME = "/home/student"
_OPT = "/opt/flowtrack-sandbox"
_DISK_POLL = 0.2  # seconds between measurements of the child's directory while waiting for it
_ZYGOTE_FORKS = 256  # exercises a zygote serves before it is replaced (bounds its own CPU time)


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
        0.5 GiB. Where the sandbox gets a cgroup (:mod:`flowtrack_course.grading.cgroups`), everything its
        processes hold together (forked children, memfd and shared memory, its tmpfs) is bounded
        by ``memory_bytes + 2 * disk_bytes``; otherwise only per process, and the seccomp filter
        (:mod:`flowtrack_course.grading.seccomp`) refuses memfd and System V shared memory, which no
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
        :data:`~flowtrack_course.grading.isolation.MAX_TREE_DEPTH` is a violation) while it waits for
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
    allowed : sequence of str, optional
        An allowlist of what the student may import besides the standard library (``"numpy"``,
        ``"scipy.linalg"``). Under bubblewrap only the packages it needs
        (:func:`~flowtrack_course.grading.runtime.allowed_packages`: ``scipy.linalg`` needs ``scipy`` and
        ``numpy``) are in the sandbox at all; the child refuses importing any other package with a
        message naming the allowlist, and the fallback's audit hook refuses the files of the others.
        Within an allowed package the granularity is the top-level package (``blocked`` still
        removes submodules). ``None`` (default): everything installed, minus ``blocked``.
    zygote : bool
        Keep the sandboxed process between exercises and fork a child per exercise (:meth:`prepare`,
        :meth:`finish`; see "Zygotes" above). Ignored in the fallback without root.
    preload : sequence of str
        Modules a zygote imports before forking (those of packages in its view; what the exercise's
        child could not import is refused there too).
    spawn : bool
        The exercise's own (trusted) code starts programs: an answer in another language
        (:mod:`flowtrack_course.grading.languages`) is compiled and run by the child. Outside
        bubblewrap the in-process audit hook then lets the child start processes and signal them;
        those run as the sandbox's uid (setpriv) with the same resource limits, beyond the hook's
        reach (the fallback is no boundary for them: ``flowtrack grade`` refuses it unless told).

    Attributes
    ----------
    cell_errors : dict of str to str
        ``grade_id -> error text`` of cells that raised when executed (known after the first start).
    isolation : str
        ``"bwrap"``, ``"setpriv"`` or ``"fallback: <why>"``.
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
        allowed: Sequence[str] | None = None,
        zygote: bool = False,
        preload: Sequence[str] = (),
        spawn: bool = False,
    ) -> None:
        self._configure(cells, blocked, allowed, spawn)
        if not isinstance(limits, Limits):
            raise TypeError("limits must be a Limits")
        self.limits = limits
        self.hidden_paths = tuple(str(Path(p).resolve()) for p in hidden_paths)
        self.cell_errors: dict[str, str] = {}
        self.stdout = ""
        self._mode, why = choose_mode()
        self.isolation = self._mode if self._mode in ("bwrap", "setpriv") else f"fallback: {why}"
        # a zygote needs a sandbox whose every process may be killed at once: bubblewrap's pid
        # namespace, or a per-sandbox uid (root); never the grader's own uid
        self._zygote = bool(zygote) and (self._mode == "bwrap" or os.geteuid() == 0)
        self._child_live = False
        self._nproc_child: int | None = None
        self._preload = tuple(preload)
        self._forks = 0  # exercises the current zygote has served
        self._inits: dict[tuple, dict] = {}  # the init messages made for the current zygote, by view
        self._init_common(workdir_parent)

    def _configure(self, cells, blocked, allowed, spawn=False) -> None:
        """Validate and set the cells, blocked modules, allowlist and ``spawn`` of the (next) exercise."""
        self.spawn = bool(spawn)
        if isinstance(cells, str | bytes) or not all(
            isinstance(c, tuple | list) and len(c) == 2 and all(isinstance(s, str) for s in c) for c in cells
        ):
            raise TypeError("cells must be a sequence of (grade_id, source) pairs of str")
        if isinstance(blocked, str) or not all(
            isinstance(b, str) and b and all(p.isidentifier() for p in b.split(".")) for b in blocked
        ):
            raise TypeError("blocked must be a sequence of dotted module names such as 'scipy.optimize'")
        self.cells = [(str(g), str(s)) for g, s in cells]
        self.blocked = tuple(dict.fromkeys([*blocked, "flowtrack_course"]))  # the tooling, blocked whole
        if allowed is not None and (isinstance(allowed, str) or not all(
            isinstance(a, str) and a and all(p.isidentifier() for p in a.split(".")) for a in allowed
        )):
            raise TypeError("allowed must be a sequence of dotted module names such as 'scipy.linalg'")
        self.allowed = None if allowed is None else tuple(dict.fromkeys(["numpy", *allowed]))
        self._packages = None if self.allowed is None else allowed_packages(self.allowed)

    @property
    def key(self) -> tuple:
        """What the sandbox's process depends on (its file system view under bubblewrap, its limits):
        exercises with equal keys can share one zygote (:class:`SandboxPool`)."""
        pk = self._packages
        view_blocked = tuple(sorted(b for b in self.blocked if pk is None or b.split(".")[0] in pk))
        return (self._mode, pk, view_blocked, self.limits, self.hidden_paths, str(self._workdir_parent))

    def _init_common(self, workdir_parent) -> None:
        self._cache = cache_root()
        self._workdir_parent = Path(workdir_parent) if workdir_parent is not None else self._cache / "work"
        if not self._workdir_parent.is_dir():
            raise ValueError(f"workdir_parent {self._workdir_parent} is not a directory")
        self._uid: int | None = None  # a fresh unprivileged uid per child when grading as root
        if os.geteuid() == 0 and not world_readable(self._workdir_parent, read=False):
            raise ValueError(
                f"workdir_parent {self._workdir_parent} must be traversable by other users when "
                "grading as root (the sandbox runs as an unprivileged uid)"
            )
        self._proc: subprocess.Popen | None = None
        self._reply_fd: int | None = None
        self._req_fd: int | None = None  # where requests go: the child's stdin, or its pipe from a zygote
        self._ctl: socket.socket | None = None  # a zygote's control socket
        self._stderr = None
        self._workdir: Path | None = None
        self._cgroup: SandboxCgroup | None = None
        self.cgroup = ""  # "v2" or "v1" when the running child has a cgroup of its own
        self.seccomp = False  # True when the running child has the seccomp filter (grading.seccomp)
        self.cleanup_problems: list[str] = []
        self._next_disk_check = 0.0
        self._cpu_used = 0.0
        self._cpu_ceiling = int(10 * self.limits.cpu_seconds + 60)

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
            loc = locate_module(b, roots)
            if loc is not None:
                out.append((b, loc))
        return out

    def _command(self, launch: bool = True) -> tuple[list[str], dict[str, str], dict[str, Any], Path]:
        """The command, environment, init message and folder of a new child (``launch``), or only the
        init message of the next exercise in a running zygote (``launch=False``)."""
        if launch:
            self._uid = sandbox_uid()
        # the cached copies are marked as used at every start (see "Cache" in the module docstring)
        runtime = live_copy(python_runtime, self._uid is not None,
                        where=lambda r: Path(r.source) if r.lib_dir is not None else None)
        sites = site_dirs()
        if self._uid is not None:
            sites = [d if world_readable(Path(d)) else str(mirror_site(Path(d))) for d in sites]
            unreadable = [d for d in sites if not world_readable(Path(d))]
            if unreadable:
                raise RuntimeError(
                    f"the sandbox's unprivileged uid cannot read the Python packages in {unreadable[0]} "
                    "(a folder on the way is not readable by other users): make it readable, e.g. "
                    f"chmod -R a+rX {unreadable[0]} and chmod o+x on its parent folders"
                )
        ft_blocked = tuple(sorted(b for b in self.blocked if b.startswith("flowtrack.")))
        ft_root = live_copy(filtered_flowtrack, ft_blocked)
        with_flowtrack = self._packages is None or "flowtrack" in self._packages
        runner = live_copy(runner_dir)
        if not launch:
            assert self._workdir is not None
            workdir = self._workdir
        else:
            workdir = Path(tempfile.mkdtemp(prefix="student-", dir=self._workdir_parent))
        # The fallback's only writable places: workdir/home (HOME and cwd) and workdir/tmp (TMPDIR),
        # measured as one tree (see Limits.disk_bytes). Under bubblewrap they stay empty (the
        # student writes to a tmpfs inside the sandbox) and workdir/home is only bubblewrap's cwd.
        home, tmp = workdir / "home", workdir / "tmp"
        for d in (home, tmp) if launch else ():
            d.mkdir(mode=0o700)
            if self._uid is not None:
                os.chown(d, self._uid, self._uid)
        if launch:
            os.chmod(workdir, 0o711)
        env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1", "LANG": "C.UTF-8",
               "PATH": "/usr/bin:/bin"}
        stdlib = runtime.stdlib if self._mode == "fallback" else python_runtime(False).stdlib
        roots = [*stdlib, *sites]
        blocked_locs = self._blocked_locations(roots)
        if self._mode == "bwrap":
            inner_sites = [f"{_OPT}/site/{i}" for i in range(len(sites))]
            cmd = bwrap_base(bwrap_path() or "bwrap")
            cmd += ["--ro-bind", runtime.source, runtime.prefix]
            for src, dst in zip(sites, inner_sites):
                if self._packages is not None:  # only what the allowlist needs
                    cmd += ["--dir", dst]
                    for entry in package_entries(src, self._packages):
                        cmd += ["--ro-bind", f"{src}/{entry}", f"{dst}/{entry}"]
                    continue
                cmd += ["--ro-bind", src, dst]
                if (Path(src) / "flowtrack").exists():  # a non-editable install: hide the real one
                    cmd += ["--ro-bind", str(ft_root / "flowtrack"), f"{dst}/flowtrack"]
            if with_flowtrack:
                cmd += ["--ro-bind", str(ft_root), f"{_OPT}/lib"]
            cmd += ["--ro-bind", str(runner), f"{_OPT}/bin"]
            for name, loc in blocked_locs:
                if self._packages is not None and name.split(".")[0] not in self._packages:
                    continue  # not in the sandbox at all
                inner = str(loc)
                for src, dst in zip(sites, inner_sites):
                    if loc.is_relative_to(src):
                        inner = dst + "/" + str(loc.relative_to(src))
                stub = stub_dir(name)
                cmd += ["--ro-bind", str(stub if loc.is_dir() else stub / "__init__.py"), inner]
            # The only writable places are two tmpfs, HOME and /tmp, each of Limits.disk_bytes: the
            # kernel bounds their size (unlinked files included), the grader's meter their sum.
            # They live in the sandbox's mount namespace (in its cgroup's memory when there is one)
            # and vanish with it: nothing a student writes reaches a disk of the host. bubblewrap's
            # own root and /dev are unbounded tmpfs, so they are made read-only once all is mounted.
            size = str(int(self.limits.disk_bytes))
            cmd += ["--size", size, "--tmpfs", _SANDBOX_HOME, "--size", size, "--tmpfs", "/tmp",
                    "--remount-ro", "/dev", "--remount-ro", "/", "--chdir", _SANDBOX_HOME, "--clearenv"]
            for k, v in {**env, "HOME": _SANDBOX_HOME, "TMPDIR": "/tmp"}.items():
                cmd += ["--setenv", k, v]
            exe = str(Path(runtime.prefix) / Path(runtime.executable).relative_to(runtime.source))
            cmd += [exe, "-I", "-S", "-B", f"{_OPT}/bin/_child.py"]
            init = {"paths": [f"{_OPT}/lib"] * with_flowtrack + inner_sites, "deny_paths": [],
                    "strict_audit": False}
        else:
            env.update(HOME=str(home), TMPDIR=str(tmp))
            if runtime.lib_dir:
                env["LD_LIBRARY_PATH"] = runtime.lib_dir
            deny = [str(FLOWTRACK_DIR), str(self._cache / "ft"), str(self._cache / "stubs"),
                    *self.hidden_paths, *(str(loc) for _, loc in blocked_locs)]
            if self._packages is not None:  # the packages the allowlist does not need
                for site in sites:
                    keep = set(package_entries(site, self._packages))
                    deny += [os.path.join(site, e) for e in sorted(os.listdir(site)) if e not in keep]
            repo = FLOWTRACK_DIR.parent.parent
            in_site = any(FLOWTRACK_DIR.is_relative_to(s) for s in sites)
            if not in_site and (repo / "pyproject.toml").exists():
                deny.append(str(repo))
            cmd = [runtime.executable, "-I", "-S", "-B", str(runner / "_child.py")]
            if self._mode == "setpriv":  # the uid switch, capabilities and no_new_privs: see setpriv_command
                assert self._uid is not None
                cmd = [*setpriv_command(self._uid), *cmd]
            init = {"paths": [str(ft_root)] * with_flowtrack + sites, "deny_paths": deny,
                    "strict_audit": True,
                    "write_root": str(workdir),
                    "allow_paths": [str(ft_root), *sites, *runtime.stdlib, str(runner)]}
        if self._packages is not None:
            init["allowed"] = list(self._packages)
            init["allowed_text"] = ", ".join(self.allowed or ())
        return cmd, env, init, workdir

    def _cgroup_memory(self) -> int:
        """What the sandbox's cgroup may hold: ``memory_bytes`` plus its two tmpfs of ``disk_bytes``."""
        return int(self.limits.memory_bytes + 2 * self.limits.disk_bytes)

    def _preexec(self, nproc_outer: int | None, seccomp=None):
        lim = self.limits
        uid = self._uid
        cgroup = self._cgroup
        via_setpriv = self._mode == "setpriv"
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
            if cgroup is not None:
                cgroup.enter()
            if seccomp is not None:  # the setpriv mode and the fallback (bubblewrap loads it itself)
                seccomp()
            if not via_setpriv:
                drop_to(uid)

        return fn

    def start(self, timeout: float | None = None) -> None:
        """Start the child and execute the cells (``run`` does this lazily); fills ``cell_errors``.

        With ``zygote=True`` the sandbox's process is started once (it imports numpy) and each
        exercise (:meth:`prepare`, :meth:`finish`) runs in a child it forks.
        """
        if self._child_live:
            return
        timeout = self.limits.wall_seconds if timeout is None else float(timeout)
        view = (self.blocked, self.allowed)
        if self._proc is None:
            cmd, env, init, workdir = self._command()
            self._launch(cmd, env, init, workdir, timeout)
            self._inits = {view: init}
        elif view in self._inits:  # a zygote's next exercise of an allowlist it served already
            init = self._inits[view]
        else:
            init = self._inits[view] = self._command(launch=False)[2]
        init = dict(init)
        init.update(op="init", nproc=self._nproc_child, blocked=list(self.blocked), cells=self.cells,
                    allow_spawn=self.spawn)
        self._cpu_used = 0.0
        deadline = time.monotonic() + timeout
        try:
            if self._zygote:
                self._forks += 1
                self._fork_child()
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
        self._child_live = True

    def _launch(self, cmd: list[str], env: dict[str, str], init: dict, workdir: Path, timeout: float) -> None:
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
            nproc_child = user_tasks() + self.limits.processes
        self._nproc_child = nproc_child
        # bubblewrap's two processes (and a zygote) come on top of the student's
        self._cgroup = SandboxCgroup.create(self._cgroup_memory(), self.limits.processes + 5)
        self.cgroup = self._cgroup.kind if self._cgroup is not None else ""
        self._stderr = tempfile.TemporaryFile()
        ctl_child = None
        ctl_fd = -1
        if self._zygote:
            self._ctl, ctl_child = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
            ctl_fd = ctl_child.fileno()
        # The seccomp filter (memfd, System V IPC, ... refused: see grading.seccomp): bubblewrap loads
        # it from a pipe (--seccomp FD) right before it executes the child; otherwise preexec_fn does.
        self.seccomp, _ = seccomp_status()
        install, filter_fd = None, None
        if self.seccomp and self._mode == "bwrap":
            filter_fd, fw = os.pipe()
            with os.fdopen(fw, "wb") as fh:
                fh.write(seccomp_program())
            cmd = [cmd[0], "--seccomp", str(filter_fd), *cmd[1:]]
        elif self.seccomp:
            install = preexec_installer()
        fds = (w,) if ctl_child is None else (w, ctl_child.fileno())
        try:
            self._proc = subprocess.Popen(
                [*cmd, str(w)], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._stderr,
                pass_fds=fds if filter_fd is None else (*fds, filter_fd), env=env,
                cwd=str(workdir / "home"), start_new_session=True,
                preexec_fn=self._preexec(nproc_outer, install),
            )
        finally:
            os.close(w)
            if filter_fd is not None:
                os.close(filter_fd)
            if ctl_child is not None:
                ctl_child.close()
        self._reply_fd = r
        self._forks = 0
        assert self._proc.stdin is not None
        self._req_fd = self._proc.stdin.fileno()
        if not self._zygote:
            return
        if self._mode == "bwrap":
            wipe, litter = [_SANDBOX_HOME, "/tmp"], []
        else:
            wipe, litter = [str(workdir / "home"), str(workdir / "tmp")], list(WORLD_WRITABLE)
        deadline = time.monotonic() + timeout
        try:
            in_view = self._packages or ()
            preload = [m for m in self._preload if m.split(".")[0] in in_view]
            # the zygote preloads under the children's import rule (blocked modules, allowlist); the
            # exercises sharing it have the same view (Sandbox.key) and hence the same rule there
            self._send({"op": "zygote", "paths": init["paths"], "nproc": nproc_child, "preload": preload,
                        "blocked": list(self.blocked), "allowed": init.get("allowed"),
                        "control": ctl_fd, "wipe": wipe, "litter": litter}, deadline)
            reply = self._recv(deadline, 1024, timeout, starting=True)
        except _ChildGone:
            self._kill()
            raise
        if not (isinstance(reply, dict) and reply.get("op") == "zygote-ready"):
            self._kill()
            raise _ChildGone("the sandbox sent an invalid start-up reply")
        os.close(self._reply_fd)  # from now on each exercise's child gets pipes of its own
        self._reply_fd = self._req_fd = None

    def _fork_child(self) -> None:
        """Ask the zygote for a child with a fresh pair of pipes (passed over the control socket)."""
        assert self._ctl is not None
        self._close_child_pipes()
        req_r, req_w = os.pipe()
        rep_r, rep_w = os.pipe()
        try:
            socket.send_fds(self._ctl, [b"fork"], [req_r, rep_w])
        except OSError:
            for fd in (req_r, req_w, rep_r, rep_w):
                os.close(fd)
            raise _ChildGone(self._death_message()) from None
        finally:
            pass
        os.close(req_r)
        os.close(rep_w)
        self._req_fd, self._reply_fd = req_w, rep_r

    def _close_child_pipes(self) -> None:
        if self._ctl is None or self._proc is None or self._req_fd == self._proc.stdin.fileno():
            return
        for name in ("_req_fd", "_reply_fd"):
            fd = getattr(self, name)
            if fd is not None:
                os.close(fd)
                setattr(self, name, None)

    # -- I/O -----------------------------------------------------------------------------------------
    def _send(self, msg: dict, deadline: float) -> None:
        data = json.dumps(msg, allow_nan=True).encode("utf-8")
        buf = memoryview(struct.pack(">I", len(data)) + data)
        assert self._proc is not None and self._req_fd is not None
        fd = self._req_fd
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
        if not is_plain(value):
            raise _ChildGone("the sandbox sent a reply that is not plain data")
        return value

    def _check_disk(self) -> None:
        """Raise _ChildGone when the child holds more than the disk limits allow.

        Under bubblewrap the kernel bounds the bytes (a tmpfs of ``disk_bytes``); its entries are
        read with ``statvfs`` through the sandbox's ``/proc/<pid>/root``. In the fallback the
        directory is walked with descriptors (what cannot be walked is a violation) and the
        deleted-but-open files of the child's processes are added.
        """
        now = time.monotonic()
        if self._workdir is None or self._proc is None or now < self._next_disk_check:
            return
        self._next_disk_check = now + _DISK_POLL
        lim = self.limits
        if self._mode == "bwrap":
            # bubblewrap's init, its only child (read directly: this runs after every batch)
            bw = self._proc.pid
            try:
                init_pid = Path(f"/proc/{bw}/task/{bw}/children").read_text().split()[:1]
            except OSError:
                init_pid = []
            usages = [mount_usage(int(pid), path) for pid in init_pid for path in (_SANDBOX_HOME, "/tmp")]
            if len(usages) < 2 or None in usages:
                return  # not mounted yet, or already gone; the kernel bounds the bytes anyway
            size = sum(u[0] for u in usages if u is not None)
            files = sum(u[1] for u in usages if u is not None)
        else:
            size, files, problem = tree_usage(self._workdir, lim.disk_files)
            if problem:
                raise _ChildGone(f"{problem}: the disk limit cannot be checked")
            size += unlinked_bytes(descendants(self._proc.pid))
            if self._uid is not None:  # what its uid keeps in the machine's world-writable folders
                for entry in uid_litter(self._uid):
                    if entry.is_dir() and not entry.is_symlink():
                        u = tree_usage(entry, lim.disk_files)
                        if u.problem:
                            raise _ChildGone(f"{u.problem}: the disk limit cannot be checked")
                        size, files = size + u.size, files + u.entries + 1
                    else:
                        try:
                            size, files = size + entry.lstat().st_blocks * 512, files + 1
                        except OSError:
                            pass
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
        if sig == signal.SIGKILL and self._cgroup is not None and self._cgroup.oom_killed():
            limit = self._cgroup_memory()
            return f"ran out of memory (the sandbox's processes together may hold {limit} bytes)"
        if sig == signal.SIGKILL:
            return "was killed (it ran out of memory or exceeded a limit)"
        if sig:
            return f"crashed ({signal_name(sig)})"
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

        Notes
        -----
        A child that an earlier batch doomed (it killed its zygote, or left a thread that ends the
        process) may die between two batches, before it answers the next one. That death belongs to
        the earlier batch: when a child started before this call dies without answering any call of
        the batch, and not by timing out, the batch is sent once more to a fresh child.
        """
        calls = list(calls)
        if not all(isinstance(c, Call) for c in calls):
            raise TypeError("calls must be a sequence of Call")
        timeout = self.limits.wall_seconds if timeout is None else timeout
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not timeout > 0:
            raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
        wire = [{"function": c.function, "args": to_wire(list(c.args)), "kwargs": to_wire(dict(c.kwargs)),
                 **({"post": to_wire(dict(c.post))} if c.post is not None else {})}
                for c in calls]
        self.stdout = ""
        outcomes: list[Outcome] = []
        if not calls:
            return outcomes
        if self._child_live and self._cpu_used > self._cpu_ceiling - self.limits.cpu_seconds - 5:
            self._kill()  # its lifetime CPU budget is nearly spent: start afresh
        for attempt in (0, 1):
            inherited = self._child_live  # a child that earlier batches used
            outcomes, gone = self._run_batch(wire, timeout)
            if gone is None:
                return outcomes
            self._kill()
            if attempt == 0 and inherited and not outcomes and not gone.startswith("timed out"):
                continue  # it died of an earlier batch: this batch gets a fresh child
            break
        return outcomes + [Outcome(ok=False, error=gone) for _ in range(len(calls) - len(outcomes))]

    def _run_batch(self, wire: list[dict], timeout: float) -> tuple[list[Outcome], str | None]:
        """One batch in the child: the outcomes received and, when the child went away, why."""
        outcomes: list[Outcome] = []
        try:
            if not self._child_live:
                self.start(timeout)
            deadline = time.monotonic() + timeout
            self._send({"op": "calls", "calls": wire, "cpu": self.limits.cpu_seconds}, deadline)
            budget = self.limits.output_bytes
            printed = []
            for _ in wire:
                reply = self._recv(deadline, budget, timeout)
                budget -= self._budget_used
                if isinstance(reply, dict) and reply.get("op") == "clean":  # the zygote: its child is gone
                    raise _ChildGone("the process exited (sys.exit / os._exit)")
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
            return outcomes, str(gone.args[0])
        return outcomes, None

    # -- teardown ------------------------------------------------------------------------------------
    def finish(self) -> None:
        """End the current exercise's child; a zygote then cleans up and waits for the next
        (:meth:`prepare`). Without a zygote (or when anything goes wrong) the sandbox is killed."""
        if self._zygote and self._proc is not None and not self._child_live:
            return  # no child was started for this exercise (e.g. no calls): the zygote waits
        if not self._zygote or not self._child_live or self._proc is None:
            self._kill()
            return
        self._child_live = False
        try:
            deadline = time.monotonic() + max(10.0, self.limits.wall_seconds)
            self._send({"op": "end"}, deadline)
            self._close_child_pipes()
            assert self._ctl is not None
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise _ChildGone("the zygote did not clean up in time")
                readable, _, _ = select.select([self._ctl], [], [], min(left, _DISK_POLL))
                self._check_disk()
                if readable:
                    break
            if self._ctl.recv(64) != b"clean":
                raise _ChildGone("the zygote did not clean up")
            if self._forks >= _ZYGOTE_FORKS:
                raise _ChildGone("replaced after serving many exercises")
            self._next_disk_check = 0.0
            self._check_disk()
        except (_ChildGone, OSError):
            self._kill()

    def prepare(self, cells: Sequence[tuple[str, str]], *, blocked: Sequence[str] = (),
                allowed: Sequence[str] | None = None, spawn: bool = False) -> None:
        """Set the next exercise of a zygote sandbox (its :attr:`key` must stay the same)."""
        key = self.key
        self._configure(cells, blocked, allowed, spawn)
        if self.key != key:
            raise ValueError("prepare: the exercise needs another sandbox (a different key)")
        if self._child_live:
            self.finish()
        self.cell_errors = {}
        self.stdout = ""

    def _kill(self) -> None:
        self._child_live = False
        p, self._proc = self._proc, None
        stdin_fd = p.stdin.fileno() if p is not None and p.stdin is not None and not p.stdin.closed else None
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
        if self._cgroup is not None:
            self._cgroup.kill()
            self._cgroup.remove()
            self._cgroup = None
        if self._uid is not None and p is not None:
            kill_uid(self._uid)
            if self._mode != "bwrap":  # no mount namespace: remove what it left in /tmp, /dev/shm, ...
                for entry in uid_litter(self._uid):
                    problems = remove_tree(entry) if entry.is_dir() and not entry.is_symlink() else []
                    if not entry.is_dir() or entry.is_symlink():
                        try:
                            entry.unlink()
                        except OSError as exc:
                            problems = [f"{entry}: {exc.strerror}"]
                    self.cleanup_problems += problems
        if self._reply_fd is not None:
            os.close(self._reply_fd)
            self._reply_fd = None
        if self._ctl is not None:
            if self._req_fd is not None and self._req_fd != stdin_fd:
                os.close(self._req_fd)
            self._ctl.close()
            self._ctl = None
        self._req_fd = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        if self._workdir is not None:
            problems = remove_tree(self._workdir)
            if problems:
                self.cleanup_problems += problems
                warnings.warn(
                    f"the sandbox could not remove all of {self._workdir}: {'; '.join(problems[:3])}",
                    RuntimeWarning, stacklevel=2,
                )
            self._workdir = None




class _Lease:
    """One exercise in a pooled zygote sandbox: the ``Sandbox`` interface ``run_exercise`` uses."""

    def __init__(self, box: Sandbox) -> None:
        self._box = box

    def __enter__(self) -> _Lease:
        return self

    def __exit__(self, *exc: object) -> None:
        self._box.finish()

    def run(self, calls: Sequence[Call], timeout: float | None = None) -> list[Outcome]:
        return self._box.run(calls, timeout)

    @property
    def isolation(self) -> str:
        return self._box.isolation

    @property
    def cell_errors(self) -> dict[str, str]:
        return self._box.cell_errors

    @property
    def stdout(self) -> str:
        return self._box.stdout


class SandboxPool:
    """Sandboxes of one student, reused across the student's exercises (a zygote per key).

    Called like :class:`Sandbox` (``pool(cells, blocked=..., allowed=..., limits=...)``), it returns
    a context manager with ``run``, ``isolation``, ``cell_errors`` and ``stdout``. Exercises whose
    sandboxes would be the same (:attr:`Sandbox.key`: the same file system view, limits and hidden
    paths) share one sandboxed process that imported numpy once; each exercise runs in a child it
    forks, with that exercise's own import guard and audit hook, and between two exercises the
    zygote kills every other process of the sandbox and empties its writable folders. A child that
    crashes, times out or exceeds a limit takes the whole sandbox down (the next exercise starts a
    new one), exactly as without the pool. Never shared between students: :meth:`close` kills all.
    Where a zygote cannot be used (the fallback as an ordinary user) every exercise gets a fresh
    sandbox.
    """

    def __init__(self, preload: Sequence[str] = ()) -> None:
        self._boxes: dict[tuple, Sandbox] = {}
        self.preload = tuple(preload)

    def __call__(self, cells: Sequence[tuple[str, str]], **kwargs: Any) -> Any:
        box = Sandbox(cells, zygote=True, preload=self.preload, **kwargs)
        if not box._zygote:
            return box
        old = self._boxes.get(box.key)
        if old is None:
            self._boxes[box.key] = box
            return _Lease(box)
        box.close()
        old.prepare(cells, blocked=kwargs.get("blocked", ()), allowed=kwargs.get("allowed"),
                    spawn=kwargs.get("spawn", False))
        return _Lease(old)

    def __enter__(self) -> SandboxPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Kill every sandbox of the pool."""
        boxes, self._boxes = list(self._boxes.values()), {}
        for box in boxes:
            box.close()
