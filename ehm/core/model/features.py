"""Batch feature construction (Alg. 2 lines 22-25, Alg. 3): sparse localized length-scale
features of many points, with the nearest clusters searched once per group of points.

Point i belongs to group g = group_of_point[i]; its feature vector has non-zeros only at the
clusters group_neighbours[g] (k of them, -1 where the map has fewer than k clusters). Cluster
m's kernel is the planar-surface one where planar[m], else k_SP (see ehm.core.model.kernels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.core.model.clusters import ClusterSet
from ehm.core.model.kernels import (
    OUTSIDE,
    cluster_kernel_reference,
    kernel_code,
    kernels_of_codes,
    projected_radii,
    sparse_kernel_reference,
)
from ehm.core.primitives.cells import cell_keys, z_order_keys
from ehm.core.primitives.radix import radix_ranks


@dataclass(frozen=True)
class PointGroups:
    """Points that share one neighbour search. group_of_point: (n,) int64, the group of each
    point; centres: (G, d) float64, metres, where each group's search is made."""

    group_of_point: np.ndarray
    centres: np.ndarray

    @classmethod
    def singletons(cls, points: np.ndarray) -> PointGroups:
        """One group per point: a search at every point (exact)."""
        return cls(np.arange(len(points), dtype=np.int64), points)

    def __add__(self, other: PointGroups) -> PointGroups:
        """The groups of this set's points followed by `other`'s."""
        return PointGroups(
            np.concatenate([self.group_of_point, other.group_of_point + len(self.centres)]),
            np.concatenate([self.centres, other.centres]),
        )

    def spread(self, points: np.ndarray) -> float:
        """Largest distance, metres, from one of `points` (n, d) to the centre of its group
        (0 for no points)."""
        if len(points) == 0:
            return 0.0
        return float(np.sqrt(_squared_offsets(points, self.group_of_point, self.centres).max()))

    def spread_reference(self, points: np.ndarray) -> float:
        """Plain NumPy twin of `spread`."""
        if len(points) == 0:
            return 0.0
        offsets = points - np.take(self.centres, self.group_of_point, axis=0)
        return float(np.sqrt(np.einsum("ij,ij->i", offsets, offsets).max()))


@numba.njit(cache=True, parallel=True)
def _squared_offsets(points, group_of_point, centres):  # pragma: no cover - compiled
    """(n,) squared distance, m^2, from each of points (n, d) to its group's centre."""
    n, d = points.shape
    squared = np.empty(n)
    for i in numba.prange(n):
        g = group_of_point[i]
        total = 0.0
        for a in range(d):
            gap = points[i, a] - centres[g, a]
            total += gap * gap
        squared[i] = total
    return squared


def group_by_cell(points: np.ndarray, cell: float) -> PointGroups:
    """Group (n, d) points, metres, by the cubic cell of side `cell` they fall in (Alg. 3
    line 1), the groups in the Z-order of their cells (z_order_keys); each group's centre is
    the mean of its points."""
    if len(points) == 0:
        return PointGroups(np.zeros(0, dtype=np.int64), np.zeros((0, points.shape[1])))
    return group_points_by_key(points, z_order_keys(cell_keys(points, cell)))


def group_points_by_key(points: np.ndarray, keys: np.ndarray) -> PointGroups:
    """Group (n, d) points, metres, by their `keys` (n,) int64 >= 0, the groups in the order
    of their keys; each group's centre is the mean of its points."""
    n, d = points.shape
    if n == 0:
        return PointGroups(np.zeros(0, dtype=np.int64), np.zeros((0, d)))
    group_of_point = radix_ranks(keys)
    sizes = np.bincount(group_of_point)
    sums = np.stack([np.bincount(group_of_point, points[:, a], len(sizes)) for a in range(d)], 1)
    return PointGroups(group_of_point, sums / sizes[:, None])


@dataclass(frozen=True)
class SparseFeatures:
    """Feature vectors of n points in compressed rows: point i's non-zero features are at the
    clusters rows[indptr[i]:indptr[i + 1]] ((nnz,) int64, each at most once per point) with
    values[indptr[i]:indptr[i + 1]] ((nnz,) float64); indptr (n + 1,) int64."""

    indptr: np.ndarray
    rows: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return len(self.indptr) - 1

    @classmethod
    def of_codes(cls, clusters: np.ndarray, codes: np.ndarray) -> SparseFeatures:
        """The kernels not zero of n points, from their codes (n, k) float64 at clusters
        (n, k) int32 or int64 (ehm.core.model.kernels.kernel_code; OUTSIDE where the kernel is
        zero or there is no cluster). Both are read in order, and only the kept codes are
        evaluated."""
        indptr = np.zeros(len(codes) + 1, dtype=np.int64)
        np.cumsum(_inside_counts(codes), out=indptr[1:])
        rows, values = _compress_codes(clusters, codes, indptr)
        kernels_of_codes(values)
        return cls(indptr, rows, values)


def features_of_codes_reference(clusters: np.ndarray, codes: np.ndarray) -> SparseFeatures:
    """Plain NumPy twin of SparseFeatures.of_codes."""
    kept = codes < OUTSIDE
    inside = codes[kept]
    values = np.where(inside < 0.0, 1.0, sparse_kernel_reference(np.sqrt(np.abs(inside))))
    indptr = np.zeros(len(codes) + 1, dtype=np.int64)
    np.cumsum(kept.sum(axis=1), out=indptr[1:])
    return SparseFeatures(indptr, clusters[kept].astype(np.int64), values)


@numba.njit(cache=True, parallel=True)
def _inside_counts(codes):  # pragma: no cover - compiled
    """(n,) int64 codes below OUTSIDE in each row of codes (n, k)."""
    n, k = codes.shape
    counts = np.zeros(n, dtype=np.int64)
    for i in numba.prange(n):
        for j in range(k):
            counts[i] += codes[i, j] < OUTSIDE
    return counts


@numba.njit(cache=True, parallel=True)
def _compress_codes(clusters, codes, indptr):  # pragma: no cover - compiled
    """Clusters and codes of the codes below OUTSIDE, row i's from indptr[i] on. Written
    without a branch on the codes: each is written and kept by moving on or not (past the
    row's last, nothing is written); a TUM frame's in half the time."""
    n, k = codes.shape
    rows = np.empty(indptr[n], dtype=np.int64)
    kept = np.empty(indptr[n])
    for i in numba.prange(n):
        out = indptr[i]
        for j in range(k):
            if out < indptr[i + 1]:
                rows[out] = clusters[i, j]
                kept[out] = codes[i, j]
            out += codes[i, j] < OUTSIDE
    return rows, kept


def training_features(
    points: np.ndarray, groups: PointGroups, neighbours: np.ndarray, clusters: ClusterSet
) -> SparseFeatures:
    """Features of training points (n, d), metres (Alg. 2 lines 22-25), each over the
    clusters its group's neighbour search found: neighbours (G, k) int64 rows, -1 for none
    (ehm.core.search.index.ClusterIndex.group_neighbours)."""
    # Each point's clusters written beside its codes, in 32 bits: compressing them then reads
    # both in order, not each point's group's neighbours again, and half the bytes.
    of_point = np.empty((len(points), neighbours.shape[1]), dtype=np.int32)
    codes = _kernel_codes(
        points,
        groups.group_of_point,
        neighbours,
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        of_point,
    )
    return SparseFeatures.of_codes(of_point, codes)


@numba.njit(cache=True, parallel=True)
def _kernel_codes(
    points, group_of_point, group_neighbours, means, transforms, planar, clusters
):  # pragma: no cover - compiled
    """(n, k) float64 kernel codes (ehm.core.model.kernels.kernel_code) of each point at its
    group's k clusters, OUTSIDE where there is none; where clusters is (n, k) (int32 or
    int64), not (0, k), those clusters (-1 for none) are written into it."""
    n = points.shape[0]
    k = group_neighbours.shape[1]
    codes = np.empty((n, k))
    keep_clusters = clusters.shape[0] == n
    for i in numba.prange(n):
        g = group_of_point[i]
        for j in range(k):
            cluster = group_neighbours[g, j]
            if keep_clusters:
                clusters[i, j] = cluster
            if cluster >= 0:
                r2, r_max = projected_radii(points, i, cluster, means, transforms)
                codes[i, j] = kernel_code(r2, r_max, planar[cluster])
            else:
                codes[i, j] = OUTSIDE
    return codes


def kernel_values(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
) -> np.ndarray:
    """(n, k) float64 kernel values of each of `points` (n, d), metres, at its group's k
    clusters group_neighbours (G, k) (0 where -1)."""
    unkept = np.empty((0, group_neighbours.shape[1]), dtype=np.int64)
    values = _kernel_codes(
        points, group_of_point, group_neighbours, means, transforms, planar, unkept
    )
    kernels_of_codes(values.reshape(-1))
    return values


@numba.njit(cache=True, inline="always")
def add_to_sums(
    scores, variance_sums, i, cluster, value, weights, inverse_precision, with_variance
):  # pragma: no cover - compiled
    """Add kernel `cluster`'s value at point i to its score and, when with_variance, to its
    variance sums (see decision_values)."""
    scores[i] += weights[cluster] * value
    if with_variance:
        variance_sums[i, 0] += value * value * inverse_precision[cluster]
        variance_sums[i, 1] += value


@numba.njit(cache=True, parallel=True)
def _weighted_sums(
    values,
    group_of_point,
    group_neighbours,
    weights,
    bias,
    inverse_precision,
    with_variance,
    scores,
    variance_sums,
):  # pragma: no cover - compiled
    """Write bias + sum_j w phi of each point from its kernel values (n, k) into scores
    (n,) and, when with_variance, add its variance sums to variance_sums (n, 2), zeros
    before (see decision_values)."""
    n, k = values.shape
    for i in numba.prange(n):
        g = group_of_point[i]
        scores[i] = bias
        for j in range(k):
            cluster = group_neighbours[g, j]
            if cluster >= 0:
                add_to_sums(
                    scores,
                    variance_sums,
                    i,
                    cluster,
                    values[i, j],
                    weights,
                    inverse_precision,
                    with_variance,
                )


# Points whose kernel values decision_values holds at once: 6 MB of them.
DECISION_CHUNK = 65_536


def decision_values(
    points: np.ndarray,
    group_of_point: np.ndarray,
    group_neighbours: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
    weights: np.ndarray,
    bias: float,
    inverse_precision: np.ndarray,
    with_variance: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """(n,) float64 w^T phi(x) + bias of each of `points` (n, d), metres, without keeping
    the features, and, when with_variance, (n, 2) float64 [sum_m phi_m^2 / lambda_m, sum_m
    phi_m] over its clusters, from inverse_precision (M,) 1 / lambda_m (see
    ehm.core.weights.uncertainty); else (0, 2)."""
    n = len(points)
    scores = np.empty(n)
    variance_sums = np.zeros((n if with_variance else 0, 2))
    for first in range(0, n, DECISION_CHUNK):
        chunk = slice(first, min(n, first + DECISION_CHUNK))
        values = kernel_values(
            points[chunk], group_of_point[chunk], group_neighbours, means, transforms, planar
        )
        _weighted_sums(
            values,
            group_of_point[chunk],
            group_neighbours,
            weights,
            bias,
            inverse_precision,
            with_variance,
            scores[chunk],
            variance_sums[chunk],
        )
    return scores, variance_sums


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
    inverse_precision: np.ndarray,
    with_variance: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `decision_values`."""
    values = kernel_values_reference(
        points, group_of_point, group_neighbours, means, transforms, planar
    )
    clusters = np.maximum(group_neighbours[group_of_point], 0)
    scores = bias + np.sum(values * weights[clusters], axis=1)
    if not with_variance:
        return scores, np.zeros((0, 2))
    return scores, np.column_stack(
        [np.sum(values**2 * inverse_precision[clusters], axis=1), np.sum(values, axis=1)]
    )
