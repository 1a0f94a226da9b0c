"""Batch feature construction (Alg. 2 lines 22-25, Alg. 3): sparse localized length-scale
features of many points, with the nearest clusters searched once per group of points.

Point i belongs to group g = group_of_point[i]; its feature vector has non-zeros only at the
clusters group_neighbours[g] (k of them, -1 where the map has fewer than k clusters).
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.kernels import sparse_kernel, sparse_kernel_reference


@numba.njit(cache=True, inline="always")
def _kernel_at(points, i, cluster, means, transforms):  # pragma: no cover - compiled
    d = points.shape[1]
    r2 = 0.0
    for a in range(d):
        projected = 0.0
        for b in range(d):
            projected += transforms[cluster, a, b] * (points[i, b] - means[cluster, b])
        r2 += projected * projected
    return sparse_kernel(np.sqrt(r2))


@numba.njit(cache=True, parallel=True)
def kernel_values(
    points, group_of_point, group_neighbours, means, transforms
):  # pragma: no cover - compiled
    """(n, k) float64 kernel values of each point at its group's k clusters."""
    n = points.shape[0]
    k = group_neighbours.shape[1]
    values = np.zeros((n, k))
    for i in numba.prange(n):
        g = group_of_point[i]
        for j in range(k):
            cluster = group_neighbours[g, j]
            if cluster >= 0:
                values[i, j] = _kernel_at(points, i, cluster, means, transforms)
    return values


@numba.njit(cache=True, parallel=True)
def decision_values(
    points, group_of_point, group_neighbours, means, transforms, weights, bias
):  # pragma: no cover - compiled
    """(n,) float64 w^T phi(x) + bias of each point, without storing the features."""
    n = points.shape[0]
    k = group_neighbours.shape[1]
    scores = np.full(n, bias)
    for i in numba.prange(n):
        g = group_of_point[i]
        for j in range(k):
            cluster = group_neighbours[g, j]
            if cluster >= 0:
                scores[i] += weights[cluster] * _kernel_at(points, i, cluster, means, transforms)
    return scores


def kernel_values_reference(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
) -> np.ndarray:
    """Plain NumPy twin of `kernel_values`."""
    neighbours = group_neighbours[group_of_point]
    safe = np.maximum(neighbours, 0)
    offsets = points[:, None, :] - means[safe]
    projected = np.einsum("nkab,nkb->nka", transforms[safe], offsets)
    values = sparse_kernel_reference(np.linalg.norm(projected, axis=2))
    return np.where(neighbours >= 0, values, 0.0)


def decision_values_reference(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    weights: np.ndarray,
    bias: float,
) -> np.ndarray:
    """Plain NumPy twin of `decision_values`."""
    values = kernel_values_reference(points, group_of_point, group_neighbours, means, transforms)
    neighbours = group_neighbours[group_of_point]
    return bias + np.sum(values * weights[np.maximum(neighbours, 0)], axis=1)
