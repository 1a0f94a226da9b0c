"""Local grids (Eq. 17): the compiled accumulation against its NumPy twin."""

import numpy as np
import pytest

from ehm.core.model.kernels import kernel_transforms
from ehm.core.snapshot import MapSnapshot
from ehm.grid.local_grids import (
    Lattice,
    LocalGrids,
    accumulate_local_grids,
    accumulate_local_grids_reference,
)


def random_local_grids(dim: int, rng: np.random.Generator) -> tuple[Lattice, LocalGrids]:
    """A grid's lattice and the local grids of 60 random clusters, some reaching past its
    edges, some of weight 0."""
    lattice = Lattice.lift(np.full(dim, -1.0), 0.1, (20, 24, 16)[:dim])
    means = rng.uniform(-1.5, 1.5, (60, dim))
    spread = rng.normal(size=(60, dim, dim)) * rng.uniform(0.02, 0.2, (60, 1, 1))
    planar = rng.random(60) < 0.5
    transforms = kernel_transforms(spread @ np.swapaxes(spread, 1, 2), 3.0, 0.02, planar)
    weights = rng.normal(size=60)
    weights[::7] = 0.0
    precision = rng.uniform(1.0, 30.0, 60)
    return lattice, MapSnapshot(means, transforms, weights, precision, planar, 0.0, 1.0, object())


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("with_variance", [False, True])
def test_compiled_accumulation_matches_reference(dim, with_variance, rng):
    lattice, snapshot = random_local_grids(dim, rng)
    local = LocalGrids.of(snapshot, np.arange(60), lattice, 1.0, with_variance)
    assert len(local) == (60 if with_variance else 60 - 9)  # without: weight 0 left out
    compiled = np.zeros((local.coefficients.shape[1], *lattice.shape))
    reference = np.zeros_like(compiled)
    accumulate_local_grids(compiled, lattice, local)
    accumulate_local_grids_reference(reference, lattice, local)
    assert np.count_nonzero(reference[0]) > 0.3 * reference[0].size
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=1e-12)
    if with_variance:
        # Squared kernels are at most the kernels, and 1 / precision is below 1.
        assert np.all(reference[1] <= reference[2] + 1e-12) and reference[2].max() > 1.0


def test_2d_lattice_is_one_voxel_thick_around_the_plane():
    lattice = Lattice.lift(np.array([1.0, 2.0]), 0.25, (4, 6))
    assert lattice.shape == (4, 6, 1)
    np.testing.assert_array_equal(lattice.origin, [1.0, 2.0, -0.125])


def test_boxes_hold_the_voxel_centres_of_each_support():
    # A ball of radius 0.3 m (k_SP reaches 3 standard deviations of 0.1 m) at (0.52, 0, 0).
    snapshot = MapSnapshot(
        np.array([[0.52, 0.0, 0.0]]),
        np.eye(3)[None] / 0.3,
        np.ones(1),
        np.full(1, 4.0),
        np.zeros(1, bool),
        0.0,
        1.0,
        1,
    )
    lattice = Lattice.lift(np.full(3, -1.0), 0.1, (20, 20, 20))
    local = LocalGrids.of(snapshot, np.arange(1), lattice)
    # Centres -1 + (i + 0.5) 0.1 within 0.3 of 0.52 along x: i = 12 (0.25) to 17 (0.75);
    # within 0.3 of 0 along y and z: i = 7 (-0.25) to 12 (0.25).
    np.testing.assert_array_equal(local.low, [[12, 7, 7]])
    np.testing.assert_array_equal(local.high, [[17, 12, 12]])
    assert local.voxels == 6 * 6 * 6
    negated = LocalGrids.of(snapshot, np.arange(1), lattice, -1.0, with_variance=True)
    np.testing.assert_array_equal(negated.coefficients, [[-1.0, -0.25, -1.0]])
