"""Stochastic gradient descent on the regularised logistic loss (Eq. 2-3), with a bias term.

Each weight has its own AdaGrad step size lr / sqrt(sum of its squared gradients), so a cluster
just added learns quickly while well-observed clusters settle. Labels are 1 (occupied)
and 0 (free); p(occupied | x) = sigmoid(w^T phi(x) + b).

A sample that stands for w samples (ehm.core.observations.evidence) is one step: its gradient counts
w times in the step and w times its square in the accumulator, so for a fresh weight the step is lr
sqrt(w), about what w steps of one sample each would take, and the cost of a pass follows the
samples, not what they stand for. Steps of one unweighted sample each would be a million on a LiDAR
sweep; one weighted step per cell scores as well, while one step scaled by w alone (no sqrt) scores
worse than stepping w times.

AdaGrad's step does not shrink with the error: a fresh weight moves lr sqrt(w) whether its
sample is badly or nearly right, and cells pooled where many rays pass (beside the sensor) stand
for hundreds of samples. No step moves a weight by more than MAX_STEP.

A pass runs on two threads: a plane across the clusters splits the samples into those whose
features reach only clusters on one side, only on the other, or both (the border). Round by
round, the two sides are stepped at once, since they share no weight (the bias moves by the
sum of both sides' steps), and the round's border samples after them.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures
from ehm.core.primitives.logistic import sigmoid, sigmoid_scalar

EPSILON = 1e-8
# The most one sample's step moves a weight, log-odds: a free cell of hundreds of samples can
# otherwise throw a free kernel to positive log-odds in one step.
MAX_STEP = 3.0
SGD_BLOCK = 4096
"""Samples a pass visits together (see `blocked_order`): their features stay in cache. A
round of sgd_rounds visits as many."""
BORDER = 2
"""The side of a sample whose clusters lie on both sides of space (see `space_sides`)."""
TWO_SIDED_MIN_SAMPLES = 8 * SGD_BLOCK
"""Fewer samples are stepped one after the other, all on the border: in a batch of few
rounds, the border's samples would all come late in the pass (in a 2D scan of 400 rays
learned after another, a wall read up to 26 cm in front of where it stands)."""


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
    lines 26-28, see `blocked_order`: the samples must come shuffled), the two sides of space
    on two threads (see `space_sides`); updates the clusters' weights and AdaGrad state and
    bias_state in place, each weight held at or below its `weight_ceilings`. Batches of fewer
    than TWO_SIDED_MIN_SAMPLES samples run on one. The features' rows are relabelled to the
    order the clusters learn in, and back after.
    """
    labels = occupied.astype(np.float64)
    rows, weights, grad_sq = features.rows, clusters.weights, clusters.grad_sq
    ceilings = weight_ceilings(clusters, config)
    stored = None
    if len(labels) >= TWO_SIDED_MIN_SAMPLES:
        sides, cluster_side = space_sides(features, clusters.means)
        # Each side's clusters stored together while they learn, so that the two threads
        # seldom write to one cache line.
        stored = np.argsort(cluster_side, kind="stable")
        place = np.empty_like(stored)  # where each cluster is stored: stored's inverse
        place[stored] = np.arange(len(stored))
        relabel(rows, place)
        weights, grad_sq, ceilings = weights[stored], grad_sq[stored], ceilings[stored]
    else:
        sides = np.full(len(labels), BORDER, dtype=np.int64)
    samples = (features.indptr, rows, features.values, labels, sample_weights)
    steps = (config.learning_rate, config.l2)
    try:
        for _ in range(config.epochs):
            plan = visiting_plan(blocked_order(len(labels), rng), sides)
            sgd_rounds(*samples, *plan, weights, grad_sq, ceilings, bias_state, *steps)
    finally:
        if stored is not None:
            relabel(rows, stored)
            clusters.weights[stored] = weights
            clusters.grad_sq[stored] = grad_sq


@numba.njit(cache=True, parallel=True)
def relabel(rows, labels):  # pragma: no cover - compiled
    """Replace each of rows (n,) int64 by labels[row], in place: a batch's features are
    relabelled without a second array as large, whose fresh pages cost more than the work."""
    for e in numba.prange(len(rows)):
        rows[e] = labels[rows[e]]


def weight_ceilings(clusters: ClusterSet, config: MapConfig) -> np.ndarray:
    """(M,) float64, log-odds: the most each cluster's weight may be. 0 for coarse clusters
    with `config.coarse_free_only` (open free space only ever says free), +inf otherwise."""
    ceilings = np.full(len(clusters.weights), np.inf)
    if config.coarse_free_only:
        ceilings[clusters.coarse] = 0.0
    return ceilings


def relabel_reference(rows: np.ndarray, labels: np.ndarray) -> None:
    """Plain NumPy twin of `relabel`."""
    rows[:] = labels[rows]


def space_sides(features: SparseFeatures, means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The side of each sample, (n,) int64: 0 or 1 when all the clusters its features reach
    lie on that side of a plane across the clusters, BORDER when they lie on both or it has
    none; and the side of each of the clusters (M,) int64, at `means` (M, d) metres.

    The plane is normal to the axis along which the reached clusters spread most, at the
    median of their coordinates weighted by how often the features reach them, so both sides
    hold about as many features; samples of one side never touch the weights of the other,
    so the two sides can be stepped at once (sgd_rounds)."""
    n = len(features.indptr) - 1
    if len(features.rows) == 0:
        return np.full(n, BORDER, dtype=np.int64), np.zeros(len(means), dtype=np.int64)
    reached = np.bincount(features.rows, minlength=len(means)).astype(np.float64)
    used = np.flatnonzero(reached)
    axis = int(np.argmax(np.ptp(means[used], axis=0)))
    coordinate = means[used, axis]
    order = np.argsort(coordinate, kind="stable")
    cumulative = np.cumsum(reached[used][order])
    middle = coordinate[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])]
    cluster_side = (means[:, axis] > middle).astype(np.int64)
    return sample_sides(features.indptr, features.rows, cluster_side), cluster_side


@numba.njit(cache=True, parallel=True)
def sample_sides(indptr, rows, cluster_side):  # pragma: no cover - compiled
    """(n,) int64: the side of `cluster_side` (c,) 0 or 1 that all of a sample's clusters
    share, BORDER where they differ or it has none (indptr, rows: its features)."""
    n = len(indptr) - 1
    side = np.full(n, BORDER, dtype=np.int64)
    for i in numba.prange(n):
        if indptr[i + 1] > indptr[i]:
            first = cluster_side[rows[indptr[i]]]
            side[i] = first
            for e in range(indptr[i] + 1, indptr[i + 1]):
                if cluster_side[rows[e]] != first:
                    side[i] = BORDER
                    break
    return side


def sample_sides_reference(
    indptr: np.ndarray, rows: np.ndarray, cluster_side: np.ndarray
) -> np.ndarray:
    """Plain NumPy twin of `sample_sides`."""
    sample = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    ones = np.bincount(sample, cluster_side[rows], len(indptr) - 1)
    counts = np.diff(indptr)
    return np.where(
        counts == 0, BORDER, np.where(ones == 0, 0, np.where(ones == counts, 1, BORDER))
    )


@numba.njit(cache=True)
def visiting_plan(order, sides, round_size=SGD_BLOCK):  # pragma: no cover - compiled
    """The visits of one pass in `order` (n,) int64, round by round (`round_size` visits
    each), each round's side 0, side 1 and BORDER samples (`sides` (n,) int64) in their order:
    (visits (n,) int64, starts (3 rounds + 1,) int64 where each round's group of each side
    begins)."""
    n = len(order)
    rounds = max(1, (n + round_size - 1) // round_size)
    starts = np.zeros(3 * rounds + 1, dtype=np.int64)
    for k in range(n):
        starts[(k // round_size) * 3 + sides[order[k]] + 1] += 1
    for g in range(3 * rounds):
        starts[g + 1] += starts[g]
    filled = starts[:-1].copy()
    visits = np.empty(n, dtype=np.int64)
    for k in range(n):
        g = (k // round_size) * 3 + sides[order[k]]
        visits[filled[g]] = order[k]
        filled[g] += 1
    return visits, starts


def visiting_plan_reference(
    order: np.ndarray, sides: np.ndarray, round_size: int = SGD_BLOCK
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `visiting_plan`."""
    n = len(order)
    rounds = max(1, -(-n // round_size))
    group = (np.arange(n) // round_size) * 3 + sides[order]
    visits = order[np.argsort(group, kind="stable")]
    starts = np.zeros(3 * rounds + 1, dtype=np.int64)
    starts[1:] = np.cumsum(np.bincount(group, minlength=3 * rounds))
    return visits, starts


def blocked_order(n: int, rng: np.random.Generator, block: int = SGD_BLOCK) -> np.ndarray:
    """(n,) int64 a random order of n samples that visits `block` consecutive samples at a
    time: the blocks in random order, the samples of each in the order they are stored. Over
    samples shuffled once before (their features are computed in that order), each block is a
    random draw in a random order that every pass repeats, and the features are read as they
    lie in memory: faster than shuffling within blocks or every pass, and as accurate.
    """
    blocks = [np.arange(start, min(start + block, n)) for start in range(0, n, block)]
    picked = rng.permutation(len(blocks))
    return np.concatenate([blocks[b] for b in picked]) if blocks else np.zeros(0, np.int64)


@numba.njit(cache=True, inline="always")
def _step(i, data, bias, learning_rate, l2):  # pragma: no cover - compiled
    """One AdaGrad step on sample i (see sgd_rounds; data as _steps takes it), each weight
    projected back under its ceiling; bias: [bias, its squared gradients]."""
    _, indptr, rows, values, labels, sample_weights, weights, grad_sq, ceilings = data
    score = bias[0]
    for e in range(indptr[i], indptr[i + 1]):
        score += weights[rows[e]] * values[e]
    error = sigmoid_scalar(score) - labels[i]
    weight = sample_weights[i]
    for e in range(indptr[i], indptr[i + 1]):
        cluster = rows[e]
        grad = error * values[e] + l2 * weights[cluster]
        grad_sq[cluster] += weight * grad * grad
        step = learning_rate * weight * grad / np.sqrt(grad_sq[cluster] + EPSILON)
        moved = weights[cluster] - min(max(step, -MAX_STEP), MAX_STEP)
        weights[cluster] = min(moved, ceilings[cluster])
    bias[1] += weight * error * error
    bias[0] -= learning_rate * weight * error / np.sqrt(bias[1] + EPSILON)


@numba.njit(cache=True, parallel=True)
def sgd_rounds(
    indptr,
    rows,
    values,
    labels,
    sample_weights,
    visits,
    starts,
    weights,
    grad_sq,
    ceilings,
    bias_state,
    learning_rate,
    l2,
):  # pragma: no cover - compiled
    """One pass over the samples in the rounds of `visits` and `starts` (visiting_plan),
    updating weights (each held at or below its ceiling; ceilings (M,) float64), grad_sq and
    bias_state in place. In each round the two sides' samples are stepped at once, each side
    from the bias at the round's start, and the bias then moves by both sides' steps; the
    round's BORDER samples follow. The result does not depend on the threads.

    indptr, rows, values: the samples' features (see SparseFeatures); labels: (n,) 0 or 1;
    sample_weights: (n,) loss weight of each sample (how many it stands for, see the module's
    docstring); bias_state: [bias, its accumulated squared gradient].
    """
    shift = np.zeros((2, 2))
    data = (visits, indptr, rows, values, labels, sample_weights, weights, grad_sq, ceilings)
    for r in range((len(starts) - 1) // 3):
        for side in numba.prange(2):
            bias = bias_state.copy()
            _steps(starts[3 * r + side], starts[3 * r + side + 1], data, bias, learning_rate, l2)
            shift[side, 0] = bias[0] - bias_state[0]
            shift[side, 1] = bias[1] - bias_state[1]
        bias_state[0] += shift[0, 0] + shift[1, 0]
        bias_state[1] += shift[0, 1] + shift[1, 1]
        _steps(starts[3 * r + 2], starts[3 * r + 3], data, bias_state, learning_rate, l2)


@numba.njit(cache=True, inline="always")
def _steps(first, last, data, bias, learning_rate, l2):  # pragma: no cover - compiled
    """AdaGrad steps on the samples visits[first:last] (data: visits, indptr, rows, values,
    labels, sample_weights, weights, grad_sq, ceilings; see sgd_rounds)."""
    visits = data[0]
    for k in range(first, last):
        _step(visits[k], data, bias, learning_rate, l2)


def sgd_rounds_reference(
    indptr: np.ndarray,
    rows: np.ndarray,
    values: np.ndarray,
    labels: np.ndarray,
    sample_weights: np.ndarray,
    visits: np.ndarray,
    starts: np.ndarray,
    weights: np.ndarray,
    grad_sq: np.ndarray,
    ceilings: np.ndarray,
    bias_state: np.ndarray,
    learning_rate: float,
    l2: float,
) -> None:
    """Plain NumPy twin of `sgd_rounds`, one sample at a time, the sides one after the other."""

    def step(i: int, bias: np.ndarray) -> None:
        touched, phi = rows[indptr[i] : indptr[i + 1]], values[indptr[i] : indptr[i + 1]]
        score = bias[0] + np.dot(weights[touched], phi)
        error, weight = sigmoid(score) - labels[i], sample_weights[i]
        grad = error * phi + l2 * weights[touched]
        grad_sq[touched] += weight * grad * grad
        step = learning_rate * weight * grad / np.sqrt(grad_sq[touched] + EPSILON)
        moved = weights[touched] - np.clip(step, -MAX_STEP, MAX_STEP)
        weights[touched] = np.minimum(moved, ceilings[touched])
        bias[1] += weight * error * error
        bias[0] -= learning_rate * weight * error / np.sqrt(bias[1] + EPSILON)

    for r in range((len(starts) - 1) // 3):
        shifts = []
        for side in (0, 1):
            bias = bias_state.copy()
            for k in range(starts[3 * r + side], starts[3 * r + side + 1]):
                step(visits[k], bias)
            shifts.append(bias - bias_state)
        bias_state += shifts[0] + shifts[1]
        for k in range(starts[3 * r + 2], starts[3 * r + 3]):
            step(visits[k], bias_state)
