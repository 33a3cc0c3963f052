"""Variational scene flow on the pixel grid (placeholder, being written)."""

__all__ = ["variational_scene_flow"]


def variational_scene_flow(*args, **kwargs):  # pragma: no cover - placeholder
    raise NotImplementedError
