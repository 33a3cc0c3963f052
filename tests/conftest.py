"""Shared pytest configuration for the flowtrack suite."""

import os
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

#: The course folder under test: this checkout. Set explicitly (the tools never guess it from their
#: own location; see flowtrack_course.course), before any test module reads the ports' folders, and
#: inherited by every subprocess and notebook kernel the tests start.
COURSE = Path(__file__).resolve().parents[1]
os.environ["FLOWTRACK_COURSE"] = str(COURSE)


@pytest.fixture
def course_dir() -> Path:
    """The course folder (this checkout), as ``$FLOWTRACK_COURSE`` names it."""
    return COURSE


@pytest.fixture
def rng():
    """A seeded generator so that every test is reproducible."""
    return np.random.default_rng(12345)
