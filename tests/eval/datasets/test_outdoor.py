"""The hillside: a slope, kerbs, a fence, thin poles at range and porous vegetation."""

import numpy as np
import pytest

from ehm.eval.datasets import hillside
from ehm.eval.datasets.outdoor import (
    HILL_FOOT,
    SLOPE_DEGREES,
    hill_height,
    hillside_scene,
)


def test_the_hillside_rises_at_its_slope_in_steps_below_the_range_noise():
    scene = hillside_scene()
    y = HILL_FOOT + np.array([1.0, 5.0, 10.0, 15.0])
    slope = np.tan(np.radians(SLOPE_DEGREES))
    np.testing.assert_allclose(hill_height(y), (y - HILL_FOOT) * slope, atol=0.02)
    x = np.full(len(y), 2.0)  # between the poles and trees
    below = np.column_stack([x, y, hill_height(y) - 0.01])
    above = np.column_stack([x, y, hill_height(y) + 0.01])
    assert scene.occupied(below).all() and not scene.occupied(above).any()


@pytest.fixture(scope="module")
def scans():
    return hillside(rings=32, azimuths=256, noise_std=0.0)


def test_scans_see_the_slope_far_up_poles_the_fence_and_through_foliage(scans):
    scene = scans.scene
    assert len(scans.scans) == 4
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans.scans])
    np.testing.assert_allclose(scene.surface_distance(hits), 0.0, atol=1e-6)
    for scan in scans.scans:
        assert not scene.occupied(scan.origin[None])[0]
        assert 0.1 < np.mean(~scan.hit_mask) < 0.6  # rays into the sky return nothing
    on_slope = hits[:, 1] > HILL_FOOT + 5.0
    assert np.any(on_slope & (hits[:, 2] > 1.5))
    size = scene.box_max - scene.box_min
    thin = np.all(size[:, :2] <= 0.1, axis=1)
    poles = thin & (scene.box_min[:, 1] > 5.0)
    fence = thin & (scene.box_min[:, 1] < 0.0)
    assert poles.sum() == 5 and fence.sum() == 23  # posts every 3 m of its 70

    def hits_on(boxes):
        inside = (hits[:, None] >= scene.box_min[boxes] - 1e-6) & (
            hits[:, None] <= scene.box_max[boxes] + 1e-6
        )
        return np.all(inside, axis=2).any(axis=1)

    assert hits_on(poles).sum() > 10 and hits_on(fence).sum() > 100
    # Foliage: hits on its balls, and rays that pass a crown's gaps to the slope behind it.
    to_balls = np.linalg.norm(hits[:, None] - scene.ball_centres, axis=2) - scene.ball_radii
    on_leaves = np.isclose(to_balls.min(axis=1), 0.0, atol=1e-6)
    assert on_leaves.sum() > 200
    crown = scene.ball_centres[0]
    behind = (np.abs(hits[:, 0] - crown[0]) < 1.0) & (hits[:, 1] > crown[1] + 2.0) & ~on_leaves
    assert behind.sum() > 5
