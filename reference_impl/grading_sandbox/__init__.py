"""grading_sandbox: run untrusted student code for an autograder, and get plain data back.

A grader hands a :class:`Sandbox` the code a student wrote (``(name, source)`` "cells", executed in
one namespace), makes calls (:class:`Call`) of the functions it defines and receives one :class:`Outcome`
per call: plain data (numbers, strings, nested lists), never an object the student's code made.
What the grader does with it (expected values, scores, feedback) is the grader's business; this
package knows nothing of any course, exercise or grading scheme, and imports nothing but the standard
library and numpy. What the sandbox may show the student is a parameter: ``packages`` (a library
the course teaches, exposed as a read-only copy with the ``blocked`` modules stubbed out),
``allowed`` (an allowlist of importable packages), ``private`` (packages never shown, e.g. the
grader's own), ``hidden_paths`` and :class:`Limits`. Its configuration from the environment is
:mod:`.config`.

>>> from grading_sandbox import Call, Sandbox
>>> with Sandbox([("answer", "def add(a, b):\\n    return a + b\\n")]) as sb:
...     [o.value for o in sb.run([Call("add", (1, 2))], timeout=30)]
[3]

Modules: :mod:`.sandbox` (the sandbox), :mod:`.pool` (zygotes shared by a student's exercises),
:mod:`.limits`, :mod:`.wire` (the data both ways, :class:`Call`, :class:`Outcome`), :mod:`.launch`
(what a child sees), :mod:`.runtime` (the interpreter, site-packages, filtered copies),
:mod:`.cache`, :mod:`.isolation` (modes, uids, clean-up, disk meters), :mod:`.cgroups`,
:mod:`.seccomp`, :mod:`.formula` (formulas read and evaluated inside the sandbox) and the runner
``_child.py``. Its attack suite is ``grading_sandbox/tests`` (run by the repository's test command;
:mod:`.testing` selects a mode for it).

Threat model
------------
The student controls the code of the graded cells and wants a higher score than their answer earns
(or to learn the hidden tests, read other students' work, or damage the grading machine). The
grader controls everything else. Defences, outermost first, and what each one stops:

1. **Separate process, data-only protocol.** The grader never imports, compiles or executes
   student code. A fresh ``python -I -S`` child runs the runner ``_child.py``, receives the cells
   and the inputs (length-prefixed JSON on stdin) and sends back plain data (length-prefixed
   JSON on a dedicated pipe). Expected values never leave the grader; the grader decodes at most
   ``Limits.output_bytes`` per batch with :func:`json.loads` and compares with its own numpy.
   This stops monkeypatching numpy / numpy.testing,
   objects whose ``__eq__`` lies, lying ndarray subclasses (only the raw buffer is serialised, and
   the grader re-checks exact JSON types), ``sys.exit``/``os._exit`` (the batch's unanswered calls
   fail; the next batch gets a fresh child) and forged result files (scores never come from exit
   codes, printed text or files).
2. **bubblewrap** (``isolation == "bwrap"``): new user, mount, pid, network, ipc, uts and cgroup
   namespaces; ``--die-with-parent``, ``--new-session``; a fresh root holding only read-only binds of
   ``/usr`` (and the ``/lib*`` links), the Python runtime, the packages of the exercise's
   allowlist (``allowed``: e.g. numpy and scipy and nothing else of the environment; without an
   allowlist the virtual environment's site-packages), a *filtered copy* of each exposed package
   (``packages``, blocked modules replaced by stubs that raise ``ImportError``) and the runner. Two tmpfs of
   ``Limits.disk_bytes`` each, HOME (the cwd) and ``/tmp``, are the only writable places: the
   kernel bounds their size, they vanish with the sandbox, and the grader reads their use with
   ``statvfs`` (bytes and files, ``disk_bytes``/``disk_files``); bubblewrap's own root and ``/dev``
   (tmpfs, i.e. RAM) are remounted read-only, so neither the disk nor the RAM of the machine can
   be filled. Nothing of the grader (its checkout, the tests, solutions, its output, gradebook) exists
   inside. Blocked third-party packages (e.g. ``scipy.optimize``) have a stub directory bound over
   them, so even loading their files by path fails. No network interfaces but loopback of the new
   namespace (so no connection to the host). When the grader runs as root it switches, before
   starting bubblewrap, to a per-sandbox unprivileged uid (RLIMIT_NPROC is then enforced and
   private to this student); a Python runtime that uid cannot read (e.g. pyenv under ``/root``) is
   mirrored once, by hard links, into a world-readable cache.
3. **Resource limits**: a cgroup per sandbox where one can be made (:mod:`.cgroups`:
   memory of all its processes together, memfd, shared memory and its tmpfs included, and
   processes), and ``setrlimit`` before exec (RLIMIT_NPROC also in the child): CPU time,
   address space (memory bombs fail with MemoryError), processes (fork bombs), open files, file
   size, no core files; the grader enforces a wall-clock timeout per batch and output size per
   batch, and on any violation kills the whole sandbox (process group; bubblewrap's pid namespace;
   as root also every process of the sandbox uid), so nothing outlives it. A seccomp filter
   (:mod:`.seccomp`, every mode) refuses ``memfd_create``, System V shared
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
a grader checks that for real (:func:`.isolation.readable_by_sandbox`) and refuses to grade
otherwise. The uid cannot signal or ptrace the grader
(another uid), cannot write anywhere but its folder and the machine's world-writable folders, whose
entries of its uid are counted against the disk limit and removed with the sandbox. Unlike
bubblewrap it can see the machine's other world-readable files and its network.
The variable :data:`.config.ENV_MODE` set to ``setpriv`` forces it; :data:`.config.ENV_BWRAP`
names the bubblewrap binary (tests point it at a failing stub to run as Gradescope does).

Zygotes (:class:`SandboxPool`, what a class run uses): starting a sandboxed interpreter and
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
zygote down with it, and the next exercise starts a new sandbox. A grader's worker may keep its
zygotes for its students one after the other. A child per exercise, not one per student: a fork
and the clean-up after it cost about 1 to 10 ms of CPU (the more the zygote imported), some 5 % of
grading a student, and they keep each exercise's import guard, namespace and limits its own (a
crash, ``sys.exit`` or a monkeypatched numpy in one exercise cannot change another one's score).

Fallback (``isolation == "fallback: <why>"``): when bubblewrap is missing or namespaces are not
allowed (a student's laptop checking their own work), the child is a plain subprocess with the
same limits, an empty temporary cwd, ``-I -S``, the filtered package copies, and (as root) a
per-sandbox uid; its folder on the host is measured by walking it with directory descriptors
(deleted files still open counted). The audit hook additionally refuses the real folders of the
exposed and private packages (and the source checkout of an editable install), blocked packages and
those outside the allowlist, ``hidden_paths`` (a grader passes the submissions, its output folder
and its key file), sockets and process spawning. This is best effort: a determined student can get
around an in-process hook (e.g. through ctypes), which is why a class run should refuse the
fallback unless told otherwise (a student's own check may fall back with a warning).
:data:`.config.ENV_MODE` set to ``fallback`` forces the fallback, ``bwrap`` requires bubblewrap;
unset, the sandbox uses bubblewrap, else setpriv (as root), else the fallback.

The prepared copies the sandbox reads are kept between runs in a cache (:mod:`.cache`);
:mod:`.runtime` makes them, :mod:`.isolation` starts and ends the child's isolation, :mod:`.wire`
encodes the data both ways.
"""


from .isolation import SandboxUnavailable, bwrap_status, choose_mode, readable_by_sandbox
from .limits import Limits
from .pool import SandboxPool
from .sandbox import Sandbox, SandboxConfigError
from .wire import Call, Outcome

__all__ = [
    "Call",
    "Limits",
    "Outcome",
    "Sandbox",
    "SandboxConfigError",
    "SandboxPool",
    "SandboxUnavailable",
    "bwrap_status",
    "choose_mode",
    "readable_by_sandbox",
]
