"""Counts of cluster centres in boxes of cells: against their twin and the exact balls."""

import numpy as np
import pytest

from ehm.core.search.centre_counts import MAX_CELLS, CentreCounts, any_within_reference


@pytest.mark.parametrize("dim", [2, 3])
def test_a_point_is_near_centres_where_its_twin_says_and_wherever_one_lies_within(rng, dim):
    """Centres in two clumps of a 10 m box; points all over it and beyond it, some not
    finite: the table's answer is its twin's, and True wherever a centre lies within the
    radius (the box of cells holds the ball)."""
    centres = np.concatenate([rng.normal(2.0, 0.3, (200, dim)), rng.normal(7.0, 0.5, (300, dim))])
    counts = CentreCounts.of(centres, 0.4)
    points = rng.uniform(-3.0, 13.0, (3000, dim))
    points[:5, 0] = [np.nan, np.inf, -np.inf, np.nan, np.nan]
    points[5:8, 0], points[5:8, -1] = 1e6, np.nan  # far along one axis, not finite on another
    for radius in (0.0, 0.3, 1.2):
        got = counts.any_within(points, radius)
        np.testing.assert_array_equal(got, any_within_reference(counts, centres, points, radius))
        exact = np.any(np.linalg.norm(points[:, None] - centres[None], axis=2) <= radius, axis=1)
        assert np.all(got[exact]) and got[:8].all()
        assert 0 < got.sum() < len(got)


def test_a_table_over_a_wide_box_takes_wider_cells(rng):
    """Centres 10 km apart at 0.1 m cells would need 10^15 cells: the cells widen until the
    table holds at most MAX_CELLS, and a point between the centres reads none near it."""
    centres = np.array([[0.0, 0.0, 0.0], [10_000.0, 10_000.0, 10_000.0]])
    counts = CentreCounts.of(centres, 0.1)
    assert counts.sums.size <= MAX_CELLS * 1.1 and counts.side >= 0.1
    assert counts.sums[-1, -1, -1] == 2
    near = counts.any_within(np.array([[5_000.0, 5_000.0, 5_000.0], [1.0, 1.0, 1.0]]), 1.0)
    np.testing.assert_array_equal(near, [False, True])


def test_cells_must_be_wider_than_nothing():
    with pytest.raises(ValueError, match="wider than 0"):
        CentreCounts.of(np.zeros((3, 3)), 0.0)
