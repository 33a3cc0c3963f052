"""Every problem of the polyglot stack, each defined once (:class:`~.base.Problem`).

The ports' vector files are :data:`VECTOR_PROBLEMS` (``cpp_java_matlab_ports/vectors/<name>.json``);
students answer :data:`GRADED_PROBLEMS` in other languages. ``projection_jacobian`` is both.

- :mod:`.kalman`: ``kalman_cv2d``, ``white_noise_q``, ``steady_state_scalar`` (ports), ``cv_model``,
  ``kalman_step`` (graded);
- :mod:`.camera`: ``projection_jacobian`` (both), ``lucas_kanade`` (ports);
- :mod:`.association`: ``mahalanobis_assignment`` (ports), ``mahalanobis_gating``, ``assignment``
  (graded);
- :mod:`.sceneflow`: ``graph_scene_flow``, ``variational_scene_flow``, ``rigid_icp`` (ports).

Examples
--------
>>> sorted(GRADED_PROBLEMS)
['assignment', 'cv_model', 'kalman_step', 'mahalanobis_gating', 'projection_jacobian']
>>> sorted(set(GRADED_PROBLEMS) & set(VECTOR_PROBLEMS))
['projection_jacobian']
"""

from __future__ import annotations

from .association import ASSIGNMENT, MAHALANOBIS_ASSIGNMENT, MAHALANOBIS_GATING
from .base import GENERIC, Case, Problem
from .camera import LUCAS_KANADE, PROJECTION_JACOBIAN
from .kalman import CV_MODEL, KALMAN_CV2D, KALMAN_STEP, STEADY_STATE_SCALAR, WHITE_NOISE_Q
from .sceneflow import GRAPH_SCENE_FLOW, RIGID_ICP, VARIATIONAL_SCENE_FLOW

__all__ = ["GENERIC", "GRADED_PROBLEMS", "PROBLEMS", "VECTOR_PROBLEMS", "Case", "Problem", "get_problem"]

#: Every problem by name, the graded ones in the order of the grader's exercises.
PROBLEMS: dict[str, Problem] = {
    p.name: p
    for p in (
        CV_MODEL,
        KALMAN_STEP,
        PROJECTION_JACOBIAN,
        MAHALANOBIS_GATING,
        ASSIGNMENT,
        KALMAN_CV2D,
        WHITE_NOISE_Q,
        MAHALANOBIS_ASSIGNMENT,
        GRAPH_SCENE_FLOW,
        VARIATIONAL_SCENE_FLOW,
        RIGID_ICP,
        LUCAS_KANADE,
        STEADY_STATE_SCALAR,
    )
}
#: The problems students answer in other languages.
GRADED_PROBLEMS: dict[str, Problem] = {n: p for n, p in PROBLEMS.items() if p.graded}
#: The problems with a vector file for the ports.
VECTOR_PROBLEMS: dict[str, Problem] = {n: p for n, p in PROBLEMS.items() if p.vector_cases is not None}


def get_problem(name: str) -> Problem:
    """The problem called ``name`` (a key of :data:`PROBLEMS`)."""
    try:
        return PROBLEMS[name]
    except KeyError:
        raise KeyError(f"no problem {name!r}; known: {', '.join(PROBLEMS)}") from None
