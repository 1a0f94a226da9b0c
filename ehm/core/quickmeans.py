"""Quick-means clustering (Alg. 1) with optional k-means refinement.

Seeds are drawn at random among the points still available; each seed gathers the available
points within the outer radius r_o (its cluster when there are at least `min_size` of them) and
takes the points within the inner radius r_i out of the pool. Drawing uniformly from the pool
at every step is the same as walking one random permutation and skipping points already taken,
which is what the kernel does. Neighbours are found through a hash of cells of side r_o.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from ehm.core.cells import cell_keys


@dataclass(frozen=True)
class QuickMeansResult:
    """Clusters of one point set.

    seeds: (S,) int64, index of each seed point. owner: (N,) int64, the seed (0..S-1) that took
    each point out of the pool. counts: (S,) int64, points within r_o of each seed when it was
    drawn. means: (S, d) float64, metres. covariances: (S, d, d) float64, m^2 (unbiased, zero
    for a single point). kept: (S,) bool, counts >= min_size: the clusters proper; the other
    seeds still group their points for neighbour search.
    """

    seeds: np.ndarray
    owner: np.ndarray
    counts: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    kept: np.ndarray


def _statistics(
    counts: np.ndarray, sums: np.ndarray, scatter: np.ndarray, centres: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Means and unbiased covariances from sums taken relative to `centres`."""
    n = counts.astype(np.float64)
    local_mean = sums / n[:, None]
    scatter_about_mean = scatter - n[:, None, None] * np.einsum(
        "si,sj->sij", local_mean, local_mean
    )
    covariances = scatter_about_mean / np.maximum(n - 1.0, 1.0)[:, None, None]
    return centres + local_mean, covariances


@numba.njit(cache=True)
def _quick_means_kernel(
    points,
    cells,
    strides,
    extents,
    cell_keys,
    cell_starts,
    cell_sizes,
    sorted_points,
    order,
    r_inner,
    r_outer,
):  # pragma: no cover - compiled
    n, d = points.shape
    available = np.ones(n, dtype=np.bool_)
    owner = np.full(n, -1, dtype=np.int64)
    seeds = np.empty(n, dtype=np.int64)
    counts = np.zeros(n, dtype=np.int64)
    sums = np.zeros((n, d))
    scatter = np.zeros((n, d, d))
    ri2 = r_inner * r_inner
    ro2 = r_outer * r_outer
    n_offsets = 3**d
    diff = np.empty(d)
    s = 0
    for seed in order:
        if not available[seed]:
            continue
        seeds[s] = seed
        for o in range(n_offsets):
            key = 0
            code = o
            inside = True
            for a in range(d):
                c = cells[seed, a] + (code % 3) - 1
                code //= 3
                if c < 0 or c >= extents[a]:
                    inside = False
                key += c * strides[a]
            if not inside:
                continue
            slot = np.searchsorted(cell_keys, key)
            if slot >= len(cell_keys) or cell_keys[slot] != key:
                continue
            for m in range(cell_starts[slot], cell_starts[slot] + cell_sizes[slot]):
                p = sorted_points[m]
                if not available[p]:
                    continue
                dist2 = 0.0
                for a in range(d):
                    diff[a] = points[p, a] - points[seed, a]
                    dist2 += diff[a] * diff[a]
                if dist2 >= ro2:
                    continue
                counts[s] += 1
                for a in range(d):
                    sums[s, a] += diff[a]
                    for b in range(d):
                        scatter[s, a, b] += diff[a] * diff[b]
                if dist2 < ri2:
                    available[p] = False
                    owner[p] = s
        s += 1
    return seeds[:s].copy(), owner, counts[:s].copy(), sums[:s].copy(), scatter[:s].copy()


def _cell_hash(points: np.ndarray, cell: float):
    """Integer cells of side `cell`, their linear keys and the points sorted by key."""
    hashed = cell_keys(points, cell)
    sorted_points = np.argsort(hashed.keys, kind="stable")
    cell_keys_sorted, cell_starts, cell_sizes = np.unique(
        hashed.keys[sorted_points], return_index=True, return_counts=True
    )
    return (
        hashed.cells,
        hashed.strides,
        hashed.extents,
        cell_keys_sorted,
        cell_starts,
        cell_sizes,
        sorted_points,
    )


def quick_means(
    points: np.ndarray,
    r_inner: float,
    r_outer: float,
    min_size: int,
    rng: np.random.Generator,
) -> QuickMeansResult:
    """Cluster (N, d) points, metres, with inner radius r_inner and outer radius r_outer."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    if len(points) == 0:
        d = points.shape[1]
        empty = np.zeros(0, dtype=np.int64)
        return QuickMeansResult(
            empty, empty, empty, np.zeros((0, d)), np.zeros((0, d, d)), np.zeros(0, dtype=bool)
        )
    if not 0 < r_inner <= r_outer:
        raise ValueError(f"quick-means needs 0 < r_inner <= r_outer, got {r_inner}, {r_outer}")
    order = rng.permutation(len(points))
    hashed = _cell_hash(points, r_outer)
    seeds, owner, counts, sums, scatter = _quick_means_kernel(
        points, *hashed[:6], hashed[6], order, float(r_inner), float(r_outer)
    )
    means, covariances = _statistics(counts, sums, scatter, points[seeds])
    return QuickMeansResult(seeds, owner, counts, means, covariances, counts >= min_size)


def quick_means_reference(
    points: np.ndarray, r_inner: float, r_outer: float, min_size: int, order: np.ndarray
) -> QuickMeansResult:
    """Plain NumPy quick-means with brute-force distances, for tests of the compiled kernel."""
    n = len(points)
    available = np.ones(n, dtype=bool)
    owner = np.full(n, -1, dtype=np.int64)
    seeds, counts, sums, scatters = [], [], [], []
    for seed in order:
        if not available[seed]:
            continue
        diff = points - points[seed]
        dist2 = np.sum(diff * diff, axis=1)
        members = available & (dist2 < r_outer**2)
        taken = members & (dist2 < r_inner**2)
        available[taken] = False
        owner[taken] = len(seeds)
        seeds.append(seed)
        counts.append(members.sum())
        sums.append(diff[members].sum(axis=0))
        scatters.append(diff[members].T @ diff[members])
    seeds_a = np.array(seeds, dtype=np.int64)
    counts_a = np.array(counts, dtype=np.int64)
    means, covariances = _statistics(counts_a, np.array(sums), np.array(scatters), points[seeds_a])
    return QuickMeansResult(seeds_a, owner, counts_a, means, covariances, counts_a >= min_size)


def kmeans_refine(
    points: np.ndarray, result: QuickMeansResult, iterations: int
) -> QuickMeansResult:
    """Lloyd iterations from the kept quick-means clusters; every point joins its nearest."""
    means = result.means[result.kept]
    if iterations == 0 or len(means) == 0:
        return result
    d = points.shape[1]
    for _ in range(iterations):
        _, owner = cKDTree(means).query(points)
        counts = np.bincount(owner, minlength=len(means))
        occupied = counts > 0
        sums = np.stack([np.bincount(owner, points[:, a], len(means)) for a in range(d)], 1)
        means = sums[occupied] / counts[occupied, None]
    _, owner = cKDTree(means).query(points)
    counts = np.bincount(owner, minlength=len(means))
    diff = points - means[owner]
    outer = np.einsum("ni,nj->nij", diff, diff).reshape(len(points), d * d)
    scatter = np.stack(
        [np.bincount(owner, outer[:, c], len(means)) for c in range(d * d)], 1
    ).reshape(-1, d, d)
    _, covariances = _statistics(counts, np.zeros_like(means), scatter, means)
    seeds = np.full(len(means), -1, dtype=np.int64)
    return QuickMeansResult(seeds, owner.astype(np.int64), counts, means, covariances, counts > 0)
