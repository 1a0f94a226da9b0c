"""Stochastic gradient descent on the logistic loss (Eq. 2-3)."""

from types import SimpleNamespace

import numba
import numpy as np
import pytest
from numpy.random import default_rng

from ehm.config import MapConfig
from ehm.core.model.features import SparseFeatures
from ehm.core.weights.sgd import (
    BORDER,
    MAX_STEP,
    TWO_SIDED_MIN_SAMPLES,
    blocked_order,
    loss_weights,
    relabel,
    relabel_reference,
    sample_sides,
    sample_sides_reference,
    sgd_rounds,
    sgd_rounds_reference,
    space_sides,
    train_weights,
    visiting_plan,
    visiting_plan_reference,
)


def sgd_pass(indptr, rows, values, labels, sample_weights, order, weights, grad_sq, *rest):
    """One pass over the samples in `order`, one after the other (every sample on the
    border), no weight held under a ceiling."""
    visits, starts = visiting_plan(order, np.full(len(labels), BORDER))
    ceilings = np.full(len(weights), np.inf)
    arguments = (indptr, rows, values, labels, sample_weights, visits, starts)
    sgd_rounds(*arguments, weights, grad_sq, ceilings, *rest)


def _two_sided_batch(rng, sparse_batch, n=2000, n_clusters=60):
    """A batch whose samples' sides follow random sides of its clusters."""
    indptr, rows, values, labels = sparse_batch(rng, n, 5, 80, n_clusters)
    cluster_side = rng.integers(0, 2, n_clusters)
    sides = sample_sides(indptr, rows, cluster_side)
    return indptr, rows, values, labels, sides


def test_sgd_rounds_match_reference(rng, sparse_batch, monkeypatch):
    indptr, rows, values, labels, sides = _two_sided_batch(rng, sparse_batch)
    assert set(np.unique(sides)) == {0, 1, BORDER}
    n, n_clusters = len(labels), 60
    visits, starts = visiting_plan(rng.permutation(n), sides, 256)
    # A third of the weights held at or below 0 (coarse clusters, weight_ceilings).
    ceilings = np.where(np.arange(n_clusters) % 3 == 0, 0.0, np.inf)
    weights = np.minimum(rng.normal(size=n_clusters), ceilings)
    state = [weights, rng.uniform(0, 1, n_clusters), ceilings, np.array([0.1, 0.5])]
    compiled = [a.copy() for a in state]
    reference = [a.copy() for a in state]
    sample_weights = rng.uniform(0.5, 3.0, n)
    sample_weights[::50] = 400.0  # cells of many samples: their first steps reach MAX_STEP
    arguments = (indptr, rows, values, labels, sample_weights, visits, starts)
    sgd_rounds(*arguments, *compiled, 1.0, 1e-3)
    sgd_rounds_reference(*arguments, *reference, 1.0, 1e-3)
    for got, want in zip(compiled, reference, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12)
    assert not np.allclose(compiled[0], state[0])
    held = ceilings == 0.0
    assert np.all(compiled[0][held] <= 0.0) and np.any(compiled[0][held] == 0.0)
    assert np.any(compiled[0][~held] > 0.0)
    # The heavy samples' steps were held: unheld, the twin's weights come out otherwise.
    unheld = [a.copy() for a in state]
    monkeypatch.setattr("ehm.core.weights.sgd.MAX_STEP", np.inf)
    sgd_rounds_reference(*arguments, *unheld, 1.0, 1e-3)
    assert not np.allclose(unheld[0], reference[0])


def test_sgd_rounds_do_not_depend_on_the_threads(rng, sparse_batch):
    indptr, rows, values, labels, sides = _two_sided_batch(rng, sparse_batch)
    visits, starts = visiting_plan(rng.permutation(len(labels)), sides, 256)
    runs = []
    for threads in (1, 2):
        state = [np.zeros(60), np.zeros(60), np.full(60, np.inf), np.zeros(2)]
        numba.set_num_threads(threads)
        try:
            sgd_rounds(
                indptr, rows, values, labels, np.ones(len(labels)), visits, starts, *state, 0.3, 0.0
            )
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        runs.append(state)
    for got, want in zip(*runs, strict=True):
        np.testing.assert_array_equal(got, want)


def test_sample_sides_and_the_visiting_plan_match_their_references(rng, sparse_batch):
    indptr, rows, _, _ = sparse_batch(rng, 3000, 6, 200, 90)
    cluster_side = rng.integers(0, 2, 90)
    sides = sample_sides(indptr, rows, cluster_side)
    np.testing.assert_array_equal(sides, sample_sides_reference(indptr, rows, cluster_side))
    order = rng.permutation(len(sides))
    for got, want in zip(
        visiting_plan(order, sides, 512), visiting_plan_reference(order, sides, 512), strict=True
    ):
        np.testing.assert_array_equal(got, want)


def test_space_sides_split_the_features_at_a_plane_and_never_share_a_cluster(rng):
    """Clusters on a line from x = 0 to 9, each sample reaching the clusters within 1 m of
    it: samples reach one side's clusters only, or they are on the border, near x = 4.5."""
    means = np.column_stack([np.arange(10.0), rng.uniform(0, 0.1, 10), np.zeros(10)])
    x = rng.uniform(0, 9, 5000)
    reached = [np.flatnonzero(np.abs(means[:, 0] - xi) <= 1.0) for xi in x]
    features = SparseFeatures(
        np.r_[0, np.cumsum([len(r) for r in reached])],
        np.concatenate(reached),
        np.ones(sum(len(r) for r in reached)),
    )
    sides, cluster_side = space_sides(features, means)
    np.testing.assert_array_equal(cluster_side, means[:, 0] > 4.5)
    assert np.all(np.abs(x[sides == BORDER] - 4.5) <= 1.5)
    for side in (0, 1):
        touched = np.concatenate([reached[i] for i in np.flatnonzero(sides == side)])
        assert len(np.unique(means[touched, 0] > 4.5)) == 1
    assert 0.3 < np.mean(sides == 0) < 0.5 and 0.3 < np.mean(sides == 1) < 0.5
    empty = SparseFeatures(np.zeros(4, dtype=np.int64), np.zeros(0, np.int64), np.zeros(0))
    np.testing.assert_array_equal(space_sides(empty, means)[0], [BORDER] * 3)


def test_training_with_each_sides_clusters_stored_together_gives_the_same_weights(rng):
    """Clusters on a line, stored in random order, each sample reaching five neighbouring
    ones: train_weights, which stores each side's clusters together while they learn, ends
    with the weights of the same passes over the clusters where they lie."""
    n, n_clusters = TWO_SIDED_MIN_SAMPLES + 5000, 60
    place = rng.permutation(n_clusters)  # cluster i lies at x = place[i]
    means = np.column_stack([place.astype(float), np.zeros((n_clusters, 2))])
    first = rng.integers(0, n_clusters - 5, n)
    rows = np.argsort(place)[(first[:, None] + np.arange(5)).ravel()]
    features = SparseFeatures(np.arange(0, 5 * n + 1, 5), rows, rng.uniform(0.1, 1.0, 5 * n))
    given_rows = rows.copy()
    occupied = rng.random(n) < 0.4
    sample_weights = rng.uniform(0.5, 2.0, n)
    config = MapConfig(epochs=2)
    coarse = rng.random(n_clusters) < 0.3
    ceilings = np.where(coarse, 0.0, np.inf)
    start = (np.minimum(rng.normal(size=n_clusters), ceilings), rng.uniform(0.1, 1.0, n_clusters))
    clusters = SimpleNamespace(
        means=means, weights=start[0].copy(), grad_sq=start[1].copy(), coarse=coarse
    )
    bias = np.array([0.1, 0.5])
    train_weights(features, occupied, sample_weights, clusters, bias, config, default_rng(7))
    sides, _ = space_sides(features, means)
    assert np.mean(sides != BORDER) > 0.8
    weights, grad_sq, want_bias = start[0].copy(), start[1].copy(), np.array([0.1, 0.5])
    order_rng = default_rng(7)
    for _ in range(2):
        visits, starts = visiting_plan(blocked_order(n, order_rng), sides)
        sgd_rounds(
            features.indptr,
            features.rows,
            features.values,
            occupied.astype(float),
            sample_weights,
            visits,
            starts,
            weights,
            grad_sq,
            ceilings,
            want_bias,
            config.learning_rate,
            config.l2,
        )
    np.testing.assert_array_equal(clusters.weights, weights)
    np.testing.assert_array_equal(clusters.grad_sq, grad_sq)
    np.testing.assert_array_equal(bias, want_bias)
    assert not np.allclose(weights, start[0])
    # The rows were relabelled while they learned, and are the given ones again.
    np.testing.assert_array_equal(features.rows, given_rows)


def test_relabel_matches_its_reference(rng):
    rows = rng.integers(0, 500, 10_000)
    labels = rng.permutation(500)
    compiled, reference = rows.copy(), rows.copy()
    relabel(compiled, labels)
    relabel_reference(reference, labels)
    np.testing.assert_array_equal(compiled, reference)
    np.testing.assert_array_equal(compiled, labels[rows])


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
    # The samples of each block of 256 (the last one 16) come one after the other, in the
    # order they are stored, and the blocks come in random order.
    block_of_visit = order // 256
    first_visit = []
    for block in range(40):
        visits = np.flatnonzero(block_of_visit == block)
        assert visits[-1] - visits[0] + 1 == len(visits) == (256 if block < 39 else 16)
        np.testing.assert_array_equal(
            order[visits], np.arange(256 * block, 256 * block + len(visits))
        )
        first_visit.append(visits[0])
    assert not np.array_equal(np.argsort(first_visit), np.arange(40))
    assert len(blocked_order(0, rng)) == 0


@pytest.mark.parametrize("weight", [1.0, 4.0, 250.0])
def test_a_sample_standing_for_w_moves_a_fresh_weight_by_sqrt_w_steps(weight):
    """One sample of weight w: its squared gradient counts w times in the accumulator and its
    gradient w times in the step, so a fresh weight moves lr sqrt(w), as w single samples
    would to within a factor of 2, but never more than MAX_STEP (the bias is not held)."""
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
    assert weights[0] == pytest.approx(min(0.3 * np.sqrt(weight), MAX_STEP), rel=1e-6)
    assert bias[0] == pytest.approx(0.3 * np.sqrt(weight), rel=1e-6)
    assert bias[1] == pytest.approx(weight * 0.25)


def test_a_heavy_sample_nearly_right_moves_a_weight_at_most_max_step():
    """A cell of 250 free samples that the bias already reads free (p = 0.0003): AdaGrad's
    first step is lr sqrt(250) = 9.5 whatever the error; it is held to MAX_STEP."""
    weights, grad_sq, bias = np.zeros(2), np.zeros(2), np.array([-8.0, 1e6])
    sgd_pass(
        np.array([0, 2]),
        np.array([0, 1]),
        np.array([0.9, 0.05]),
        np.array([0.0]),
        np.array([250.0]),
        np.array([0]),
        weights,
        grad_sq,
        bias,
        0.6,
        0.0,
    )
    # Both weights step the same scale-free amount, held to MAX_STEP against free.
    np.testing.assert_allclose(weights, [-MAX_STEP, -MAX_STEP])
    assert 0.6 * np.sqrt(250.0) > MAX_STEP
