"""Shared test doubles for the grader's tests."""

from __future__ import annotations

from typing import ClassVar

from flowtrack_course.grading.exercises import plain_data
from flowtrack_course.grading.spec import Outcome


class RecordingSandbox:
    """Sandbox stand-in for ``run_exercise``: records the calls it is sent and echoes their argument.

    ``sent`` holds ``(function, plain data of the arguments)`` of every call since the caller last
    emptied it; nothing of the student's code is run (what is checked is the inputs sent).
    """

    sent: ClassVar[list[tuple[str, list]]] = []

    def __init__(self, cells, **kwargs):
        self.isolation = "recording"
        self.cell_errors: dict[str, str] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def run(self, calls, timeout):
        self.sent.extend((c.function, plain_data(list(c.args))) for c in calls)
        return [Outcome(True, plain_data(c.args[0])) for c in calls]
