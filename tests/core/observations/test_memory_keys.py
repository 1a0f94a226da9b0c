"""Keys of the memory's cells: each point's cell and kind, as its NumPy twin names them."""

import numpy as np
import pytest

from ehm.core.observations.evidence import FREE_ALONG_RAY, OCCUPIED
from ehm.core.observations.memory_keys import (
    SUB_BITS,
    cell_corners,
    cell_corners_reference,
    memory_keys,
    memory_keys_reference,
)
from ehm.errors import InputError

# Fine cells of 0.25 m (regions of 1 m around hits), coarse ones of 2.5 m (regions of 5 m).
SIDES = (0.25, 2.5)


@pytest.mark.parametrize("dim", [2, 3])
def test_memory_keys_name_the_cell_and_kind_of_each_point(rng, dim):
    points = rng.uniform(-80.0, 80.0, (2000, dim))
    kinds = rng.integers(0, 3, 2000)
    keys = memory_keys(points, kinds, SIDES)
    np.testing.assert_array_equal(keys, memory_keys_reference(points, kinds, SIDES))
    corners = cell_corners(keys, dim, SIDES)
    np.testing.assert_array_equal(corners, cell_corners_reference(keys, dim, SIDES))
    side = np.where(kinds == FREE_ALONG_RAY, SIDES[1], SIDES[0])[:, None]
    assert np.all((points >= corners - 1e-9) & (points < corners + side + 1e-9))
    np.testing.assert_array_equal((keys >> SUB_BITS) & 3, kinds)


@pytest.mark.parametrize("dim", [2, 3])
def test_memory_keys_agree_with_their_twin_on_the_sides_of_cells(rng, dim):
    """Points a whole number of centimetres from the origin in cells of 3 cm and 20 cm: many
    lie on a side, where the rounding of the division decides."""
    points = rng.integers(-3000, 3000, (5000, dim)) * 0.01
    kinds = rng.integers(0, 3, 5000)
    for sides in ((0.03, 0.2), (0.12 / 4, 0.6 / 3)):
        keys = memory_keys(points, kinds, sides)
        np.testing.assert_array_equal(keys, memory_keys_reference(points, kinds, sides))


def test_points_beyond_the_reach_of_memory_keys_are_refused():
    far = np.array([[0.0, 0.0, 1e15]])
    for keys in (memory_keys, memory_keys_reference):
        with pytest.raises(InputError, match="set max_range"):
            keys(far, np.array([OCCUPIED]), SIDES)
