"""Ex09: track management: the trusted tests of the notebook next to this file."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from flowtrack_course.grading.engine.authoring import (
    Check,
    Exercise,
    Mistake,
    Outcome,
    Report,
    graded_test,
)


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


def manage_variant(
    frames: Sequence[Sequence[int]],
    min_hits: int,
    max_misses: int,
    *,
    delete_early: bool = False,
    confirm_late: bool = False,
    tentative_coasts: bool = False,
    reuse_ids: bool = False,
) -> list[list[list[Any]]]:
    """The exercise's bookkeeping written out here, with the catalogued mistakes as options.

    With no option it is the rule the exercise states (tests/test_mistakes.py checks it against the
    trusted tracker): ``delete_early`` deletes a confirmed track at ``max_misses`` misses,
    ``confirm_late`` confirms at ``min_hits + 1`` hits, ``tentative_coasts`` lets a tentative track
    survive misses like a confirmed one, ``reuse_ids`` gives an object back its old id.
    """
    tracks: dict[int, dict[str, Any]] = {}
    next_id = 0
    old_ids: dict[int, int] = {}
    need = min_hits + 1 if confirm_late else min_hits
    out = []
    for labels in frames:
        seen = set(labels)
        for lab, t in tracks.items():
            if lab in seen:
                t["hits"] += 1
                t["misses"] = 0
            else:
                t["misses"] += 1
            t["confirmed"] = t["confirmed"] or t["hits"] >= need
        limit = max_misses - 1 if delete_early else max_misses
        tracks = {
            lab: t
            for lab, t in tracks.items()
            if not ((t["misses"] > 0 and not t["confirmed"] and not tentative_coasts) or t["misses"] > limit)
        }
        for lab in labels:
            if lab not in tracks:
                if reuse_ids and lab in old_ids:
                    tid = old_ids[lab]
                else:
                    tid = next_id
                    next_id += 1
                old_ids[lab] = tid
                tracks[lab] = {"id": tid, "hits": 1, "misses": 0, "confirmed": need <= 1}
        report = []
        for t in sorted(tracks.values(), key=lambda t: t["id"]):
            status = "tentative" if not t["confirmed"] else ("coasting" if t["misses"] > 0 else "confirmed")
            report.append([t["id"], status])
        out.append(report)
    return out


_EX09_MISTAKES = {
    "deletion-off-by-one": {"delete_early": True},
    "confirmation-off-by-one": {"confirm_late": True},
    "tentative-track-coasts": {"tentative_coasts": True},
    "track-id-reused": {"reuse_ids": True},
}


def _ex09_check(frames, min_hits, max_misses) -> Check:
    expected = expected_frames(frames, min_hits, max_misses)
    variants = {k: manage_variant(frames, min_hits, max_misses, **o) for k, o in _EX09_MISTAKES.items()}
    return _frames_check(expected, {k: v for k, v in variants.items() if v != expected})


def _frames_check(expected: list[list[list[Any]]], variants: dict | None = None) -> Check:
    """Credit per frame: the frame's list of ``[id, status]`` must match exactly."""
    variants = variants or {}

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
            return 1.0, Report("ok", checked=variants)
        normed = [norm(g) for g in got]
        mistakes = [k for k, v in variants.items() if normed == [[tuple(x) for x in f] for f in v]]
        head = f"{good}/{len(expected)} frames right"
        e = [tuple(x) for x in expected[first_bad]]
        public = f"{head}, first wrong frame: {first_bad}: expected {e}, got {normed[first_bad]}"
        # (which frame is wrong first is the answer's choice: not in the hidden-safe text)
        return good / len(expected), Report(public, head, mistakes, checked=variants)

    return check


_EX09_FRAMES = [[0], [0, 1], [0], [0, 1], [], [], [2], [0], [], [], [], [], [0]]


@graded_test("scripted sequence: min_hits = 2, max_misses = 2", "test_public_sequence", 4.0, hidden=False)
def _ex09_public(rng):
    return [
        ("manage_tracks", (_EX09_FRAMES, 2, 2), {}, _ex09_check(_EX09_FRAMES, 2, 2)),
        ("manage_tracks", (_EX09_FRAMES, 1, 0), {}, _ex09_check(_EX09_FRAMES, 1, 0)),
    ]


def _ex09_random_frames(rng, n_frames: int, n_objects: int, p_detect: float) -> list[list[int]]:
    frames = []
    for _ in range(n_frames):
        labels = [lab for lab in range(n_objects) if rng.random() < p_detect]
        rng.shuffle(labels)  # the order of detections inside a frame decides the order of births
        frames.append([int(v) for v in labels])
    return frames


_EX09_STRATA = (  # (template seed, frames, objects, detection probability, min_hits, max_misses)
    (101, 15, 3, 0.7, 2, 1),
    (102, 25, 5, 0.6, 3, 2),
    (103, 20, 4, 0.5, 1, 3),
    (104, 30, 6, 0.8, 2, 0),
)


@graded_test("random scripted sequences", "test_random_sequences", 6.0, hidden=True)
def _ex09_hidden(rng):
    """Fixed event scripts, relabelled and reordered per student.

    Every student gets the same four scripts (the same births, misses and deletions at the same
    frames), with the objects' labels permuted and the detections of a frame shuffled by the
    student's seed: a given answer scores the same for every student (per-frame credit on random
    scripts made one answer score 4.16 to 4.52 of 10), and the inputs still differ.
    """
    out = []
    for seed, n_frames, n_obj, p, min_hits, max_misses in _EX09_STRATA:
        script = _ex09_random_frames(np.random.default_rng(seed), n_frames, n_obj, p)
        perm = rng.permutation(n_obj)
        frames = []
        for labels in script:
            f = [int(perm[lab]) for lab in labels]
            rng.shuffle(f)
            frames.append(f)
        check = _ex09_check(frames, min_hits, max_misses)
        out.append(("manage_tracks", (frames, min_hits, max_misses), {}, check))
    return out


# The catalogued mistakes this exercise defines: stable ids (instructors' reports count them
# across terms), what the mistake is, why it is wrong, which lesson section explains it.
_L5 = "lesson 05_multi_object_tracking"

MISTAKES = (
    Mistake(
        "deletion-off-by-one",
        "a confirmed track is deleted one frame early: it survives max_misses consecutive misses "
        f"and is deleted at miss max_misses + 1; see {_L5} §4 (births, occlusions and deletions)",
    ),
    Mistake(
        "confirmation-off-by-one",
        "a track is confirmed one hit late: it is confirmed once it has min_hits hits (the birth "
        f"counts as the first); see {_L5} §4 (births, occlusions and deletions)",
    ),
    Mistake(
        "tentative-track-coasts",
        "a tentative track survives a miss: only confirmed tracks coast; a tentative track missed "
        "once is deleted (most false alarms are never seen twice); "
        f"see {_L5} §4 (births, occlusions and deletions)",
    ),
    Mistake(
        "track-id-reused",
        "a track id is reused: every new track gets the next unused id, even for an object seen "
        "before (a reused id would merge two tracks in the metrics); "
        f"see {_L5} §4-5 (births, deletions and what the metrics count)",
    ),
)


EXERCISE = Exercise(
    id="ex09_track_management",
    title="Track management: births, coasting and deletion",
    notebook="ex09_track_management.ipynb",
    answer_cells=("manage_tracks",),
    blocked=("flowtrack.tracking",),
    allowed=('numpy',),
    tests=(_ex09_public, _ex09_hidden),
    packages=("flowtrack",),
    mistakes=MISTAKES,
)
