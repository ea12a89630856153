import numpy as np
import pytest


@pytest.fixture
def rng():
    """A seeded random generator (tests are deterministic)."""
    return np.random.default_rng(12345)
