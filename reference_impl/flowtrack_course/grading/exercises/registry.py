"""The registry of the exercises: one module per exercise, each defining ``EXERCISE``.

A new exercise is a module ``exNN_<name>.py`` in this package (its tests, built with the helpers of
:mod:`~flowtrack_course.grading.exercises.checks`, and its :class:`~flowtrack_course.grading.spec.Exercise`) added to
the import list below.
"""

from __future__ import annotations

from pathlib import Path

from ..spec import Exercise
from . import (
    ex01_projection_jacobian,
    ex02_optical_flow,
    ex03_gauss_seidel,
    ex04_graph_scene_flow,
    ex05_cv_model,
    ex06_kalman_predict_update,
    ex07_mahalanobis_gating,
    ex08_hungarian,
    ex09_track_management,
    ex10_motion_clustering,
    ex11_concepts,
    ex12_rgbd_data_term,
)

__all__ = ["EXERCISES", "get_exercise"]

EXERCISES: tuple[Exercise, ...] = (
    ex01_projection_jacobian.EXERCISE,
    ex02_optical_flow.EXERCISE,
    ex03_gauss_seidel.EXERCISE,
    ex04_graph_scene_flow.EXERCISE,
    ex05_cv_model.EXERCISE,
    ex06_kalman_predict_update.EXERCISE,
    ex07_mahalanobis_gating.EXERCISE,
    ex08_hungarian.EXERCISE,
    ex09_track_management.EXERCISE,
    ex10_motion_clustering.EXERCISE,
    ex11_concepts.EXERCISE,
    ex12_rgbd_data_term.EXERCISE,
)


def get_exercise(id_or_notebook_path: str | Path | Exercise) -> Exercise:
    """Look up an exercise by id (``"ex01_projection_jacobian"``) or by a notebook path/file name.

    Raises
    ------
    KeyError
        No exercise has that id or notebook file name.
    """
    if isinstance(id_or_notebook_path, Exercise):
        return id_or_notebook_path
    if not isinstance(id_or_notebook_path, (str, Path)):
        raise TypeError(
            f"id_or_notebook_path must be a str or Path, got {type(id_or_notebook_path).__name__}"
        )
    key = str(id_or_notebook_path)
    name = Path(key).name
    stem = name[: -len(".ipynb")] if name.endswith(".ipynb") else name
    for ex in EXERCISES:
        if key == ex.id or stem == ex.id or name == ex.notebook:
            return ex
    raise KeyError(f"no exercise {key!r}; known: {', '.join(e.id for e in EXERCISES)}")
