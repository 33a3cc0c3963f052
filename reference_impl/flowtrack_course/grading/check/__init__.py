"""``flowtrack check``: a student's own run of an exercise's public tests, in the grader's sandbox
(:mod:`.check`), and the same tests in a notebook's own process for nbgrader (:mod:`.inprocess`).
"""

from .check import check_notebook, format_report
from .inprocess import run_in_process

__all__ = ["check_notebook", "format_report", "run_in_process"]
