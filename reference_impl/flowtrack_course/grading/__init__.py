"""The autograder: the grading engine, the instructor's commands and what they export.

The grading process never imports or executes student code: it extracts the graded cells of a
notebook, runs them in a sandboxed child process (the separate package :mod:`grading_sandbox`),
sends that child inputs and receives plain data (numbers and nested lists), which it converts and
compares with its own numpy. The exercises are the course's, found in its folder
(``exercises/<id>/grading.py``), never listed here.

Layers, bottom up (each imports only those below it; ``tests/test_architecture.py`` checks them):

- :mod:`.engine`: what an exercise is, one exercise in the sandbox, a student, a class, the
  results; it finds the course's exercises and never names one;
- :mod:`.languages`: the answers in other languages (a source of exercises);
- :mod:`.sources`: a command's exercises: the course's and the other languages';
- :mod:`.export`: the nbgrader gradebook, the LMS files, the class report, the Gradescope zip;
- the commands, one folder each: :mod:`.assign` (``flowtrack release``), :mod:`.check`
  (``flowtrack check``, and the notebooks' in-process runner), :mod:`.grade` (``flowtrack grade``,
  the Gradescope runner);
- :mod:`.cli`: their arguments.
"""
