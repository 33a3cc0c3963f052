"""Where the course folder is: the one way every tool finds ``lessons/``, ``exercises/`` and the ports.

The course folder is a checkout of the course repository: ``lessons/``, ``exercises/``,
``solutions/``, ``cpp_java_matlab_ports/`` (and, for ``flowtrack gradescope``, ``pyproject.toml``
and ``reference_impl/``). The tooling is an installed package and may live anywhere (an editable
install, a wheel in some virtual environment), so it never guesses the folder from its own location.
In this order:

1. an explicit folder: the ``course`` argument, i.e. a command's ``--course DIR`` option;
2. the environment variable ``FLOWTRACK_COURSE``;
3. the current folder (its parent when the current folder is the course's ``lessons/``, where
   a lesson runs).

The folder found must hold what the caller needs, else :class:`CourseNotFound` (a
``FileNotFoundError``) names the folder, where it came from and what is missing.

Examples
--------
>>> import os, tempfile
>>> from pathlib import Path
>>> d = Path(tempfile.mkdtemp())
>>> (d / "lessons").mkdir()
>>> course_root(d, need=("lessons",)) == d.resolve()
True
>>> try:
...     course_root(d, need=("lessons", "exercises"))
... except CourseNotFound as exc:
...     print(str(exc).split(") ", 1)[1])
has no exercises/; pass --course DIR or set FLOWTRACK_COURSE to a checkout of the course
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    "ENV", "CourseNotFound", "add_course_option", "course_root", "ports_dir", "use_course", "vectors_dir",
]

#: The environment variable naming the course folder.
ENV = "FLOWTRACK_COURSE"
#: What a full course folder holds.
COURSE_PARTS = ("lessons", "exercises", "cpp_java_matlab_ports")


class CourseNotFound(FileNotFoundError):
    """The course folder (``--course``, ``$FLOWTRACK_COURSE`` or the current folder) lacks a part."""


def course_root(course: str | os.PathLike | None = None, *, need: Sequence[str] = COURSE_PARTS) -> Path:
    """The course folder: ``course`` if given, else ``$FLOWTRACK_COURSE``, else the current folder.

    Parameters
    ----------
    course : str or path-like, optional
        An explicit folder (a command's ``--course DIR``).
    need : sequence of str
        Entries (folders or files, relative) the folder must hold; default the lessons, exercises
        and ports folders.

    Returns
    -------
    pathlib.Path
        The folder, absolute.

    Raises
    ------
    CourseNotFound
        The folder does not exist or lacks one of ``need``; the message names the folder, where it
        came from and what is missing, and how to point the tools elsewhere.
    TypeError
        ``course`` is not a path, or ``need`` is a string.
    """
    if isinstance(need, str):
        raise TypeError(f"need must be a sequence of names, got the string {need!r}")
    if course is not None:
        if not isinstance(course, (str, os.PathLike)):
            raise TypeError(f"course must be a path, got {type(course).__name__}")
        root, origin = Path(course), "from --course"
    elif os.environ.get(ENV):
        root, origin = Path(os.environ[ENV]), f"from ${ENV}"
    else:
        root, origin = Path.cwd(), "the current folder"
        here = root.resolve()
        # `jupyter lab lessons/` runs a lesson with lessons/ as its current folder: the course is
        # the folder that holds it (what the current folder says, not where this file is)
        if (here.name == "lessons" and not all((here / n).exists() for n in need)
                and all((here.parent / n).exists() for n in need)):
            root, origin = here.parent, "the folder holding the current lessons/ folder"
    root = root.expanduser().resolve()
    hint = f"pass --course DIR or set {ENV} to a checkout of the course"
    if not root.is_dir():
        raise CourseNotFound(f"course folder {root} ({origin}) does not exist; {hint}")
    missing = [n for n in need if not (root / n).exists()]
    if missing:
        shown = ", ".join(n + ("" if "." in n else "/") for n in missing)
        raise CourseNotFound(f"course folder {root} ({origin}) has no {shown}; {hint}")
    return root


def use_course(course: str | os.PathLike | None, *, need: Sequence[str] = COURSE_PARTS) -> Path:
    """A command's ``--course``: check the folder (:func:`course_root`) and make it this process's
    course folder by setting ``$FLOWTRACK_COURSE`` (so that the modules and subprocesses it runs
    find the same folder); returns it."""
    root = course_root(course, need=need)
    os.environ[ENV] = str(root)
    return root


def ports_dir(course: str | os.PathLike | None = None) -> Path:
    """The ports folder ``<course>/cpp_java_matlab_ports`` (sources, ``vectors/``, build cache)."""
    return course_root(course, need=("cpp_java_matlab_ports",)) / "cpp_java_matlab_ports"


def vectors_dir(course: str | os.PathLike | None = None) -> Path:
    """The shared test vectors ``<course>/cpp_java_matlab_ports/vectors``."""
    return ports_dir(course) / "vectors"


def add_course_option(parser) -> None:
    """Add ``--course DIR`` to an argparse parser (``args.course``, default None: see :func:`course_root`)."""
    parser.add_argument(
        "--course",
        metavar="DIR",
        default=None,
        help=f"the course folder (a checkout with lessons/, exercises/, cpp_java_matlab_ports/); "
        f"default: ${ENV}, else the current folder",
    )
