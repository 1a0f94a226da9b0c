"""Planes that points lie on: the plane of a batch's hits around each hit (by cells), and of
weighted groups of points.

A group of points lies on a plane when its least spread (the smallest eigenvalue of its
scatter) is a small share of the next and it does not lie on a line: its middle spread is more
than LINEAR_SPREAD of the largest (a post's points, or one ring of a LiDAR's, lie on a line).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.core.primitives.cells import packed_cell_keys
from ehm.core.primitives.eigen import eigen_in_place
from ehm.core.primitives.hashing import EMPTY_KEY, hash_slot, row_table, table_size

# The batch's hits in a cell lie on a plane when there are at least PLANE_HITS of them and their
# least spread is at most HIT_PLANAR_SPREAD of the next (and not on a line).
PLANE_HITS = 6
HIT_PLANAR_SPREAD = 0.1
LINEAR_SPREAD = 0.1
# Cells one thread decomposes at a time, with one set of scratch arrays (made per cell, they
# would cost a good part of the pass).
CHUNK = 1024


@dataclass(frozen=True)
class HitPlanes:
    """The planes of a batch's n hits, each from the hits in its cell. normals (n, d): the
    unit normal of the plane they lie on (PLANE_HITS, HIT_PLANAR_SPREAD), NaN where they lie
    on none; where the cell holds too few hits, or hits on a line, the cell of twice the side
    decides. spreads (n,) metres and axes (n, d) unit: the standard deviation of the cell's
    hits along their axis of least spread, and that axis, in any cell of at least PLANE_HITS
    hits not on a line (planar or not), NaN elsewhere."""

    normals: np.ndarray
    spreads: np.ndarray
    axes: np.ndarray


def hit_planes(hit_points: np.ndarray, side: float) -> HitPlanes:
    """The HitPlanes of a batch's hits (n, d), metres, in cells of `side` metres. Where hits
    lie on a line (a LiDAR's rings a few centimetres apart on a wall a few metres away), the
    cell of twice the side may hold a plane."""
    planes = cell_planes(hit_points, side)
    sparse = np.flatnonzero(planes.sparse)
    if len(sparse):
        # The wider cells are decomposed only where they hold a sparse hit, from all of their
        # hits in the order given: the planes they give are those of the whole batch's.
        n = len(hit_points)
        wide = packed_cell_keys(hit_points, np.full(n, 2.0 * side), np.zeros(n, np.int64), 0)
        deciding = np.flatnonzero(in_cells_of(wide, sparse))
        wider = cell_planes(hit_points[deciding], 2.0 * side)
        planes.normals[sparse] = wider.normals[np.searchsorted(deciding, sparse)]
    return HitPlanes(planes.normals, planes.spreads, planes.axes)


@numba.njit(cache=True, nogil=True)
def in_cells_of(keys, rows):  # pragma: no cover - compiled
    """(n,) bool: whether each of `keys` (n,) int64 >= 0 is the key of one of the `rows`
    (m,) int64."""
    table, _ = row_table(keys[rows])
    inside = np.empty(len(keys), dtype=np.bool_)
    for i in range(len(keys)):
        inside[i] = table[hash_slot(table, keys[i])] != EMPTY_KEY
    return inside


def in_cells_of_reference(keys: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Plain NumPy twin of `in_cells_of`."""
    return np.isin(keys, keys[rows])


@dataclass(frozen=True)
class CellPlanes:
    """For each of n hits, from the hits in its cell: normals (n, d), NaN where they lie on
    no plane; sparse (n,) bool, too few of them or on a line for one; spreads (n,) metres and
    axes (n, d), their least spread and its axis, NaN where sparse."""

    normals: np.ndarray
    sparse: np.ndarray
    spreads: np.ndarray
    axes: np.ndarray


def cell_planes(hit_points: np.ndarray, side: float) -> CellPlanes:
    """The CellPlanes of hits (n, d), metres, in cells of `side` metres."""
    n = len(hit_points)
    if n == 0:
        empty = np.full(hit_points.shape, np.nan)
        return CellPlanes(empty, np.zeros(0, dtype=bool), np.zeros(0), empty.copy())
    keys = packed_cell_keys(hit_points, np.full(n, side), np.zeros(n, dtype=np.int64), 0)
    return CellPlanes(
        *_cell_planes_kernel(hit_points, keys, PLANE_HITS, HIT_PLANAR_SPREAD, LINEAR_SPREAD)
    )


@numba.njit(cache=True, parallel=True)
def _cell_planes_kernel(points, keys, min_hits, planar, linear):  # pragma: no cover - compiled
    """cell_planes of points (n, d) in the cells of keys (n,) int64 >= 0: each cell's points
    found through a table of its key (ehm.core.primitives.hashing), their offsets from the cell's
    first point summed with their outer products in one pass; where a cell holds at least
    `min_hits`, the eigen decomposition of its scatter gives its unit normal where the least
    spread is at most `planar` of the next, and it lies on a line where the middle spread is
    at most `linear` of the largest; elsewhere, its least spread (standard deviation) and axis.
    Returns per point (normals, sparse, spreads, axes)."""
    n, d = points.shape
    table = np.full(table_size(n), EMPTY_KEY, dtype=np.int64)
    rows = np.zeros(len(table), dtype=np.int64)
    cell = np.empty(n, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    cells = 0
    for i in range(n):
        s = hash_slot(table, keys[i])
        if table[s] == EMPTY_KEY:
            table[s] = keys[i]
            rows[s] = cells
            first[cells] = i
            cells += 1
        cell[i] = rows[s]
    count = np.zeros(cells, dtype=np.int64)
    sums = np.zeros((cells, d))
    outer = np.zeros((cells, d, d))
    offset = np.empty(d)
    for i in range(n):
        c = cell[i]
        count[c] += 1
        for a in range(d):
            offset[a] = points[i, a] - points[first[c], a]
            sums[c, a] += offset[a]
        for a in range(d):
            for b in range(d):
                outer[c, a, b] += offset[a] * offset[b]
    normals = np.full((cells, d), np.nan)
    least = np.full((cells, d), np.nan)
    spreads = np.full(cells, np.nan)
    sparse = np.zeros(cells, dtype=np.bool_)
    for chunk in numba.prange((cells + CHUNK - 1) // CHUNK):
        scatter, spread, axes = np.empty((d, d)), np.empty(d), np.empty((d, d))
        for c in range(chunk * CHUNK, min((chunk + 1) * CHUNK, cells)):
            if count[c] < min_hits:
                sparse[c] = True
                continue
            for a in range(d):
                for b in range(d):
                    scatter[a, b] = outer[c, a, b] - sums[c, a] * sums[c, b] / count[c]
            axes[:] = 0.0
            eigen_in_place(scatter, spread, axes)
            if spread[1] <= linear * spread[d - 1]:
                sparse[c] = True
                continue
            spreads[c] = np.sqrt(max(spread[0], 0.0) / count[c])
            for a in range(d):
                least[c, a] = axes[a, 0]
            if spread[0] <= planar * spread[1]:
                for a in range(d):
                    normals[c, a] = axes[a, 0]
    hit_normals = np.empty((n, d))
    hit_axes = np.empty((n, d))
    hit_spreads = np.empty(n)
    hit_sparse = np.empty(n, dtype=np.bool_)
    for i in numba.prange(n):
        c = cell[i]
        hit_sparse[i] = sparse[c]
        hit_spreads[i] = spreads[c]
        for a in range(d):
            hit_normals[i, a] = normals[c, a]
            hit_axes[i, a] = least[c, a]
    return hit_normals, hit_sparse, hit_spreads, hit_axes


def cell_planes_reference(hit_points: np.ndarray, side: float) -> CellPlanes:
    """Plain NumPy twin of `cell_planes`."""
    n = len(hit_points)
    keys = packed_cell_keys(hit_points, np.full(n, side), np.zeros(n, dtype=np.int64), 0)
    _, cell, counts = np.unique(keys, return_inverse=True, return_counts=True)
    spread, axes = group_spreads(hit_points, cell, np.ones(n))
    sparse = (counts < PLANE_HITS) | _on_a_line(spread)
    normals = plane_normals(spread, axes, HIT_PLANAR_SPREAD)
    normals[sparse] = np.nan
    least = np.sqrt(np.maximum(spread[:, 0], 0.0) / counts)
    least[sparse] = np.nan
    least_axes = np.where(sparse[:, None], np.nan, axes[:, :, 0])
    return CellPlanes(normals[cell], sparse[cell], least[cell], least_axes[cell])


def group_spreads(
    points: np.ndarray, group: np.ndarray, weight: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The spread of the (n, d) points of each group (group (n,) int64, 0 .. G - 1, each met),
    weighted by weight (n,): the eigenvalues of their scatter, ascending (G, d), and its unit
    eigenvectors, one a column (G, d, d)."""
    d, size = points.shape[1], group.max() + 1
    total = np.bincount(group, weight, size)
    means = np.stack([np.bincount(group, weight * p, size) for p in points.T], axis=1)
    offsets = points - (means / total[:, None])[group]
    scatter = np.empty((size, d, d))
    for a in range(d):
        for b in range(d):
            scatter[:, a, b] = np.bincount(group, weight * offsets[:, a] * offsets[:, b], size)
    return np.linalg.eigh(scatter)


def _on_a_line(spread: np.ndarray) -> np.ndarray:
    """(G,) bool: spreads (G, d) whose middle one is at most LINEAR_SPREAD of the largest (a
    post's points, or one ring of a LiDAR's)."""
    return spread[:, 1] <= LINEAR_SPREAD * spread[:, -1]


def plane_normals(spread: np.ndarray, axes: np.ndarray, planar_spread: float) -> np.ndarray:
    """(G, d): the axis of least spread of each group (spread (G, d), axes (G, d, d) from
    `group_spreads`) where it is at most `planar_spread` of the next and the group is not on a
    line; NaN elsewhere."""
    flat = (spread[:, 0] <= planar_spread * spread[:, 1]) & ~_on_a_line(spread)
    return np.where(flat[:, None], axes[:, :, 0], np.nan)
