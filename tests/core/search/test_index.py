"""Neighbour search over cluster centres: kd-trees per scale, anisotropic ranking (Sec. 3.1)."""

import numpy as np

from ehm.core.search.index import (
    ClusterIndex,
    KernelRanking,
    kernel_radii,
    kernel_radii_reference,
    tree_rows_into,
    tree_rows_reference,
)


def test_index_returns_nearest_fine_then_nearest_coarse_clusters(rng):
    centres = rng.uniform(-5, 5, (200, 3))
    coarse = rng.random(200) < 0.3
    points = rng.uniform(-5, 5, (50, 3))
    found = ClusterIndex(centres, coarse).nearest(points, 5, 2)
    assert found.shape == (50, 7)
    for point, row in zip(points, found, strict=True):
        distance = np.linalg.norm(centres - point, axis=1)
        for scale, columns in ((False, row[:5]), (True, row[5:])):
            rows = np.flatnonzero(coarse == scale)
            expected = rows[np.argsort(distance[rows])[: len(columns)]]
            np.testing.assert_array_equal(np.sort(columns), np.sort(expected))


def test_bounded_searches_find_every_centre_within_reach_and_none_beyond(rng):
    """Centres in two clumps of a 20 m box, kernels reaching 0.3-0.6 m: points all over the
    box, most far from every centre (those are not searched), and points among the centres
    (all searched) find the nearest centres of each scale within the largest reach plus the
    spread, as brute force does."""
    centres = np.concatenate([rng.normal(3.0, 0.5, (150, 3)), rng.normal(15.0, 1.0, (150, 3))])
    coarse = rng.random(300) < 0.3
    reach = rng.uniform(0.3, 0.6, 300)
    index = ClusterIndex(centres, coarse, reach)
    spread = 0.1
    scattered = rng.uniform(0.0, 20.0, (2000, 3))
    among = centres[rng.integers(0, 300, 2000)] + rng.normal(0.0, 0.05, (2000, 3))
    for points, far_share in ((scattered, (0.5, 1.0)), (among, (0.0, 0.01))):
        found = index.nearest(points, 4, 2, spread)
        for scale, columns in ((False, found[:, :4]), (True, found[:, 4:])):
            rows = np.flatnonzero(coarse == scale)
            bound = reach[rows].max() + spread
            distance = np.linalg.norm(points[:, None] - centres[rows][None], axis=2)
            order = np.argsort(distance, axis=1)[:, : columns.shape[1]]
            within = np.take_along_axis(distance, order, axis=1) <= bound
            np.testing.assert_array_equal(columns, np.where(within, rows[order], -1))
        assert far_share[0] <= np.mean(np.all(found == -1, axis=1)) < far_share[1]


def test_index_pads_missing_clusters_and_drops_an_absent_scale():
    centres = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    found = ClusterIndex(centres, np.array([False, False])).nearest(np.zeros((1, 3)), 3, 2)
    np.testing.assert_array_equal(found, [[0, 1, -1]])
    found = ClusterIndex(centres, np.array([False, True])).nearest(np.zeros((1, 3)), 2, 2)
    np.testing.assert_array_equal(found, [[0, -1, 1, -1]])


def test_tree_rows_match_reference(rng):
    rows = rng.permutation(50)[:20]
    tree_index = rng.integers(0, 21, (300, 6))  # 20: the tree found none
    for k in (6, 9):
        found = np.empty((300, k), dtype=np.int64)
        tree_rows_into(found, tree_index, rows)
        np.testing.assert_array_equal(found, tree_rows_reference(tree_index, rows, k))
        assert np.all(found[:, 6:] == -1)
        assert np.all((found[:, :6] == -1) == (tree_index == 20))
    columns = np.empty((300, 10), dtype=np.int64)  # written into a view of some columns
    tree_rows_into(columns[:, 2:8], tree_index, rows)
    np.testing.assert_array_equal(columns[:, 2:8], tree_rows_reference(tree_index, rows, 6))


def test_kernel_radii_match_reference(rng, random_clusters):
    clusters = random_clusters(rng)
    assert 0 < clusters.planar_kernel.sum() < len(clusters)
    points = rng.uniform(0, 6, (300, 3))
    candidates = rng.integers(-1, len(clusters), (300, 12))
    args = (points, candidates, clusters.means, clusters.transforms, clusters.planar_kernel)
    compiled, reference = kernel_radii(*args), kernel_radii_reference(*args)
    np.testing.assert_allclose(compiled, reference, rtol=1e-12)
    assert np.all(np.isinf(compiled[candidates < 0]))


def test_anisotropic_search_ranks_by_kernel_radius(rng, random_clusters):
    clusters = random_clusters(rng)
    ranking = KernelRanking(clusters.means, clusters.transforms, clusters.planar_kernel, 3)
    index = ClusterIndex(clusters.means, clusters.coarse, None, ranking)
    points = rng.uniform(0, 6, (200, 3))
    found = index.nearest_of_scale(points, False, 5)
    candidates = ClusterIndex(clusters.means, clusters.coarse).nearest_of_scale(points, False, 15)
    radii = kernel_radii_reference(
        points, candidates, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    expected = np.take_along_axis(candidates, np.argsort(radii, axis=1, kind="stable")[:, :5], 1)
    np.testing.assert_array_equal(found, expected)
    radii_found = kernel_radii_reference(
        points, found, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    assert np.all(np.diff(radii_found, axis=1) >= 0)
