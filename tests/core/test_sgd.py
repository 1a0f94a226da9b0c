"""Stochastic gradient descent on the logistic loss (Eq. 2-3)."""

import numpy as np
import pytest

from ehm.core.weights.sgd import (
    blocked_order,
    loss_weights,
    sgd_pass,
    sgd_pass_reference,
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


@pytest.mark.parametrize("weight", [1.0, 4.0, 250.0])
def test_a_sample_standing_for_w_moves_a_fresh_weight_by_sqrt_w_steps(weight):
    """One sample of weight w: its squared gradient counts w times in the accumulator and its
    gradient w times in the step, so a fresh weight moves lr sqrt(w), as w single samples
    would to within a factor of 2."""
    weights, grad_sq, bias = np.zeros(1), np.zeros(1), np.zeros(2)
    sgd_pass(
        np.array([0, 1]),
        np.array([0]),
        np.array([0.8]),
        np.array([1.0]),
        np.array([weight]),
        np.array([0]),
        weights,
        grad_sq,
        bias,
        0.3,
        0.0,
    )
    gradient = 0.5 * 0.8  # (sigmoid(0) - 1) * phi, negated
    assert grad_sq[0] == pytest.approx(weight * gradient**2)
    assert weights[0] == pytest.approx(0.3 * np.sqrt(weight), rel=1e-6)
    assert bias[0] == pytest.approx(0.3 * np.sqrt(weight), rel=1e-6)
    assert bias[1] == pytest.approx(weight * 0.25)
