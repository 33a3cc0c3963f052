"""What the sandbox's Python sees: the interpreter and its standard library (mirrored when the
sandbox's uid cannot read them), the site-packages, filtered copies of the packages a sandbox
exposes (blocked modules replaced by stubs), stub packages bound over blocked third-party modules,
and the runner (``_child.py``). Every copy lives in the sandbox cache (:mod:`.cache`).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import re
import shutil
import sys
import sysconfig
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .cache import atomic_dir, cache_root, link_or_copy, world_readable

__all__ = ["Runtime", "allowed_packages", "filtered_packages", "package_dir", "package_entries",
           "locate_module", "mirror_site", "project_root", "pth_dirs", "python_runtime", "runner_dir",
           "site_dirs", "stub_dir"]


@functools.lru_cache(maxsize=64)
def package_dir(name: str) -> Path:
    """The folder of the installed top-level package ``name`` (an editable checkout or
    site-packages), found without importing it.

    Raises
    ------
    ValueError
        ``name`` is not a top-level package that can be found.

    >>> package_dir("json").name
    'json'
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"package names must be top-level import names, got {name!r}")
    spec = importlib.util.find_spec(name)
    locations = list(spec.submodule_search_locations or ()) if spec is not None else []
    if not locations:
        raise ValueError(f"{name!r} is not an installed package (a folder with __init__.py)")
    return Path(locations[0]).resolve()


def project_root(folder: Path, sites: Sequence[str]) -> Path | None:
    """The source checkout a package folder outside every site-packages folder comes from (an
    editable install): its nearest ancestor holding ``pyproject.toml``, ``setup.py`` or ``.git``,
    else None. Installed packages (inside one of ``sites``) have none."""
    folder = Path(folder).resolve()
    if any(folder.is_relative_to(Path(s).resolve()) for s in sites):
        return None
    for parent in folder.parents:
        if any((parent / marker).exists() for marker in ("pyproject.toml", "setup.py", ".git")):
            return parent
    return None


@dataclass(frozen=True)
class Runtime:
    executable: str  # path of the python binary (outside)
    prefix: str  # base prefix as seen inside bwrap (original path)
    source: str  # directory bound at ``prefix`` inside bwrap
    stdlib: tuple[str, ...]  # stdlib dirs (outside paths)
    lib_dir: str | None  # LD_LIBRARY_PATH for the fallback when mirrored


@functools.lru_cache(maxsize=4)
def python_runtime(need_world_readable: bool) -> Runtime:
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
    if not need_world_readable or (world_readable(prefix) and world_readable(exe)):
        return Runtime(str(exe), str(prefix), str(prefix), stdlib_dirs, None)
    key = hashlib.sha256(f"{prefix}\0{sys.version}".encode()).hexdigest()[:16]
    skip = {"site-packages", "test", "idlelib", "tkinter", "turtledemo", "lib2to3", "ensurepip"}

    def build(tmp: Path) -> None:
        (tmp / "bin").mkdir(mode=0o755)
        link_or_copy(exe, tmp / "bin" / exe.name)
        (tmp / "lib").mkdir(mode=0o755)
        for lib in (prefix / "lib").glob("libpython*"):
            if lib.is_file():
                link_or_copy(lib, tmp / "lib" / lib.name)
        src_std = prefix / "lib" / f"python{ver}"
        for dirpath, dirnames, filenames in os.walk(src_std):
            rel = Path(dirpath).relative_to(src_std)
            if rel == Path("."):
                dirnames[:] = [d for d in dirnames if d not in skip]
            out = tmp / "lib" / f"python{ver}" / rel
            out.mkdir(mode=0o755, parents=True, exist_ok=True)
            for f in filenames:
                if not os.path.islink(os.path.join(dirpath, f)):
                    link_or_copy(Path(dirpath) / f, out / f)

    mirror = atomic_dir(cache_root() / "python" / key, build, prune=True)
    mirror_std = tuple(str(mirror / Path(p).resolve().relative_to(prefix.resolve())) for p in stdlib_dirs)
    return Runtime(str(mirror / "bin" / exe.name), str(prefix), str(mirror), mirror_std, str(mirror / "lib"))


def site_dirs() -> list[str]:
    """The interpreter's existing site-packages folders, in ``site`` order, then those a ``.pth``
    file put on ``sys.path`` (another environment's packages chained in), without duplicates: the
    sandbox's child runs with ``-S``, so it sees only the folders given here."""
    import site

    dirs = []
    for d in site.getsitepackages():
        if Path(d).is_dir() and d not in dirs:
            dirs.append(d)
    for d in sys.path:
        if d and Path(d).name in ("site-packages", "dist-packages") and Path(d).is_dir() and d not in dirs:
            dirs.append(d)
    return dirs


def mirror_site(site: Path, leave_out: Sequence[str] = ()) -> Path:
    """A world-readable mirror (hard links, else copies) of a site-packages folder the sandbox's
    unprivileged uid cannot reach (e.g. a virtual environment under ``/root``); rebuilt when a
    package is added, removed or replaced. The top-level entries ``leave_out`` (the exposed
    packages, which the sandbox gets as filtered copies, and the private ones) are left out."""
    leave_out = tuple(sorted(set(leave_out)))
    # the format's version is in the key: mirrors made before private files were copied rather
    # than hard-linked are not reused
    h = hashlib.sha256(f"mirror 2\0{site.resolve()}\0{sys.version}\0{','.join(leave_out)}".encode())
    for e in sorted(os.scandir(site), key=lambda e: e.name):
        h.update(f"{e.name}\0{e.stat(follow_symlinks=False).st_mtime_ns}\n".encode())
    key = h.hexdigest()[:20]

    def build(tmp: Path) -> None:
        for dirpath, dirnames, filenames in os.walk(site):
            rel = Path(dirpath).relative_to(site)
            if rel == Path("."):
                dirnames[:] = [d for d in dirnames if d not in leave_out]
            dirnames[:] = [d for d in dirnames if d != "__pycache__"]
            out = tmp / rel
            out.mkdir(mode=0o755, parents=True, exist_ok=True)
            os.chmod(out, 0o755)
            for f in filenames:
                src = Path(dirpath) / f
                if src.is_symlink():
                    os.symlink(os.readlink(src), out / f)
                else:
                    link_or_copy(src, out / f)

    return atomic_dir(cache_root() / "site" / key, build, prune=True)


def _signature(folder: Path) -> str:
    """Names, sizes and mtimes of the files of a package folder (what its filtered copy is made
    from; an edit changes the key, and so makes a new copy)."""
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if "__pycache__" in p.parts or not p.is_file():
            continue
        st = p.stat()
        h.update(f"{p.relative_to(folder)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def _stub_source(name: str) -> str:
    return f"raise ImportError({name + ' is not available in this exercise'!r})\n"


@functools.lru_cache(maxsize=64)
def filtered_packages(packages: tuple[str, ...], blocked: tuple[str, ...]) -> Path:
    """Read-only copies of the top-level ``packages`` in one folder, each blocked module directly
    inside one of them (``pkg.mod`` of ``blocked``) replaced by a stub that raises ``ImportError``;
    returns the folder (a ``sys.path`` root)."""
    folders = {name: package_dir(name) for name in packages}
    mods = {name: sorted({b.split(".")[1] for b in blocked if b.startswith(name + ".")}) for name in packages}
    desc = "\0".join(f"{n}\0{_signature(folders[n])}\0{','.join(mods[n])}" for n in sorted(packages))
    key = hashlib.sha256(desc.encode()).hexdigest()[:20]

    def ignore(d: str, names: list[str]) -> list[str]:
        return [n for n in names if n == "__pycache__" or n.endswith(".pyc")]

    def build(tmp: Path) -> None:
        for name in sorted(packages):
            dst = tmp / name
            shutil.copytree(folders[name], dst, ignore=ignore)
            for m in mods[name]:
                if (dst / m).is_dir():
                    shutil.rmtree(dst / m)
                    (dst / m).mkdir()
                    (dst / m / "__init__.py").write_text(_stub_source(f"{name}.{m}"))
                else:
                    (dst / f"{m}.py").write_text(_stub_source(f"{name}.{m}"))
        for dirpath, _dirnames, filenames in os.walk(tmp):
            os.chmod(dirpath, 0o755)
            for f in filenames:
                os.chmod(os.path.join(dirpath, f), 0o644)

    return atomic_dir(cache_root() / "pkg" / key, build, prune=True)


def stub_dir(name: str) -> Path:
    """A cached folder holding a stub package ``name`` (its ``__init__.py``), built once
    atomically under the sandbox cache; the stub stands in for a package the sandbox withholds."""
    key = hashlib.sha256(name.encode()).hexdigest()[:16]

    def build(tmp: Path) -> None:
        (tmp / "__init__.py").write_text(_stub_source(name))
        os.chmod(tmp / "__init__.py", 0o644)

    return atomic_dir(cache_root() / "stubs" / key, build)


@functools.lru_cache(maxsize=1)
def runner_dir() -> Path:
    """The folder the sandbox runs its child from: ``_child.py`` and the modules it loads by path
    (``errors.py``, ``formula.py``), keyed by their contents."""
    files = {name: (Path(__file__).parent / name).read_bytes()
             for name in ("_child.py", "errors.py", "formula.py")}
    key = hashlib.sha256(b"\0".join(files[n] for n in sorted(files))).hexdigest()[:16]

    def build(tmp: Path) -> None:
        for name, src in files.items():
            (tmp / name).write_bytes(src)
            os.chmod(tmp / name, 0o644)

    return atomic_dir(cache_root() / "bin" / key, build, prune=True)


def locate_module(name: str, roots: Sequence[str]) -> Path | None:
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


def _site_state() -> tuple[int, ...]:
    """mtimes of the site-packages folders: an install or removal changes them (cache key)."""
    out = []
    for d in site_dirs():
        try:
            out.append(os.stat(d).st_mtime_ns)
        except OSError:
            out.append(0)
    return tuple(out)


@functools.lru_cache(maxsize=4)
def _distributions(state: tuple[int, ...]) -> dict[str, list[str]]:
    import importlib.metadata as md

    return md.packages_distributions()


def allowed_packages(allowed: Sequence[str]) -> tuple[str, ...]:
    """The top-level packages an allowlist needs: those it names (``scipy.linalg`` -> ``scipy``) and,
    through their distributions' requirements (extras left out), what they import themselves
    (``scipy`` -> ``numpy``; ``sympy`` -> ``mpmath``). Sorted.

    >>> allowed_packages(["numpy", "scipy.linalg"])
    ('numpy', 'scipy')
    """
    return _allowed_packages(tuple(allowed), _site_state())


@functools.lru_cache(maxsize=64)
def _allowed_packages(allowed: tuple[str, ...], state: tuple[int, ...]) -> tuple[str, ...]:
    import importlib.metadata as md

    tops = {a.split(".")[0] for a in allowed}
    by_top = _distributions(state)
    todo = [d for t in tops for d in by_top.get(t, [])]
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name.lower() in seen:
            continue
        seen.add(name.lower())
        try:
            dist = md.distribution(name)
        except md.PackageNotFoundError:
            continue
        tops |= {t for t, dists in by_top.items() if name in dists and not t.startswith("_")}
        for req in dist.requires or ():
            if "extra ==" in req.replace('"', "").replace("'", ""):
                continue
            m = re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*", req)
            if m:
                todo.append(m.group(0))
    return tuple(sorted(tops))


def package_entries(site: str, packages: Sequence[str]) -> list[str]:
    """The entries of the site-packages folder ``site`` that the top-level ``packages`` consist of:
    the package folders or modules and every other top-level entry their distributions installed
    (the bundled libraries ``numpy.libs``, ``scipy.libs``; the ``.dist-info`` folders, which
    ``importlib.metadata`` reads; ``.pth`` files and single modules).

    An entry is the first part of an installed file's path below the folder its distribution was
    installed in, so ``site`` may be that folder or a mirror of it (:func:`mirror_site`: the same
    names in another folder); only the names present in ``site`` are returned.

    >>> site = site_dirs()[0]
    >>> {"numpy", "numpy.libs"} & set(package_entries(site, ["numpy"])) == {"numpy", "numpy.libs"} & {
    ...     e for e in os.listdir(site)}
    True
    """
    return list(_package_entries(str(site), tuple(packages), _site_state()))


@functools.lru_cache(maxsize=64)
def _package_entries(site: str, packages: tuple[str, ...], state: tuple[int, ...]) -> tuple[str, ...]:
    import importlib.metadata as md

    by_top = _distributions(state)
    root = Path(site)
    names: set[str] = set()
    for top in packages:
        names.update((top, f"{top}.py"))
        for dist_name in by_top.get(top, []):
            try:
                dist = md.distribution(dist_name)
                base = Path(dist.locate_file("")).resolve()
            except (md.PackageNotFoundError, OSError, RuntimeError):
                continue
            for f in dist.files or ():
                parts = Path(f).parts
                if not parts:
                    continue
                if parts[0] == "..":  # e.g. ../../../bin/f2py: outside, unless it comes back in
                    try:
                        p = (base / f).resolve()
                    except (OSError, RuntimeError):
                        continue
                    if not p.is_relative_to(base) or p == base:
                        continue
                    parts = p.relative_to(base).parts
                names.add(parts[0])
    names.discard("__pycache__")
    return tuple(sorted(n for n in names if os.path.lexists(root / n)))


def pth_dirs(sites: Sequence[str]) -> list[str]:
    """The folders the ``.pth`` files of ``sites`` put on ``sys.path`` (lines that are folders;
    ``import`` lines are code and not followed), existing ones, in order, without the ``sites``
    themselves: the sandbox's child runs with ``-S`` and never reads a ``.pth`` file, so a package
    installed in such a folder (a wheel that puts its modules in a sub-folder, an editable install)
    is importable there only when the folder is given to it too.

    >>> pth_dirs([])
    []
    """
    out: list[str] = []
    seen = {str(Path(s).resolve()) for s in sites}
    for site in sites:
        try:
            pths = sorted(e.name for e in os.scandir(site) if e.name.endswith(".pth") and e.is_file())
        except OSError:
            continue
        for name in pths:
            try:
                lines = Path(site, name).read_text(encoding="utf-8", errors="replace").splitlines()
            except OSError:
                continue
            for line in lines:
                line = line.strip()
                if not line or line.startswith(("#", "import ", "import\t")):
                    continue
                folder = Path(site, line).resolve()  # relative lines are relative to the site
                if folder.is_dir() and str(folder) not in seen:
                    seen.add(str(folder))
                    out.append(str(folder))
    return out
