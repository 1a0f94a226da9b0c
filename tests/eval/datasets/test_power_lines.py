"""The power lines: wires thinner than a voxel along two axes, poles, house fronts."""

import numpy as np
import pytest

from ehm.eval.datasets import power_lines
from ehm.eval.datasets.power_lines import (
    CABLE_HEIGHT,
    CONDUCTOR_WIDTH,
    CONDUCTORS,
    CROSSING_HEIGHT,
    CROSSING_X,
    LINE_Y,
    power_lines_scene,
)


def test_each_wire_is_solid_across_its_width_only():
    scene = power_lines_scene()
    x = np.array([3.0, 3.0])
    for dy, z in CONDUCTORS:
        inside = np.column_stack([x, [LINE_Y + dy] * 2, [z - 0.005, z + 0.005]])
        beside = inside + np.array([0.0, CONDUCTOR_WIDTH, 0.0])
        assert scene.occupied(inside).all() and not scene.occupied(beside).any()
    cable = np.array([[3.0, LINE_Y, CABLE_HEIGHT + 0.012], [3.0, LINE_Y, CABLE_HEIGHT + 0.02]])
    np.testing.assert_array_equal(scene.occupied(cable), [True, False])
    # The crossing wire spans the road at its height.
    over_road = np.column_stack([[CROSSING_X] * 3, [-8.0, 0.0, 6.0], [CROSSING_HEIGHT] * 3])
    assert scene.occupied(over_road).all()


@pytest.fixture(scope="module")
def dataset():
    return power_lines(noise_std=0.0)


def test_the_lidar_sees_each_wire_in_a_few_hits_from_below(dataset):
    scene = dataset.scene
    hits = np.concatenate([s.points_world[s.hit_mask] for s in dataset.scans])
    assert len(dataset.scans) == 5
    # Noise-free hits lie on the scene's surfaces: a step back along the ray is free.
    origins = np.concatenate([np.broadcast_to(s.origin, s.points_world.shape)[s.hit_mask]
                              for s in dataset.scans])  # fmt: skip
    rays = (hits - origins) / np.linalg.norm(hits - origins, axis=1)[:, None]
    assert not scene.occupied(hits - 0.01 * rays).any()
    conductors = np.zeros(len(hits), dtype=bool)
    for dy, z in CONDUCTORS:
        conductors |= (np.abs(hits[:, 1] - LINE_Y - dy) < 0.02) & (np.abs(hits[:, 2] - z) < 0.02)
    cable = (np.abs(hits[:, 1] - LINE_Y) < 0.03) & (np.abs(hits[:, 2] - CABLE_HEIGHT) < 0.03)
    crossing = (np.abs(hits[:, 0] - CROSSING_X) < 0.02) & (
        np.abs(hits[:, 2] - CROSSING_HEIGHT) < 0.02
    )
    # A few dozen hits each in five scans of 32,768 rays: a wire is seen a few rays at a time.
    for wire in (conductors, cable, crossing):
        assert 10 <= wire.sum() <= 200


def test_the_range_noise_follows_the_seed():
    a, b = power_lines(seed=1, azimuths=64), power_lines(seed=1, azimuths=64)
    c = power_lines(seed=2, azimuths=64)
    np.testing.assert_array_equal(a.scans[0].points_world, b.scans[0].points_world)
    assert not np.array_equal(a.scans[0].points_world, c.scans[0].points_world)
