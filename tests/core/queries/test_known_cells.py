"""Cells wholly inside a kernel's support: where rays need not ask whether space is known."""

import numpy as np
import pytest

from ehm.core.queries.cover import unpack_cells
from ehm.core.queries.known_cells import KnownCover, known_cells_reference


def random_kernels(rng, dim, count=40):
    means = rng.uniform(-3.0, 3.0, (count, dim))
    # Transforms of ellipsoids 0.3-1.5 m across their axes, turned at random.
    transforms = np.empty((count, dim, dim))
    for m in range(count):
        rotation, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
        transforms[m] = np.diag(1.0 / rng.uniform(0.3, 1.5, dim)) @ rotation.T
    planar = rng.random(count) < 0.3
    return means, transforms, planar


@pytest.mark.parametrize("dim", [2, 3])
def test_compiled_cells_agree_with_the_reference(rng, dim):
    means, transforms, planar = random_kernels(rng, dim)
    found = KnownCover.of_kernels(means, transforms, planar, 0.25).cells()
    expected = known_cells_reference(means, transforms, planar, 0.25)
    assert len(found.keys) > 100
    np.testing.assert_array_equal(found.keys, expected.keys)
    np.testing.assert_array_equal(found.low, expected.low)
    np.testing.assert_array_equal(found.high, expected.high)


def test_every_point_of_a_known_cell_lies_in_a_support_and_most_of_the_space_is_covered(rng):
    means, transforms, planar = random_kernels(rng, 3, count=20)
    side = 0.2
    cells = unpack_cells(KnownCover.of_kernels(means, transforms, planar, side).keys, 21, 3)
    points = (cells[rng.integers(0, len(cells), 20_000)] + rng.random((20_000, 3))) * side
    u = np.einsum("mab,pmb->pma", transforms, points[:, None, :] - means[None])
    inside = np.where(planar, np.abs(u).max(axis=2) < 1.0, (u * u).sum(axis=2) < 1.0)
    assert inside.any(axis=1).all()
    # And the cells hold most of the supports: points drawn in the kernels' supports fall in a
    # known cell unless near a support's edge (within a cell's diagonal of it).
    lone = ~planar & (np.linalg.norm(np.linalg.inv(transforms), axis=(1, 2)) > 0.8)
    m = np.flatnonzero(lone)[0]
    inner = means[m] + rng.normal(size=(2000, 3)) @ np.linalg.inv(transforms[m]).T * 0.15
    keys = set(map(tuple, cells))
    taken = [tuple(c) for c in np.floor(inner / side).astype(np.int64)]
    assert np.mean([c in keys for c in taken]) > 0.95


def test_a_cover_follows_kernels_out_and_in_as_one_counted_afresh(rng):
    means, transforms, planar = random_kernels(rng, 3, count=30)
    kernels = (means, transforms, planar)
    first = tuple(array[:20] for array in kernels)
    cover = KnownCover.of_kernels(*first, 0.25)
    moved = (means[:5] + 0.3, transforms[:5], planar[:5])
    followed = cover.changed(
        tuple(array[:5] for array in kernels),  # five kernels moved...
        tuple(np.concatenate([m, a[20:]]) for m, a in zip(moved, kernels, strict=True)),
    )  # ...and ten new ones
    now = tuple(np.concatenate([m, a[5:]]) for m, a in zip(moved, kernels, strict=True))
    afresh = KnownCover.of_kernels(*now, 0.25)
    np.testing.assert_array_equal(followed.keys, afresh.keys)
    np.testing.assert_array_equal(followed.counts, afresh.counts)
    assert np.all(afresh.counts >= 1) and afresh.counts.max() > 1
