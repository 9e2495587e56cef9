import numpy as np
import pytest

from bayesdrag.io.drag_tables import load_m101


@pytest.fixture(scope="session")
def m101():
    """155 mm M101 zero-yaw drag curve (BRL MR-1167), shipped in the package."""
    return load_m101()


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
