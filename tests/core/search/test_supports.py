"""The support hash: every kernel not zero at a point, exactly, as the map's clusters change."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.model.kernels import OUTSIDE, kernels_of_codes
from ehm.core.search.supports import (
    SupportHash,
    _candidate_counts,
    _scale_keys,
    _sub_cell_groups,
    _sub_cell_mask,
    copy_segments,
    copy_segments_reference,
    sub_cell_groups_reference,
    sub_cell_slabs,
    support_boxes,
    support_features_reference,
)


def _listed(clusters, sides=(0.3, 1.0)):
    table = SupportHash(clusters.dim, sides)
    table.update(
        np.arange(len(clusters)),
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        clusters.coarse,
    )
    return table


def _assert_same_features(got, want):
    indptr, rows, values = got.indptr, got.rows, got.values
    np.testing.assert_array_equal(indptr, want.indptr)
    # Rows come in the hash's order within each point: compare them sorted.
    for i in range(len(indptr) - 1):
        part = slice(indptr[i], indptr[i + 1])
        order = np.argsort(rows[part])
        np.testing.assert_array_equal(rows[part][order], want.rows[part])
        np.testing.assert_allclose(values[part][order], want.values[part], atol=1e-12)


def test_features_are_every_kernel_not_zero_at_each_point(rng, random_clusters):
    clusters = random_clusters(rng)
    points = rng.uniform(-0.5, 6.5, (3000, 3))
    table = _listed(clusters)
    want = support_features_reference(
        points, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    _assert_same_features(
        table.features(points, clusters.means, clusters.transforms, clusters.planar_kernel),
        want,
    )
    per_point = np.diff(want.indptr)
    assert per_point.max() >= 3 and np.mean(per_point == 0) < 0.9


def test_features_gathered_in_many_chunks_are_those_of_one(rng, random_clusters, monkeypatch):
    clusters = random_clusters(rng)
    crowd = rng.uniform(0, 6, (40, 3))[rng.integers(0, 40, 1500)] + rng.normal(0, 0.02, (1500, 3))
    points = np.vstack([rng.uniform(-0.5, 6.5, (1500, 3)), crowd])
    table = _listed(clusters)
    args = (clusters.means, clusters.transforms, clusters.planar_kernel)
    whole = table.features(points, *args)
    monkeypatch.setattr("ehm.core.search.supports._CHUNK_CANDIDATES", 97)
    chunked = table.features(points, *args)
    for got, want in zip(
        (chunked.indptr, chunked.rows, chunked.values),
        (whole.indptr, whole.rows, whole.values),
        strict=True,
    ):
        np.testing.assert_array_equal(got, want)
    _assert_same_features(chunked, support_features_reference(points, *args))
    empty = table.features(np.zeros((0, 3)), *args)
    assert len(empty) == 0 and len(empty.rows) == 0


def test_copy_segments_matches_its_reference(rng):
    counts = rng.integers(0, 6, 300)
    sources = rng.integers(0, 1000, 300)
    targets = np.cumsum(counts) - counts
    rows, codes = rng.integers(0, 50, 1010), rng.random(1010)
    got = (np.full(counts.sum(), -1), np.zeros(counts.sum()))
    want = (np.full(counts.sum(), -1), np.zeros(counts.sum()))
    copy_segments(rows, codes, sources, counts, targets, *got)
    copy_segments_reference(rows, codes, sources, counts, targets, *want)
    for compiled, reference in zip(got, want, strict=True):
        np.testing.assert_array_equal(compiled, reference)
    np.testing.assert_array_equal(got[0][targets[1] : targets[2]], rows[sources[1] :][: counts[1]])
    assert np.all(got[0] >= 0)


def test_2d_kernels_and_points_far_outside(rng):
    from ehm.config import MapConfig
    from ehm.core.model.clusters import ClusterSet

    n = 200
    clusters = ClusterSet.empty(2)
    spread = rng.normal(size=(n, 2, 2)) * rng.uniform(0.02, 0.3, (n, 1, 1))
    clusters.append(
        rng.uniform(-3, 3, (n, 2)),
        spread @ np.swapaxes(spread, 1, 2),
        np.full(n, 10),
        rng.random(n) < 0.3,
        rng.random(n) < 0.5,
    )
    clusters.refresh(np.arange(n), MapConfig(planar_kernel=True, planar_ratio=0.3))
    table = _listed(clusters, (0.2, 0.9))
    crowds = rng.uniform(-3, 3, (20, 2))[rng.integers(0, 20, 2000)] + rng.normal(0, 0.01, (2000, 2))
    points = np.vstack([rng.uniform(-4, 4, (2000, 2)), crowds, [[1e12, -1e12], [-5e5, 3.0]]])
    args = (clusters.means, clusters.transforms, clusters.planar_kernel)
    _assert_same_features(table.features(points, *args), support_features_reference(points, *args))


def test_decision_values_sum_every_kernel(rng, random_clusters):
    clusters = random_clusters(rng)
    table = _listed(clusters)
    points = rng.uniform(0, 6, (2000, 3))
    weights = rng.normal(size=len(clusters))
    inverse_precision = 1.0 / rng.uniform(1, 20, len(clusters))
    want = support_features_reference(
        points, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    indptr, rows, values = want.indptr, want.rows, want.values
    point = np.repeat(np.arange(len(points)), np.diff(indptr))
    want_scores = 0.25 + np.bincount(point, weights[rows] * values, len(points))
    want_squares = np.bincount(point, values**2 * inverse_precision[rows], len(points))
    want_sums = np.bincount(point, values, len(points))
    kernels = (clusters.means, clusters.transforms, clusters.planar_kernel)
    learned = (weights, 0.25, inverse_precision)
    scores, variance_sums = table.decision_values(points, *kernels, *learned, True)
    np.testing.assert_allclose(scores, want_scores, atol=1e-12)
    np.testing.assert_allclose(
        variance_sums, np.column_stack([want_squares, want_sums]), atol=1e-12
    )
    plain, none = table.decision_values(points, *kernels, *learned, False)
    np.testing.assert_array_equal(plain, scores)
    assert none.shape == (0, 2)


def test_updates_follow_moved_and_added_kernels(rng, random_clusters):
    """Kernels listed in small batches, then moved and grown, give the features of a hash
    built at once from the final kernels; the table and pool grow on the way."""
    clusters = random_clusters(rng, n=600)
    table = SupportHash(3, (0.3, 1.0))
    for start in range(0, 600, 37):
        rows = np.arange(start, min(start + 37, 600))
        table.update(
            rows, clusters.means[:600], clusters.transforms, clusters.planar_kernel, clusters.coarse
        )
    moved = rng.choice(600, 150, replace=False)
    clusters.means[moved] += rng.normal(scale=0.4, size=(150, 3))
    clusters.transforms[moved[:50]] *= 0.5  # supports twice as wide
    table.update(
        moved, clusters.means, clusters.transforms, clusters.planar_kernel, clusters.coarse
    )
    points = rng.uniform(-1, 7, (3000, 3))
    args = (clusters.means, clusters.transforms, clusters.planar_kernel)
    _assert_same_features(table.features(points, *args), support_features_reference(points, *args))


def test_support_boxes_hold_the_supports(rng, random_clusters):
    clusters = random_clusters(rng, n=50)
    low, high = support_boxes(clusters.means, clusters.transforms, clusters.planar_kernel)
    points = rng.uniform(-1, 7, (20000, 3))
    covering = support_features_reference(
        points, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    indptr, rows = covering.indptr, covering.rows
    point = np.repeat(np.arange(len(points)), np.diff(indptr))
    assert np.all(points[point] >= low[rows]) and np.all(points[point] <= high[rows])
    # Tight: the ball's box touches the ellipsoid along each axis.
    volume = np.prod(high - low, axis=1)
    assert np.all(volume > 0) and np.all(volume < 50.0)


def test_kernels_beyond_the_cells_of_the_hash_are_refused(random_clusters, rng):
    clusters = random_clusters(rng, n=5)
    clusters.means[2] = [1e6, 0.0, 0.0]
    with pytest.raises(ValueError, match="beyond the cells"):
        _listed(clusters)


def test_points_on_sub_cell_boundaries_find_every_kernel(rng, random_clusters):
    """Points on the faces and corners of sub-cells (sides 0.3 / 4 and 1.0 / 4 m), negative
    coordinates among them, find exactly the kernels the brute-force reference finds."""
    clusters = random_clusters(rng)
    clusters.means[:] -= 3.0
    clusters.refresh(np.arange(len(clusters)), MapConfig(planar_kernel=True, planar_ratio=0.3))
    table = _listed(clusters)
    steps = rng.integers(-48, 48, (4000, 3)).astype(np.float64)
    points = np.vstack([steps * 0.075, steps * 0.25, steps * 0.075 + [0.0, 1e-12, -1e-12]])
    args = (clusters.means, clusters.transforms, clusters.planar_kernel)
    _assert_same_features(table.features(points, *args), support_features_reference(points, *args))


def test_sub_cell_masks_leave_out_most_kernels_of_a_cell(rng, random_clusters):
    clusters = random_clusters(rng, n=2000)
    table = _listed(clusters)
    points = rng.uniform(0, 6, (3000, 3))
    arguments = table._arguments()
    keys = _scale_keys(points, arguments)
    listed = sum(_candidate_counts(keys[scale], arguments) for scale in (0, 1))
    every_sub_cell = np.full_like(arguments[4], ~np.uint64(0))
    unmasked = (*arguments[:4], every_sub_cell, *arguments[5:])
    in_cells = sum(_candidate_counts(keys[scale], unmasked) for scale in (0, 1))
    nonzero = np.diff(
        support_features_reference(
            points, clusters.means, clusters.transforms, clusters.planar_kernel
        ).indptr
    )
    assert np.all(listed >= nonzero) and np.all(listed <= in_cells)
    assert listed.sum() < 0.5 * in_cells.sum()


def test_points_are_grouped_by_sub_cells_cell_by_cell_as_the_reference_groups_them(rng):
    """Keys as _scale_keys makes them (0: no cell; 1 + slot * 64 + sub-cell), pairs of them
    repeated in any order: the groups are the distinct pairs, cell by cell, each group's rows
    in their own order."""
    n_slots = 50
    cells = rng.integers(0, n_slots + 1, (2, 400))
    sub_cells = rng.integers(0, 64, (2, 400))
    distinct = np.where(cells > 0, 1 + (cells - 1) * 64 + sub_cells, 0)
    keys = np.ascontiguousarray(distinct[:, rng.integers(0, 400, 6000)])
    starts, order = _sub_cell_groups(keys, n_slots)
    want_starts, want_order = sub_cell_groups_reference(keys, n_slots)
    np.testing.assert_array_equal(starts, want_starts)
    np.testing.assert_array_equal(order, want_order)
    pairs = keys[:, order[starts[:-1]]]
    assert len(np.unique(pairs, axis=1).T) == len(starts) - 1 > 300
    for g in range(len(starts) - 1):
        rows = order[starts[g] : starts[g + 1]]
        assert np.all(keys[:, rows] == pairs[:, g : g + 1]) and np.all(np.diff(rows) > 0)
    empty_starts, empty_order = _sub_cell_groups(np.zeros((2, 0), dtype=np.int64), n_slots)
    assert list(empty_starts) == [0] and len(empty_order) == 0


def test_points_sharing_sub_cells_get_their_own_kernels_in_any_order(rng, random_clusters):
    """Crowds of points in few sub-cells (which share one list of candidates) each get the
    features the reference finds, whatever order they are given in."""
    clusters = random_clusters(rng)
    table = _listed(clusters)
    centres = rng.uniform(0.0, 6.0, (40, 3))
    points = centres[rng.integers(0, 40, 5000)] + rng.normal(0.0, 0.05, (5000, 3))
    args = (clusters.means, clusters.transforms, clusters.planar_kernel)
    want = support_features_reference(points, *args)
    _assert_same_features(table.features(points, *args), want)
    order = rng.permutation(len(points))
    shuffled = table.features(points[order], *args)
    counts = np.diff(shuffled.indptr)
    np.testing.assert_array_equal(counts, np.diff(want.indptr)[order])


def test_kernel_codes_below_outside_have_a_value():
    """Features keep the kernels whose code is below OUTSIDE: the code just below it has a
    value, OUTSIDE and above have none."""
    values = np.array([np.nextafter(OUTSIDE, 0.0), OUTSIDE, np.nextafter(OUTSIDE, 2.0), -1.0])
    kernels_of_codes(values)
    assert values[0] > 0.0 and np.all(values[1:3] == 0.0) and values[3] == 1.0


@pytest.mark.parametrize("dim", [2, 3])
def test_sub_cell_masks_are_the_sub_cells_of_the_box_in_the_cell(rng, dim):
    """The mask of a kernel's box of sub-cells in one cell, from slabs, holds the bit
    (numbered as _cell_of numbers sub-cells) of every sub-cell of the cell inside the box."""
    divisions = 2 ** (6 // dim)
    slabs = sub_cell_slabs(dim, divisions)
    cell = rng.integers(-5, 5, (300, dim))
    sub_lo = cell * divisions + rng.integers(-6, divisions, (300, dim))
    sub_hi = sub_lo + rng.integers(0, 2 * divisions, (300, dim))
    keep = np.all((sub_hi >= cell * divisions) & (sub_lo < (cell + 1) * divisions), axis=1)
    local = np.stack(np.meshgrid(*[np.arange(divisions)] * dim, indexing="ij"), -1)
    local = local.reshape(-1, dim)
    bits = (local * divisions ** np.arange(dim)).sum(axis=1).astype(np.uint64)
    for m in np.flatnonzero(keep):
        inside = np.all(
            (cell[m] * divisions + local >= sub_lo[m]) & (cell[m] * divisions + local <= sub_hi[m]),
            axis=1,
        )
        want = np.bitwise_or.reduce(np.uint64(1) << bits[inside], initial=np.uint64(0))
        got = _sub_cell_mask(m, cell[m].astype(np.int64), sub_lo, sub_hi, divisions, slabs)
        assert got == want
