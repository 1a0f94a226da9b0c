"""OctoMap through its Python bindings."""

import numpy as np
import pytest

from ehm.core.sensor.scan import Scan
from ehm.eval.baselines import make_mapper


def test_octomap_reads_unknown_space_as_one_half(small_room_split, octomap_bindings):
    mapper = make_mapper("octomap", 0.05, seed=0)
    mapper.build(small_room_split.train)
    far = np.array([[50.0, 50.0, 50.0], [-40.0, 0.0, 1.0]])
    np.testing.assert_array_equal(mapper.occupancy(far), [0.5, 0.5])


def test_octomap_maps_2d_scans_in_a_plane(octomap_bindings):
    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    ring = 3.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    mapper = make_mapper("octomap", 0.05, seed=0)
    mapper.build([Scan(ring, np.zeros(2))])
    p = mapper.occupancy(np.array([[3.0, 0.0], [1.5, 0.0], [9.0, 0.0]]))
    assert p[0] > 0.5 and p[1] < 0.5 and p[2] == 0.5
    # The labels say the same, read at once.
    np.testing.assert_array_equal(
        mapper.labels(np.array([[3.0, 0.0], [1.5, 0.0], [9.0, 0.0]])), [1.0, 0.0, 0.5]
    )


def test_octomap_memory_is_the_trees(small_room_split, octomap_bindings):
    mapper = make_mapper("octomap", 0.05, seed=0)
    for query in (mapper.occupancy, mapper.labels):
        with pytest.raises(RuntimeError, match="build the map"):
            query(np.zeros((1, 3)))
    assert mapper.memory_bytes() == 0
    mapper.build(small_room_split.train)
    assert mapper.memory_bytes() == mapper.tree.memoryUsage() > 0
