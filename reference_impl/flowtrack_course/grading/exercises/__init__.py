r"""The exercise registry: trusted test definitions of the exercise notebooks in ``exercises/``.

Every :class:`~flowtrack_course.grading.spec.Exercise` here names its notebook, the nbgrader ``grade_id``\ s of
the answer cells a student fills in, the modules the student's code may not import, and its
:class:`~flowtrack_course.grading.spec.GradedTest`\ s. A test's ``build(rng)`` returns the
:class:`~flowtrack_course.grading.spec.Call`\ s to make and a scorer; expected values are computed in
``build`` by the trusted reference (``flowtrack`` itself, or scipy for the Hungarian algorithm) on the
grader's side and never sent to the student's code. Public tests use small fixed inputs (the ones the
notebook's visible asserts show) and get ``rng`` seeded with the fixed
:func:`~flowtrack_course.grading.spec.public_seed`; hidden tests draw other inputs from ``rng``, which the
grader seeds per student with :func:`~flowtrack_course.grading.spec.student_seed`. Every scorer gives partial
credit: the fraction of calls (or checks) that pass.

:func:`~flowtrack_course.grading.exercises.inprocess.run_in_process` runs the same tests on functions found in a namespace dict (the notebook's
``globals()``): it converts inputs and results to plain data exactly as the sandboxed child does,
seeds public tests with the same fixed seed as ``flowtrack grade`` and ``flowtrack check`` (a student
sees the same public inputs in every path), and applies the same scorers with the same clipping (a
NaN or infinite fraction earns 0). It is what the notebooks' own hidden-test blocks call, so that
``nbgrader autograde`` also grades these notebooks (with partial credit). It executes student code
in the calling process and is therefore **not secure**: flowtrack's grader runs student code only in
:mod:`flowtrack_course.grading.sandbox`.

The package: :mod:`~flowtrack_course.grading.exercises.checks` (shared scoring helpers), one module per
exercise (``ex01_projection_jacobian`` ... ``ex12_rgbd_data_term``),
:mod:`~flowtrack_course.grading.exercises.registry` (``EXERCISES``, ``get_exercise``) and
:mod:`~flowtrack_course.grading.exercises.inprocess` (``run_in_process``).

Examples
--------
>>> ex = get_exercise("ex05_cv_model")
>>> ex.notebook, ex.answer_cells, ex.max_score
('ex05_cv_model.ipynb', ('cv_transition', 'cv_process_noise'), 10.0)
"""

from __future__ import annotations

from ..wire import plain_data
from .inprocess import run_in_process
from .registry import EXERCISES, get_exercise

__all__ = [
    "EXERCISES",
    "get_exercise",
    "plain_data",
    "run_in_process",
]
