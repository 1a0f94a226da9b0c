"""Grid files (.npz)."""

import numpy as np
import pytest

import ehm
from ehm.io.grid_file import load_grid, save_grid


@pytest.mark.parametrize("std", [False, True])
def test_grid_file_round_trip(plan, std, tmp_path):
    grid = ehm.HilbertMap(prior_precision=2.0).fit(plan.scans).grid(resolution=0.1, std=std)
    save_grid(grid, tmp_path / "plan.npz")
    loaded = load_grid(tmp_path / "plan.npz")
    np.testing.assert_array_equal(loaded.probability, grid.probability)
    np.testing.assert_array_equal(loaded.origin, grid.origin)
    assert loaded.resolution == grid.resolution
    assert loaded.has_std == std
    if std:
        np.testing.assert_array_equal(loaded.std, grid.std)
        assert np.load(tmp_path / "plan.npz")["std"].shape == grid.shape
    np.savez(tmp_path / "other.npz", scores=np.zeros(3))
    with pytest.raises(
        ValueError, match=r"not an ehm grid file \(no intercept, origin, resolution\)"
    ):
        load_grid(tmp_path / "other.npz")
    np.savez(
        tmp_path / "half.npz",
        scores=np.zeros(3),
        intercept=0.0,
        origin=np.zeros(1),
        resolution=0.1,
        variance_sums=np.zeros((2, 3)),
    )
    with pytest.raises(ValueError, match="variance_sums without prior_precision"):
        load_grid(tmp_path / "half.npz")
