"""``flowtrack release``: the student bundle (:mod:`.release`)."""

from .release import release, release_notebook, scan_bundle

__all__ = ["release", "release_notebook", "scan_bundle"]
