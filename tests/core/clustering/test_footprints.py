"""How wide the fine clusters of a place are: the footprint of the rays there."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.clustering.footprints import MAX_LEVEL, fine_levels
from ehm.core.observations.samples import scan_rays
from ehm.core.sensor.scan import Scan


def _fan(origin: np.ndarray, n_rays: int) -> Scan:
    """A 2D scan of `n_rays` rays over a half turn, 10 m long."""
    angles = np.linspace(0.0, np.pi, n_rays, endpoint=False)
    return Scan(origin + 10.0 * np.column_stack([np.cos(angles), np.sin(angles)]), origin)


def test_levels_step_up_where_a_radius_spans_fewer_footprints():
    """180 rays over pi: 1 degree apart. With 3 hits per radius of 0.12 m, level 0 holds to
    0.12 / 3 / 0.01745 = 2.29 m from the sensor, level 1 to twice that, level 2 beyond."""
    config = MapConfig(cluster_radius=0.12, hits_per_radius=3.0)
    rays = scan_rays([_fan(np.zeros(2), 180)], config)
    spacing = np.pi / 180
    edge = 0.12 / 3.0 / spacing
    distances = np.array([0.5, 0.99 * edge, 1.01 * edge, 1.99 * edge, 2.01 * edge, 50.0])
    points = np.column_stack([distances, np.zeros(6)])
    np.testing.assert_array_equal(fine_levels(points, rays, config), [0, 0, 1, 1, 2, MAX_LEVEL])
    assert MAX_LEVEL == 2
    off = fine_levels(points, rays, config.replace(hits_per_radius=0.0))
    np.testing.assert_array_equal(off, np.zeros(6))


def test_levels_follow_the_nearest_origin_of_the_batch():
    """Two scans 6 m apart: a point beside the second is near a sensor, at level 0; one 8.5 m
    from both, beyond twice the last edge (2.29 m), at the last level."""
    config = MapConfig(hits_per_radius=3.0)
    scans = [_fan(np.zeros(2), 180), _fan(np.array([6.0, 0.0]), 180)]
    rays = scan_rays(scans, config)
    points = np.array([[6.5, 0.0], [3.0, 8.0]])
    levels = fine_levels(points, rays, config)
    assert levels[0] == 0 and levels[1] == MAX_LEVEL


def test_no_points_have_no_levels():
    config = MapConfig(hits_per_radius=3.0)
    rays = scan_rays([_fan(np.zeros(2), 180)], config)
    assert fine_levels(np.zeros((0, 2)), rays, config).shape == (0,)


def test_a_batch_that_reaches_no_farther_than_level_zero_is_all_level_zero():
    """1 m rays, 1 degree apart: level 0 holds to 2.29 m, beyond the batch's reach, so its
    samples (and the ones waiting near them) are all of level 0, measured or not."""
    config = MapConfig(hits_per_radius=3.0)
    scan = _fan(np.zeros(2), 180)
    near = Scan(scan.origin + (scan.points_world - scan.origin) / 10.0, scan.origin)
    rays = scan_rays([near], config)
    points = np.random.default_rng(0).uniform(-1.2, 1.2, (500, 2))
    np.testing.assert_array_equal(fine_levels(points, rays, config), np.zeros(500))
    # Measured through a batch of 10 m rays from the same origin, they are of level 0 too.
    np.testing.assert_array_equal(fine_levels(points, scan_rays([scan], config), config), 0)
