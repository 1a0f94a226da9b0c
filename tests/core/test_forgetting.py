"""Clusters forget the evidence taken back from the memory in the measure it stood behind them."""

import numpy as np

from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures
from ehm.core.weights.forgetting import forget, standing_shares


def test_the_standing_share_weighs_each_entry_by_its_kernel_value():
    # Entry 0 reaches clusters 0 (0.5) and 1 (1.0); entry 1 reaches cluster 1 (0.25).
    features = SparseFeatures(np.array([0, 2, 3]), np.array([0, 1, 1]), np.array([0.5, 1.0, 0.25]))
    before, after = np.array([4.0, 8.0]), np.array([1.0, 8.0])
    share = standing_shares(features, before, after, 3)
    # Cluster 0: 0.5 * 1 / (0.5 * 4); cluster 1: (1 + 2) / (4 + 2); cluster 2 unreached.
    np.testing.assert_allclose(share, [0.25, 0.5, 1.0])


def test_occupied_fine_clusters_forget_in_that_share():
    clusters = ClusterSet.empty(2)
    clusters.append(
        np.zeros((4, 2)),
        np.tile(np.eye(2), (4, 1, 1)),
        np.full(4, 10.0),
        coarse=np.array([False, False, True, False]),
        occupied=np.array([True, True, True, False]),
        precision=5.0,
    )
    clusters.weights[:] = [2.0, -1.0, 2.0, 2.0]
    clusters.grad_sq[:] = 8.0
    rows = forget(clusters, np.array([0.25, 0.5, 0.5, 0.5]), prior_precision=1.0)
    np.testing.assert_array_equal(rows, [0, 1])
    # A positive weight shrinks with its evidence; a negative one stays for SGD to move.
    np.testing.assert_allclose(clusters.weights, [0.5, -1.0, 2.0, 2.0])
    np.testing.assert_allclose(clusters.grad_sq, [2.0, 4.0, 8.0, 8.0])
    np.testing.assert_allclose(clusters.precision, [2.0, 3.0, 5.0, 5.0])
    np.testing.assert_allclose(clusters.counts, [2.5, 5.0, 10.0, 10.0])
