"""The runner executed inside the sandbox (``python -I -S _child.py REPLY_FD``).

It is started by :class:`grading_sandbox.sandbox.Sandbox` and never imported by the grader. It imports
only the standard library and numpy. Protocol: length-prefixed (4-byte big-endian) UTF-8
JSON messages; requests on stdin, replies on the file descriptor given as the first argument.

1. ``{"op": "init", ...}``: sys.path additions, blocked modules, denied paths, limits, the cells.
   The runner lowers RLIMIT_NPROC, installs the import blocker and the audit hook, points fd 1/2 at
   /dev/null (student prints go to a capped in-memory buffer), executes the cells one by one in one
   namespace and replies ``{"op": "ready", "cell_errors": {grade_id: text}}``.
2. ``{"op": "calls", "calls": [{"function", "args", "kwargs"}, ...]}``: one reply per call,
   ``{"ok": true, "value": plain data, "printed": text}`` or ``{"ok": false, "error": text}``.
   A call with ``"post": {"op": "formula", ...}`` has its result (a formula as text) parsed and
   evaluated here by ``formula.py`` (shipped next to this file, loaded before any student code):
   the reply carries numbers at the grader's points, never the text for the grader to parse.

An exception raised by student code is told by ``errors.py`` (shipped next to this file, loaded
first): the one formatter the grader's in-process stand-ins use too. An init message with
``"seccomp"`` (a filter program, hex) makes the child add that filter (an exercise that starts no
program: no fork, no exec) before it executes the first cell.

Everything here runs with student code in the same process, so nothing here is trusted by the
grader: the parent treats each reply as untrusted data.
"""

import builtins
import json
import os
import resource
import struct
import sys

_MAX_TEXT = 2000
_PRINT_CAP = 64 * 1024
_UNAVAILABLE = "is not available in this exercise"  # the import rule's (and the stubs') refusal


class _NotPlain(Exception):
    """A result that is not plain data (``args[0]`` says why)."""


class _Reported(Exception):
    """A call that failed for a reason the runner words itself (``args[0]``)."""


def _read_exact(fd, n):
    chunks = []
    while n:
        b = os.read(fd, min(n, 1 << 20))
        if not b:
            raise EOFError
        chunks.append(b)
        n -= len(b)
    return b"".join(chunks)


def _read_msg():
    (n,) = struct.unpack(">I", _read_exact(0, 4))
    return json.loads(_read_exact(0, n).decode("utf-8"))


class _Capped:
    """A text sink keeping the first ``cap`` characters (student prints), dropping the rest."""

    encoding = "utf-8"
    errors = "replace"

    def __init__(self, cap):
        self.cap = cap
        self.parts = []
        self.size = 0
        self.dropped = False

    def write(self, s):
        if not isinstance(s, str):
            s = str(s)
        room = self.cap - self.size
        if room > 0:
            self.parts.append(s[:room])
            self.size += min(len(s), room)
        if len(s) > room:
            self.dropped = True
        return len(s)

    def flush(self):
        pass

    def isatty(self):
        return False

    def take(self):
        text = "".join(self.parts)
        if self.dropped:
            text += "\n[... output truncated]"
        self.parts, self.size, self.dropped = [], 0, False
        return text[:_MAX_TEXT]


def _import_rule(blocked, allowed, allowed_text, stdlib_paths):
    """``refuse(name)``: raise ImportError when module ``name`` is a ``blocked`` module or inside one,
    or (with an ``allowed`` list of top-level packages) in a package that is neither in the standard
    library nor allowed. The child's rule, and the zygote's while it preloads (so a zygote never
    imports what the exercises' children could not)."""
    blocked = tuple(blocked)
    allowed = None if allowed is None else frozenset([*allowed, "__main__"]) | sys.stdlib_module_names
    stdlib_found = {}

    def in_stdlib(top):
        """True for a module of the standard library's folders (``_sysconfigdata_*`` is not listed in
        ``sys.stdlib_module_names``)."""
        if top not in stdlib_found:
            from importlib.machinery import PathFinder

            stdlib_found[top] = PathFinder.find_spec(top, stdlib_paths) is not None
        return stdlib_found[top]

    def refuse(name):
        for b in blocked:
            if name == b or name.startswith(b + "."):
                raise ImportError(f"{b} {_UNAVAILABLE}")
        top = name.partition(".")[0]
        if allowed is not None and top not in allowed and not in_stdlib(top):
            raise ImportError(
                f"{top} {_UNAVAILABLE} (you may import: {allowed_text}, "
                "and the standard library)"
            )

    return refuse


_CLEAN_EXIT = 165  # an exercise's child that received "end" (the zygote then cleans and goes on)


def _config_error(reply_fd, module, exc):
    """Tell the grader that ``module`` (numpy, or a module of the allowlist) cannot be imported
    before any student code ran (its configuration, never the student's doing), and exit."""
    text = f"{type(exc).__name__}: {exc}".strip()[:_MAX_TEXT]
    data = json.dumps({"op": "config-error", "module": module, "error": text}).encode("utf-8")
    buf = struct.pack(">I", len(data)) + data
    while buf:
        buf = buf[os.write(reply_fd, buf):]
    os._exit(0)


def _setup(msg):
    for p in msg["paths"]:
        if p not in sys.path:
            sys.path.append(p)
    nproc = msg.get("nproc")
    if nproc is not None:
        try:
            resource.setrlimit(resource.RLIMIT_NPROC, (nproc, nproc))
        except (ValueError, OSError):
            pass


def _wipe(roots, litter_roots):
    """Empty the writable folders between two exercises (the zygote's own uid owns everything in
    them); also what this uid left in the machine's world-writable folders."""
    import shutil

    def fix(func, path, exc):
        parent = os.path.dirname(path)
        os.chmod(parent, 0o700)
        if os.path.isdir(path) and not os.path.islink(path):
            os.chmod(path, 0o700)
            shutil.rmtree(path, onerror=fix)
        else:
            func(path)

    uid = os.getuid()
    for root in roots:
        for name in os.listdir(root):
            path = os.path.join(root, name)
            if os.path.isdir(path) and not os.path.islink(path):
                os.chmod(path, 0o700)
                shutil.rmtree(path, onerror=fix)
            else:
                os.unlink(path)
    for root in litter_roots:
        try:
            names = os.listdir(root)
        except OSError:
            continue
        for name in names:
            path = os.path.join(root, name)
            try:
                if os.lstat(path).st_uid != uid:
                    continue
            except OSError:
                continue
            if os.path.isdir(path) and not os.path.islink(path):
                os.chmod(path, 0o700)
                shutil.rmtree(path, onerror=fix)
            else:
                os.unlink(path)


_DIR = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW


def _pristine(roots):
    """``[(root, (mode, uid, gid))]``: the writable folders as the sandbox made them (before any
    student code), what :func:`_rebuild` brings them back to."""
    out = []
    for root in roots:
        st = os.lstat(root)
        out.append((root, (st.st_mode & 0o7777, st.st_uid, st.st_gid)))
    return out


def _rebuild(pristine, litter_roots):
    """Give the next exercise the writable folders a fresh sandbox has: each root gets back its
    mode (a student's ``chmod 555 $HOME /tmp`` would fail every later build) and loses every
    extended attribute and ACL, then is emptied; it is checked to be empty, of its first mode and
    owner and without attributes. Raises when it is not (the zygote then ends: the grader starts a
    new sandbox)."""
    for root, (mode, _, _) in pristine:
        fd = os.open(root, _DIR)
        try:
            os.fchmod(fd, mode | 0o700)  # writable by its owner while it is emptied
            try:
                names = os.listxattr(fd)
            except OSError:  # a filesystem without extended attributes
                names = []
            for name in names:
                os.removexattr(fd, name)
        finally:
            os.close(fd)
    _wipe([root for root, _ in pristine], litter_roots)
    for root, (mode, uid, gid) in pristine:
        fd = os.open(root, _DIR)
        try:
            os.fchmod(fd, mode)
            st = os.fstat(fd)
            try:
                left = os.listxattr(fd)
            except OSError:
                left = []
            if os.listdir(fd) or left or (st.st_mode & 0o7777, st.st_uid, st.st_gid) != (mode, uid, gid):
                raise RuntimeError(f"{root} could not be rebuilt")
        finally:
            os.close(fd)


_LIMITS = ("RLIMIT_AS", "RLIMIT_CPU", "RLIMIT_NOFILE", "RLIMIT_NPROC", "RLIMIT_FSIZE", "RLIMIT_CORE",
           "RLIMIT_STACK", "RLIMIT_DATA", "RLIMIT_MEMLOCK")


def _scheduling():
    """What a process of this uid could change in the zygote and its next child would inherit: its
    nice value, scheduling policy and priority, CPU affinity and resource limits. (The seccomp
    filter refuses changing another process's; a zygote whose values changed anyway, e.g. where no
    filter could be installed, ends, since an unprivileged process cannot take them back.)"""
    limits = tuple(resource.getrlimit(getattr(resource, n)) for n in _LIMITS if hasattr(resource, n))
    return (os.getpriority(os.PRIO_PROCESS, 0), os.sched_getscheduler(0), os.sched_getparam(0).sched_priority,
            tuple(sorted(os.sched_getaffinity(0))), limits)


def _survivors(me):
    """Processes of this sandbox other than the zygote (and bubblewrap's init): under bubblewrap
    /proc is the sandbox's pid namespace; otherwise the processes of this (per-sandbox) uid."""
    uid = os.getuid()
    out = []
    for name in os.listdir("/proc"):
        if not name.isdigit() or int(name) in (me, 1):
            continue
        try:
            if os.stat(f"/proc/{name}").st_uid != uid:
                continue
            with open(f"/proc/{name}/stat") as fh:
                if fh.read().rsplit(")", 1)[1].split()[0] == "Z":
                    continue
        except (OSError, IndexError):
            continue
        out.append(int(name))
    return out


def _zygote(msg, reply_fd, stdlib_paths):
    """Serve exercises one after the other, each in a child forked from here (numpy and the
    ``preload`` modules imported once, before any student code exists).

    The zygote never reads student data: per exercise the grader sends, over the control socket
    (fd ``msg["control"]``), the two ends of a fresh pair of pipes; the forked child reads its
    init message (the cells) and the calls from the first and replies on the second. Once the child
    is gone the zygote kills every other process of the sandbox, checks that none is left, empties
    the writable folders and answers ``clean``. A child that dies otherwise (crash, limit, exit)
    takes the zygote with it, with the same status, so the grader sees the death as without one.
    The zygote is not dumpable: its children (the same uid) can neither ptrace it nor open its
    memory or descriptors through /proc.
    """
    import ctypes
    import signal
    import socket

    ctl = socket.socket(fileno=int(msg["control"]))
    _setup(msg)
    try:
        import numpy  # noqa: F401  - the point: forked children start with it imported
    except BaseException as exc:
        _config_error(reply_fd, "numpy", exc)

    # Preloading follows the children's import rule (the blocked modules of this sandbox's view and
    # its allowlist): whatever a preloaded module would import that an exercise's child may not is
    # refused here too (as in a fresh sandbox, where the child's guard refuses it), so nothing
    # blocked ever sits in a zygote's memory.
    refuse = _import_rule(msg.get("blocked", ()), msg.get("allowed"), "", stdlib_paths)

    class _PreloadGuard:
        @staticmethod
        def find_spec(name, path=None, target=None):
            refuse(name)
            return None

    sys.meta_path.insert(0, _PreloadGuard)
    for name in msg.get("preload", ()):
        try:
            __import__(name)
        except Exception:
            pass
    sys.meta_path.remove(_PreloadGuard)
    try:
        ctypes.CDLL(None, use_errno=True).prctl(4, 0, 0, 0, 0)  # PR_SET_DUMPABLE = 0
    except Exception:
        os._exit(4)
    # The zygote's own CPU (forks, clean-ups) may run up to the lifetime ceiling; each child gets
    # back the soft limit a fresh sandbox has (RLIMIT_CPU counts a process's own time).
    cpu_soft, cpu_hard = resource.getrlimit(resource.RLIMIT_CPU)
    resource.setrlimit(resource.RLIMIT_CPU, (cpu_hard, cpu_hard))
    devnull = os.open(os.devnull, os.O_WRONLY)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    os.close(devnull)
    pristine = _pristine(msg.get("wipe", ()))
    litter_roots = list(msg.get("litter", ()))
    scheduling = _scheduling()
    data = json.dumps({"op": "zygote-ready"}).encode()
    os.write(reply_fd, struct.pack(">I", len(data)) + data)
    os.close(reply_fd)
    me = os.getpid()
    while True:
        try:
            data, fds, _, _ = socket.recv_fds(ctl, 64, 2)
        except OSError:
            os._exit(0)
        if data != b"fork" or len(fds) != 2:
            os._exit(0)
        req, rep = fds
        pid = os.fork()
        if pid == 0:
            try:
                resource.setrlimit(resource.RLIMIT_CPU, (cpu_soft, cpu_hard))
                ctl.close()
                os.dup2(req, 0)
                os.close(req)
                _serve(_read_msg(), rep, stdlib_paths)
            finally:
                os._exit(1)
        os.close(req)
        os.close(rep)
        _, status = os.waitpid(pid, 0)
        if os.WIFSIGNALED(status):
            sig = os.WTERMSIG(status)
            signal.signal(sig, signal.SIG_DFL)
            os.kill(me, sig)
            os._exit(128 + sig)
        code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else 1
        if code != _CLEAN_EXIT:
            os._exit(code)
        for _ in range(20):  # everything of this sandbox but the zygote (and bubblewrap's init)
            try:
                os.kill(-1, signal.SIGKILL)
            except OSError:
                pass
            try:
                while os.waitpid(-1, os.WNOHANG)[0]:
                    pass
            except ChildProcessError:
                pass
            if not _survivors(me):
                break
        else:
            os._exit(3)  # something survived: the grader discards this sandbox
        try:
            _rebuild(pristine, litter_roots)
            if _scheduling() != scheduling:
                os._exit(3)
        except Exception:
            os._exit(3)
        ctl.send(b"clean")


def main():
    global _ERRORS
    _ERRORS = _load("errors")
    reply_fd = os.dup(int(sys.argv[1]))
    os.close(int(sys.argv[1]))
    os.set_inheritable(reply_fd, False)
    init = _read_msg()
    stdlib_paths = list(sys.path[1:])  # -I -S: the runner's folder, then only the standard library
    if init.get("op") == "zygote":
        _zygote(init, reply_fd, stdlib_paths)
    else:
        _serve(init, reply_fd, stdlib_paths)


def _load(name):
    """The module ``<name>.py`` from this file's folder (None when it is missing), loaded by path."""
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), f"{name}.py")
    if not os.path.isfile(path):
        return None
    spec = importlib.util.spec_from_file_location(f"_sandbox_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_ERRORS = None  # errors.py, loaded by main() before anything else


def _add_filter(hex_program):
    """Install one more seccomp filter (``no_new_privs`` first, which the sandbox has set already)."""
    import ctypes

    data = bytes.fromhex(hex_program)

    class Fprog(ctypes.Structure):
        _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]

    buf = ctypes.create_string_buffer(data, len(data))
    fprog = Fprog(len(data) // 8, ctypes.cast(buf, ctypes.c_void_p))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong]
    if libc.prctl(38, 1, None, 0, 0) != 0 or libc.prctl(22, 2, ctypes.addressof(fprog), 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "the exercise's seccomp filter could not be installed")


def _serve(init, reply_fd, stdlib_paths):
    _setup(init)
    formula = _load("formula")  # before the import guard and any student code
    errors = _ERRORS
    if init.get("seccomp"):  # this exercise starts no program: no fork, no exec from here on
        try:
            _add_filter(init["seccomp"])
        except OSError:
            os._exit(5)  # never run student code without the filter the grader asked for

    try:
        import numpy as np
    except BaseException as exc:
        _config_error(reply_fd, "numpy", exc)

    ndarray = np.ndarray
    to_list = np.ndarray.tolist
    as_array = np.array
    view = np.ndarray.view
    generic = np.generic
    scalar_types = {np.float64, np.float32, np.float16, np.int64, np.int32, np.int16, np.int8,
                    np.uint64, np.uint32, np.uint16, np.uint8, np.bool_}
    ok_kinds = set("biuf")
    dumps = json.dumps
    pack = struct.pack
    write = os.write
    exception_text = errors.exception_text
    not_plain = errors.not_plain

    def send(obj):
        data = dumps(obj).encode("utf-8")
        buf = pack(">I", len(data)) + data
        while buf:
            buf = buf[write(reply_fd, buf):]

    def to_plain(x, depth=0):
        if depth > 32:
            raise _NotPlain("the result is nested too deeply")
        t = type(x)
        if x is None or t is bool or t is int or t is float or t is str:
            return x
        if t is list or t is tuple:
            return [to_plain(v, depth + 1) for v in x]
        if t is dict:
            if not all(type(k) is str for k in x):
                raise _NotPlain("a returned dict has non-string keys")
            return {k: to_plain(v, depth + 1) for k, v in x.items()}
        if isinstance(x, ndarray):
            base = as_array(view(x, ndarray), copy=True)  # the raw buffer, never a subclass' methods
            if base.dtype.kind not in ok_kinds:
                raise _NotPlain(f"returned an array of dtype {base.dtype}; return numbers")
            return to_list(base)
        if t in scalar_types:
            return to_list(as_array(x))
        if isinstance(x, generic):
            raise _NotPlain(f"returned a numpy scalar of type {t.__name__}; return real numbers")
        raise _NotPlain(
            f"returned an object of type {t.__name__}; return numbers, lists or numpy arrays"
        )

    def from_wire(x):
        t = type(x)
        if t is dict:
            if "__ndarray__" in x:
                return as_array(x["__ndarray__"], dtype=x["dtype"]).reshape(x["shape"])
            return {k: from_wire(v) for k, v in x.items()}
        if t is list:
            return [from_wire(v) for v in x]
        return x

    blocked = tuple(init.get("blocked", ()))
    refuse_blocked = _import_rule(blocked, init.get("allowed"), init.get("allowed_text", ""), stdlib_paths)

    class _Blocker:
        """sys.meta_path entry refusing blocked modules (a second line behind the file system)."""

        @staticmethod
        def find_spec(name, path=None, target=None):
            refuse_blocked(name)
            return None

    sys.meta_path.insert(0, _Blocker)
    for name in list(sys.modules):  # already imported (numpy's own imports): blocked ones go
        if any(name == b or name.startswith(b + ".") for b in blocked):
            del sys.modules[name]

    deny = tuple(os.path.realpath(p) for p in init.get("deny_paths", ()))
    allow = tuple(os.path.realpath(p) for p in init.get("allow_paths", ()))
    strict = bool(init.get("strict_audit"))
    realpath = os.path.realpath
    fsdecode = os.fsdecode

    def resolved(p):
        """The real path of an audited path argument; None for a file descriptor, "" if unusable."""
        if isinstance(p, int) or p is None:
            return None
        try:
            return realpath(fsdecode(p))
        except Exception:
            return ""

    def deepest(rp, roots):
        """Length of the longest of ``roots`` that is ``rp`` or one of its ancestors (-1: none)."""
        return max((len(r) for r in roots if rp == r or rp.startswith(r + os.sep)), default=-1)

    def denied_path(p):
        rp = resolved(p)
        if rp is None:
            return False
        return not rp or deepest(rp, deny) > deepest(rp, allow)

    spawn_events = {"os.exec", "os.posix_spawn", "os.spawn", "os.system", "os.fork", "os.forkpty",
                    "subprocess.Popen", "pty.spawn", "os.kill", "os.killpg", "signal.pthread_kill"}

    allow_spawn = bool(init.get("allow_spawn"))  # the exercise's driver compiles and runs programs
    write_root = init.get("write_root")
    write_root = realpath(write_root) if write_root else None
    mutating = {"os.mkdir", "os.rmdir", "os.remove", "os.rename", "os.link", "os.symlink", "os.chmod",
                "os.chown", "os.truncate", "os.utime", "shutil.rmtree", "shutil.move", "shutil.copyfile"}

    def outside(p):
        rp = resolved(p)
        if rp is None:
            return False
        return not rp or (deepest(rp, (write_root,)) < 0 and rp != os.devnull)

    def audit(event, args):
        if write_root is not None and args:
            writing = event in mutating or (
                event == "open" and (
                    (isinstance(args[1], str) and any(c in args[1] for c in "wax+"))
                    or (isinstance(args[2], int) and args[2] & (os.O_WRONLY | os.O_RDWR | os.O_CREAT))
                )
            )
            if writing and outside(args[0]):
                raise PermissionError(f"{args[0]!r}: the sandbox may only write in its own directory")
        if event == "import" and args and isinstance(args[0], str):
            refuse_blocked(args[0])
        elif event in ("open", "os.listdir", "os.scandir", "os.chdir", "ctypes.dlopen", "shutil.copyfile",
                       "os.rename", "os.link", "os.symlink", "os.truncate", "os.remove"):
            if args and denied_path(args[0]):
                raise PermissionError(f"{args[0]!r} is not accessible from the sandbox")
        elif strict and ((event in spawn_events and not allow_spawn) or event.startswith("socket.")
                         or event == "ctypes.dlsym"):
            raise PermissionError(f"{event} is not allowed in the sandbox")

    sys.addaudithook(audit)

    # What the allowlist names must import, under the rule and the hook student code gets, before
    # any of it runs: a failure is the grader's configuration (a library of a wheel missing from the
    # sandbox's view), reported as such instead of as the student's error.
    for name in init.get("probe", ()):
        try:
            __import__(name)
        except BaseException as exc:
            if _UNAVAILABLE not in str(exc):  # not what the exercise itself refuses
                _config_error(reply_fd, name, exc)

    # Student prints: fd 1/2 -> /dev/null (C-level writes vanish), sys.stdout/err -> capped buffer.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    os.close(devnull)
    sink = _Capped(_PRINT_CAP)
    sys.stdout = sys.stderr = sink
    builtins.input = None

    ns = {"__name__": "__main__", "__builtins__": builtins}
    cell_errors = {}
    for gid, src in init["cells"]:
        try:
            code = compile(src, f"<cell {gid}>", "exec")
            exec(code, ns)
        except BaseException as exc:  # student code may raise anything
            cell_errors[gid] = exception_text(exc, cell=True)
    sink.take()
    send({"op": "ready", "cell_errors": cell_errors})

    while True:
        try:
            msg = _read_msg()
        except EOFError:
            os._exit(0)
        if msg.get("op") == "end":  # the next exercise (the zygote goes on)
            os._exit(_CLEAN_EXIT)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        used = usage.ru_utime + usage.ru_stime
        try:
            _, hard = resource.getrlimit(resource.RLIMIT_CPU)
            soft = int(used + float(msg.get("cpu", 20))) + 1
            if hard != resource.RLIM_INFINITY:
                soft = min(soft, hard)
            resource.setrlimit(resource.RLIMIT_CPU, (soft, hard))
        except (ValueError, OSError):
            pass
        for call in msg.get("calls", ()):
            try:
                name = call["function"]
                fn = ns.get(name)
                if fn is None:
                    raise _Reported(errors.missing_function(name))
                if not callable(fn):
                    raise TypeError(f"{name!r} is not a function")
                args = from_wire(call.get("args", []))
                kwargs = from_wire(call.get("kwargs", {}))
                value = fn(*args, **kwargs)
                post = call.get("post")
                if post is not None:  # a formula: parsed and evaluated here, numbers go back
                    if formula is None:
                        raise RuntimeError("the sandbox cannot read formulas (formula.py is missing)")
                    value = formula.apply(post, value)
                try:
                    plain = to_plain(value)
                except _NotPlain as exc:
                    raise _Reported(not_plain(exc.args[0])) from None
                reply = {"ok": True, "value": plain}
            except _Reported as exc:
                reply = {"ok": False, "error": exc.args[0]}
            except BaseException as exc:
                reply = {"ok": False, "error": exception_text(exc)}
            reply["printed"] = sink.take()
            usage = resource.getrusage(resource.RUSAGE_SELF)
            reply["cpu"] = usage.ru_utime + usage.ru_stime
            try:
                send(reply)
            except (ValueError, TypeError, OverflowError):
                send({"ok": False, "error": "the result could not be encoded", "printed": ""})


if __name__ == "__main__":
    main()
