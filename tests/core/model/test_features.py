"""Sparse features, one neighbour search per group of points (Alg. 2, 3)."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.model import features
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import (
    PointGroups,
    SparseFeatures,
    decision_values,
    decision_values_reference,
    features_of_codes_reference,
    group_by_cell,
    group_points_by_key,
    kernel_values,
    kernel_values_reference,
    training_features,
)
from ehm.core.model.kernels import INSIDE_BOX, OUTSIDE, kernel_transforms
from ehm.core.search.index import ClusterIndex


def _random_problem(rng, dim):
    n_clusters, n_points, n_groups, k = 40, 500, 30, 6
    means = rng.uniform(0, 2, (n_clusters, dim))
    a = rng.normal(size=(n_clusters, dim, dim)) * 0.2
    covariances = a @ np.swapaxes(a, 1, 2)
    planar = rng.random(n_clusters) < 0.5
    transforms = kernel_transforms(covariances, 3.0, 0.05, planar)
    points = rng.uniform(0, 2, (n_points, dim))
    group_of_point = rng.integers(0, n_groups, n_points)
    neighbours = rng.integers(0, n_clusters, (n_groups, k))
    neighbours[0, 3:] = -1  # fewer clusters than k
    return points, group_of_point, neighbours, means, transforms, planar


def test_kernel_values_match_reference(rng):
    for dim in (2, 3):
        problem = _random_problem(rng, dim)
        compiled = kernel_values(*problem)
        np.testing.assert_allclose(compiled, kernel_values_reference(*problem), atol=1e-12)
        assert np.count_nonzero(compiled) > 0.05 * compiled.size
        assert np.any(compiled == 1.0) and np.any((compiled > 0) & (compiled < 1))


def test_features_of_codes_match_reference(rng):
    n, k = 400, 7
    codes = rng.uniform(0.0, 1.0, (n, k))
    codes[rng.random((n, k)) < 0.3] = OUTSIDE
    codes[rng.random((n, k)) < 0.1] = INSIDE_BOX
    clusters = rng.integers(0, 50, (n, k))
    clusters[codes == OUTSIDE] = -1
    compiled = SparseFeatures.of_codes(clusters, codes)
    reference = features_of_codes_reference(clusters, codes)
    np.testing.assert_array_equal(compiled.indptr, reference.indptr)
    np.testing.assert_array_equal(compiled.rows, reference.rows)
    np.testing.assert_allclose(compiled.values, reference.values, rtol=1e-12, atol=1e-15)
    assert 0 < len(compiled.rows) < codes.size and np.all(compiled.values > 0)
    assert not np.isin(-1, compiled.rows) and np.any(compiled.values == 1.0)


@pytest.mark.parametrize("chunk", [65_536, 64])
def test_decision_values_match_reference(rng, monkeypatch, chunk):
    monkeypatch.setattr(features, "DECISION_CHUNK", chunk)  # one chunk, then eight
    problem = _random_problem(rng, 3)
    weights = rng.normal(size=len(problem[3]))
    inverse_precision = 1.0 / rng.uniform(1.0, 50.0, len(weights))
    for with_variance in (False, True):
        compiled = decision_values(*problem, weights, 0.3, inverse_precision, with_variance)
        reference = decision_values_reference(
            *problem, weights, 0.3, inverse_precision, with_variance
        )
        for got, want in zip(compiled, reference, strict=True):
            np.testing.assert_allclose(got, want, atol=1e-12)
    scores, squares = compiled
    assert squares.shape == (len(scores), 2)
    assert np.all(squares[:, 1] >= squares[:, 0]) and squares[:, 1].max() > 1.0


def test_searches_bounded_by_kernel_reach_give_the_same_features(rng):
    means = rng.uniform(-3, 3, (300, 3))
    covariances = np.array([np.diag(rng.uniform(0.01, 0.3, 3) ** 2) for _ in range(300)])
    clusters = ClusterSet.empty(3)
    clusters.append(means, covariances, np.full(300, 10), rng.random(300) < 0.3, np.ones(300))
    clusters.refresh(np.arange(300), MapConfig(planar_kernel=True))
    assert 0 < clusters.planar_kernel.sum() < 300
    points = rng.uniform(-3, 3, (2000, 3))
    groups = group_by_cell(points, 0.5)
    group_of_point, centres, spread = groups.group_of_point, groups.centres, groups.spread(points)
    args = (points, group_of_point)
    cluster_arrays = (
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        rng.normal(size=300),
        0.0,
        np.ones(300),
        True,
    )
    bounded = ClusterIndex.of(clusters).nearest(centres, 8, 2, spread)
    unbounded = ClusterIndex(clusters.means, clusters.coarse).nearest(centres, 8, 2)
    assert (bounded == -1).sum() > (unbounded == -1).sum()  # the bound did prune
    for got, want in zip(
        decision_values(*args, bounded, *cluster_arrays),
        decision_values(*args, unbounded, *cluster_arrays),
        strict=True,
    ):
        np.testing.assert_allclose(got, want, atol=1e-12)


def test_group_by_cell_groups_points_sharing_a_cell():
    points = np.array([[0.01, 0.01], [0.09, 0.02], [0.15, 0.01], [0.02, 0.19], [0.12, 0.05]])
    groups = group_by_cell(points, 0.1)
    group_of_point, centres = groups.group_of_point, groups.centres
    assert group_of_point[0] == group_of_point[1] != group_of_point[2] == group_of_point[4]
    assert len(centres) == 3
    np.testing.assert_allclose(centres[group_of_point[2]], [0.135, 0.03])
    assert groups.spread(points) == pytest.approx(np.hypot(0.04, 0.005))
    assert PointGroups.singletons(points).spread(points) == 0.0
    assert group_by_cell(np.zeros((0, 2)), 0.1).centres.shape == (0, 2)


def test_group_points_by_key_numbers_the_groups_in_the_order_of_their_keys():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 2.0], [3.0, 0.0]])
    groups = group_points_by_key(points, np.array([7, 3, 7, 3]))
    np.testing.assert_array_equal(groups.group_of_point, [1, 0, 1, 0])
    np.testing.assert_allclose(groups.centres, [[2.0, 0.0], [1.0, 1.0]])


@pytest.mark.parametrize("dim", [2, 3])
def test_the_spread_of_groups_agrees_with_its_numpy_twin(rng, dim):
    points = rng.uniform(-3.0, 3.0, (5000, dim))
    groups = group_by_cell(points, 0.4)
    assert groups.spread(points) == pytest.approx(groups.spread_reference(points), rel=1e-15)
    assert 0.0 < groups.spread(points) <= 0.4 * np.sqrt(dim)


def test_training_features_are_the_kernels_of_each_groups_neighbours(room_map, rng):
    clusters = room_map.clusters_
    index = ClusterIndex.of(clusters)
    points = rng.uniform([-4, -3, 0], [4, 3, 3], (3000, 3))
    groups = group_by_cell(points, 0.3)
    neighbours = index.group_neighbours(points, groups, 5, 2)
    features = training_features(points, groups, neighbours, clusters)
    assert neighbours.shape == (len(groups.centres), 7)
    # Each group's clusters: the nearest fine, then the nearest coarse ones of its centre, no
    # farther than a kernel reaches plus how far the group's points spread.
    spread = groups.spread(points)
    for scale, columns in ((False, slice(0, 5)), (True, slice(5, 7))):
        rows = np.flatnonzero(clusters.coarse == scale)
        bound = clusters.reach()[rows].max() + spread
        for g in range(0, len(groups.centres), 50):
            distance = np.linalg.norm(clusters.means[rows] - groups.centres[g], axis=1)
            nearest = rows[np.argsort(distance)[: columns.stop - columns.start]]
            nearest = nearest[
                np.linalg.norm(clusters.means[nearest] - groups.centres[g], axis=1) < bound
            ]
            found = neighbours[g, columns]
            np.testing.assert_array_equal(np.sort(found[found >= 0]), np.sort(nearest))
    expected = kernel_values_reference(
        points,
        groups.group_of_point,
        neighbours,
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
    )
    clusters_of_point = neighbours[groups.group_of_point]
    kept = (clusters_of_point >= 0) & (expected != 0.0)
    np.testing.assert_array_equal(np.diff(features.indptr), kept.sum(axis=1))
    np.testing.assert_array_equal(features.rows, clusters_of_point[kept])
    np.testing.assert_allclose(features.values, expected[kept], atol=1e-12)
    assert np.all(features.values != 0) and len(features.values) > 0.2 * expected.size


def test_point_groups_add_up_with_their_groups_renumbered():
    first = PointGroups(np.array([0, 1, 0]), np.array([[0.0, 0.0], [1.0, 1.0]]))
    second = PointGroups(np.array([0, 0]), np.array([[5.0, 5.0]]))
    both = first + second
    np.testing.assert_array_equal(both.group_of_point, [0, 1, 0, 2, 2])
    np.testing.assert_array_equal(both.centres, [[0, 0], [1, 1], [5, 5]])
