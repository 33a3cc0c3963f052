"""Text the grader shows: messages are cut to a bounded length.

>>> clip_message("short"), clip_message("x" * 5000).endswith("x ... (truncated)")
('short', True)
"""

from __future__ import annotations

__all__ = ["MAX_MESSAGE", "clip_message"]

MAX_MESSAGE = 2000


def clip_message(text: str) -> str:
    """``text`` (made a ``str``) cut to :data:`MAX_MESSAGE` characters, saying so."""
    text = str(text)
    return text if len(text) <= MAX_MESSAGE else text[: MAX_MESSAGE - 15] + " ... (truncated)"
