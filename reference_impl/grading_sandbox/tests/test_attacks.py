"""The attack list, run against the Sandbox directly with a toy exercise.

The toy exercise grades ``add(a, b)`` against ``a + b`` computed here by the test (the trusted
oracle) on random arrays. Each attack must score what an honest wrong answer scores (0), the run
must complete, later calls must still work, and nothing outside the student's temporary directory
may change. Every attack runs under bubblewrap (required: the test fails if it is missing); the fast
ones also under the fallback.
"""

import hashlib
import os
import socket
from pathlib import Path

import numpy as np
import pytest

from grading_sandbox import Call, Limits, SandboxPool, bwrap_status
from grading_sandbox import Sandbox as _Sandbox
from grading_sandbox.runtime import package_dir, project_root, site_dirs
from grading_sandbox.testing import SANDBOX_MODES, use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

# the checkout these tests run from: the source tree of the package (found as the sandbox finds it)
REPO = project_root(package_dir("grading_sandbox"), site_dirs())
LIBRARY = ("flowtrack",)  # the package these sandboxes expose (the repository's library)
GRADER = ("flowtrack_course",)  # a grader's own package: never importable nor readable


def Sandbox(cells, **kwargs):
    return _Sandbox(cells, packages=LIBRARY, private=GRADER, **kwargs)


def _matches(outcome, expected, rtol=1e-6, atol=1e-9) -> bool:
    """The toy exercise's trusted comparison: a plain-data array of ``expected``'s shape, within the
    tolerances (what a grader's comparison checks)."""
    if not outcome.ok:
        return False
    try:
        got = np.array(outcome.value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return False
    return got.shape == np.shape(expected) and bool(np.allclose(got, expected, rtol=rtol, atol=atol))
LIMITS = Limits(cpu_seconds=3, wall_seconds=5, memory_bytes=1 << 30, processes=16)
HONEST_MUL = "\ndef mul(a, b):\n    return np.asarray(a) * b\n"


def _bwrap(monkeypatch):
    ok, why = bwrap_status()
    assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")


@pytest.fixture(params=SANDBOX_MODES)
def mode(request, monkeypatch, tmp_path_factory):
    return use_sandbox_mode(request.param, monkeypatch, tmp_path_factory)


@pytest.fixture
def bwrap_only(monkeypatch):
    _bwrap(monkeypatch)
    return "bwrap"


@pytest.fixture(params=["bwrap", "setpriv"])
def strong(request, monkeypatch, tmp_path_factory):
    """The modes that hold against code going around the in-process hook (namespaces, a uid)."""
    return use_sandbox_mode(request.param, monkeypatch, tmp_path_factory)


NEXT_EXERCISE = """
import os, tempfile
def probe():
    return [sorted(os.listdir(".")), sorted(os.listdir(tempfile.gettempdir())), "add" in globals()]
"""


def grade(cell: str, seed: int = 0, timeout: float = 5, blocked=(), hidden=(),
          spawn=False) -> tuple[float, list]:
    """Score the toy exercise: fraction of 3 add-calls within tolerance, then check mul still works.

    Run twice: in a fresh Sandbox, and as one exercise of a SandboxPool (the fast path of
    ``flowtrack grade``: a zygote forking a child per exercise) followed by another exercise in the
    same pool, which must start clean (empty HOME and TMPDIR, none of the attack's names). Both must
    score the same; the pooled run's outcomes are returned.
    """
    rng = np.random.default_rng(seed)
    pairs = [(rng.normal(size=(4, 3)), rng.normal(size=(4, 3))) for _ in range(3)]
    src = "import numpy as np\n" + cell + HONEST_MUL
    x = rng.normal(size=5)
    runs = []
    for pooled in (False, True):
        pool = SandboxPool()
        factory = pool if pooled else _Sandbox
        with factory([("answer", src)], limits=LIMITS, blocked=blocked, hidden_paths=hidden,
                     packages=LIBRARY, private=GRADER, spawn=spawn) as sb:
            outcomes = sb.run([Call("add", p) for p in pairs], timeout=timeout)
            score = np.mean([_matches(o, a + b) for o, (a, b) in zip(outcomes, pairs)])
            after = sb.run([Call("mul", (x, 3.0))], timeout=10)  # other tests go on
        assert _matches(after[0], x * 3.0), after[0]
        if pooled:
            with pool([("next", NEXT_EXERCISE)], limits=LIMITS, blocked=blocked, hidden_paths=hidden,
                      packages=LIBRARY, private=GRADER) as nx:
                (probe,) = nx.run([Call("probe")], timeout=10)
            assert probe.ok and probe.value == [[], [], False], probe
        pool.close()
        runs.append((float(score), outcomes))
    (plain, plain_out), (score, outcomes) = runs
    # (which calls fail may differ: a student who kills its zygote, the same uid, loses the rest of
    # its own batch, which a fresh sandbox's init would have survived; the score may not differ)
    assert plain == score, (plain_out, outcomes)
    return score, outcomes


def test_honest_answers_score_and_wrong_answers_do_not(mode):
    assert grade("def add(a, b):\n    return np.asarray(a) + b\n")[0] == 1.0
    assert grade("def add(a, b):\n    return np.asarray(a) - b\n")[0] == 0.0


@pytest.mark.parametrize("how", ["sys.exit(0)", "os._exit(0)", "raise SystemExit(0)"])
def test_exit_in_the_graded_function(mode, how):
    score, outcomes = grade(f"import os, sys\ndef add(a, b):\n    {how}\n")
    assert score == 0.0
    assert all(not o.ok and "exited" in o.error for o in outcomes)


def test_monkeypatching_numpy_comparisons(mode):
    cell = """
import numpy.testing
np.allclose = lambda *a, **k: True
np.array_equal = lambda *a, **k: True
np.isclose = lambda *a, **k: True
np.testing.assert_allclose = lambda *a, **k: None
np.testing.assert_array_equal = lambda *a, **k: None
def add(a, b):
    return np.zeros((4, 3))
"""
    score, _ = grade(cell)
    assert score == 0.0
    assert not np.allclose(0.0, 1.0)  # the grader's numpy is untouched


def test_object_whose_eq_is_always_true(mode):
    cell = """
class Anything:
    def __eq__(self, other):
        return True
    __hash__ = object.__hash__
    def __array__(self, *a, **k):
        return np.zeros((4, 3))
def add(a, b):
    return Anything()
"""
    score, outcomes = grade(cell)
    assert score == 0.0 and all(not o.ok for o in outcomes)


def test_lying_ndarray_subclass(mode):
    # The raw buffer holds a wrong answer; every method a naive grader might call tells the truth.
    cell = """
class Liar(np.ndarray):
    def __eq__(self, other):
        return np.ones(np.shape(other), dtype=bool)
    def tolist(self):
        return self.truth.tolist()
    def __array__(self, *a, **k):
        return self.truth
    def __iter__(self):
        return iter(self.truth)
    def __getitem__(self, i):
        return self.truth[i]
    def view(self, *a, **k):
        return self.truth
    def __array_function__(self, func, types, args, kwargs):
        return True
def add(a, b):
    out = (np.asarray(a) + b + 1.0).view(Liar)
    out.truth = np.asarray(a) + b
    return out
"""
    score, outcomes = grade(cell)
    assert score == 0.0 and all(o.ok for o in outcomes)  # converted from the raw (wrong) buffer


def test_writing_onto_the_reply_channel(mode):
    cell = """
import os, struct, json
def add(a, b):
    fake = json.dumps({"ok": True, "value": "x" * 10}).encode()
    for fd in range(3, 40):
        try:
            os.write(fd, struct.pack(">I", 0xFFFFFFF0) + b"junk")
        except OSError:
            pass
    return 0
"""
    score, outcomes = grade(cell)
    assert score == 0.0 and not outcomes[0].ok


@pytest.fixture
def course(tmp_path):
    """A course directory outside the sandbox: hidden tests, solutions, gradebook, grader output."""
    root = tmp_path / "course"
    for rel in ("exercises/hidden_tests.py", "solutions/ex01.py", "gradebook.db", "out/grades.csv",
                "out/alice/results.json"):
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("SECRET " + rel)
    return root


def _snapshot(root: Path) -> dict:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
        for p in sorted(root.rglob("*"))
    }


def test_reading_hidden_tests_solutions_and_gradebook(mode, course):
    targets = [str(p) for p in sorted(course.rglob("*")) if p.is_file()]
    targets += [str(REPO / d) for d in ("exercises", "solutions", "reference_impl/flowtrack/camera.py",
                                        "exercises/ex05_cv_model/grading.py",
                                        "reference_impl/flowtrack_course/grading/engine/run.py", "README.md")]
    cell = f"""
import os
TARGETS = {targets!r}
def add(a, b):
    found = []
    for t in TARGETS:
        try:
            if os.path.isdir(t):
                found.append(os.listdir(t))
            else:
                found.append(open(t).read())
        except OSError:
            pass
    if found:
        raise RuntimeError("LEAK " + repr(found)[:200])
    return np.asarray(a) + b
"""
    score, outcomes = grade(cell, hidden=[course])
    assert score == 1.0, [o.error for o in outcomes]  # nothing could be read


def test_writing_fake_results_anywhere(mode, course, tmp_path):
    before = _snapshot(tmp_path)
    repo_before = {p.name for p in REPO.iterdir()}
    targets = [str(course / "out" / "grades.csv"), str(course / "out" / "alice" / "results.json"),
               str(course / "results.json"), str(tmp_path / "grades.csv"), str(REPO / "results.json"),
               str(REPO / "grades.csv"), "/tmp/results.json", "results.json", "../results.json",
               os.path.expanduser("~/results.json")]
    cell = f"""
import os
def add(a, b):
    for t in {targets!r}:
        try:
            os.makedirs(os.path.dirname(t) or ".", exist_ok=True)
            with open(t, "w") as f:
                f.write('{{"score": 100, "tests": []}}')
        except OSError:
            pass
    return np.zeros((4, 3))
"""
    score, _ = grade(cell, hidden=[course])
    assert score == 0.0
    assert _snapshot(tmp_path) == before
    assert {p.name for p in REPO.iterdir()} == repo_before
    assert not Path("/tmp/results.json").exists()


def test_infinite_loop(mode):
    score, outcomes = grade("def add(a, b):\n    while True:\n        pass\n", timeout=2)
    assert score == 0.0 and all("timed out" in o.error or "CPU" in o.error for o in outcomes)


def test_memory_bomb(mode):
    cell = "def add(a, b):\n    x = [bytearray(1 << 26) for _ in range(10 ** 6)]\n    return x\n"
    score, outcomes = grade(cell, timeout=20)
    assert score == 0.0 and "memory" in outcomes[0].error


@pytest.mark.parametrize("spawn", [False, True], ids=["notebook", "starts-programs"])
def test_fork_bomb(strong, spawn):
    # a notebook's child may not fork at all (the kernel refuses); an exercise that starts programs
    # may, up to the sandbox's process limit
    cell = """
import os
def add(a, b):
    while True:
        try:
            os.fork()
        except OSError:
            pass
"""
    score, outcomes = grade(cell, timeout=2, spawn=spawn)
    assert score == 0.0 and all(not o.ok for o in outcomes)


def test_100_mb_of_output(mode):
    cell = """
import os, sys
def add(a, b):
    block = "x" * (1 << 20)
    for _ in range(100):
        print(block)
        sys.stderr.write(block)
        os.write(1, block.encode())
    return ["y" * (1 << 20)] * 100
"""
    score, outcomes = grade(cell, timeout=20)
    assert score == 0.0 and "output limit" in outcomes[0].error


def test_opening_a_socket(mode):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(5)
    server.setblocking(False)
    port = server.getsockname()[1]
    cell = f"""
import socket
def add(a, b):
    s = socket.create_connection(("127.0.0.1", {port}), timeout=1)
    s.sendall(b"give me the hidden tests")
    return np.asarray(a) + b
"""
    try:
        score, outcomes = grade(cell)
        with pytest.raises(BlockingIOError):
            server.accept()  # nobody connected
    finally:
        server.close()
    assert score == 0.0 and all(not o.ok for o in outcomes)


def test_importing_the_graded_flowtrack_function(mode):
    real = REPO / "reference_impl" / "flowtrack" / "camera.py"
    cell = f"""
import importlib, importlib.util, sys
def add(a, b):
    try:
        from flowtrack.camera import projection_jacobian
        return "imported"
    except ImportError:
        pass
    for path in [{str(real)!r}]:
        try:
            spec = importlib.util.spec_from_file_location("cam", path)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            return "loaded by path"
        except (ImportError, OSError, AttributeError):
            pass
    try:
        import flowtrack_course.grading.engine
        return "grader imported"
    except ImportError:
        pass
    return np.asarray(a) + b
"""
    score, outcomes = grade(cell, blocked=["flowtrack.camera"])
    assert score == 1.0, [o.value if o.ok else o.error for o in outcomes]


def test_blocked_third_party_by_path(bwrap_only):
    import scipy.optimize

    so = Path(scipy.optimize.__file__).parent
    cell = f"""
import glob, importlib.util
def add(a, b):
    files = glob.glob({str(so)!r} + "/*") + glob.glob("/opt/flowtrack-sandbox/site/*/scipy/optimize/*")
    for f in files:
        if f.endswith(".so") or f.endswith("_lsap.py"):
            return "found " + f
    try:
        from scipy.optimize import linear_sum_assignment
        return "imported"
    except ImportError:
        return np.asarray(a) + b
"""
    score, outcomes = grade(cell, blocked=["scipy.optimize"])
    assert score == 1.0, [o.value if o.ok else o.error for o in outcomes]


# --------------------------------------------------------------------------------------------------
# Attacks beyond the list: the machine itself, the reply channel, cleanup, comparisons.


def test_filling_the_disk_or_the_ram_is_stopped(mode):
    # 20 MB in the student's directory (over a 4 MiB disk limit) and, under bubblewrap, attempts on
    # bubblewrap's own tmpfs mounts (RAM no rlimit covers): the root, /dev, /dev/shm.
    limits = Limits(cpu_seconds=3, wall_seconds=5, memory_bytes=1 << 30, processes=16,
                    disk_bytes=4 << 20)
    cell = """
import os, tempfile, time
def fill(where):
    d = tempfile.gettempdir() if where == "tmp" else where
    for i in range(20):
        with open(os.path.join(d, f"f{i}"), "wb") as f:
            f.write(b"x" * (1 << 20))
    time.sleep(3)  # the grader measures while it waits
    return 1
def ram():
    ok = []
    for d in ("/", "/dev", "/dev/shm", "/opt", "/home"):
        try:
            open(d + "/x", "wb").close()
            ok.append(d)
        except OSError:
            pass
    return ok
"""
    for where in ("tmp", "."):
        with Sandbox([("a", cell)], limits=limits) as sb:
            (out,) = sb.run([Call("fill", (where,))], timeout=5)
            # the grader's meter (fallback) or the kernel's bound on the sandbox's tmpfs (bubblewrap)
            assert not out.ok and ("disk limit" in out.error or "No space left" in out.error), (where, out)
            (again,) = sb.run([Call("ram")], timeout=10)  # a fresh child, other tests go on
            assert again.ok
            if mode == "bwrap":
                assert again.value == [], again.value


def test_forged_replies_on_the_reply_channel(mode):
    # The student finds the reply pipe and writes raw frames: deeply nested JSON, a 100000-digit
    # integer, a frame that never completes (slow drip). Each fails the call; nothing hangs.
    frames = {
        "nested": "b'[' * 100000 + b']' * 100000",
        "bigint": "b'{\"ok\": true, \"value\": ' + b'9' * 100000 + b'}'",
    }
    for name, payload in [*frames.items(), ("drip", None)]:
        if payload is None:
            body = ("    os.write(fd, struct.pack('>I', 100))\n"
                    "    for _ in range(100):\n        os.write(fd, b' ')\n        time.sleep(0.3)\n")
        else:
            body = f"    d = {payload}\n    os.write(fd, struct.pack('>I', len(d)) + d)\n"
        find_pipe = (
            "import os, struct, time\ndef add(a, b):\n"
            "    fd = next(f for f in range(3, 40) if 'pipe' in os.path.realpath(f'/proc/self/fd/{f}'))\n"
        )
        cell = find_pipe + body + "    return 0\n"
        score, outcomes = grade(cell, timeout=2)
        assert score == 0.0 and not outcomes[0].ok, (name, outcomes[0])
        # the forged frame did reach the grader (not, say, a failure to find the pipe)
        assert ("timed out" if name == "drip" else "not valid data") in outcomes[0].error, outcomes[0]


def test_a_grandchild_holding_the_reply_pipe_dies_with_the_sandbox(strong):
    cell = """
import os, time
def add(a, b):
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            time.sleep(1000)  # keeps the reply pipe open
        os._exit(0)
    os._exit(0)
"""
    with Sandbox([("a", "import numpy as np\n" + cell + HONEST_MUL)], limits=LIMITS) as sb:
        (out,) = sb.run([Call("add", (1.0, 2.0))], timeout=5)
        uid = sb._uid
        assert not out.ok
        x = np.arange(3.0)
        assert _matches(sb.run([Call("mul", (x, 2.0))], timeout=10)[0], 2 * x)
    if uid is not None:  # grading as root: a per-sandbox uid, so we can look for survivors
        from grading_sandbox.isolation import uid_has_processes

        assert not uid_has_processes(uid)


def test_signals_and_ctypes_cannot_reach_the_grader(mode):
    cell = """
import ctypes, os, signal
def add(a, b):
    for target in (os.getppid(), -1, 1):
        try:
            os.kill(target, signal.SIGKILL)
        except (OSError, PermissionError):
            pass
    if MODE in ("bwrap", "setpriv"):  # ctypes goes around any in-process hook: namespaces or the uid stop it
        libc = ctypes.CDLL(None)
        libc.kill(os.getppid(), 9)
        libc.kill(-1, 9)
    return np.zeros((4, 3))
"""
    score, _ = grade(f"MODE = {mode!r}\n" + cell)
    assert score == 0.0  # and we are still here: grade() ran a later call successfully


def test_students_cannot_see_each_others_directories(mode):
    if mode == "fallback" and os.geteuid() != 0:
        pytest.skip("the fallback as an ordinary user runs every student as that user")
    writer = "def add():\n    open('answer.txt', 'w').write('SECRET')\n    return 1\n"
    with Sandbox([("a", writer)], limits=LIMITS) as a:
        assert a.run([Call("add")], timeout=10)[0].ok
        secret = a._workdir / "home" / "answer.txt"
        if mode == "bwrap":  # written to the sandbox's own tmpfs: not on the host at all
            assert not secret.exists()
            secret = Path("/home/student/answer.txt")  # the same path in another sandbox
        else:
            assert secret.read_text() == "SECRET"
        reader = f"def add():\n    return open({str(secret)!r}).read()\n"
        with Sandbox([("b", reader)], limits=LIMITS) as b:
            (out,) = b.run([Call("add")], timeout=10)
        assert not out.ok, out.value


def test_cleanup_does_not_chmod_through_planted_symlinks():
    # A read-only directory holding a symlink to a file of the grader makes the first unlink fail
    # (for a non-root grader); the clean-up then must not chmod the symlink's target.
    import shutil
    import tempfile

    from grading_sandbox.isolation import remove_tree

    tmp_path = Path(tempfile.mkdtemp(prefix="ft-rmtree-"))  # traversable by the uid used below
    try:
        _check_cleanup(tmp_path, remove_tree)
    finally:
        shutil.rmtree(tmp_path, ignore_errors=True)


def _check_cleanup(tmp_path, remove_tree):
    target = tmp_path / "grader_secret"
    target.write_text("x")
    target.chmod(0o600)
    work = tmp_path / "work"
    (work / "d").mkdir(parents=True)
    (work / "d" / "link").symlink_to(target)
    (work / "d").chmod(0o500)
    uid = 65534 if os.geteuid() == 0 else None
    if uid is not None:  # root ignores the read-only directory; act as an ordinary user
        for p in (tmp_path, work, work / "d"):
            os.chown(p, uid, uid)
        os.lchown(work / "d" / "link", uid, uid)
        os.chown(target, uid, uid)
        os.chmod(tmp_path, 0o755)
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        code = 1
        try:
            if uid is not None:
                os.setresgid(uid, uid, uid)
                os.setresuid(uid, uid, uid)
            remove_tree(work)
            code = 0
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert not work.exists()
    assert target.stat().st_mode & 0o777 == 0o600


def test_writing_into_the_sandbox_caches_or_the_runtime(mode):
    # The filtered flowtrack copy, the runner, the Python runtime (or its mirror) and numpy are
    # shared by every later student: none of them may be changed from inside.
    from grading_sandbox import runtime

    # The copy and the runner this sandbox mounts (built here if a source edit made new ones);
    # the shared cache folders themselves gain copies for other blocked sets from parallel runs.
    grade("def add(a, b):\n    return np.asarray(a) + b\n")
    mounted = (runtime.filtered_packages(LIBRARY, ()), runtime.runner_dir())
    before = [_snapshot(d) for d in mounted]
    cell = """
import os, sys, flowtrack, numpy
def add(a, b):
    wrote = []
    dirs = [os.path.dirname(flowtrack.__file__), os.path.dirname(os.__file__),
            os.path.dirname(numpy.__file__), os.path.dirname(os.path.abspath(sys.argv[0]))]
    for d in dirs:
        for name in ("__init__.py", "evil.py", "_child.py"):
            try:
                with open(os.path.join(d, name), "a") as f:
                    f.write("\\nraise SystemExit")
                wrote.append(os.path.join(d, name))
            except OSError:
                pass
    if wrote:
        raise RuntimeError("WROTE " + repr(wrote))
    return np.asarray(a) + b
"""
    score, outcomes = grade(cell)
    assert score == 1.0, [o.error for o in outcomes]
    assert [_snapshot(d) for d in mounted] == before
    assert all(before), "the snapshot saw the mounted files"
