"""The sandbox: protocol, conversion, cell errors, restarts, limits, blocked modules, its cache.

Expected values are computed here with numpy (the independent oracle); the sandbox only transports.
The attack suite is in test_attacks.py. The exposed package of these tests is the repository's own
library, ``flowtrack`` (any package would do).
"""

import math
import os
import time
from pathlib import Path

import numpy as np
import pytest

from grading_sandbox import Call, Limits, bwrap_status
from grading_sandbox import Sandbox as _Sandbox
from grading_sandbox.runtime import package_dir, project_root, site_dirs

pytestmark = pytest.mark.xdist_group("sandbox")

# the checkout these tests run from: the source tree of the package (found as the sandbox finds it)
REPO = project_root(package_dir("grading_sandbox"), site_dirs())
FAST = Limits(cpu_seconds=5, wall_seconds=10, memory_bytes=1 << 30)
LIBRARY = ("flowtrack",)  # the package these sandboxes expose
GRADER = ("flowtrack_course",)  # a grader's own package: never importable nor readable


def Sandbox(cells, **kwargs):
    return _Sandbox(cells, packages=LIBRARY, private=GRADER, **kwargs)


@pytest.fixture(params=["bwrap", "fallback"])
def mode(request, monkeypatch):
    if request.param == "bwrap":
        ok, why = bwrap_status()
        assert ok, f"bubblewrap must work for the grader's tests (make test installs it): {why}"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", request.param)
    return request.param


# -- extract_cells ----------------------------------------------------------------------------------


ECHO = """
import numpy as np
def describe(x):
    return {"type": type(x).__name__, "dtype": str(getattr(x, "dtype", "")), "shape": list(np.shape(x))}
def add(a, b):
    return np.asarray(a) + b
def scalar():
    return np.float32(1.5), np.int64(7), np.bool_(True), 2, "text", None
def special():
    return [float("nan"), float("inf"), -float("inf")]
def obj():
    return object()
def cplx():
    return np.ones(2) * 1j
"""


def test_protocol_roundtrip_and_conversion(mode, rng):
    a = rng.normal(size=(3, 2))
    b = rng.normal(size=(3, 2))
    calls = [
        Call("add", (a, b)),
        Call("describe", (a,)),
        Call("describe", (np.arange(4).reshape(2, 2),)),
        Call("describe", (np.zeros((0, 3)),)),
        Call("describe", ([1, 2, 3],)),
        Call("describe", (3,)),
        Call("describe", (), {"x": (1.0, 2.0)}),
        Call("scalar"),
        Call("special"),
        Call("obj"),
        Call("cplx"),
    ]
    with Sandbox([("echo", ECHO)], limits=FAST) as sb:
        assert sb.isolation == "bwrap" if mode == "bwrap" else sb.isolation.startswith("fallback:")
        out = sb.run(calls, timeout=20)
    assert out[0].ok and np.array_equal(np.asarray(out[0].value), a + b)  # JSON keeps float64 exactly
    assert out[1].value == {"type": "ndarray", "dtype": "float64", "shape": [3, 2]}
    assert out[2].value == {"type": "ndarray", "dtype": "int64", "shape": [2, 2]}
    assert out[3].value == {"type": "ndarray", "dtype": "float64", "shape": [0, 3]}
    assert out[4].value == {"type": "list", "dtype": "", "shape": [3]}
    assert out[5].value == {"type": "int", "dtype": "", "shape": []}
    assert out[6].value == {"type": "list", "dtype": "", "shape": [2]}  # tuples travel as lists
    assert out[7].value == [1.5, 7, True, 2, "text", None]
    assert [type(v) for v in out[7].value[:4]] == [float, int, bool, int]
    v = out[8].value
    assert math.isnan(v[0]) and v[1] == math.inf and v[2] == -math.inf
    assert not out[9].ok and "object" in out[9].error
    assert not out[10].ok and "complex" in out[10].error


def test_arguments_that_cannot_be_sent_raise():
    sb = Sandbox([("a", "x = 1")])
    with pytest.raises(TypeError, match="cannot be sent"):
        sb.run([Call("f", (object(),))])
    with pytest.raises(TypeError, match="Call"):
        sb.run(["f"])
    with pytest.raises(ValueError, match="timeout"):
        sb.run([Call("f")], timeout=0)
    with pytest.raises(TypeError, match="cells"):
        Sandbox("def f(): pass")
    with pytest.raises(TypeError, match="blocked"):
        Sandbox([("a", "")], blocked="scipy")
    with pytest.raises(ValueError, match="cpu_seconds"):
        Limits(cpu_seconds=-1)


def test_cell_errors_are_reported_and_other_cells_run(mode):
    cells = [
        ("broken", "def f(:\n    pass\n"),
        ("raises", "raise RuntimeError('boom')"),
        ("exits", "import sys\nsys.exit(3)"),
        ("good", "def g(x):\n    return 2 * x\n"),
    ]
    with Sandbox(cells, limits=FAST) as sb:
        out = sb.run([Call("g", (21,)), Call("f", (1,))], timeout=20)
        assert set(sb.cell_errors) == {"broken", "raises", "exits"}
        assert "SyntaxError" in sb.cell_errors["broken"]
        assert "RuntimeError: boom" in sb.cell_errors["raises"]
        assert "sys.exit" in sb.cell_errors["exits"]
    assert out[0].ok and out[0].value == 42
    assert not out[1].ok and "no function named 'f'" in out[1].error


def test_prints_are_captured_not_mixed_with_replies(mode):
    src = "import os\ndef f(x):\n    print('hello', x)\n    os.write(1, b'raw fd write')\n    return x\n"
    with Sandbox([("a", src)], limits=FAST) as sb:
        out = sb.run([Call("f", (5,))], timeout=20)
        assert out[0].value == 5
        assert "hello 5" in sb.stdout


def test_restart_after_crash_reexecutes_cells(mode):
    src = (
        "import os\ncount = 0\n"
        "def bump():\n    global count\n    count += 1\n    return count\n"
        "def die():\n    os._exit(0)\n"
    )
    with Sandbox([("a", src)], limits=FAST) as sb:
        assert [o.value for o in sb.run([Call("bump"), Call("bump")], timeout=20)] == [1, 2]
        out = sb.run([Call("bump"), Call("die"), Call("bump")], timeout=20)
        assert out[0].value == 3
        assert not out[1].ok and "exited" in out[1].error
        assert not out[2].ok and "exited" in out[2].error
        # a fresh child: the cells ran again, so the counter starts over
        assert [o.value for o in sb.run([Call("bump")], timeout=20)] == [1]


def test_a_child_doomed_by_an_earlier_batch_does_not_cost_the_next(mode):
    # The first batch leaves a thread that ends the process a moment after the batch was answered
    # (as a student who kills its zygote does). The next batch must not be charged for that death:
    # it is sent again to a fresh child, once. A batch that kills its own child is not rescued.
    src = (
        "import os, threading, time\ncount = 0\n"
        "def bump():\n    global count\n    count += 1\n    return count\n"
        "def doom():\n"
        "    threading.Thread(target=lambda: (time.sleep(0.3), os._exit(0))).start()\n    return 1\n"
        "def die():\n    os._exit(0)\n"
    )
    with Sandbox([("a", src)], limits=FAST) as sb:
        assert [o.value for o in sb.run([Call("bump"), Call("doom")], timeout=20)] == [1, 1]
        time.sleep(1.0)  # the child is gone now, and the grader has not been told
        assert [o.value for o in sb.run([Call("bump")], timeout=20)] == [1]  # a fresh child's count
        assert sb.run([Call("bump")], timeout=20)[0].value == 2  # and it lives on
        out = sb.run([Call("die"), Call("bump")], timeout=20)
        assert [o.ok for o in out] == [False, False] and "exited" in out[0].error
        assert sb.run([Call("bump")], timeout=20)[0].value == 1


def test_timeout_cpu_memory_and_output_limits(mode):
    src = (
        "import numpy as np\n"
        "def spin():\n    while True:\n        pass\n"
        "def sleep():\n    import time\n    time.sleep(60)\n"
        "def hog():\n    return np.ones(1 << 31).sum()\n"
        "def big():\n    return list(range(400_000))\n"
        "def ok():\n    return 1\n"
    )
    lim = Limits(cpu_seconds=1, wall_seconds=5, memory_bytes=1 << 30, output_bytes=1 << 20)
    with Sandbox([("a", src)], limits=lim) as sb:
        out = sb.run([Call("spin"), Call("ok")], timeout=60)  # generous: the CPU limit must fire first
        assert [o.ok for o in out] == [False, False]
        assert "CPU time" in out[0].error
        out = sb.run([Call("sleep")], timeout=1)
        assert out[0].error == "timed out after 1 s"
        out = sb.run([Call("hog"), Call("ok")], timeout=20)
        assert "memory" in out[0].error and out[1].value == 1
        out = sb.run([Call("big"), Call("ok")], timeout=20)
        assert "output limit" in out[0].error and not out[1].ok
        assert sb.run([Call("ok")], timeout=20)[0].value == 1


def test_blocked_modules_and_filtered_flowtrack(mode):
    src = """
import importlib
def try_import(name):
    try:
        importlib.import_module(name)
        return "ok"
    except ImportError as exc:
        return "ImportError: " + str(exc)
"""
    blocked = ["flowtrack.kalman", "scipy.optimize"]
    with Sandbox([("a", src)], blocked=blocked, limits=FAST) as sb:
        names = ["flowtrack.kalman", "flowtrack.camera", "flowtrack_course.grading",
                 "flowtrack_course.grading.engine", "grading_sandbox",
                 "scipy.optimize", "scipy.linalg", "numpy"]
        outcomes = sb.run([Call("try_import", (n,)) for n in names], timeout=30)
        out = dict(zip(names, (o.value for o in outcomes)))
    assert out["flowtrack.kalman"] == "ImportError: flowtrack.kalman is not available in this exercise"
    assert out["flowtrack.camera"] == "ok"
    assert out["flowtrack_course.grading"].startswith("ImportError")
    assert out["flowtrack_course.grading.engine"].startswith("ImportError")
    assert out["grading_sandbox"].startswith("ImportError")  # the sandbox itself
    assert out["scipy.optimize"].startswith("ImportError") and "scipy.optimize" in out["scipy.optimize"]
    assert out["scipy.linalg"] == "ok" and out["numpy"] == "ok"


def test_the_repository_is_invisible_under_bwrap(monkeypatch):
    assert bwrap_status()[0], "bubblewrap must work for the grader's tests"
    monkeypatch.setenv("FLOWTRACK_SANDBOX", "bwrap")
    src = """
import os, sys
def look(path):
    return os.path.exists(path)
def ls(path):
    return sorted(os.listdir(path)) if os.path.isdir(path) else None
def env():
    return sorted(os.environ)
def ident():
    return [os.getuid(), os.getcwd(), os.listdir("."), sorted(os.listdir("/"))]
"""
    with Sandbox([("a", src)], limits=FAST) as sb:
        out = sb.run([Call("look", (str(REPO),)), Call("ls", (str(Path.home()),)), Call("env"),
                      Call("ident")], timeout=20)
    assert out[0].value is False
    # at most the directories leading to a bound Python runtime (e.g. pyenv's), nothing else of home
    assert out[1].value in (None, [], [".pyenv"], [".local"])
    assert set(out[2].value) <= {"PATH", "HOME", "PWD", "TMPDIR", "LANG", "MPLBACKEND",
                                 "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                                 "PYTHONDONTWRITEBYTECODE"}
    uid, cwd, listing, root = out[3].value
    assert uid == 65534 and cwd == "/home/student" and listing == []
    assert "work" not in root
    if os.geteuid() == 0:  # the grader is root: the child must not be
        assert sb._uid is None or sb._uid >= 1_600_000_000


@pytest.mark.skipif(os.geteuid() != 0, reason="only root hands the sandbox to another uid")
def test_root_with_a_private_tmpdir_still_grades(tmp_path, monkeypatch):
    # A fresh machine where root's TMPDIR is private (e.g. /root/tmp, mode 700): the sandbox's
    # unprivileged uid must still reach its cache and its directory.
    import tempfile

    from grading_sandbox import cache

    private = tmp_path / "private"
    private.mkdir(mode=0o700)
    monkeypatch.delenv("FLOWTRACK_SANDBOX_CACHE", raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(private))
    root = cache.cache_root()
    assert not root.is_relative_to(private) and cache.world_readable(root / "work", read=False)
    with Sandbox([("a", "def f(x):\n    return x + 1\n")], limits=FAST) as sb:
        assert sb.run([Call("f", (1,))], timeout=20)[0].value == 2


@pytest.mark.skipif(os.geteuid() != 0, reason="only root hands the sandbox to another uid")
def test_root_with_a_private_venv_still_grades(tmp_path, monkeypatch):
    # A fresh clone under /root (mode 700) with its .venv there: the unprivileged uid cannot read
    # those packages, so the sandbox gets a world-readable mirror of them (without flowtrack).
    from grading_sandbox import runtime
    from grading_sandbox import sandbox as sbmod

    real = runtime.site_dirs()
    private = tmp_path / "venv" / "site-packages"
    (private / "mypkg").mkdir(parents=True)
    (private / "mypkg" / "__init__.py").write_text("X = 42\n")
    (private / "flowtrack").mkdir()
    (private / "flowtrack" / "secret.py").write_text("S = 1\n")
    # made under umask 077 (as root's `python3 -m venv .venv` with a private umask): a hard link
    # of a 0600 file would keep its mode, so the mirror must copy it
    (private / "mypkg" / "__init__.py").chmod(0o600)
    (private / "mypkg").chmod(0o700)
    (tmp_path / "venv").chmod(0o700)
    monkeypatch.setattr(sbmod, "site_dirs", lambda: [*real, str(private)])
    src = ("import glob\ndef f():\n    import mypkg\n"
           "    return [mypkg.X, glob.glob('/opt/*/site/*/flowtrack')]\n")
    for mode in ("bwrap", "fallback"):
        monkeypatch.setenv("FLOWTRACK_SANDBOX", mode)
        with Sandbox([("a", src)], limits=FAST) as sb:
            (out,) = sb.run([Call("f")], timeout=20)
        assert out.ok and out.value[0] == 42, (mode, out)
        if mode == "bwrap":
            assert out.value[1] == []  # the mirror leaves flowtrack out


# -- the cache of prepared copies -------------------------------------------------------------------


@pytest.fixture
def private_cache(monkeypatch):
    """A cache root of its own (FLOWTRACK_SANDBOX_CACHE, in a directory other users can traverse, as
    the sandbox's uid must when grading as root); the makers' remembered copies are forgotten before
    and after, so neither this test nor later ones use another root's copies."""
    import shutil
    import tempfile

    from grading_sandbox import cache, runtime

    makers = (runtime.filtered_packages, runtime.runner_dir, runtime.python_runtime)
    for m in makers:
        m.cache_clear()
    base = Path(tempfile.mkdtemp(prefix="flowtrack-cache-test-"))
    base.chmod(0o711)
    monkeypatch.setenv("FLOWTRACK_SANDBOX_CACHE", str(base))
    try:
        yield cache.cache_root()
    finally:
        for m in makers:
            m.cache_clear()
        shutil.rmtree(base, ignore_errors=True)


def _aged(path, days):
    t = time.time() - days * 86400
    os.utime(path, (t, t), follow_symlinks=False)
    return path


def test_stale_cached_copies_are_pruned_when_a_new_one_is_made(private_cache, tmp_path):
    from grading_sandbox import cache

    kind = private_cache / "pkg"
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("not the cache's")
    _aged(outside, 5)  # as stale as can be: only following a symlink would reach it

    def copy(name, days, link_out=False):
        d = kind / name
        d.mkdir()
        (d / "flowtrack").mkdir()
        (d / "flowtrack" / "__init__.py").write_text("")
        if link_out:
            (d / "escape").symlink_to(outside, target_is_directory=True)
        return _aged(d, days)

    stale = copy("a" * 20, 2, link_out=True)  # an older version, unused for two days
    recent = copy("b" * 20, 0.5)  # another fingerprint used hours ago: maybe by a running grader
    current = copy("c" * 20, 3)  # old, but the one asked for now: it is used, not rebuilt
    (kind / ".build-x1").mkdir()
    crashed = _aged(kind / ".build-x1", 2)  # a build interrupted two days ago
    (kind / ".build-x2").mkdir()  # a build in progress
    (kind / ".trash-9-9").mkdir()  # left by an interrupted prune
    (kind / "notes").mkdir()
    foreign = _aged(kind / "notes", 5)  # not a name the cache makes
    link = kind / ("d" * 20)
    link.symlink_to(outside, target_is_directory=True)
    _aged(link, 5)

    built = []
    assert cache.atomic_dir(current, built.append, prune=True) == current
    assert built == [] and time.time() - current.stat().st_mtime < 60  # marked as used
    assert stale.exists()  # nothing new was made: nothing is pruned

    new = cache.atomic_dir(kind / ("e" * 20), lambda tmp: (tmp / "x").write_text("1"), prune=True)
    assert (new / "x").read_text() == "1"
    left = sorted(p.name for p in kind.iterdir())
    assert left == sorted([".build-x2", ".lock", "b" * 20, "c" * 20, "d" * 20, "e" * 20, "notes"])
    assert not stale.exists() and not crashed.exists()
    assert recent.is_dir() and current.is_dir() and link.is_symlink() and foreign.is_dir()
    assert (outside / "keep.txt").read_text() == "not the cache's"  # symlinks were not followed


def test_sandbox_starts_mark_their_copies_used_and_survive_a_prune(mode, private_cache):
    stale = private_cache / "pkg" / ("a" * 20)  # a flowtrack copy of an older version
    (stale / "flowtrack").mkdir(parents=True)
    _aged(stale, 2)
    src = ("import importlib\ndef where(name):\n"
           "    return importlib.import_module(name).__file__.rsplit('/flowtrack/', 1)[1]\n")
    calls = [Call("where", ("flowtrack.camera",))]

    def copies():
        return sorted(p for p in (private_cache / "pkg").iterdir() if p.name[0] != ".")

    with Sandbox([("a", src)], blocked=["flowtrack.kalman"], limits=FAST) as sb:
        assert sb.run(calls, timeout=30)[0].value == "camera.py"
    (current,) = copies()  # the one made for this sandbox; the stale one was pruned on making it
    assert current != stale and not stale.exists()
    # an old copy is marked as used when a child starts with it ...
    _aged(current, 3)
    with Sandbox([("a", src)], blocked=["flowtrack.kalman"], limits=FAST) as sb:
        assert sb.run(calls, timeout=30)[0].value == "camera.py"
    assert time.time() - current.stat().st_mtime < 60
    # ... and one another grader pruned while this process remembered it is made again
    import shutil

    shutil.rmtree(current)
    with Sandbox([("a", src)], blocked=["flowtrack.kalman"], limits=FAST) as sb:
        out = sb.run(calls, timeout=30)[0]
    assert out.ok and out.value == "camera.py", out
    assert copies() == [current]


@pytest.mark.parametrize(
    "allowed", [("numpy",), ("numpy", "scipy.linalg"), ("numpy", "sympy", "flowtrack.kalman")]
)
def test_package_entries_match_every_file_resolved(allowed):
    """The sandbox's view of an allowlist: every entry of site-packages holding a file of the
    allowed packages' distributions, their metadata included (the oracle resolves each file of each
    distribution)."""
    import importlib.metadata as md

    from grading_sandbox.runtime import allowed_packages, package_entries, site_dirs

    packages = allowed_packages(allowed)
    by_top = md.packages_distributions()
    for site in site_dirs():
        root = Path(site).resolve()
        want = {p for top in packages for p in (top, f"{top}.py") if (root / p).exists()}
        for dist in {d for top in packages for d in by_top.get(top, [])}:
            d = md.distribution(dist)
            for f in d.files or ():
                p = Path(d.locate_file(f)).resolve()
                if p.is_relative_to(root) and p != root:
                    first = p.relative_to(root).parts[0]
                    if first != "__pycache__":  # the metadata too: importlib.metadata reads it
                        want.add(first)
        assert package_entries(site, packages) == sorted(n for n in want if (root / n).exists())


def test_a_cache_variable_naming_a_missing_folder_says_so(monkeypatch, tmp_path):
    from grading_sandbox import cache, config

    monkeypatch.setenv(config.ENV_CACHE, str(tmp_path / "nowhere"))
    with pytest.raises(FileNotFoundError, match=f"{config.ENV_CACHE}=.*no such folder"):
        cache.cache_root()
