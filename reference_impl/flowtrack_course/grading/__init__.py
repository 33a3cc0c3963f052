"""The autograder: exercises' trusted test definitions, a sandbox for student code, and the
instructor's commands (release, check, grade, gradescope).

The grading process never imports or executes student code: it extracts the graded cells of a
notebook, runs them in a sandboxed child process, sends that child inputs and receives plain data
(numbers and nested lists), which it converts and compares with its own numpy.
"""
