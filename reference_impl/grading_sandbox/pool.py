"""Sandboxes reused across one student's exercises: a zygote per kind of exercise
(:class:`SandboxPool`; see "Zygotes" in the package's docstring)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .sandbox import Sandbox
from .wire import Call, Outcome

__all__ = ["SandboxPool"]


class _Lease:
    """One exercise in a pooled zygote sandbox: the ``Sandbox`` interface ``run_exercise`` uses."""

    def __init__(self, box: Sandbox) -> None:
        self._box = box

    def __enter__(self) -> _Lease:
        return self

    def __exit__(self, *exc: object) -> None:
        self._box.finish()

    def start(self, timeout: float | None = None) -> None:
        self._box.start(timeout)

    def run(self, calls: Sequence[Call], timeout: float | None = None) -> list[Outcome]:
        return self._box.run(calls, timeout)

    @property
    def isolation(self) -> str:
        return self._box.isolation

    @property
    def cell_errors(self) -> dict[str, str]:
        return self._box.cell_errors

    @property
    def stdout(self) -> str:
        return self._box.stdout


class SandboxPool:
    """Sandboxes of one student, reused across the student's exercises (a zygote per key).

    Called like :class:`Sandbox` (``pool(cells, blocked=..., allowed=..., limits=...)``), it returns
    a context manager with ``run``, ``isolation``, ``cell_errors`` and ``stdout``. Exercises whose
    sandboxes would be the same (:attr:`Sandbox.key`: the same file system view, limits and hidden
    paths) share one sandboxed process that imported numpy once; each exercise runs in a child it
    forks, with that exercise's own import guard and audit hook, and between two exercises the
    zygote kills every other process of the sandbox and empties its writable folders. A child that
    crashes, times out or exceeds a limit takes the whole sandbox down (the next exercise starts a
    new one), exactly as without the pool. Never shared between students: :meth:`close` kills all.
    Where a zygote cannot be used (the fallback as an ordinary user) every exercise gets a fresh
    sandbox.
    """

    def __init__(self, preload: Sequence[str] = ()) -> None:
        self._boxes: dict[tuple, Sandbox] = {}
        self.preload = tuple(preload)

    def __call__(self, cells: Sequence[tuple[str, str]], **kwargs: Any) -> Any:
        box = Sandbox(cells, zygote=True, preload=self.preload, **kwargs)
        if not box._zygote:
            return box
        old = self._boxes.get(box.key)
        if old is None:
            self._boxes[box.key] = box
            return _Lease(box)
        box.close()
        old.prepare(cells, blocked=kwargs.get("blocked", ()), allowed=kwargs.get("allowed"),
                    spawn=kwargs.get("spawn", False))
        return _Lease(old)

    def __enter__(self) -> SandboxPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Kill every sandbox of the pool."""
        boxes, self._boxes = list(self._boxes.values()), {}
        for box in boxes:
            box.close()
