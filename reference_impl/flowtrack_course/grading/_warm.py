"""Imported by the fork server of ``flowtrack grade --jobs N`` before it forks the grading workers.

It imports the grader and builds the public tests of the registry's exercises once (which imports
the reference code they use: sympy, scipy, flowtrack's modules), so the workers forked from it
start with all that in their (shared, copy-on-write) memory instead of each doing it again.
Nothing here touches student data. A failure is ignored: a worker then does the work itself.
"""

from __future__ import annotations


def warm() -> None:
    from .exercises import EXERCISES
    from .grade import warm_public_tests

    warm_public_tests(EXERCISES)

try:
    warm()
except Exception:  # pragma: no cover - best effort
    pass
