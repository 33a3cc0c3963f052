"""The demo's settings: the pipeline's (:class:`flowtrack.pipeline.PipelineConfig`) and its scoring."""

from __future__ import annotations

from dataclasses import dataclass

from flowtrack.pipeline import PipelineConfig

__all__ = ["DEFAULT_NOISE", "DemoConfig"]

DEFAULT_NOISE = 0.002  #: depth noise (m, standard deviation) of the synthetic scene


@dataclass(frozen=True)
class DemoConfig(PipelineConfig):
    """Tuning of the pipeline (metres, seconds; :class:`~flowtrack.pipeline.PipelineConfig`) and the
    CLEAR-MOT match distance the demo scores its tracks with."""

    mot_max_dist: float = 0.1  #: CLEAR-MOT match distance (m)
