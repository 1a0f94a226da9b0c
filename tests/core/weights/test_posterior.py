"""Bayesian weight updates: the compiled coordinate descent against its NumPy twin, and what
the posterior does."""

import numpy as np

from ehm.core.weights.posterior import posterior_update, posterior_update_reference
from ehm.core.weights.uncertainty import curvature_sum


def test_compiled_update_matches_reference(rng, sparse_batch):
    batch = sparse_batch(rng)
    state = [rng.normal(size=40), rng.uniform(0.5, 3.0, 40), np.array([0.2, 5.0])]
    compiled = [a.copy() for a in state]
    reference = [a.copy() for a in state]
    sample_weights = rng.uniform(0.5, 3.0, len(batch[3]))
    posterior_update(*batch, sample_weights, *compiled, 3)
    posterior_update_reference(*batch, sample_weights, *reference, 3)
    for got, want in zip(compiled, reference, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)
    assert not np.allclose(compiled[0], state[0])
    np.testing.assert_array_equal(compiled[1], state[1])  # the prior, left as it was


def test_sweeps_reach_the_minimum_of_the_regularised_loss(rng, sparse_batch):
    indptr, rows, values, labels = sparse_batch(rng)
    weights, precision, bias = np.zeros(40), np.ones(40), np.array([0.0, 1.0])
    posterior_update(
        indptr, rows, values, labels, np.ones(len(labels)), weights, precision.copy(), bias, 50
    )
    phi = np.zeros((len(labels), 40))
    phi[np.repeat(np.arange(len(labels)), np.diff(indptr)), rows] = values
    p = 1 / (1 + np.exp(-(phi @ weights + bias[0])))
    gradient = phi.T @ (p - labels) + precision * weights
    np.testing.assert_allclose(gradient, 0.0, atol=1e-6)


def test_weights_seen_often_move_little():
    # One feature, always 1. First 1,000 samples, 900 of them occupied; then a batch of 100
    # free ones. With the first batch's posterior as prior, the weight lands near the log-odds
    # of all 1,100 samples (900 against 200), not near the last batch's.
    weights, precision, bias = np.zeros(1), np.ones(1), np.array([0.0, 1e12])
    learned = []
    for labels in (np.r_[np.ones(900), np.zeros(100)], np.zeros(100)):
        n = len(labels)
        batch = (np.arange(n + 1), np.zeros(n, dtype=np.int64), np.ones(n))
        posterior_update(*batch, labels, np.ones(n), weights, precision, bias, 20)
        curvature_sum(*batch, np.ones(n), weights, bias[0], precision)
        learned.append(weights[0])
    # The first is exact up to the prior; the second carries the Laplace approximation's error
    # (the prior is quadratic, the loss it stands for is not): 1.32 against 1.50.
    assert abs(learned[0] - np.log(900 / 100)) < 0.05
    assert abs(learned[1] - np.log(900 / 200)) < 0.2
    assert precision[0] > 1 + 0.9 * 0.1 * 1000  # 1 + sum of p (1 - p)
