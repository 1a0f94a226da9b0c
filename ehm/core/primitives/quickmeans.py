"""Quick-means clustering (Alg. 1) with optional k-means refinement.

Seeds are drawn at random among the points still available; each seed gathers the available points
within the outer radius r_o (its cluster when there are at least `min_size` of them) and takes the
points within the inner radius r_i out of the pool. Points may carry weights and scatter: each then
stands for `weight` samples whose mean it is and whose scatter about it is given
(ehm.core.observations.evidence), and a cluster's count, mean and covariance are those of all the
samples its points stand for. Drawing uniformly from the pool at every step is the same as walking
one random permutation and skipping points already taken, which is what the kernel does. Neighbours
are found through a hash of cells of side r_o / CELLS_PER_RADIUS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from ehm.core.primitives.cells import cell_keys
from ehm.core.primitives.hashing import group_by_key


@dataclass(frozen=True)
class QuickMeansResult:
    """Clusters of one point set.

    seeds: (S,) int64, index of each seed point. owner: (N,) int64, the seed (0..S-1) that took
    each point out of the pool. counts: (S,) float64, weight of the points within r_o of each
    seed when it was drawn (their number when unweighted). means: (S, d) float64, metres.
    covariances: (S, d, d) float64, m^2 (unbiased, zero for a single point). kept: (S,) bool,
    counts >= min_size: the clusters proper; the other seeds still group their points for
    neighbour search.
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


# Cells of the neighbour hash per outer radius: finer cells gain nothing; what counts is that
# taken points leave their cells and that a cell's points lie together in memory.
CELLS_PER_RADIUS = 1


@numba.njit(cache=True)
def _row_reach(seed_offset, steps, cell):  # pragma: no cover - compiled
    """Squared distance from a seed, `seed_offset` metres into its cell, to the nearest point
    of the cell `steps` cells away along one axis (0 when steps == 0)."""
    if steps > 0:
        gap = steps * cell - seed_offset
    elif steps < 0:
        gap = seed_offset - (steps + 1) * cell
    else:
        return 0.0
    return gap * gap


@numba.njit(cache=True, nogil=True)
def _quick_means_kernel(
    points,
    cells,
    strides,
    extents,
    cell_keys,
    cell_starts,
    cell_sizes,
    sorted_points,
    sorted_index,
    sorted_weights,
    point_scatter,
    order,
    r_inner,
    r_outer,
    cell,
    low,
):  # pragma: no cover - compiled
    """Alg. 1 over points (n, d) in the random `order`.

    cells (n, d): each point's cell of side `cell` from the corner `low`, keyed by `strides`
    (strides[0] == 1); cell_keys: sorted, one per cell, with the start and size of the cell's
    points in sorted_points (their coordinates, cell by cell), sorted_index (their rows in
    `points`) and sorted_weights (their weights); point_scatter: each point's own scatter, by
    its row in `points` ((0, d, d) for none: read only for the points a seed reaches, it is not
    copied cell by cell). Points taken out of the pool leave their cell (sizes and the sorted arrays
    change in place), so a seed reads only points still available, one after the other in
    memory. Returns (seeds, owner, counts, sums, scatter), sums and scatter about each seed,
    each point's weighing its weight.
    """
    n, d = points.shape
    reach = CELLS_PER_RADIUS
    width = 2 * reach + 1
    available = np.ones(n, dtype=np.bool_)
    owner = np.full(n, -1, dtype=np.int64)
    seeds = np.empty(n, dtype=np.int64)
    counts = np.zeros(n)
    with_scatter = point_scatter.shape[0] > 0
    sums = np.empty((n, d))  # rows written as seeds are drawn: no pages touched for the rest
    scatter = np.empty((n, d, d))
    ri2 = r_inner * r_inner
    ro2 = r_outer * r_outer
    diff = np.empty(d)
    # Squared distances from the seed to the points of one cell.
    dist2s = np.empty(max(1, np.max(cell_sizes)) if len(cell_sizes) else 1)
    s = 0
    for seed in order:
        if not available[seed]:
            continue
        seeds[s] = seed
        sums[s] = 0.0
        scatter[s] = 0.0
        # One row of cells along axis 0 per offset of the other axes, skipping rows and cells
        # wholly beyond r_o; a row's cells are consecutive keys, found with one search.
        for o in range(width ** (d - 1)):
            row_key = 0
            row_gap = 0.0
            code = o
            inside = True
            for a in range(1, d):
                step = code % width - reach
                code //= width
                c = cells[seed, a] + step
                if c < 0 or c >= extents[a]:
                    inside = False
                row_gap += _row_reach(points[seed, a] - low[a] - cells[seed, a] * cell, step, cell)
                row_key += c * strides[a]
            if not inside or row_gap >= ro2:
                continue
            offset0 = points[seed, 0] - low[0] - cells[seed, 0] * cell
            first = max(cells[seed, 0] - reach, 0)
            last = min(cells[seed, 0] + reach, extents[0] - 1)
            slot = np.searchsorted(cell_keys, row_key + first)
            while slot < len(cell_keys) and cell_keys[slot] <= row_key + last:
                step = cell_keys[slot] - row_key - cells[seed, 0]
                if row_gap + _row_reach(offset0, step, cell) < ro2:
                    # The distances of the cell's points first, in one loop without branches
                    # that LLVM vectorises, then the points within r_o.
                    first_m = cell_starts[slot]
                    for q in range(cell_sizes[slot]):
                        total = 0.0
                        for a in range(d):
                            gap = sorted_points[first_m + q, a] - points[seed, a]
                            total += gap * gap
                        dist2s[q] = total
                    m = first_m
                    while m < cell_starts[slot] + cell_sizes[slot]:
                        dist2 = dist2s[m - first_m]
                        if dist2 >= ro2:
                            m += 1
                            continue
                        for a in range(d):
                            diff[a] = sorted_points[m, a] - points[seed, a]
                        w = sorted_weights[m]
                        counts[s] += w
                        for a in range(d):
                            sums[s, a] += w * diff[a]
                            for b in range(d):
                                scatter[s, a, b] += w * diff[a] * diff[b]
                        if with_scatter:
                            for a in range(d):
                                for b in range(d):
                                    scatter[s, a, b] += point_scatter[sorted_index[m], a, b]
                        if dist2 < ri2:
                            p = sorted_index[m]
                            available[p] = False
                            owner[p] = s
                            # Out of the cell: the cell's last point takes its place.
                            cell_sizes[slot] -= 1
                            tail = cell_starts[slot] + cell_sizes[slot]
                            sorted_index[m] = sorted_index[tail]
                            sorted_index[tail] = p
                            sorted_weights[m] = sorted_weights[tail]
                            dist2s[m - first_m] = dist2s[tail - first_m]
                            for a in range(d):
                                sorted_points[m, a] = sorted_points[tail, a]
                        else:
                            m += 1
                slot += 1
        s += 1
    return seeds[:s].copy(), owner, counts[:s].copy(), sums[:s].copy(), scatter[:s].copy()


def _cell_hash(
    points: np.ndarray, weights: np.ndarray, scatter: np.ndarray, cell: float
) -> tuple[np.ndarray, ...]:
    """Integer cells of side `cell` of (n, d) points, their linear keys (sorted, one per
    cell), where each cell's points start and how many there are, and the points'
    coordinates, rows and weights (n,) cell by cell, and the scatter ((n, d, d), or none) as
    given (the arguments of _quick_means_kernel from `cells` to `point_scatter`), after the
    cells' lower corner (d,) metres."""
    hashed = cell_keys(points, cell)
    distinct, bounds, sorted_index = group_by_key(hashed.keys)
    starts, sizes = bounds[:-1], np.diff(bounds)
    return hashed.low, (
        hashed.cells,
        hashed.strides,
        hashed.extents,
        distinct,
        starts,
        sizes,
        points[sorted_index],
        sorted_index,
        weights[sorted_index],
        scatter,
    )


def quick_means(
    points: np.ndarray,
    r_inner: float,
    r_outer: float,
    min_size: float,
    rng: np.random.Generator,
    weights: np.ndarray | None = None,
    scatter: np.ndarray | None = None,
) -> QuickMeansResult:
    """Cluster (N, d) points, metres, with inner radius r_inner and outer radius r_outer,
    seeds drawn in a random order from `rng` (see quick_means_in_order for the rest)."""
    order = rng.permutation(len(points))
    return quick_means_in_order(points, r_inner, r_outer, min_size, order, weights, scatter)


def quick_means_in_order(
    points: np.ndarray,
    r_inner: float,
    r_outer: float,
    min_size: float,
    order: np.ndarray,
    weights: np.ndarray | None = None,
    scatter: np.ndarray | None = None,
) -> QuickMeansResult:
    """Cluster (N, d) points, metres, with inner radius r_inner and outer radius r_outer,
    drawing seeds in `order` (N,) int64, a permutation of the rows.

    weights: (N,) float64 samples each point stands for (None: one each); scatter: (N, d, d)
    m^2, those samples' scatter about the point (None: none); a cluster is kept when its
    weight reaches min_size. The compiled pass holds no lock: parts of a batch may be
    clustered on threads of their own."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    d = points.shape[1]
    if len(points) == 0:
        empty = np.zeros(0, dtype=np.int64)
        return QuickMeansResult(
            empty, empty, np.zeros(0), np.zeros((0, d)), np.zeros((0, d, d)), np.zeros(0, bool)
        )
    if not 0 < r_inner <= r_outer:
        raise ValueError(f"quick-means needs 0 < r_inner <= r_outer, got {r_inner}, {r_outer}")
    cell = r_outer / CELLS_PER_RADIUS
    weights = np.ones(len(points)) if weights is None else np.asarray(weights, np.float64)
    scatter = np.zeros((0, d, d)) if scatter is None else np.asarray(scatter, np.float64)
    low, hashed = _cell_hash(points, weights, scatter, cell)
    seeds, owner, counts, sums, scatter = _quick_means_kernel(
        points,
        *hashed,
        np.asarray(order, dtype=np.int64),
        float(r_inner),
        float(r_outer),
        cell,
        low,
    )
    means, covariances = _statistics(counts, sums, scatter, points[seeds])
    return QuickMeansResult(seeds, owner, counts, means, covariances, counts >= min_size)


def quick_means_reference(
    points: np.ndarray,
    r_inner: float,
    r_outer: float,
    min_size: float,
    order: np.ndarray,
    weights: np.ndarray | None = None,
    scatter: np.ndarray | None = None,
) -> QuickMeansResult:
    """Plain NumPy quick-means with brute-force distances, for tests of the compiled kernel."""
    n, d = points.shape
    weights = np.ones(n) if weights is None else weights
    scatter = np.zeros((n, d, d)) if scatter is None else scatter
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
        w = weights[members]
        counts.append(w.sum())
        sums.append((w[:, None] * diff[members]).sum(axis=0))
        scatters.append((w[:, None] * diff[members]).T @ diff[members] + scatter[members].sum(0))
    seeds_a = np.array(seeds, dtype=np.int64)
    counts_a = np.array(counts, dtype=np.float64)
    means, covariances = _statistics(counts_a, np.array(sums), np.array(scatters), points[seeds_a])
    return QuickMeansResult(seeds_a, owner, counts_a, means, covariances, counts_a >= min_size)


def kmeans_refine(
    points: np.ndarray,
    result: QuickMeansResult,
    iterations: int,
    weights: np.ndarray | None = None,
    scatter: np.ndarray | None = None,
) -> QuickMeansResult:
    """Lloyd iterations from the kept quick-means clusters; every point joins its nearest.
    weights, scatter: as `quick_means` takes them (None: one sample each, no scatter)."""
    means = result.means[result.kept]
    if iterations == 0 or len(means) == 0:
        return result
    n, d = points.shape
    weights = np.ones(n) if weights is None else weights
    for _ in range(iterations):
        _, owner = cKDTree(means).query(points)
        counts = np.bincount(owner, weights, len(means))
        occupied = counts > 0
        sums = np.stack(
            [np.bincount(owner, weights * points[:, a], len(means)) for a in range(d)], 1
        )
        means = sums[occupied] / counts[occupied, None]
    _, owner = cKDTree(means).query(points)
    counts = np.bincount(owner, weights, len(means))
    diff = points - means[owner]
    outer = weights[:, None] * np.einsum("ni,nj->nij", diff, diff).reshape(n, d * d)
    if scatter is not None:
        outer = outer + scatter.reshape(n, d * d)
    scatter_sums = np.stack(
        [np.bincount(owner, outer[:, c], len(means)) for c in range(d * d)], 1
    ).reshape(-1, d, d)
    _, covariances = _statistics(counts, np.zeros_like(means), scatter_sums, means)
    seeds = np.full(len(means), -1, dtype=np.int64)
    return QuickMeansResult(seeds, owner.astype(np.int64), counts, means, covariances, counts > 0)
