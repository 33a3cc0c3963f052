"""Imported by the fork server of a class run before it forks the grading workers.

It imports the grader, discovers the course's exercises (the folder ``$FLOWTRACK_COURSE``, else the
current folder: :func:`flowtrack_course.course.course_root`) and builds their public tests once
(which imports the reference code they use: sympy, scipy, the course's library), so the workers
forked from it start with all that in their (shared, copy-on-write) memory instead of each doing it
again. Nothing here touches student data. A failure is ignored: a worker then does the work itself.
"""

from __future__ import annotations


def warm() -> None:
    from ...course import course_root
    from .discovery import EXERCISES_DIR, discover
    from .run import warm_public_tests

    warm_public_tests(discover(course_root(need=(EXERCISES_DIR,))).exercises)


try:
    warm()
except Exception:  # pragma: no cover - best effort
    pass
