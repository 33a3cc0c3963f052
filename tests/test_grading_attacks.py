"""Issue 5's attack list, run against the Sandbox directly with a toy exercise.

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

from flowtrack.grading.sandbox import Limits, Sandbox, bwrap_status
from flowtrack.grading.spec import Call, compare_arrays

pytestmark = pytest.mark.xdist_group("sandbox")

REPO = Path(__file__).resolve().parents[1]
LIMITS = Limits(cpu_seconds=3, wall_seconds=5, memory_bytes=1 << 30, processes=16)
HONEST_MUL = "\ndef mul(a, b):\n    return np.asarray(a) * b\n"


def _bwrap(monkeypatch):
    ok, why = bwrap_status()
    assert ok, f"bubblewrap must work for the attack tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")


@pytest.fixture(params=["bwrap", "fallback"])
def mode(request, monkeypatch):
    if request.param == "bwrap":
        _bwrap(monkeypatch)
    else:
        monkeypatch.setenv("FLOWTRACK_SANDBOX", "fallback")
    return request.param


@pytest.fixture
def bwrap_only(monkeypatch):
    _bwrap(monkeypatch)
    return "bwrap"


def grade(cell: str, seed: int = 0, timeout: float = 5, blocked=(), hidden=()) -> tuple[float, list]:
    """Score the toy exercise: fraction of 3 add-calls within tolerance, then check mul still works."""
    rng = np.random.default_rng(seed)
    pairs = [(rng.normal(size=(4, 3)), rng.normal(size=(4, 3))) for _ in range(3)]
    src = "import numpy as np\n" + cell + HONEST_MUL
    with Sandbox([("answer", src)], limits=LIMITS, blocked=blocked, hidden_paths=hidden) as sb:
        outcomes = sb.run([Call("add", p) for p in pairs], timeout=timeout)
        score = np.mean([compare_arrays(o, a + b)[0] for o, (a, b) in zip(outcomes, pairs)])
        x = rng.normal(size=5)
        after = sb.run([Call("mul", (x, 3.0))], timeout=10)  # other tests go on
    assert compare_arrays(after[0], x * 3.0)[0], after[0]
    return float(score), outcomes


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
                                        "reference_impl/flowtrack/grading/exercises.py", "README.md")]
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


def test_fork_bomb(bwrap_only):
    cell = """
import os
def add(a, b):
    while True:
        try:
            os.fork()
        except OSError:
            pass
"""
    score, outcomes = grade(cell, timeout=2)
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
        import flowtrack.grading.exercises
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
