"""A map's own frame, near its first sensor pose when that lies far from the world origin."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.sensor.local_frame import LOCAL_ORIGIN_STEP, in_frame, local_origin_for
from ehm.core.sensor.scan import Scan


def test_maps_near_the_world_origin_keep_it():
    assert local_origin_for(np.array([9_999.0, -50.0, 2.0])).tolist() == [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(
        local_origin_for(np.array([499_781.6, 4_200_300.0, 2500.0])), [499_712, 4_200_448, 2048]
    )


def test_scans_and_the_learn_box_move_into_the_frame_exactly(rng):
    origin = np.array([488.0, 4101.0, 3.0]) * LOCAL_ORIGIN_STEP
    sensor = origin + np.array([1.5, -2.0, 1.0])
    points = sensor + rng.uniform(-5.0, 5.0, (100, 3))
    hit_mask = rng.random(100) < 0.9
    scan = Scan(points, sensor, hit_mask, time=4.0)
    box = (*(origin - 10.0), *(origin + 10.0))
    (local,), config = in_frame([scan], MapConfig(learn_box=box), origin)
    np.testing.assert_array_equal(local.points_world + origin, points)
    np.testing.assert_array_equal(local.origin, [1.5, -2.0, 1.0])
    np.testing.assert_array_equal(local.hit_mask, hit_mask)
    assert local.time == 4.0
    assert config.learn_box == (-10.0, -10.0, -10.0, 10.0, 10.0, 10.0)


def test_the_world_frame_leaves_scans_and_settings_as_given(rng):
    scans = [Scan(rng.uniform(-5.0, 5.0, (10, 2)), np.zeros(2))]
    config = MapConfig(learn_box=(-1.0, -1.0, 1.0, 1.0))
    kept, same = in_frame(scans, config, np.zeros(2))
    assert kept is scans and same is config
