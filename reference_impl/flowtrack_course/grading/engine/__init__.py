"""The grading engine: what an exercise is, how one runs in the sandbox, how a student and a class
are graded, what the results are. It finds the course's exercises (:mod:`.discovery`) and never names
one; it imports no exercise, no export and no command.

Layers, bottom up (each imports only those below it):

- :mod:`.text`, :mod:`.compare`, :mod:`.mistakes` (the one mistake matcher), :mod:`.notebook`
  (answer cells of a submission), :mod:`.seeds`;
- :mod:`.spec` (:class:`~.spec.Exercise`, :class:`~.spec.GradedTest`), :mod:`.feedback`,
  :mod:`.symbolic`, :mod:`.authoring` (what an exercise's grading module is written with);
- :mod:`.discovery` (one folder per exercise), :mod:`.catalog` (the course and other sources of
  exercises), :mod:`.results`, :mod:`.jobs` (a run's options and jobs as data);
- :mod:`.run` (one exercise in the sandbox), :mod:`.student` (one student's folder: where its
  files are, whether earlier results stand), :mod:`.layout` (what a SUBMISSIONS folder holds:
  renamed copies, flat LMS downloads), :mod:`.classrun` (a class, in worker processes).

The sandbox is the separate package :mod:`grading_sandbox`.
"""
