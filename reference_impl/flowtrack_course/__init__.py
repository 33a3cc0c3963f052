"""flowtrack_course: the course's tooling, built on the library :mod:`flowtrack`.

- :mod:`flowtrack_course.grading` – exercise registry, sandbox, ``release``, ``check``, ``grade``,
  ``gradescope``.
- :mod:`flowtrack_course.ports` – shared test vectors and the harnesses of the C++, Java, Octave,
  Mathics and bdsim ports.
- :mod:`flowtrack_course.book`, :mod:`flowtrack_course.notebooks` – the rendered book, headless notebooks.
- :mod:`flowtrack_course.widgets` – lesson widgets that degrade to static figures.
- :mod:`flowtrack_course.demo`, :mod:`flowtrack_course.report` – the main job and its HTML report.
- :mod:`flowtrack_course.cli` – the ``flowtrack`` command.

The library never imports this package (``tests/test_architecture.py``).
"""

from flowtrack import __version__

__all__ = ["__version__"]
