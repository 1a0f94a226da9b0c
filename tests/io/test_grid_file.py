"""Grid files (.npz)."""

import numpy as np
import pytest

import ehm
from ehm.io.grid_file import load_grid, save_grid


def test_grid_file_round_trip(plan, tmp_path):
    grid = ehm.HilbertMap().fit(plan.scans).grid(resolution=0.1)
    save_grid(grid, tmp_path / "plan.npz")
    loaded = load_grid(tmp_path / "plan.npz")
    np.testing.assert_array_equal(loaded.probability, grid.probability)
    np.testing.assert_array_equal(loaded.origin, grid.origin)
    assert loaded.resolution == grid.resolution
    np.savez(tmp_path / "other.npz", scores=np.zeros(3))
    with pytest.raises(
        ValueError, match=r"not an ehm grid file \(no intercept, origin, resolution\)"
    ):
        load_grid(tmp_path / "other.npz")
