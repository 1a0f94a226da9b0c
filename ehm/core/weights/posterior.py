"""Bayesian weight updates: a Gaussian posterior per weight, mean and diagonal precision (as
Bayesian Hilbert maps keep, Senanayake & Ramos 2017), updated batch by batch with the previous
posterior as the prior (Laplace approximation), so that weights seen many times move little.

For one batch of samples the weights w and the bias b minimise
    J = sum_i c_i loss(y_i, w^T phi_i + b) + 1/2 sum_m lambda_m (w_m - mu_m)^2
        + 1/2 lambda_b (b - mu_b)^2,
with loss the logistic loss of Eq. 2, c_i the weight of sample i's class, and mu, lambda the
posterior so far (a new cluster: mean the weight it joined with, MapConfig.initial_weight,
precision `prior_precision`). Coordinate descent minimises J: each weight the batch touches
takes, in turn, a Newton step along its own axis (clipped to MAX_STEP log-odds), with the
scores of the samples it touches kept current; then the bias, whose precision then grows by the
curvature the batch adds. The weights' precisions grow as under every update rule
(ehm.core.weights.uncertainty.add_curvature).
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures
from ehm.core.primitives.logistic import sigmoid, sigmoid_scalar

# Largest change of one weight in one coordinate step, log-odds.
MAX_STEP = 4.0


def update_posterior(
    features: SparseFeatures,
    occupied: np.ndarray,
    sample_weights: np.ndarray,
    clusters: ClusterSet,
    bias_state: np.ndarray,
    config: MapConfig,
) -> None:
    """Update the clusters' weights and bias_state ([bias, its precision]) with one batch of
    samples with `features`, labels `occupied` (n,) bool and loss weights `sample_weights` (n,)
    float64, in place: `config.epochs` sweeps of coordinate descent."""
    posterior_update(
        features.indptr,
        features.rows,
        features.values,
        occupied.astype(np.float64),
        sample_weights,
        clusters.weights,
        clusters.precision,
        bias_state,
        config.epochs,
    )


@numba.njit(cache=True)
def posterior_update(
    indptr,
    rows,
    values,
    labels,
    sample_weights,
    weights,
    precision,
    bias_state,
    sweeps,
):  # pragma: no cover - compiled
    """One batch: `sweeps` rounds of coordinate descent on J with the weights' prior
    precisions `precision`, then the bias precision's update; weights and bias_state ([bias,
    its precision]) change in place.

    indptr, rows, values: the samples' features (see SparseFeatures); labels: (n,) 0 or 1;
    sample_weights: (n,) loss weight of each sample. Clusters are visited in increasing
    order."""
    n = len(indptr) - 1
    n_clusters = weights.shape[0]
    # Entries (sample, value) of each cluster, in compressed columns.
    start = np.zeros(n_clusters + 1, dtype=np.int64)
    for e in range(len(rows)):
        start[rows[e] + 1] += 1
    for m in range(n_clusters):
        start[m + 1] += start[m]
    fill = start[:-1].copy()
    entry_sample = np.empty(start[n_clusters], dtype=np.int64)
    entry_value = np.empty(start[n_clusters])
    scores = np.full(n, bias_state[0])
    for i in range(n):
        for e in range(indptr[i], indptr[i + 1]):
            m = rows[e]
            entry_sample[fill[m]] = i
            entry_value[fill[m]] = values[e]
            fill[m] += 1
            scores[i] += weights[m] * values[e]
    prior_mean = weights.copy()
    prior_bias = bias_state[0]
    for _ in range(sweeps):
        for m in range(n_clusters):
            if start[m] == start[m + 1]:
                continue
            gradient = precision[m] * (weights[m] - prior_mean[m])
            curvature = precision[m]
            for e in range(start[m], start[m + 1]):
                i = entry_sample[e]
                v = entry_value[e]
                p = sigmoid_scalar(scores[i])
                gradient += sample_weights[i] * (p - labels[i]) * v
                curvature += sample_weights[i] * p * (1.0 - p) * v * v
            step = min(max(-gradient / curvature, -MAX_STEP), MAX_STEP)
            weights[m] += step
            for e in range(start[m], start[m + 1]):
                scores[entry_sample[e]] += step * entry_value[e]
        gradient = bias_state[1] * (bias_state[0] - prior_bias)
        curvature = bias_state[1]
        for i in range(n):
            p = sigmoid_scalar(scores[i])
            gradient += sample_weights[i] * (p - labels[i])
            curvature += sample_weights[i] * p * (1.0 - p)
        step = min(max(-gradient / curvature, -MAX_STEP), MAX_STEP)
        bias_state[0] += step
        for i in range(n):
            scores[i] += step
    for i in range(n):
        p = sigmoid_scalar(scores[i])
        bias_state[1] += sample_weights[i] * p * (1.0 - p)


def posterior_update_reference(
    indptr: np.ndarray,
    rows: np.ndarray,
    values: np.ndarray,
    labels: np.ndarray,
    sample_weights: np.ndarray,
    weights: np.ndarray,
    precision: np.ndarray,
    bias_state: np.ndarray,
    sweeps: int,
) -> None:
    """Plain NumPy twin of `posterior_update`, one cluster at a time over dense columns."""
    phi = np.zeros((len(indptr) - 1, len(weights)))
    phi[np.repeat(np.arange(len(indptr) - 1), np.diff(indptr)), rows] = values
    prior_mean, prior_bias = weights.copy(), bias_state[0]
    touched = np.flatnonzero(np.any(phi != 0.0, axis=0))
    for _ in range(sweeps):
        for m in touched:
            p = sigmoid(phi @ weights + bias_state[0])
            gradient = precision[m] * (weights[m] - prior_mean[m])
            gradient += np.sum(sample_weights * (p - labels) * phi[:, m])
            curvature = precision[m] + np.sum(sample_weights * p * (1 - p) * phi[:, m] ** 2)
            weights[m] += np.clip(-gradient / curvature, -MAX_STEP, MAX_STEP)
        p = sigmoid(phi @ weights + bias_state[0])
        gradient = bias_state[1] * (bias_state[0] - prior_bias) + np.sum(
            sample_weights * (p - labels)
        )
        curvature = bias_state[1] + np.sum(sample_weights * p * (1 - p))
        bias_state[0] += np.clip(-gradient / curvature, -MAX_STEP, MAX_STEP)
    p = sigmoid(phi @ weights + bias_state[0])
    bias_state[1] += np.sum(sample_weights * p * (1 - p))
