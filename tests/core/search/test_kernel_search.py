"""One interface over the two kernel searches: where the nearest clusters are all the
clusters that reach a point, both searches read the same model."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.model.features import decision_values_reference
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.kernel_search import (
    NearestSearch,
    SupportSearch,
    kernel_search,
    query_groups,
)
from ehm.core.search.supports import support_features_reference

# Enough neighbours that the nearest search finds every cluster whose kernel reaches a point.
EVERY = {"neighbours": 400, "coarse_neighbours": 400}


def _searches(clusters, **settings):
    found = []
    for features in ("support", "nearest"):
        search = kernel_search(MapConfig(features=features, **settings), clusters.dim)
        search.relist(clusters, AnchorLayers(), None)
        found.append(search)
    return found


def _sorted_rows(features):
    return [
        sorted(features.rows[a:b].tolist())
        for a, b in zip(features.indptr[:-1], features.indptr[1:], strict=True)
    ]


def test_each_setting_gives_its_search(random_clusters, rng):
    support, nearest = _searches(random_clusters(rng, n=50))
    assert isinstance(support, SupportSearch) and not support.truncated
    assert isinstance(nearest, NearestSearch) and nearest.truncated
    assert nearest.shares_searches and not support.shares_searches
    point_searches = kernel_search(MapConfig(train_search="point"), 3)
    assert not point_searches.shares_searches
    assert support.nbytes > 0 and nearest.nbytes > 0


def test_with_every_neighbour_both_searches_find_every_kernel_at_a_point(random_clusters, rng):
    clusters = random_clusters(rng)
    points = rng.uniform(-0.5, 6.5, (2000, 3))
    want = support_features_reference(
        points, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    every = _sorted_rows(want)
    for search in _searches(clusters, **EVERY):
        found = search.features(points, clusters)
        assert _sorted_rows(found) == every
        # Queries read the clusters found, kernels 0 at the point among them.
        indptr, rows = search.rows(points, clusters, "exact")
        read = _sorted_rows(type(found)(indptr, rows, np.ones(len(rows))))
        assert all(set(a) <= set(b) for a, b in zip(every, read, strict=True))
        assert (read == every) == (not search.truncated)


@pytest.mark.parametrize("mode", ["batch", "exact"])
def test_both_searches_sum_the_same_log_odds_and_variance(random_clusters, rng, mode):
    clusters = random_clusters(rng)
    clusters.weights[:] = rng.normal(size=len(clusters))
    clusters.precision[:] = rng.uniform(1.0, 5.0, len(clusters))
    points = rng.uniform(-0.5, 6.5, (2000, 3))
    want = support_features_reference(
        points, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    point_of_entry = np.repeat(np.arange(len(points)), np.diff(want.indptr))
    scores = 0.3 + np.bincount(
        point_of_entry, want.values * clusters.weights[want.rows], len(points)
    )
    squares = np.bincount(
        point_of_entry, want.values**2 / clusters.precision[want.rows], len(points)
    )
    for search in _searches(clusters, **EVERY):
        found = search.sums(points, clusters, 0.3, True, mode, 0.5)
        np.testing.assert_allclose(found.scores, scores, atol=1e-9)
        np.testing.assert_allclose(found.variance_sums[:, 0], squares, atol=1e-9)
        plain = search.sums(points, clusters, 0.3, False, mode, 0.5)
        np.testing.assert_array_equal(plain.scores, found.scores)
        assert plain.variance_sums.shape == (0, 2)


def test_nearest_sums_in_batch_mode_read_each_groups_neighbours(random_clusters, rng):
    clusters = random_clusters(rng)
    clusters.weights[:] = rng.normal(size=len(clusters))
    clusters.precision[:] = rng.uniform(1.0, 5.0, len(clusters))
    points = rng.uniform(-0.5, 6.5, (3000, 3))
    _, nearest = _searches(clusters)  # truncated: groups differ in what they read
    groups = query_groups(points, "batch", 0.5)
    want = decision_values_reference(
        points,
        groups.group_of_point,
        nearest._group_neighbours(points, groups),
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        clusters.weights,
        0.3,
        1.0 / clusters.precision,
        True,
    )
    found = nearest.sums(points, clusters, 0.3, True, "batch", 0.5)
    np.testing.assert_allclose(found.scores, want[0], atol=1e-12)
    np.testing.assert_allclose(found.variance_sums, want[1], atol=1e-12)


def test_reading_near_places_reads_each_point_as_alone(random_clusters, rng):
    clusters = random_clusters(rng)
    clusters.weights[:] = rng.normal(size=len(clusters))
    places = rng.uniform(0.5, 5.5, (100, 3))
    rows = rng.integers(0, 100, 1000)
    points = places[rows] + rng.uniform(-0.05, 0.05, (1000, 3))
    for search in _searches(clusters, **EVERY):
        read = search.near_reader(places, 0.1, clusters, -0.2)
        np.testing.assert_allclose(
            read(points, rows), search.log_odds(points, clusters, -0.2), atol=1e-12
        )


def test_merge_candidates_are_covering_kernels_or_nearest_centres(random_clusters, rng):
    clusters = random_clusters(rng)
    means = rng.uniform(0.0, 6.0, (300, 3))
    coarse = rng.random(300) < 0.2
    support, nearest = _searches(clusters)
    covering = support.merge_candidates(means, coarse, clusters)
    want = support_features_reference(
        means, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    pairs = sorted(zip(covering.pair_new.tolist(), covering.pair_old.tolist(), strict=True))
    expected = [(i, int(j)) for i, found in enumerate(_sorted_rows(want)) for j in found]
    assert pairs == expected
    near = nearest.merge_candidates(means, coarse, clusters)
    assert np.all(clusters.coarse[near.pair_old] == coarse[near.pair_new])
    assert np.all(np.bincount(near.pair_new, minlength=300) <= 4)
    for i in range(0, 300, 37):  # each new cluster's candidates are the nearest of its scale
        same = np.flatnonzero(clusters.coarse == coarse[i])
        distance = np.linalg.norm(clusters.means[same] - means[i], axis=1)
        chosen = near.pair_old[near.pair_new == i]
        assert len(chosen) == 0 or set(chosen) <= set(same[np.argsort(distance)[:4]].tolist())


def test_query_groups_share_cells_in_batch_mode_and_not_in_exact(rng):
    points = rng.uniform(0.0, 1.0, (500, 3))
    batch = query_groups(points, "batch", 0.25)
    assert len(batch.centres) <= 64
    cells = np.floor((points - points.min(axis=0)) / 0.25).astype(int)  # from the low corner
    for group in range(len(batch.centres)):
        assert len(np.unique(cells[batch.group_of_point == group], axis=0)) == 1
    exact = query_groups(points, "exact", 0.25)
    np.testing.assert_array_equal(exact.group_of_point, np.arange(500))
