"""Fixtures of the sandbox's tests."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    """A seeded generator so that every test is reproducible."""
    return np.random.default_rng(12345)
