"""Ex09: track management: the trusted tests of ``exercises/ex09_track_management.ipynb``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..spec import Exercise, Outcome, as_float_array, compare_arrays
from .checks import Check, array_check, graded_test, pinhole, points_in_front, tuple_check

def expected_frames(frames: Sequence[Sequence[int]], min_hits: int, max_misses: int) -> list[list[list[Any]]]:
    """Run the trusted :class:`flowtrack.tracking.MultiObjectTracker` on the scripted sequence.

    Object ``l`` sits still at ``(50 l, 0)`` and is detected exactly, so the tracker's gated
    nearest-neighbour association assigns a detection of ``l`` to the live track of ``l`` (if any):
    the association rule the exercise states.
    """
    from flowtrack.tracking import MultiObjectTracker

    trk = MultiObjectTracker(dt=1.0, q=1e-4, r=1e-2, dim=2, min_hits=min_hits, max_misses=max_misses)
    out = []
    for labels in frames:
        Z = np.array([[50.0 * lab, 0.0] for lab in labels]).reshape(-1, 2)
        trk.step(Z)
        out.append([[int(t.id), str(t.status)] for t in trk.tracks])
    return out


def _frames_check(expected: list[list[list[Any]]]) -> Check:
    """Credit per frame: the frame's list of ``[id, status]`` must match exactly."""

    def norm(frame: Any) -> list[tuple[Any, Any]] | None:
        if type(frame) not in (list, tuple):
            return None
        out = []
        for item in frame:
            if type(item) not in (list, tuple) or len(item) != 2:
                return None
            tid, status = item
            if type(tid) is float and tid == int(tid):
                tid = int(tid)
            if type(tid) is not int or type(status) is not str:
                return None
            out.append((tid, status))
        return out

    def check(outcome: Outcome) -> tuple[float, str]:
        if not outcome.ok:
            return 0.0, outcome.error or "the call failed"
        got = outcome.value
        if type(got) not in (list, tuple) or len(got) != len(expected):
            return 0.0, f"expected a list with one entry per frame ({len(expected)} frames)"
        good = 0
        first_bad = None
        for t, (g, e) in enumerate(zip(got, expected)):
            if norm(g) == [tuple(x) for x in e]:
                good += 1
            elif first_bad is None:
                first_bad = t
        if first_bad is None:
            return 1.0, "ok"
        return good / len(expected), f"{good}/{len(expected)} frames right, first wrong frame: {first_bad}"

    return check


_EX09_FRAMES = [[0], [0, 1], [0], [0, 1], [], [], [2], [0], [], [], [], [], [0]]


@graded_test("scripted sequence: min_hits = 2, max_misses = 2", "test_public_sequence", 4.0, hidden=False)
def _ex09_public(rng):
    return [
        ("manage_tracks", (_EX09_FRAMES, 2, 2), {}, _frames_check(expected_frames(_EX09_FRAMES, 2, 2))),
        ("manage_tracks", (_EX09_FRAMES, 1, 0), {}, _frames_check(expected_frames(_EX09_FRAMES, 1, 0))),
    ]


def _ex09_random_frames(rng, n_frames: int, n_objects: int, p_detect: float) -> list[list[int]]:
    frames = []
    for _ in range(n_frames):
        labels = [lab for lab in range(n_objects) if rng.random() < p_detect]
        rng.shuffle(labels)  # the order of detections inside a frame decides the order of births
        frames.append([int(v) for v in labels])
    return frames


@graded_test("random scripted sequences", "test_random_sequences", 6.0, hidden=True)
def _ex09_hidden(rng):
    out = []
    for n_frames, n_obj, p, min_hits, max_misses in (
        (15, 3, 0.7, 2, 1),
        (25, 5, 0.6, 3, 2),
        (20, 4, 0.5, 1, 3),
        (30, 6, 0.8, 2, 0),
    ):
        frames = _ex09_random_frames(rng, n_frames, n_obj, p)
        out.append(
            (
                "manage_tracks",
                (frames, min_hits, max_misses),
                {},
                _frames_check(expected_frames(frames, min_hits, max_misses)),
            )
        )
    return out


EXERCISE = Exercise(
    id="ex09_track_management",
    title="Track management: births, coasting and deletion",
    notebook="ex09_track_management.ipynb",
    answer_cells=("manage_tracks",),
    blocked=("flowtrack.tracking",),
    allowed=('numpy',),
    tests=(_ex09_public, _ex09_hidden),
)
