"""Grid bounds and sizes, checked before anything is allocated."""

import numpy as np
import pytest


@pytest.mark.parametrize(
    ("bounds", "resolution", "message"),
    [
        (None, 0.0, "resolution must be a positive"),
        (None, -0.1, "resolution must be a positive"),
        (None, float("nan"), "resolution must be a positive"),
        ([[0, 0, 0], [1, 1]], 0.1, "shape (2, 3)"),
        ([[0, 0, 0], [1, np.inf, 1]], 0.1, "must be finite"),
        ([[0, 0, 0], [1, -1, 1]], 0.1, "inverted"),
        ([[0, 0, 0], [1, 1, 0]], 0.1, "empty: zero extent on axis 2"),
        ([[-1e4, -1e4, -10], [1e4, 1e4, 10]], 0.01, "more than the limit of 1.00 GiB"),
    ],
)
def test_bad_grids_are_refused_before_allocating(room_map, bounds, resolution, message):
    with pytest.raises(ValueError, match="grid") as error:
        room_map.grid(bounds, resolution)
    assert message in str(error.value)


def test_grids_with_the_std_count_40_bytes_a_voxel(room_map):
    # 100 x 100 x 100 voxels: 16 MB without the std, 40 MB with it.
    bounds = np.array([[-2.0, -2.0, 0.0], [2.0, 2.0, 4.0]])
    room_map.grid(bounds, 0.04, max_bytes=20_000_000)
    with pytest.raises(ValueError, match=r"would take 0\.04 GiB"):
        room_map.grid(bounds, 0.04, max_bytes=20_000_000, std=True)
