"""How new clusters join the map (Alg. 2 lines 4-21)."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.clustering.grouping import NewClusters
from ehm.core.clustering.merging import (
    absorb_clusters,
    anisotropic_distances,
    anisotropic_distances_reference,
    match_new_clusters,
    merge_average,
    merge_pooled,
)
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.kernels import covariance_square_roots
from ehm.core.primitives.eigen import symmetric_eigen
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.kernel_search import kernel_search


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


def _new(means, covariances, coarse, occupied):
    return NewClusters(means, covariances, np.full(len(means), 10), coarse, occupied)


def _candidates(clusters, new, search):
    """Merge candidates of `new` among `clusters`: the nearest centres, or the clusters whose
    kernels cover each new mean."""
    found = kernel_search(MapConfig(features=search), 3)
    found.relist(clusters, AnchorLayers(), None)
    return found.merge_candidates(new.means, new.coarse, clusters)


def _match(clusters, new, search):
    candidates = _candidates(clusters, new, search)
    return match_new_clusters(
        clusters, candidates, new, symmetric_eigen(new.covariances), MapConfig()
    )


SEARCHES = pytest.mark.parametrize("search", ["nearest", "support"])


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
    rows = np.zeros(1, dtype=np.int64)
    distance = anisotropic_distances(offset, roots, rows, np.zeros((1, 3)), roots, rows)
    np.testing.assert_allclose(distance, [np.sqrt(4 / 4 + 16 / 16)])


@pytest.mark.parametrize("dim", [2, 3])
def test_anisotropic_distances_agree_with_their_numpy_twin(rng, dim):
    def side(n):
        a = rng.normal(size=(n, dim, dim)) * 0.3
        roots = covariance_square_roots(a @ np.swapaxes(a, 1, 2), 0.01)
        return rng.uniform(-1.0, 1.0, (n, dim)), roots

    means_a, roots_a = side(30)
    means_b, roots_b = side(40)
    rows_a, rows_b = rng.integers(0, 30, 500), rng.integers(0, 40, 500)
    pairs = (means_a, roots_a, rows_a, means_b, roots_b, rows_b)
    distances = anisotropic_distances(*pairs)
    np.testing.assert_allclose(distances, anisotropic_distances_reference(*pairs), rtol=1e-10)
    assert distances.min() < 1.0 < distances.max()


@SEARCHES
def test_match_merges_only_within_one_standard_deviation(rng, search):
    clusters = _set_from([rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [2, 0, 0])])
    covariances = np.repeat(clusters.covariances[:1], 3, axis=0)
    means = np.array([[0.05, 0, 0], [1.0, 0, 0], [2.02, 0.01, 0]])
    coarse, occupied = np.zeros(3, bool), np.ones(3, bool)
    new = _new(means, covariances, coarse, occupied)
    targets = _match(clusters, new, search)
    np.testing.assert_array_equal(targets, [0, -1, 1])


@SEARCHES
def test_match_merges_only_clusters_of_the_same_scale(rng, search):
    clusters = _set_from(
        [rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [2, 0, 0])], coarse=[False, True]
    )
    covariances = np.repeat(clusters.covariances[:1], 4, axis=0)
    means = np.array([[0.05, 0, 0], [0.05, 0, 0], [2.02, 0, 0], [2.02, 0, 0]])
    new = _new(means, covariances, np.array([False, True, False, True]), np.ones(4, bool))
    targets = _match(clusters, new, search)
    np.testing.assert_array_equal(targets, [0, -1, -1, 1])


@SEARCHES
def test_match_merges_only_clusters_of_the_same_label(rng, search):
    clusters = _set_from(
        [rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [0.1, 0, 0])], occupied=[True, False]
    )
    covariances = np.repeat(clusters.covariances[:1], 2, axis=0)
    means = np.array([[0.08, 0, 0], [0.02, 0, 0]])
    new = _new(means, covariances, np.zeros(2, bool), np.array([True, False]))
    targets = _match(clusters, new, search)
    np.testing.assert_array_equal(targets, [0, 1])


@SEARCHES
def test_absorb_merges_close_clusters_and_adds_the_others(rng, search):
    clusters = _set_from([rng.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [2, 0, 0])])
    weights = np.array([1.5, -2.0])
    clusters.weights[:] = weights
    covariances = np.repeat(clusters.covariances[:1], 4, axis=0)
    means = np.array([[0.05, 0, 0], [1.0, 0, 0], [5.0, 0, 0], [8.0, 0, 0]])
    coarse = np.array([False, False, False, True])
    new = _new(means, covariances, coarse, np.array([True, True, False, False]))
    config = MapConfig(initial_weight=2.5)
    absorbed = absorb_clusters(clusters, _candidates(clusters, new, search), new, config)
    assert (absorbed.n_new, absorbed.n_merged) == (3, 1)
    np.testing.assert_array_equal(absorbed.changed, [0, 2, 3, 4])
    assert len(clusters) == 5 and clusters.counts[0] == 50 + 10
    # Merged clusters keep their weights; new fine ones start at their label's initial
    # weight (occupied +, free -), coarse ones at 0, with their kernels ready.
    np.testing.assert_array_equal(clusters.weights, [*weights, 2.5, -2.5, 0.0])
    np.testing.assert_allclose(clusters.means[2:], means[1:])
    assert np.all(np.abs(clusters.transforms[2:]).sum(axis=(1, 2)) > 0)
