"""Simulated scans of the synthetic scenes."""

import numpy as np

from ehm.eval.datasets import warehouse


def test_warehouse_scans_start_in_free_space_and_end_on_surfaces():
    data = warehouse(rings=8, azimuths=90, noise_std=0.0)
    assert len(data.scans) == 6
    for scan in data.scans:
        assert not data.scene.occupied(scan.origin[None])[0]
        hits = scan.points_world[scan.hit_mask]
        assert len(hits) > 0.9 * len(scan)
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)
