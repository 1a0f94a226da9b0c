"""Batch feature construction (Alg. 2 lines 22-25, Alg. 3): sparse localized length-scale
features of many points, with the nearest clusters searched once per group of points.

Point i belongs to group g = group_of_point[i]; its feature vector has non-zeros only at the
clusters group_neighbours[g] (k of them, -1 where the map has fewer than k clusters). Cluster
m's kernel is the planar-surface one where planar[m], else k_SP (see ehm.kernels).
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.cells import cell_keys
from ehm.kernels import cluster_kernel, cluster_kernel_reference, projected_radii


def group_by_cell(points: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Group (n, d) points, metres, by the cubic cell of side `cell` they fall in (Alg. 3
    line 1). Returns group_of_point (n,) int64 and the mean of each group's points (G, d)."""
    n, d = points.shape
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, d))
    _, group_of_point = np.unique(cell_keys(points, cell).keys, return_inverse=True)
    group_of_point = group_of_point.ravel().astype(np.int64)
    sizes = np.bincount(group_of_point)
    sums = np.stack([np.bincount(group_of_point, points[:, a], len(sizes)) for a in range(d)], 1)
    return group_of_point, sums / sizes[:, None]


def group_spread(points: np.ndarray, group_of_point: np.ndarray, centres: np.ndarray) -> float:
    """Largest distance, metres, from a point to the centre of its group (0 for no points)."""
    if len(points) == 0:
        return 0.0
    return float(np.sqrt(np.max(np.sum((points - centres[group_of_point]) ** 2, axis=1))))


@numba.njit(cache=True, inline="always")
def _kernel_at(points, i, cluster, means, transforms, planar):  # pragma: no cover - compiled
    r2, r_max = projected_radii(points, i, cluster, means, transforms)
    return cluster_kernel(r2, r_max, planar[cluster])


@numba.njit(cache=True, parallel=True)
def kernel_values(
    points, group_of_point, group_neighbours, means, transforms, planar
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
                values[i, j] = _kernel_at(points, i, cluster, means, transforms, planar)
    return values


@numba.njit(cache=True, parallel=True)
def decision_values(
    points, group_of_point, group_neighbours, means, transforms, planar, weights, bias
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
                value = _kernel_at(points, i, cluster, means, transforms, planar)
                scores[i] += weights[cluster] * value
    return scores


def kernel_values_reference(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
) -> np.ndarray:
    """Plain NumPy twin of `kernel_values`."""
    neighbours = group_neighbours[group_of_point]
    safe = np.maximum(neighbours, 0)
    offsets = points[:, None, :] - means[safe]
    projected = np.einsum("nkab,nkb->nka", transforms[safe], offsets)
    values = cluster_kernel_reference(projected, planar[safe])
    return np.where(neighbours >= 0, values, 0.0)


def decision_values_reference(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
    weights: np.ndarray,
    bias: float,
) -> np.ndarray:
    """Plain NumPy twin of `decision_values`."""
    values = kernel_values_reference(
        points, group_of_point, group_neighbours, means, transforms, planar
    )
    neighbours = group_neighbours[group_of_point]
    return bias + np.sum(values * weights[np.maximum(neighbours, 0)], axis=1)
