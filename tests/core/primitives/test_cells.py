"""Integer cells of a grid over a point set."""

import numpy as np
import pytest

from ehm.core.primitives.cells import cell_keys


def test_points_in_one_cell_share_a_key_and_keys_differ_between_cells(rng):
    points = rng.uniform([-2.0, 5.0, 0.0], [3.0, 7.0, 1.0], (2000, 3))
    keys = cell_keys(points, 0.25)
    expected_cells = np.floor((points - points.min(axis=0)) / 0.25).astype(np.int64)
    np.testing.assert_array_equal(keys.cells, expected_cells)
    np.testing.assert_array_equal(keys.extents, expected_cells.max(axis=0) + 1)
    # One key per distinct cell, and back: keys are a bijection of the cells.
    distinct_cells = np.unique(keys.cells, axis=0)
    assert len(np.unique(keys.keys)) == len(distinct_cells)
    np.testing.assert_array_equal(keys.keys, keys.cells @ keys.strides)
    assert keys.strides.tolist() == [1, keys.extents[0], keys.extents[0] * keys.extents[1]]


def test_keys_that_would_overflow_are_refused():
    points = np.array([[0.0, 0.0, 0.0], [1e7, 1e7, 1e7]])
    with pytest.raises(ValueError, match="cell keys overflow"):
        cell_keys(points, 0.01)
