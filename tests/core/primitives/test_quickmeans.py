"""Quick-means (Alg. 1)."""

import numpy as np
import pytest

from ehm.core.primitives.quickmeans import kmeans_refine, quick_means, quick_means_reference


def _cloud(rng, n=3000, dim=3):
    centres = rng.uniform(0, 4, (12, dim))
    return centres[rng.integers(0, 12, n)] + rng.normal(0, 0.3, (n, dim))


@pytest.mark.parametrize("dim", [2, 3])
def test_compiled_quick_means_matches_reference(rng, dim):
    points = _cloud(rng, 1500, dim)
    result = quick_means(points, 0.2, 0.3, 4, np.random.default_rng(7))
    order = np.random.default_rng(7).permutation(len(points))
    reference = quick_means_reference(points, 0.2, 0.3, 4, order)
    np.testing.assert_array_equal(result.seeds, reference.seeds)
    np.testing.assert_array_equal(result.owner, reference.owner)
    np.testing.assert_array_equal(result.counts, reference.counts)
    np.testing.assert_allclose(result.means, reference.means, atol=1e-12)
    np.testing.assert_allclose(result.covariances, reference.covariances, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_compiled_weighted_quick_means_matches_reference(rng, dim):
    points = _cloud(rng, 1200, dim)
    weights = rng.uniform(0.2, 5.0, len(points))
    spread = rng.normal(0, 0.05, (len(points), dim, dim))
    scatter = np.einsum("nij,nkj->nik", spread, spread)
    result = quick_means(points, 0.2, 0.3, 6.0, np.random.default_rng(3), weights, scatter)
    order = np.random.default_rng(3).permutation(len(points))
    reference = quick_means_reference(points, 0.2, 0.3, 6.0, order, weights, scatter)
    np.testing.assert_array_equal(result.owner, reference.owner)
    np.testing.assert_allclose(result.counts, reference.counts, rtol=1e-12)
    np.testing.assert_array_equal(result.kept, reference.kept)
    np.testing.assert_allclose(result.means, reference.means, atol=1e-12)
    np.testing.assert_allclose(result.covariances, reference.covariances, atol=1e-12)


def test_points_standing_for_samples_cluster_as_the_samples_would(rng):
    """Two points, each the mean of a group of samples with their scatter, form the cluster
    the samples form: the same count, mean and covariance."""
    groups = [rng.normal(c, 0.02, (30, 3)) for c in ([0.0, 0.0, 0.0], [0.05, 0.0, 0.0])]
    samples = np.concatenate(groups)
    means = np.array([g.mean(axis=0) for g in groups])
    scatter = np.array([(g - g.mean(0)).T @ (g - g.mean(0)) for g in groups])
    pooled = quick_means(means, 0.5, 0.5, 4, rng, np.array([30.0, 30.0]), scatter)
    direct = quick_means(samples, 0.5, 0.5, 4, rng)
    assert len(pooled.means) == len(direct.means) == 1
    assert pooled.counts[0] == direct.counts[0] == 60
    np.testing.assert_allclose(pooled.means, direct.means, atol=1e-12)
    np.testing.assert_allclose(pooled.covariances, direct.covariances, atol=1e-12)


def test_every_point_lies_within_inner_radius_of_its_seed(rng):
    points = _cloud(rng)
    result = quick_means(points, 0.25, 0.4, 5, rng)
    distance = np.linalg.norm(points - points[result.seeds[result.owner]], axis=1)
    assert np.all(result.owner >= 0)
    assert np.all(distance < 0.25)


def test_no_kept_cluster_is_smaller_than_minimum(rng):
    points = _cloud(rng)
    result = quick_means(points, 0.25, 0.4, 7, rng)
    assert np.all(result.counts[result.kept] >= 7)
    assert np.any(~result.kept)  # the rule does drop something on this cloud


def test_fewer_clusters_as_radii_grow(rng):
    points = _cloud(rng)
    counts = [
        int(quick_means(points, r, 1.5 * r, 3, np.random.default_rng(1)).kept.sum())
        for r in (0.1, 0.2, 0.4, 0.8)
    ]
    assert counts == sorted(counts, reverse=True)
    assert counts[0] > 3 * counts[-1]


def test_statistics_match_members(rng):
    points = _cloud(rng, 800)
    result = quick_means(points, 0.3, 0.3, 1, rng)
    # With r_inner == r_outer, a cluster's members are exactly the points it owns.
    for s in range(0, len(result.seeds), 17):
        members = points[result.owner == s]
        np.testing.assert_allclose(result.means[s], members.mean(axis=0), atol=1e-12)
        if len(members) > 1:
            np.testing.assert_allclose(result.covariances[s], np.cov(members.T), atol=1e-12)


def test_kmeans_refinement_lowers_potential(rng):
    points = _cloud(rng)
    result = quick_means(points, 0.3, 0.45, 5, rng)
    kept = result.means[result.kept]

    def potential(centres):
        d = np.linalg.norm(points[:, None] - centres[None], axis=2)
        return np.sum(d.min(axis=1) ** 2)

    refined = kmeans_refine(points, result, 5)
    assert potential(refined.means) < potential(kept)
    assert np.all(refined.counts > 0)


def test_bad_radii_are_refused(rng):
    with pytest.raises(ValueError, match="r_inner <= r_outer"):
        quick_means(_cloud(rng, 10), 0.5, 0.2, 1, rng)
