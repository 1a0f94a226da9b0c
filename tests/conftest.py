import numpy as np
import pytest

from ehm.datasets import floor_plan_2d, virtual_room
from ehm.datasets.real import DataMissingError


@pytest.fixture(scope="session")
def room():
    return virtual_room(seed=0)


@pytest.fixture(scope="session")
def plan():
    return floor_plan_2d(seed=0)


@pytest.fixture
def rng():
    return np.random.default_rng(42)


def load_or_skip(loader):
    """Run a real-data loader, skipping the test with its message when the data is absent."""
    try:
        return loader()
    except DataMissingError as missing:
        pytest.skip(str(missing))
