"""Stochastic gradient descent on the logistic loss (Eq. 2-3)."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.clusters import ClusterSet
from ehm.core.features import SparseFeatures
from ehm.core.sgd import (
    blocked_order,
    loss_weights,
    sgd_pass,
    sgd_pass_reference,
    train_weights,
    weighted_visits,
)


def test_sgd_pass_matches_reference(rng, sparse_batch):
    n, n_clusters = 400, 30
    indptr, rows, values, labels = sparse_batch(rng, n, 5, 20, n_clusters)
    order = rng.permutation(n)
    state = [rng.normal(size=n_clusters), rng.uniform(0, 1, n_clusters), np.array([0.1, 0.5])]
    compiled = [a.copy() for a in state]
    reference = [a.copy() for a in state]
    sample_weights = rng.uniform(0.5, 3.0, n)
    sgd_pass(indptr, rows, values, labels, sample_weights, order, *compiled, 0.3, 1e-3)
    sgd_pass_reference(indptr, rows, values, labels, sample_weights, order, *reference, 0.3, 1e-3)
    for got, want in zip(compiled, reference, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12)
    assert not np.allclose(compiled[0], state[0])


def test_sgd_separates_two_classes():
    # One feature per class: weights must move towards the labels.
    n = 2000
    labels = np.tile([1.0, 0.0], n // 2)
    weights, grad_sq, bias = np.zeros(2), np.zeros(2), np.zeros(2)
    sgd_pass(
        np.arange(n + 1),
        np.where(labels == 1.0, 0, 1),
        np.ones(n),
        labels,
        np.ones(n),
        np.arange(n),
        weights,
        grad_sq,
        bias,
        0.3,
        0.0,
    )
    assert weights[0] + bias[0] > 2.0
    assert weights[1] + bias[0] < -2.0


def test_balanced_classes_carry_half_of_the_loss_each():
    occupied = np.array([True, False, False, False])
    np.testing.assert_allclose(loss_weights(occupied, np.ones(4), True), [2, 2 / 3, 2 / 3, 2 / 3])
    weight = np.array([3.0, 1.0, 1.0, 2.0])  # thinned samples: each stands for several
    balanced = loss_weights(occupied, weight, True)
    assert balanced[0] == pytest.approx(balanced[1:].sum())  # equal totals
    assert balanced.sum() == pytest.approx(weight.sum())
    np.testing.assert_array_equal(loss_weights(occupied, weight, False), weight)
    np.testing.assert_array_equal(loss_weights(np.ones(3, bool), weight[:3], True), weight[:3])


def test_blocked_order_visits_every_sample_once_a_block_at_a_time():
    rng = np.random.default_rng(0)
    order = blocked_order(10_000, rng, block=256)
    np.testing.assert_array_equal(np.sort(order), np.arange(10_000))
    # The samples of each block of 256 (the last one 16) come one after the other, in random
    # order, and the blocks come in random order.
    block_of_visit = order // 256
    first_visit = []
    for block in range(40):
        visits = np.flatnonzero(block_of_visit == block)
        assert visits[-1] - visits[0] + 1 == len(visits) == (256 if block < 39 else 16)
        assert not np.array_equal(order[visits], np.sort(order[visits]))
        first_visit.append(visits[0])
    assert not np.array_equal(np.argsort(first_visit), np.arange(40))
    assert len(blocked_order(0, rng)) == 0


def test_heavy_samples_are_visited_as_often_as_they_weigh():
    sample_of_visit, per_visit = weighted_visits(np.array([1.0, 3.0, 0.4, 2.6]))
    np.testing.assert_array_equal(sample_of_visit, [0, 1, 1, 1, 2, 3, 3, 3])
    np.testing.assert_allclose(per_visit, [1.0, 1.0, 0.4, 2.6 / 3])
    sample_of_visit, per_visit = weighted_visits(np.array([1.0, 0.4, 1.2]))
    np.testing.assert_array_equal(sample_of_visit, [0, 1, 2])
    np.testing.assert_array_equal(per_visit, [1.0, 0.4, 1.2])


def test_a_sample_weighing_three_learns_as_three_copies():
    """Two samples weighing 3 and 2 train exactly as the five copies they stand for: the
    passes visit the same rows in the same random order."""

    def train(features, occupied, weights):
        clusters = ClusterSet.empty(2)
        clusters.append(
            np.zeros((2, 2)),
            np.tile(np.eye(2), (2, 1, 1)),
            np.ones(2),
            np.zeros(2, bool),
            np.array([True, False]),
        )
        bias_state = np.zeros(2)
        config = MapConfig(epochs=3)
        rng = np.random.default_rng(5)
        train_weights(features, occupied, weights, clusters, bias_state, config, rng)
        return clusters.weights, bias_state

    heavy = SparseFeatures(
        np.array([0, 2, 4]), np.array([0, 1, 0, 1]), np.array([0.9, 0.2, 0.1, 0.7])
    )
    copies = SparseFeatures(
        np.arange(0, 12, 2), np.tile([0, 1], 5), np.array([0.9, 0.2] * 3 + [0.1, 0.7] * 2)
    )
    got = train(heavy, np.array([True, False]), np.array([3.0, 2.0]))
    want = train(copies, np.array([True] * 3 + [False] * 2), np.ones(5))
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    assert got[0][0] > 0 > got[0][1]
