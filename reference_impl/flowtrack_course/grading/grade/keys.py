"""The instructor's seed key: permission check and why results are re-graded.

A key that others can read lets them compute every student's hidden-test inputs, so
:func:`check_key_file` refuses a file whose mode grants any permission to group or others
(``mode & 0o077``) and names the fix. :func:`regrade_reasons` compares the results a grade run
finds in OUT with what it is about to grade, so the run summary can say how many students are
re-graded and why (another seed key, changed tests, changed submissions, ``--force``).
"""

from __future__ import annotations

import json
import os
import shlex
import stat
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

from ..engine.results import student_folder

__all__ = ["InsecureKeyError", "check_key_file", "describe_regrades", "regrade_reasons"]


class InsecureKeyError(ValueError):
    """The seed key file can be read (or written) by users other than its owner."""


def check_key_file(path: str | os.PathLike) -> None:
    """Refuse a key file whose permissions grant anything to group or others.

    A missing file passes (it is created owner-only by
    :func:`~flowtrack_course.grading.engine.seeds.read_secret`).

    Raises
    ------
    InsecureKeyError
        ``mode & 0o077 != 0``; the message holds the ``chmod 600`` fix.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return
    if stat.S_ISREG(mode) and mode & 0o077:
        raise InsecureKeyError(
            f"secret file {path} has mode {stat.filemode(mode)} ({mode & 0o777:03o}): other users can read "
            f"the seed key and predict every hidden test's inputs. Fix: chmod 600 {shlex.quote(str(path))}"
        )


def regrade_reasons(
    out: str | os.PathLike,
    students: Sequence[str],
    *,
    exercises_hash: str,
    submission_hashes: Mapping[str, str],
    key_id: str,
    force: bool = False,
) -> dict[str, str]:
    """``{student: reason}`` for students with earlier results in ``out`` that will be re-graded.

    Reasons, first that applies: ``"--force"``, ``"seed key changed"``, ``"tests changed"``,
    ``"submission changed"``. Students without earlier results (new) and those kept are not listed.
    """
    reasons: dict[str, str] = {}
    for s in students:
        try:
            data = json.loads((Path(out) / student_folder(s) / "results.json").read_text(encoding="utf-8"))
            info = data["extra_data"]["flowtrack"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if force:
            reasons[s] = "--force"
        elif info.get("secret_id", "") != key_id:
            reasons[s] = "seed key changed"
        elif info.get("exercises_hash") != exercises_hash:
            reasons[s] = "tests changed"
        elif info.get("submission_hash") != submission_hashes.get(s):
            reasons[s] = "submission changed"
    return reasons


def describe_regrades(reasons: Mapping[str, str]) -> str:
    """One summary line, e.g. ``re-graded 3 students with earlier results: 3 seed key changed``."""
    if not reasons:
        return ""
    counts = Counter(reasons.values())
    parts = ", ".join(f"{n} {why}" for why, n in counts.most_common())
    line = f"re-graded {len(reasons)} student(s) with earlier results: {parts}"
    if "seed key changed" in counts:
        line += " (hidden-test inputs depend on the key: use the same --secret-file for every run of a class)"
    return line
