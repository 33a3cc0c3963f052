"""The languages of the polyglot stack: one :class:`~flowtrack_course.polyglot.base.Toolchain` each.

:data:`LANGUAGES` is the one list of language families: the ``--lang`` values of ``flowtrack ports``
(each runs the ports of its module, :mod:`flowtrack_course.polyglot.cpp`, ...) and, for those with an
answer ``extension``, the languages students answer in (:data:`GRADED_LANGUAGES`, in the order of
the grader's exercises and of their ``grades.csv`` columns). Adding a language is adding its module
here; its toolchain says what it needs, how an answer is built and run, and runs its ports.

Debian packages: ``g++ libeigen3-dev nlohmann-json3-dev`` (C++ answers; the ports add ``cmake make
libpcl-dev libgtest-dev``), ``octave``, ``openjdk-17-jdk-headless libgoogle-gson-java libejml-java``
(Java answers; the ports add ``libopencv-java junit5``); Mathics3 and bdsim are the PyPI packages
``mathics3`` and ``bdsim`` (the ``ports`` extra; ``mathics3`` is in the ``grader`` extra too).

Examples
--------
>>> LANGUAGES
('cpp', 'octave', 'java', 'mathics', 'blocks')
>>> GRADED_LANGUAGES, TOOLCHAINS["java"].source_name("cv_model")
(('cpp', 'octave', 'java', 'mathics'), 'CvModel.java')
"""

from __future__ import annotations

from . import blocks, cpp, java, mathics, octave
from .base import Toolchain, ToolchainMissing

__all__ = ["GRADED_LANGUAGES", "LANGUAGES", "TOOLCHAINS", "Toolchain", "ToolchainMissing"]

TOOLCHAINS: dict[str, Toolchain] = {
    t.language: t
    for t in (cpp.TOOLCHAIN, octave.TOOLCHAIN, java.TOOLCHAIN, mathics.TOOLCHAIN, blocks.TOOLCHAIN)
}
LANGUAGES: tuple[str, ...] = tuple(TOOLCHAINS)
GRADED_LANGUAGES: tuple[str, ...] = tuple(lang for lang, t in TOOLCHAINS.items() if t.graded)
