"""Clusters forget the evidence taken back from the memory in the measure it stood behind them."""

import numpy as np

from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures
from ehm.core.weights.forgetting import fade, fade_shares, forget, mark_seen, standing_shares


def clusters_of(coarse: list[bool], occupied: list[bool]) -> ClusterSet:
    """2D clusters at the origin, one per flag, each of 10 samples with posterior precision 5."""
    n = len(coarse)
    clusters = ClusterSet.empty(2)
    clusters.append(
        np.zeros((n, 2)),
        np.tile(np.eye(2), (n, 1, 1)),
        np.full(n, 10.0),
        coarse=np.array(coarse),
        occupied=np.array(occupied),
        precision=5.0,
    )
    return clusters


def test_the_standing_share_weighs_each_entry_by_its_kernel_value():
    # Entry 0 reaches clusters 0 (0.5) and 1 (1.0); entry 1 reaches cluster 1 (0.25).
    features = SparseFeatures(np.array([0, 2, 3]), np.array([0, 1, 1]), np.array([0.5, 1.0, 0.25]))
    before, after = np.array([4.0, 8.0]), np.array([1.0, 8.0])
    share = standing_shares(features, before, after, 3)
    # Cluster 0: 0.5 * 1 / (0.5 * 4); cluster 1: (1 + 2) / (4 + 2); cluster 2 unreached.
    np.testing.assert_allclose(share, [0.25, 0.5, 1.0])


def test_occupied_fine_clusters_forget_in_that_share():
    clusters = clusters_of(coarse=[False, False, True, False], occupied=[True, True, True, False])
    clusters.weights[:] = [2.0, -1.0, 2.0, 2.0]
    clusters.grad_sq[:] = 8.0
    rows = forget(clusters, np.array([0.25, 0.5, 0.5, 0.5]), prior_precision=1.0)
    np.testing.assert_array_equal(rows, [0, 1])
    # A positive weight shrinks with its evidence; a negative one stays for SGD to move.
    np.testing.assert_allclose(clusters.weights, [0.5, -1.0, 2.0, 2.0])
    np.testing.assert_allclose(clusters.grad_sq, [2.0, 4.0, 8.0, 8.0])
    np.testing.assert_allclose(clusters.precision, [2.0, 3.0, 5.0, 5.0])
    np.testing.assert_allclose(clusters.counts, [2.5, 5.0, 10.0, 10.0])


def test_unseen_evidence_stands_whole_for_forget_after_then_halves_every_quarter_of_it():
    seen = np.array([0.0, 0.0, 0.0, 9.0, np.nan])
    # From time 0 to 14 with forget_after 4: the first three unseen past 4 s for 10 s.
    shares = fade_shares(seen, before=0.0, now=14.0, forget_after=4.0)
    np.testing.assert_allclose(shares, [0.5**10, 0.5**10, 0.5**10, 0.5**1, 1.0])
    # Fading in steps composes to fading at once.
    steps = np.ones(len(seen))
    for before, now in [(0.0, 3.0), (3.0, 5.5), (5.5, 14.0)]:
        steps *= fade_shares(seen, before, now, 4.0)
    np.testing.assert_allclose(steps, shares)
    assert fade_shares(np.array([0.0]), 0.0, 4.0, 4.0)[0] == 1.0


def test_faded_clusters_drift_to_the_prior_free_and_occupied_alike():
    clusters = clusters_of(coarse=[False, True, False], occupied=[True, False, False])
    clusters.weights[:] = [2.0, -4.0, 1.0]
    clusters.grad_sq[:] = 8.0
    rows = fade(clusters, np.array([0.5, 0.25, 1.0]), prior_precision=1.0)
    np.testing.assert_array_equal(rows, [0, 1])
    np.testing.assert_allclose(clusters.weights, [1.0, -1.0, 1.0])
    np.testing.assert_allclose(clusters.grad_sq, [4.0, 2.0, 8.0])
    np.testing.assert_allclose(clusters.precision, [3.0, 2.0, 5.0])
    np.testing.assert_allclose(clusters.counts, [5.0, 2.5, 10.0])


def test_clusters_the_new_samples_reach_are_seen_now():
    clusters = clusters_of(coarse=[False] * 3, occupied=[True] * 3)
    assert np.isnan(clusters.seen).all()
    # Sample 0 (new) reaches clusters 0 and 2, sample 1 (replayed) cluster 1.
    features = SparseFeatures(np.array([0, 2, 3]), np.array([0, 2, 1]), np.ones(3))
    mark_seen(clusters, features, np.array([True, False]), 7.5)
    np.testing.assert_array_equal(clusters.seen, [7.5, np.nan, 7.5])
