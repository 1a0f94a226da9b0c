"""Fixtures of the baseline tests: a small split of the virtual room, OctoMap's bindings."""

import pytest

from ehm.eval.datasets import virtual_room
from ehm.eval.protocol import held_out_rays


@pytest.fixture(scope="module")
def small_room_split():
    """A coarse scan of the virtual room (about 12,000 rays), 60 % of its rays to train."""
    data = virtual_room(seed=0, rings=24, azimuths=500)
    return held_out_rays(data.scans, 0.6, 0.05, seed=0)


@pytest.fixture
def octomap_bindings():
    """Skips the test when OctoMap's Python bindings are not installed."""
    return pytest.importorskip("octomap", reason="pip install 'ehm[octomap]'")
