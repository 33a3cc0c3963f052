"""The sandbox itself: :class:`Sandbox` runs one student's cells in an isolated child and calls
their functions (the threat model and the defences are in the package's docstring).
"""

from __future__ import annotations

import functools
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
from pathlib import Path
from typing import Any

from .cache import cache_root, live_copy, world_readable
from .cgroups import SandboxCgroup
from .isolation import (
    WORLD_WRITABLE,
    choose_mode,
    descendants,
    drop_to,
    kill_uid,
    mount_usage,
    remove_tree,
    sandbox_uid,
    signal_name,
    tree_usage,
    uid_litter,
    unlinked_bytes,
    user_tasks,
)
from .isolation import bwrap_path as _bwrap_path
from .launch import HOME, SandboxConfigError, View, bwrap_command, config_error, fallback_command
from .limits import Limits
from .runtime import (
    allowed_packages,
    filtered_packages,
    locate_module,
    mirror_site,
    package_dir,
    project_root,
    pth_dirs,
    python_runtime,
    runner_dir,
    site_dirs,
)
from .seccomp import no_spawn_program, preexec_installer, seccomp_status
from .seccomp import program as seccomp_program
from .wire import Call, Outcome, is_plain, to_wire

__all__ = ["Sandbox", "SandboxConfigError"]

#: the package itself: never importable by student code
_OWN = __name__.partition(".")[0]
_DISK_POLL = 0.2  # seconds between measurements of the child's directory while waiting for it
_ZYGOTE_FORKS = 256  # exercises a zygote serves before it is replaced (bounds its own CPU time)
_DEFAULT_LIMITS = Limits()  # a frozen dataclass: immutable


@functools.lru_cache(maxsize=1)
def _no_spawn_hex() -> str:
    """The no-spawn filter (:func:`.seccomp.no_spawn_program`) as the child's init message carries it."""
    return no_spawn_program().hex()


class _ChildGone(Exception):
    """The child cannot answer any more; ``args[0]`` is the message for the unanswered calls."""


# --------------------------------------------------------------------------------------------------


class Sandbox:
    """Run one student's cells of one exercise in an isolated child and call their functions.

    Parameters
    ----------
    cells : sequence of (str, str)
        ``(grade_id, source)`` of the answer cells, executed in order in one namespace.
    blocked : sequence of str
        Modules the student may not import, e.g. ``"mylib.solver"`` or ``"scipy.optimize"``.
    packages : sequence of str
        Top-level packages the sandbox exposes (e.g. the course's library): each is shown as a
        read-only copy in which the blocked modules directly inside it are stubs raising
        ``ImportError`` (the copies are cached, :mod:`.runtime`); their real folders are never
        shown. With an allowlist, only those the allowlist needs.
    private : sequence of str
        Top-level packages the student may never import nor read (e.g. the grader's own); this
        package is always one of them.
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
        (:func:`.runtime.allowed_packages`: ``scipy.linalg`` needs ``scipy`` and
        ``numpy``) are in the sandbox at all; the child refuses importing any other package with a
        message naming the allowlist, and the fallback's audit hook refuses the files of the others.
        Within an allowed package the granularity is the top-level package (``blocked`` still
        removes submodules). ``None`` (default): everything installed, minus ``blocked``.
    zygote : bool
        Keep the sandboxed process between exercises and fork a child per exercise (:meth:`prepare`,
        :meth:`finish`; see "Zygotes" in the package's docstring). Ignored in the fallback without
        root.
    preload : sequence of str
        Modules a zygote imports before forking (those of packages in its view; what the exercise's
        child could not import is refused there too).
    spawn : bool
        The exercise's own (trusted) code starts programs (e.g. an answer in another language is
        compiled and run by the child). Outside bubblewrap the in-process audit hook then lets the
        child start processes and signal them; those run as the sandbox's uid (setpriv) with the
        same resource limits, beyond the hook's reach (the fallback is no boundary for them).

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
    >>> from grading_sandbox import Call
    >>> with Sandbox([("a", "def add(a, b):\\n    return a + b\\n")]) as sb:
    ...     [o.value for o in sb.run([Call("add", (1, 2)), Call("add", ([1.5], [2.0]))], timeout=30)]
    [3, [1.5, 2.0]]
    """

    def __init__(
        self,
        cells: Sequence[tuple[str, str]],
        *,
        blocked: Sequence[str] = (),
        limits: Limits = _DEFAULT_LIMITS,
        packages: Sequence[str] = (),
        private: Sequence[str] = (),
        workdir_parent: Path | None = None,
        hidden_paths: Sequence[str | Path] = (),
        allowed: Sequence[str] | None = None,
        zygote: bool = False,
        preload: Sequence[str] = (),
        spawn: bool = False,
    ) -> None:
        for what, names in (("packages", packages), ("private", private)):
            if isinstance(names, str) or not all(isinstance(n, str) and n.isidentifier() for n in names):
                raise TypeError(f"{what} must be a sequence of top-level package names")
        self.packages = tuple(dict.fromkeys(packages))
        self.private = tuple(dict.fromkeys([*private, _OWN]))
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
        self.blocked = tuple(dict.fromkeys([*blocked, *self.private]))  # private packages: blocked whole
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
        return (self._mode, pk, view_blocked, self.limits, self.hidden_paths, str(self._workdir_parent),
                self.packages)

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
        self.seccomp = False  # True when the running child has the seccomp filter (.seccomp)
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
            if b.split(".")[0] in self.packages:  # their filtered copies hold the stubs
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
        # the cached copies are marked as used at every start (see the cache's docstring)
        runtime = live_copy(python_runtime, self._uid is not None,
                            where=lambda r: Path(r.source) if r.lib_dir is not None else None)
        real_sites = site_dirs()
        sites = [*real_sites, *self._pth_sites(real_sites)]
        if self._uid is not None:
            leave_out = (*self.packages, *self.private)
            sites = [d if world_readable(Path(d)) else str(mirror_site(Path(d), leave_out)) for d in sites]
            unreadable = [d for d in sites if not world_readable(Path(d))]
            if unreadable:
                raise RuntimeError(
                    f"the sandbox's unprivileged uid cannot read the Python packages in {unreadable[0]} "
                    "(a folder on the way is not readable by other users): make it readable, e.g. "
                    f"chmod -R a+rX {unreadable[0]} and chmod o+x on its parent folders"
                )
        exposed = tuple(p for p in self.packages if self._packages is None or p in self._packages)
        lib_blocked = tuple(sorted(b for b in self.blocked if b.split(".")[0] in exposed and "." in b))
        lib_root = live_copy(filtered_packages, exposed, lib_blocked) if exposed else None
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
        view = View(runtime, tuple(sites), self._packages, lib_root, runner, self.packages,
                    tuple(self._blocked_locations([*stdlib, *sites])), self._hidden(real_sites))
        if self._mode == "bwrap":
            cmd, init = bwrap_command(view, _bwrap_path() or "bwrap", env, self.limits.disk_bytes)
        else:
            env.update(HOME=str(home), TMPDIR=str(tmp))
            if runtime.lib_dir:
                env["LD_LIBRARY_PATH"] = runtime.lib_dir
            cmd, init = fallback_command(view, workdir, self._uid, self._mode == "setpriv", runtime.stdlib)
        if self._packages is not None:
            init["allowed"] = list(self._packages)
            init["allowed_text"] = ", ".join(self.allowed or ())
        return cmd, env, init, workdir

    def _pth_sites(self, sites: Sequence[str]) -> list[str]:
        """The folders the ``.pth`` files of ``sites`` add (:func:`.runtime.pth_dirs`), for the
        packages installed there; a folder holding an exposed or a private package (the source
        checkout of an editable install) is left out: those come from their filtered copies, or never.
        """
        own = (*self.packages, *self.private)
        return [d for d in pth_dirs(sites) if not any((Path(d) / name).exists() for name in own)]

    def _probe_modules(self) -> list[str]:
        """What the child imports before any student code (numpy always): the allowlist's modules
        that are not blocked. Failing to import one is the grader's configuration error."""
        names = ["numpy", *(self.allowed or ())]
        blocked = self.blocked
        return [n for n in dict.fromkeys(names)
                if not any(n == b or n.startswith(b + ".") for b in blocked)]

    def _config_error(self, reply: dict) -> SandboxConfigError:
        return config_error(reply, self.isolation, self._uid is not None, self._cache)

    def _hidden(self, sites: Sequence[str]) -> tuple[str, ...]:
        """What the fallback's audit hook refuses: the real folders of the exposed and private
        packages (and the checkout of an editable install), the cache's copies and stubs, and
        ``hidden_paths``."""
        out = [str(self._cache / "pkg"), str(self._cache / "stubs"), *self.hidden_paths]
        for name in (*self.packages, *self.private):
            try:
                folder = package_dir(name)
            except ValueError:  # not installed: nothing to hide
                continue
            root = project_root(folder, sites)
            out += [str(folder)] + ([str(root)] if root is not None else [])
        return tuple(dict.fromkeys(out))

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
                    allow_spawn=self.spawn, probe=self._probe_modules(),
                    seccomp=_no_spawn_hex() if self.seccomp and not self.spawn else None)
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
        if isinstance(reply, dict) and reply.get("op") == "config-error":
            error = self._config_error(reply)
            self._kill()
            raise error
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
        # The seccomp filter (memfd, IPC, namespaces, ... refused: see .seccomp): bubblewrap loads
        # it from a pipe (--seccomp FD) right before it executes the child; otherwise preexec_fn does,
        # with the socket rule (no network namespace there: AF_UNIX only).
        self.seccomp, _ = seccomp_status()
        install, filter_fd = None, None
        if self.seccomp and self._mode == "bwrap":
            filter_fd, fw = os.pipe()
            with os.fdopen(fw, "wb") as fh:
                fh.write(seccomp_program())
            cmd = [cmd[0], "--seccomp", str(filter_fd), *cmd[1:]]
        elif self.seccomp:
            install = preexec_installer(network=False)
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
            wipe, litter = [HOME, "/tmp"], []
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
        if isinstance(reply, dict) and reply.get("op") == "config-error":
            error = self._config_error(reply)
            self._kill()
            raise error
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
            usages = [mount_usage(int(pid), path) for pid in init_pid for path in (HOME, "/tmp")]
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
