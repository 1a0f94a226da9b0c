"""Integer cells of a grid over a point set."""

import numpy as np
import pytest

from ehm.core.primitives.cells import (
    cell_keys,
    in_neighbour_cells,
    in_neighbour_cells_reference,
    packed_cell_keys,
    packed_cell_keys_reference,
    z_order_keys,
    z_order_keys_reference,
)
from ehm.errors import InputError


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


@pytest.mark.parametrize("dim", [2, 3])
def test_z_order_keys_agree_with_their_numpy_twin_and_key_each_cell_once(rng, dim):
    points = rng.uniform(-40.0, 40.0, (5000, dim))
    keyed = cell_keys(points, 0.5)
    keys = z_order_keys(keyed)
    np.testing.assert_array_equal(keys, z_order_keys_reference(keyed.cells))
    # One key per cell, as the linear keys: the same cells, in another order.
    n_cells = len(np.unique(keyed.keys))
    assert len(np.unique(keys)) == n_cells
    assert len(np.unique(np.column_stack([keyed.keys, keys]), axis=0)) == n_cells
    # In Z-order the cells of a block of two along each axis come before the cells beyond it,
    # the last axis the fastest.
    block = np.array([[0, 0], [0, 1], [1, 0], [1, 1]] if dim == 2 else [[0, 0, 1], [0, 1, 0]])
    beyond = np.full((1, dim), 2)
    assert np.all(np.diff(z_order_keys_reference(np.vstack([block, beyond]))) > 0)


def test_z_order_keys_fall_back_to_linear_keys_beyond_their_bits():
    points = np.array([[0.0, 0.0, 0.0], [3e6, 0.0, 0.0]])  # 3e6 cells of 1 m along x
    keyed = cell_keys(points, 1.0)
    np.testing.assert_array_equal(z_order_keys(keyed), keyed.keys)


def test_keys_that_would_overflow_are_refused():
    points = np.array([[0.0, 0.0, 0.0], [1e7, 1e7, 1e7]])
    with pytest.raises(ValueError, match="cell keys overflow"):
        cell_keys(points, 0.01)


@pytest.mark.parametrize("dim", [2, 3])
def test_packed_keys_agree_with_their_numpy_twin(rng, dim):
    points = rng.uniform(-50.0, 50.0, (5000, dim))
    kind = rng.integers(0, 4, len(points))
    side = np.array([0.2, 0.03, 0.03, 0.5])[kind]  # one side per kind, as the callers keep
    compiled = packed_cell_keys(points, side, kind, 2)
    np.testing.assert_array_equal(compiled, packed_cell_keys_reference(points, side, kind, 2))
    # Points in one cell of one kind share a key, and no others do.
    cells = np.column_stack([np.floor(points / side[:, None]), kind])
    assert len(np.unique(compiled)) == len(np.unique(cells, axis=0))


@pytest.mark.parametrize("keys_of", [packed_cell_keys, packed_cell_keys_reference])
def test_packed_keys_refuse_points_beyond_their_reach(keys_of):
    points = np.array([[1.0, 2.0, 3.0], [4e9, 0.0, 0.0]])
    with pytest.raises(InputError, match="lies 4000000000 m from the map's origin"):
        keys_of(points, np.full(2, 0.05), np.zeros(2, dtype=np.int64), 2)


@pytest.mark.parametrize("dim", [2, 3])
def test_neighbour_cells_agree_with_their_numpy_twin_and_hold_every_near_point(rng, dim):
    anchors = rng.uniform(-3.0, 3.0, (30, dim))
    points = rng.uniform(-5.0, 5.0, (4000, dim))
    inside = in_neighbour_cells(anchors, points, 0.4)
    np.testing.assert_array_equal(inside, in_neighbour_cells_reference(anchors, points, 0.4))
    distance = np.linalg.norm(points[:, None, :] - anchors[None, :, :], axis=2).min(axis=1)
    assert inside[distance <= 0.4].all()
    assert not inside[distance > 0.4 * 2.0 * np.sqrt(dim)].any()
    assert 0 < inside.sum() < len(points) // 2


def test_neighbour_cells_too_many_to_key_are_none():
    anchors = np.array([[0.0, 0.0, 0.0], [1e7, 1e7, 1e7]])
    assert in_neighbour_cells(anchors, np.zeros((3, 3)), 1e-3) is None
