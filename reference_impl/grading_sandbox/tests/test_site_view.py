"""What the sandbox's child sees of an installed wheel under an allowlist: every top-level entry the
wheel installed (its bundled libraries ``<name>.libs``, its ``.dist-info``), the folders its ``.pth``
file adds, whether the site-packages folder is mirrored (root grading from a ``.venv`` other users
cannot read) or not; and a child that cannot import what its allowlist names reports the grader's
configuration error instead of a student's failure.

The wheels here are made by hand (a RECORD listing their files, as pip writes it) in a site-packages
folder of their own, chained into ``sys.path`` for the test.
"""

from __future__ import annotations

import functools
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

from grading_sandbox import Call, Limits, Sandbox, SandboxConfigError, runtime
from grading_sandbox import sandbox as sbmod
from grading_sandbox.testing import use_sandbox_mode

pytestmark = pytest.mark.xdist_group("sandbox")

FAST = Limits(cpu_seconds=5, wall_seconds=20, memory_bytes=1 << 30)

# A wheel whose package loads a file of its bundled-library folder at import (as numpy loads
# numpy.libs/libscipy_openblas*.so) and reads its own version from its metadata.
FAKEWHEEL = """
import importlib.metadata, os
_here = os.path.dirname(os.path.abspath(__file__))
with open(os.path.join(_here, os.pardir, "fakewheel.libs", "libfake.txt")) as fh:
    LIB = fh.read()
VERSION = importlib.metadata.version("fakewheel")
"""


def _wheel(site: Path, name: str, files: dict[str, str]) -> None:
    """Install ``files`` (path relative to ``site`` -> text) as distribution ``name`` 1.0."""
    info = site / f"{name}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "top_level.txt").write_text(name + "\n")
    for rel, text in files.items():
        (site / rel).parent.mkdir(parents=True, exist_ok=True)
        (site / rel).write_text(text)
    record = [*files, f"{info.name}/METADATA", f"{info.name}/top_level.txt", f"{info.name}/RECORD"]
    (info / "RECORD").write_text("".join(f"{r},,\n" for r in record))


@pytest.fixture
def fake_site(monkeypatch):
    """A site-packages folder with three hand-made wheels, on ``sys.path`` and among the sandbox's
    site folders: ``fakewheel`` (a bundled library and its metadata), ``pthwheel`` (its package in
    a folder its ``.pth`` file adds) and ``brokenwheel`` (its import fails, as a wheel missing a
    shared library does)."""
    top = Path(tempfile.mkdtemp(prefix="flowtrack-fake-site-"))  # other users may traverse /tmp
    root = top / "venv"
    site = root / "lib" / "site-packages"
    _wheel(site, "fakewheel", {"fakewheel/__init__.py": FAKEWHEEL, "fakewheel.libs/libfake.txt": "LIBFAKE"})
    _wheel(site, "pthwheel", {"pthwheel.pth": "pthwheel_src\n",
                              "pthwheel_src/pthwheel/__init__.py": "X = 'from the .pth folder'\n"})
    _wheel(site, "brokenwheel", {"brokenwheel/__init__.py": (
        "raise ImportError('libbroken.so.1: cannot open shared object file: No such file or directory')\n")})
    for d in [top, root, *(p for p in root.rglob("*") if p.is_dir())]:
        d.chmod(0o755)
    real = runtime.site_dirs()
    sites = functools.partial(lambda real: [*real, str(site)], real)
    monkeypatch.setattr(runtime, "site_dirs", sites)
    monkeypatch.setattr(sbmod, "site_dirs", sites)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.syspath_prepend(str(site / "pthwheel_src"))  # as site.py adds it
    runtime._distributions.cache_clear()
    runtime._package_entries.cache_clear()
    runtime._allowed_packages.cache_clear()
    yield root, site
    runtime._distributions.cache_clear()
    runtime._package_entries.cache_clear()
    runtime._allowed_packages.cache_clear()
    for name in [m for m in sys.modules if m.split(".")[0] in ("fakewheel", "pthwheel", "brokenwheel")]:
        del sys.modules[name]
    shutil.rmtree(top, ignore_errors=True)


def test_package_entries_of_a_mirror_are_those_of_the_site(fake_site, tmp_path):
    """A mirror (the same names in another folder) gets the same entries as the folder it mirrors:
    the bundled libraries and the metadata included."""
    _, site = fake_site
    numpy_site = Path(runtime.package_dir("numpy")).parent
    for folder in (site, numpy_site):
        mirror = tmp_path / f"mirror-{folder.name}-{len(str(folder))}"
        mirror.mkdir()
        for entry in os.listdir(folder):
            (mirror / entry).mkdir()
        for packages in (("fakewheel",), runtime.allowed_packages(["numpy", "scipy.linalg"])):
            want = runtime.package_entries(str(folder), packages)
            assert runtime.package_entries(str(mirror), packages) == want
    assert {"fakewheel", "fakewheel.libs", "fakewheel-1.0.dist-info"} <= set(
        runtime.package_entries(str(site), ("fakewheel",)))
    numpy_entries = runtime.package_entries(str(numpy_site), ("numpy",))
    assert "numpy" in numpy_entries
    assert any(e.startswith("numpy-") and e.endswith(".dist-info") for e in numpy_entries)
    if (numpy_site / "numpy.libs").exists():  # the manylinux wheel's bundled OpenBLAS
        assert "numpy.libs" in numpy_entries


USE = """
def libs():
    import fakewheel, pthwheel
    return [fakewheel.LIB, fakewheel.VERSION, pthwheel.X]
def scipy_solve():
    import numpy as np, scipy.linalg
    return scipy.linalg.solve(np.eye(2) * 2.0, np.ones(2)).tolist()
"""


@pytest.mark.parametrize("mirrored", [False, True], ids=["readable", "mirrored"])
@pytest.mark.parametrize("mode", ["bwrap", "setpriv", "fallback"])
def test_wheels_libraries_metadata_and_pth_folders_are_in_view(fake_site, monkeypatch, mode, mirrored):
    root, _ = fake_site
    if mirrored and os.geteuid() != 0:
        pytest.skip("only root hands the sandbox to another uid (and mirrors what it cannot read)")
    use_sandbox_mode(mode, monkeypatch)
    if mirrored:  # as a .venv that `flowtrack release` made in the bundle (drwx------)
        root.chmod(0o700)
    allowed = ("numpy", "scipy.linalg", "fakewheel", "pthwheel")
    with Sandbox([("a", USE)], allowed=allowed, limits=FAST) as sb:
        out = sb.run([Call("libs"), Call("scipy_solve")], timeout=20)
    assert [o.ok for o in out] == [True, True], [o.error for o in out]
    assert out[0].value == ["LIBFAKE", "1.0", "from the .pth folder"]
    assert out[1].value == [0.5, 0.5]


@pytest.mark.parametrize("zygote", [False, True])
@pytest.mark.parametrize("mode", ["bwrap", "setpriv", "fallback"])
def test_an_allowlisted_module_that_cannot_be_imported_is_a_configuration_error(
        fake_site, monkeypatch, mode, zygote):
    use_sandbox_mode(mode, monkeypatch)
    cells = [("a", "raise SystemExit('student code must not run')\ndef f():\n    return 1\n")]
    with Sandbox(cells, allowed=("numpy", "brokenwheel"), limits=FAST, zygote=zygote) as sb:
        with pytest.raises(SandboxConfigError) as err:
            sb.run([Call("f")], timeout=20)
    e = err.value
    assert e.module == "brokenwheel" and "libbroken.so.1: cannot open shared object file" in e.error
    text = str(e)
    assert text.startswith("grader configuration error") and "not the student's work" in text
    assert "Fix:" in text
    # what the exercise itself refuses (a blocked module) is not a configuration error
    with Sandbox([("a", "def f():\n    return 2\n")], allowed=("numpy", "brokenwheel"),
                 blocked=("brokenwheel",), limits=FAST) as sb:
        assert sb.run([Call("f")], timeout=20)[0].value == 2
