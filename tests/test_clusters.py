import numpy as np
import pytest

from ehm.clusters import (
    ClusterSet,
    anisotropic_distances,
    match_new_clusters,
    merge_average,
    merge_pooled,
)
from ehm.config import MapConfig
from ehm.features import decision_values, group_by_cell, group_spread
from ehm.index import ClusterIndex


def _set_from(groups, coarse=None, occupied=None):
    clusters = ClusterSet.empty(3)
    clusters.append(
        np.array([g.mean(axis=0) for g in groups]),
        np.array([np.cov(g.T) for g in groups]),
        np.array([len(g) for g in groups]),
        np.zeros(len(groups), bool) if coarse is None else np.asarray(coarse),
        np.ones(len(groups), bool) if occupied is None else np.asarray(occupied),
    )
    clusters.refresh(np.arange(len(groups)), MapConfig())
    return clusters


def test_pooled_merge_equals_statistics_of_the_union(rng):
    old = [rng.normal(c, 0.2, (30, 3)) for c in ([0, 0, 0], [5, 0, 0])]
    new = [rng.normal(c, 0.3, (n, 3)) for c, n in (([0.1, 0, 0], 12), ([0.2, 0.1, 0], 20))]
    clusters = _set_from(old)
    merge_pooled(
        clusters,
        np.array([0, 0]),
        np.array([g.mean(axis=0) for g in new]),
        np.array([np.cov(g.T) for g in new]),
        np.array([len(g) for g in new]),
    )
    union = np.concatenate([old[0], *new])
    np.testing.assert_allclose(clusters.means[0], union.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(clusters.covariances[0], np.cov(union.T), atol=1e-12)
    assert clusters.counts[0] == len(union)
    np.testing.assert_allclose(clusters.means[1], old[1].mean(axis=0))


def test_average_merge_applies_the_papers_rule_in_order(rng):
    clusters = _set_from([rng.normal(0, 0.2, (10, 3)), rng.normal(3, 0.2, (10, 3))])
    mean0, cov0 = clusters.means[0].copy(), clusters.covariances[0].copy()
    means = rng.normal(size=(3, 3))
    covariances = np.array([np.eye(3) * s for s in (1.0, 2.0, 3.0)])
    merge_average(clusters, np.array([0, 1, 0]), means, covariances, np.array([5, 5, 5]))
    expected_mean = ((mean0 + means[0]) / 2 + means[2]) / 2
    expected_cov = ((cov0 + covariances[0]) / 2 + covariances[2]) / 2
    np.testing.assert_allclose(clusters.means[0], expected_mean)
    np.testing.assert_allclose(clusters.covariances[0], expected_cov)
    assert clusters.counts[0] == 20


def test_anisotropic_distance_is_eq14():
    # Sigma_a = Sigma_b = diag(1, 4, 9): (sqrt + sqrt)^2 = diag(4, 16, 36).
    roots = np.diag([1.0, 2.0, 3.0])[None]
    offset = np.array([[2.0, 4.0, 0.0]])
    distance = anisotropic_distances(offset, roots, np.zeros((1, 3)), roots)
    np.testing.assert_allclose(distance, [np.sqrt(4 / 4 + 16 / 16)])


def test_match_merges_only_within_one_standard_deviation(rng):
    clusters = _set_from([rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [2, 0, 0])])
    covariances = np.repeat(clusters.covariances[:1], 3, axis=0)
    means = np.array([[0.05, 0, 0], [1.0, 0, 0], [2.02, 0.01, 0]])
    coarse, occupied = np.zeros(3, bool), np.ones(3, bool)
    targets = match_new_clusters(
        clusters, clusters.index(), means, covariances, coarse, occupied, 1.0, 1e-3
    )
    np.testing.assert_array_equal(targets, [0, -1, 1])


def test_match_merges_only_clusters_of_the_same_scale(rng):
    clusters = _set_from(
        [rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [2, 0, 0])], coarse=[False, True]
    )
    covariances = np.repeat(clusters.covariances[:1], 4, axis=0)
    means = np.array([[0.05, 0, 0], [0.05, 0, 0], [2.02, 0, 0], [2.02, 0, 0]])
    coarse = np.array([False, True, False, True])
    targets = match_new_clusters(
        clusters, clusters.index(), means, covariances, coarse, np.ones(4, bool), 1.0, 1e-3
    )
    np.testing.assert_array_equal(targets, [0, -1, -1, 1])


def test_match_merges_only_clusters_of_the_same_label(rng):
    clusters = _set_from(
        [rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [0.1, 0, 0])], occupied=[True, False]
    )
    covariances = np.repeat(clusters.covariances[:1], 2, axis=0)
    means = np.array([[0.08, 0, 0], [0.02, 0, 0]])
    occupied = np.array([True, False])
    targets = match_new_clusters(
        clusters, clusters.index(), means, covariances, np.zeros(2, bool), occupied, 1.0, 1e-3
    )
    np.testing.assert_array_equal(targets, [0, 1])


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


def test_index_pads_missing_clusters_and_drops_an_absent_scale():
    centres = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    found = ClusterIndex(centres, np.array([False, False])).nearest(np.zeros((1, 3)), 3, 2)
    np.testing.assert_array_equal(found, [[0, 1, -1]])
    found = ClusterIndex(centres, np.array([False, True])).nearest(np.zeros((1, 3)), 2, 2)
    np.testing.assert_array_equal(found, [[0, -1, 1, -1]])


def test_searches_bounded_by_kernel_reach_give_the_same_features(rng):
    means = rng.uniform(-3, 3, (300, 3))
    covariances = np.array([np.diag(rng.uniform(0.01, 0.3, 3) ** 2) for _ in range(300)])
    clusters = ClusterSet.empty(3)
    clusters.append(means, covariances, np.full(300, 10), rng.random(300) < 0.3, np.ones(300))
    clusters.refresh(np.arange(300), MapConfig(planar_kernel=True))
    assert 0 < clusters.planar_kernel.sum() < 300
    points = rng.uniform(-3, 3, (2000, 3))
    group_of_point, centres = group_by_cell(points, 0.5)
    spread = group_spread(points, group_of_point, centres)
    args = (points, group_of_point)
    cluster_arrays = (
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        rng.normal(size=300),
        0.0,
    )
    bounded = clusters.index().nearest(centres, 8, 2, spread)
    unbounded = ClusterIndex(clusters.means, clusters.coarse).nearest(centres, 8, 2)
    assert (bounded == -1).sum() > (unbounded == -1).sum()  # the bound did prune
    np.testing.assert_allclose(
        decision_values(*args, bounded, *cluster_arrays),
        decision_values(*args, unbounded, *cluster_arrays),
        atol=1e-12,
    )


def test_group_by_cell_groups_points_sharing_a_cell():
    points = np.array([[0.01, 0.01], [0.09, 0.02], [0.15, 0.01], [0.02, 0.19], [0.12, 0.05]])
    group_of_point, centres = group_by_cell(points, 0.1)
    assert group_of_point[0] == group_of_point[1] != group_of_point[2] == group_of_point[4]
    assert len(centres) == 3
    np.testing.assert_allclose(centres[group_of_point[2]], [0.135, 0.03])
    assert group_spread(points, group_of_point, centres) == pytest.approx(np.hypot(0.04, 0.005))
