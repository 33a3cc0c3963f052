"""Where the benchmark scripts put their tables: printed always, recorded only by full runs."""

from __future__ import annotations

from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def publish(name: str, text: str, quick: bool) -> None:
    """Print ``text``; unless ``quick`` (a smoke run), write it to ``results/<name>.md``."""
    print(text)
    if quick:
        return
    RESULTS.mkdir(exist_ok=True)
    out = RESULTS / f"{name}.md"
    out.write_text(text)
    print("wrote", out)


def save_small_png(fig, path, dpi: int = 60, colors: int = 128) -> None:
    """Save a matplotlib figure as a palette PNG (``colors`` colours): galleries stay small in the repo."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    buf.seek(0)
    Image.open(buf).convert("RGB").quantize(colors=colors).save(path, optimize=True)
