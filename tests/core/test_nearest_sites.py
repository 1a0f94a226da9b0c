"""The nearest site of every voxel, against scipy's feature transform."""

import numpy as np
import pytest

from ehm.core.queries.nearest_sites import nearest_sites, nearest_sites_reference


def squared_distances(found: np.ndarray) -> np.ndarray:
    """Squared distance, voxels, from each voxel to the voxel whose flat index it holds."""
    site = np.stack(np.unravel_index(found, found.shape))
    return ((site - np.indices(found.shape)) ** 2).sum(axis=0)


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


def test_a_lone_site_is_every_voxel_s_nearest_and_an_empty_grid_has_none():
    sites = np.zeros((4, 5, 6), dtype=bool)
    sites[1, 2, 3] = True
    assert np.all(nearest_sites(sites) == np.ravel_multi_index((1, 2, 3), sites.shape))
    assert np.all(nearest_sites(np.zeros((3, 3, 3), dtype=bool)) == -1)
    with pytest.raises(ValueError, match="3D"):
        nearest_sites(np.ones((3, 3), dtype=bool))
