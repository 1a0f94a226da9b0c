"""The cells kernels of positive weight reach, counted anew and followed through changes."""

import numpy as np

from ehm.core.queries.cover import KernelCover, covered_cells, pack_cells, unpack_cells


def test_a_followed_cover_is_the_cover_of_the_kernels_now(rng):
    means = rng.uniform(-3, 3, (200, 3))
    reach = rng.uniform(0.05, 0.8, 200)
    weights = rng.normal(size=200)
    cover = KernelCover.of_kernels(means, reach, weights, 0.25)
    # Twenty kernels change (weight, place, reach), thirty are merged away, forty are new.
    changed = rng.choice(170, 20, replace=False)
    new_means, new_reach, new_weights = means[:170].copy(), reach[:170].copy(), weights[:170].copy()
    new_means[changed] += rng.normal(0, 0.3, (20, 3))
    new_reach[changed] *= 1.5
    new_weights[changed] = rng.normal(size=20)
    new_means = np.concatenate([new_means, rng.uniform(-3, 3, (40, 3))])
    new_reach = np.concatenate([new_reach, rng.uniform(0.05, 0.8, 40)])
    new_weights = np.concatenate([new_weights, rng.normal(size=40)])
    gone = np.concatenate([changed, np.arange(170, 200)])
    arrived = np.concatenate([changed, np.arange(170, 210)])
    followed = cover.changed(
        (means[gone], reach[gone], weights[gone]),
        (new_means[arrived], new_reach[arrived], new_weights[arrived]),
    )
    anew = KernelCover.of_kernels(new_means, new_reach, new_weights, 0.25)
    np.testing.assert_array_equal(followed.keys, anew.keys)
    np.testing.assert_array_equal(followed.counts, anew.counts)
    np.testing.assert_allclose(followed.sums, anew.sums, rtol=0, atol=1e-12)


def test_cells_are_the_boxes_of_positive_kernels():
    means = np.array([[0.1, 0.1], [5.0, 5.0], [0.3, 0.3]])
    cover = KernelCover.of_kernels(
        means, np.array([0.2, 1.0, 0.1]), np.array([1.0, -2.0, 0.5]), 1.0
    )
    # The negative kernel reaches nothing; the other two share the cell (0, 0), and the
    # first reaches (-1, -1) to (0, 0).
    cells = unpack_cells(cover.keys, cover.bits, 2)
    expected = {(-1, -1): 1.0, (-1, 0): 1.0, (0, -1): 1.0, (0, 0): 1.5}
    assert {tuple(c): s for c, s in zip(cells.tolist(), cover.sums, strict=True)} == expected
    assert cover.counts.tolist() == [1 if s == 1.0 else 2 for s in cover.sums]
    low, high = np.array([[0, 0]]), np.array([[1, 2]])
    cells, owners = covered_cells(low, high)
    assert len(cells) == 6 and np.all(owners == 0)
    np.testing.assert_array_equal(unpack_cells(pack_cells(cells, 31), 31, 2), cells)
