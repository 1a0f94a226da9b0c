"""The range noise a batch's hits show: read off their spread about the planes they lie on,
by bands of range, and the free sample in front of each hit moved clear of it."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations.range_noise import range_noise
from ehm.core.observations.samples import front_clearances, scan_rays
from ehm.core.sensor.scan import Scan

WALLS = np.array([1.02, 2.1, 3.9, 6.06])


def _walls(rng: np.random.Generator, noise_per_metre: float) -> Scan:
    """A depth camera at the origin looking along +x at walls about 1, 2, 4 and 6 m away
    (each in the middle of a layer of 12 cm cells), each a band of its rays, their ranges
    noisy by noise_per_metre times the wall's distance squared."""
    directions = np.column_stack(
        [np.ones(40_000), rng.uniform(-0.5, 0.5, 40_000), rng.uniform(-0.4, 0.4, 40_000)]
    )
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    distance = WALLS[np.digitize(directions[:, 1], [-0.25, 0.0, 0.25])]
    ranges = distance / directions[:, 0]  # walls x = distance, faced head on
    ranges += rng.normal(0.0, noise_per_metre * distance**2)
    return Scan(directions * ranges[:, None], np.zeros(3))


def test_range_noise_reads_a_depth_cameras_noise_growing_with_range(rng):
    """Walls with range noise of 0.5 mm x distance^2 (0.5 to 18 mm) read it at their range
    within 25 %, along the rays whatever the angle they meet the wall at; walls without
    noise read none."""
    rays = scan_rays([_walls(rng, 0.0005)], MapConfig())
    for distance in WALLS:
        on_wall = np.abs(rays.ends[:, 0] - distance) < 0.1
        expected = 0.0005 * distance**2
        assert np.median(rays.hit_noise[on_wall]) == pytest.approx(expected, rel=0.25)
    still = scan_rays([_walls(rng, 0.0)], MapConfig())
    assert np.abs(still.hit_noise).max() < 1e-9


def test_range_noise_of_too_few_measured_hits_is_none():
    spreads = np.array([0.01, np.nan, 0.02])
    axes = np.tile([1.0, 0.0, 0.0], (3, 1))
    noise = range_noise(np.array([1.0, 2.0, 3.0]), axes, spreads, axes)
    np.testing.assert_array_equal(noise, 0.0)


def test_free_samples_in_front_of_noisy_hits_move_clear_of_the_noise(rng):
    """Each hit's free sample lies noise_clearance times the noise at its range farther in
    front of it; 0 leaves it within the surface margin."""
    scan = _walls(rng, 0.0005)
    config = MapConfig()
    rays = scan_rays([scan], config)
    np.testing.assert_allclose(front_clearances(rays, config), 2.0 * rays.hit_noise)
    assert config.noise_clearance == 2.0
    assert not front_clearances(rays, config.replace(noise_clearance=0.0)).any()
