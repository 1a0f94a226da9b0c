"""Stochastic gradient descent on the regularised logistic loss (Eq. 2-3), with a bias term.

Each weight has its own AdaGrad step size lr / sqrt(sum of its squared gradients), so a cluster
added with weight 0 learns quickly while well-observed clusters settle. Labels are 1 (occupied)
and 0 (free); p(occupied | x) = sigmoid(w^T phi(x) + b).

A sample that stands for w samples (ehm.core.observations.evidence) is one step: its gradient counts
w times in the step and w times its square in the accumulator, so for a fresh weight the step is lr
sqrt(w), about what w steps of one sample each would take, and the cost of a pass follows the
samples, not what they stand for. Steps of one unweighted sample each would be a million on a LiDAR
sweep; one weighted step per cell scores the same held-out F1 (BENCHMARKS.md), while one step scaled
by w alone (no sqrt) lost 0.02-0.05 against stepping w times.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures
from ehm.core.model.logistic import sigmoid, sigmoid_scalar

EPSILON = 1e-8
SGD_BLOCK = 4096
"""Samples a pass visits together (see `blocked_order`): their features stay in cache."""


def loss_weights(occupied: np.ndarray, weight: np.ndarray, balance: bool) -> np.ndarray:
    """(n,) float64 loss weight of samples with labels `occupied` (n,) bool and weights
    `weight` (n,) float64 (TrainingSamples.weight): the weights, or, when balancing, scaled so
    each class carries half of their total, so the density of free samples does not move the
    0.5 boundary."""
    total = weight.sum()
    total_occupied = weight[occupied].sum()
    total_free = total - total_occupied
    if not balance or total_occupied == 0 or total_free == 0:
        return weight
    return weight * np.where(occupied, total / (2 * total_occupied), total / (2 * total_free))


def train_weights(
    features: SparseFeatures,
    occupied: np.ndarray,
    sample_weights: np.ndarray,
    clusters: ClusterSet,
    bias_state: np.ndarray,
    config: MapConfig,
    rng: np.random.Generator,
) -> None:
    """`config.epochs` passes of SGD over samples with `features`, labels `occupied` (n,)
    bool and loss weights `sample_weights` (n,) float64, each in a fresh random order (Alg. 2
    lines 26-28, see `blocked_order`: the samples must come shuffled); updates the clusters'
    weights and AdaGrad state and bias_state in place."""
    labels = occupied.astype(np.float64)
    for _ in range(config.epochs):
        sgd_pass(
            features.indptr,
            features.rows,
            features.values,
            labels,
            sample_weights,
            blocked_order(len(labels), rng),
            clusters.weights,
            clusters.grad_sq,
            bias_state,
            config.learning_rate,
            config.l2,
        )


def blocked_order(n: int, rng: np.random.Generator, block: int = SGD_BLOCK) -> np.ndarray:
    """(n,) int64 a random order of n samples that visits `block` consecutive samples at a
    time: the blocks in random order, the samples of each in random order. Over samples that
    were shuffled before, each block is a random draw, so passes in this order learn as
    passes in a fresh permutation do; the features of a block are read from memory once
    instead of one sample at a time (SGD over the sample scan: 200 ms against 600)."""
    order = np.arange(n, dtype=np.int64)
    starts = range(0, n, block)
    for start in starts:
        rng.shuffle(order[start : start + block])
    picked = rng.permutation(len(starts))
    return np.concatenate([order[starts[b] : starts[b] + block] for b in picked] or [order])


@numba.njit(cache=True)
def sgd_pass(
    indptr,
    rows,
    values,
    labels,
    sample_weights,
    order,
    weights,
    grad_sq,
    bias_state,
    learning_rate,
    l2,
):  # pragma: no cover - compiled
    """One pass over the samples in `order`, updating weights, grad_sq and bias_state in place.

    indptr, rows, values: the samples' features (see SparseFeatures); labels: (n,) 0 or 1;
    sample_weights: (n,) loss weight of each sample (how many it stands for, see the module's
    docstring); bias_state: [bias, its accumulated squared gradient].
    """
    for i in order:
        score = bias_state[0]
        for e in range(indptr[i], indptr[i + 1]):
            score += weights[rows[e]] * values[e]
        error = sigmoid_scalar(score) - labels[i]
        weight = sample_weights[i]
        for e in range(indptr[i], indptr[i + 1]):
            cluster = rows[e]
            grad = error * values[e] + l2 * weights[cluster]
            grad_sq[cluster] += weight * grad * grad
            step = learning_rate * weight * grad / np.sqrt(grad_sq[cluster] + EPSILON)
            weights[cluster] -= step
        bias_state[1] += weight * error * error
        bias_state[0] -= learning_rate * weight * error / np.sqrt(bias_state[1] + EPSILON)


def sgd_pass_reference(
    indptr: np.ndarray,
    rows: np.ndarray,
    values: np.ndarray,
    labels: np.ndarray,
    sample_weights: np.ndarray,
    order: np.ndarray,
    weights: np.ndarray,
    grad_sq: np.ndarray,
    bias_state: np.ndarray,
    learning_rate: float,
    l2: float,
) -> None:
    """Plain NumPy twin of `sgd_pass`, one sample at a time."""
    for i in order:
        touched, phi = rows[indptr[i] : indptr[i + 1]], values[indptr[i] : indptr[i + 1]]
        score = bias_state[0] + np.dot(weights[touched], phi)
        error, weight = sigmoid(score) - labels[i], sample_weights[i]
        grad = error * phi + l2 * weights[touched]
        grad_sq[touched] += weight * grad * grad
        weights[touched] -= learning_rate * weight * grad / np.sqrt(grad_sq[touched] + EPSILON)
        bias_state[1] += weight * error * error
        bias_state[0] -= learning_rate * weight * error / np.sqrt(bias_state[1] + EPSILON)
