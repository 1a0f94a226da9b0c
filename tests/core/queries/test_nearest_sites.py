"""The nearest site of every voxel, against scipy's feature transform."""

import numpy as np
import pytest

from ehm.core.queries.nearest_sites import nearest_sites, nearest_sites_reference


def squared_distances(found: np.ndarray) -> np.ndarray:
    """Squared distance, voxels, from each voxel to the voxel whose flat index it holds."""
    return squared_distances_in(found, np.array(found.shape), np.zeros(3, dtype=int))


def squared_distances_in(found: np.ndarray, grid_shape: np.ndarray, offset: np.ndarray):
    """The same for a box at `offset` in a grid of `grid_shape`, whose flat indices it holds."""
    site = np.stack(np.unravel_index(found, tuple(grid_shape)))
    return ((site - offset[:, None, None, None] - np.indices(found.shape)) ** 2).sum(axis=0)


@pytest.mark.parametrize(
    ("shape", "share"),
    [
        ((7, 9, 11), 0.02),
        ((30, 20, 25), 0.001),
        ((16, 16, 16), 0.3),
        ((5, 1, 8), 0.2),
        ((40, 30, 1), 0.01),
    ],
)
def test_every_voxel_finds_a_site_as_near_as_scipy_finds(rng, shape, share):
    sites = rng.random(shape) < share
    sites[shape[0] // 2, 0, shape[2] - 1] = True
    found = nearest_sites(sites)
    assert sites.ravel()[found.ravel()].all()
    # Where two sites are equally near either may be given: the distances agree exactly.
    np.testing.assert_array_equal(
        squared_distances(found), squared_distances(nearest_sites_reference(sites))
    )


def test_a_box_placed_in_a_grid_gives_the_grid_s_flat_indices(rng):
    """A box of 9 x 8 x 7 voxels at (4, 2, 1) in a grid of 30 x 20 x 10: each voxel's nearest
    site is the box's own, flat in the grid, as the twin places scipy's."""
    sites = rng.random((9, 8, 7)) < 0.05
    sites[0, 0, 0] = True
    offset, grid_shape = np.array([4, 2, 1]), np.array([30, 20, 10])
    found = nearest_sites(sites, offset, grid_shape)
    in_box = np.stack(np.unravel_index(nearest_sites(sites), sites.shape))
    placed = np.ravel_multi_index(tuple(in_box + offset[:, None, None, None]), tuple(grid_shape))
    np.testing.assert_array_equal(found, placed)
    np.testing.assert_array_equal(
        squared_distances_in(found, grid_shape, offset),
        squared_distances_in(
            nearest_sites_reference(sites, offset, grid_shape), grid_shape, offset
        ),
    )
    with pytest.raises(ValueError, match="2\\^31"):
        nearest_sites(sites, offset, np.array([2048, 2048, 1024]))


def test_a_lone_site_is_every_voxel_s_nearest_and_an_empty_grid_has_none():
    sites = np.zeros((4, 5, 6), dtype=bool)
    sites[1, 2, 3] = True
    assert np.all(nearest_sites(sites) == np.ravel_multi_index((1, 2, 3), sites.shape))
    assert np.all(nearest_sites(np.zeros((3, 3, 3), dtype=bool)) == -1)
    with pytest.raises(ValueError, match="3D"):
        nearest_sites(np.ones((3, 3), dtype=bool))
