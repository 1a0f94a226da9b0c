"""Evidence of a batch of scans, gathered per cell before it is learned.

Every ray gives the training samples the paper assumes (ehm.core.observations.samples describes
them): the hit and a point up to `occupied_depth` behind it are occupied, a point in the band in
front of it is free, and free points lie along the ray `free_spacing` apart. Drawn one by one they
are about twelve samples a ray, and every later step paid for each (a LiDAR sweep of 88,000 rays
gave 1.1 million). Here they are not kept: each is added where it falls to the statistics of its
cell and kind (weight, sum and scatter of positions), in a compiled pass over the rays (two,
each over half of a large batch's rays, on two threads, their cells then joined), and a batch
leaves one weighted sample per cell and kind, at the mean of the samples that fell there, with
their scatter about it. Clustering pools the statistics exactly (ehm.core.primitives.quickmeans),
and the loss of a cell's samples is, to first order in the cell's size, the loss of its mean
weighted by their number.

Kinds: occupied samples and free samples in front of hits live in fine cells, free samples
along rays in coarse cells (`cell_sides`). Free samples along a ray are stratified, one in
each `spacing` of its length from a random offset, so a ray of length L gives L / spacing of
them in expectation, as independent draws would, with less noise. The cells are small against
the kernels they train (a quarter of a cluster radius, a third of a free cluster's): coarser
cells blur what the kernels learn. With
`surface_pooling`, the samples behind and in front of hits, which fill a slab around the
surface where the hits fill its face, are gathered in cells that many times as wide
(`kind_sides`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from itertools import pairwise, repeat

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.observations.samples import (
    ScanRays,
    TrainingSamples,
    free_sample_counts,
    front_clearances,
    front_depth,
    front_stretches,
    learn_box,
    ray_randoms,
    samples_of_rays,
)
from ehm.core.primitives.cells import packed_cell_keys
from ehm.core.primitives.hashing import EMPTY_KEY, hash_bits, hash_slot, table_size
from ehm.core.sensor.boxes import points_in_box
from ehm.errors import InputError

# Kinds of samples, in the order the compiled pass numbers them: free samples along rays (in
# coarse cells), free samples in front of hits, occupied samples (hits, in fine cells) and
# occupied samples behind hits in cells of their own where they are clustered apart or pooled
# in wider cells (behind_kind; otherwise in the hits' cells, of the kind OCCUPIED).
FREE_ALONG_RAY, FREE_AT_SURFACE, OCCUPIED, OCCUPIED_BEHIND = 0, 1, 2, 3
# Bits of a cell key that hold the kind, and their mask.
KIND_BITS = 2
KIND_MASK = (1 << KIND_BITS) - 1
# Cells of each kind across the cluster radius of its kind (`cluster_radius` around hits,
# `free_cluster_radius` along rays): 3 cm and 20 cm at the default 5 cm of detail; coarser
# cells lose accuracy, finer ones cost cells for no gain.
FINE_CELLS_PER_RADIUS = 4
COARSE_CELLS_PER_RADIUS = 3
# A batch of at least PARALLEL_MIN_SAMPLES samples (a sweep of 88,000 rays gives 1.1 million)
# is gathered in GATHER_PARTS parts of its rays, about as many samples in each, each part in a
# table of its own on a thread of its own as far as there are threads; a cell a later part
# met too (a few, most of them coarse cells along rays) is folded into the earlier part's, and
# the parts' cells follow one another. The parts do not follow the threads, so a map is the
# same on any machine.
PARALLEL_MIN_SAMPLES = 100_000
GATHER_PARTS = 2
# A table starts with a row for every SAMPLES_PER_CELL samples: a scan's samples fill 3-7 per
# cell (OctoMap's sample scan 4.2, a TUM frame 6.7, a street sweep 3.2), so it seldom grows.
SAMPLES_PER_CELL = 3
# Cells gather_kernel remembers having met lately (2^RECENT_BITS; 64 KB, within a core's
# second-level cache).
RECENT_BITS = 12


# The depth of a hit's free sample, compiled for gather_kernel from the one definition its NumPy
# twin uses.
_front_depth = numba.njit(cache=True, inline="always")(front_depth)


def statistics_width(dim: int) -> int:
    """Values a cell keeps (see _CellTable): its weight, the sum of its samples' offsets from
    its corner (dim) and the upper triangle of their scatter about it (dim (dim + 1) / 2)."""
    return 1 + dim + dim * (dim + 1) // 2


@dataclass
class _CellTable:
    """Cells met so far: an open-addressing table of keys (ehm.core.primitives.hashing)
    pointing into rows filled in the order cells are met. Per row: key (c,) int64, which holds
    the cell's corner and kind (cell_corners); stats (c, statistics_width(d)): the weight, the
    sum of the samples' offsets from the corner and the upper triangle of their scatter about it,
    row-major (one cache line or two per sample added)."""

    dim: int
    keys: np.ndarray
    index: np.ndarray
    key: np.ndarray
    stats: np.ndarray
    used: int = 0

    @classmethod
    def empty(cls, capacity: int, dim: int) -> _CellTable:
        size = table_size(capacity)
        capacity = size // 2
        return cls(
            dim,
            np.full(size, EMPTY_KEY, dtype=np.int64),
            np.zeros(size, dtype=np.int64),
            np.zeros(capacity, dtype=np.int64),
            np.zeros((capacity, statistics_width(dim))),
        )

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(keys, index, key, stats), as the compiled passes take them."""
        return self.keys, self.index, self.key, self.stats

    def grown(self) -> _CellTable:
        """The same cells in a table of twice the capacity."""
        table = _CellTable.empty(2 * len(self.key), self.dim)
        n = self.used
        for name in ("key", "stats"):
            getattr(table, name)[:n] = getattr(self, name)[:n]
        table.used = n
        _rehash(self.keys, self.index, table.keys, table.index)
        return table


@numba.njit(cache=True)
def _rehash(keys, index, new_keys, new_index):  # pragma: no cover - compiled
    for s in range(len(keys)):
        if keys[s] != EMPTY_KEY:
            t = hash_slot(new_keys, keys[s])
            new_keys[t] = keys[s]
            new_index[t] = index[s]


@numba.njit(cache=True, nogil=True)
def gather_kernel(
    first_ray,
    last_ray,
    origins,
    directions,
    lengths,
    hits,
    free_start,
    dense_start,
    spacing,
    far_counts,
    dense_counts,
    thinning,
    random,
    box,
    occupied_depth,
    margin,
    front_reach,
    front_stretch,
    front_clearance,
    sides,
    behind_kind,
    bits,
    band,
    table,
    used,
):  # pragma: no cover - compiled
    """Add the samples of rays first_ray, first_ray + 1, ..., last_ray - 1 to the cells of
    `table` (the arrays of a _CellTable, `used` cells filled). Stops before a ray whose samples
    might fill the table over half or its rows; returns (the next ray, cells used).

    origins (n, d) metres, each ray's start; directions (n, d) unit; lengths (n,) metres to
    each ray's end; hits (n,) bool; free_start (n,) metres: where each ray's free samples
    begin, `thinning` spacings (n,) metres apart, far_counts (n,) of them, each of that weight;
    dense_start (n,) metres: where dense_counts (n,) more begin, a spacing apart (see
    ehm.core.observations.samples.free_sample_counts); random (n, 3) uniforms in [0, 1): depth
    behind the hit, depth in front, offset of the free samples
    (ehm.core.observations.samples.ray_randoms); box (2, d), or (0, d) for none: samples around
    hits outside it are left out; front_stretch (n,): how many times as far along its ray each
    hit's free sample lies (ehm.core.observations.samples.front_stretches); front_clearance
    (n,) metres: how much farther still (ehm.core.observations.samples.front_clearances);
    sides (4,) metres: the cell side of each kind (kind_sides); behind_kind: the kind of the
    occupied sample behind each hit (OCCUPIED or OCCUPIED_BEHIND); bits: bits per axis of a key;
    band: metres, free samples along a ray with a hit that lie within it before the hit are of
    the kind FREE_AT_SURFACE (`fine_free_band`).

    Each sample is added where it is made, in one place of this loop: a helper taking the
    table's arrays, called once per sample, is several times slower.
    """
    keys, index, row_key, stats = table
    d = directions.shape[1]
    half = np.int64(1) << (bits - 1)
    capacity = min(len(row_key), len(keys) // 2)
    point = np.empty(d)
    cell = np.empty(d)
    offset = np.empty(d)
    # The key and row of cells met lately, one slot per top bits of the key's hash: a scan's
    # neighbouring rays meet the same cells, and the table, larger than the processor's
    # caches, is not searched for them.
    recent = np.full((2, 1 << RECENT_BITS), EMPTY_KEY, dtype=np.int64)
    for r in range(first_ray, last_ray):
        if used + 3 + far_counts[r] + dense_counts[r] > capacity:
            return r, used
        around_hit = 3 if hits[r] else 0
        for j in range(around_hit + far_counts[r] + dense_counts[r]):
            # The j-th sample of the ray: its depth along the ray, kind, weight and cell side.
            if j < around_hit:
                weight = 1.0
                if j == 0:
                    depth, kind = lengths[r], OCCUPIED
                elif j == 1:
                    depth, kind = lengths[r] + occupied_depth * random[r, 0], behind_kind
                else:
                    front = front_stretch[r] * _front_depth(margin, front_reach, random[r, 1])
                    front += front_clearance[r]
                    depth, kind = lengths[r] - min(front, lengths[r]), FREE_AT_SURFACE
            elif j < around_hit + far_counts[r]:
                k = j - around_hit
                depth = free_start[r] + (k + random[r, 2]) * thinning * spacing[r]
                weight, kind = float(thinning), FREE_ALONG_RAY
            else:
                k = j - around_hit - far_counts[r]
                depth = dense_start[r] + (k + random[r, 2]) * spacing[r]
                weight, kind = 1.0, FREE_ALONG_RAY
            if j >= around_hit and hits[r] and lengths[r] - depth < band:
                kind = FREE_AT_SURFACE
            side = sides[kind]
            inside = True
            key = np.int64(0)
            for a in range(d):
                point[a] = origins[r, a] + directions[r, a] * depth
                if j < around_hit and box.shape[0] == 2:
                    inside &= box[0, a] <= point[a] <= box[1, a]
                cell[a] = np.floor(point[a] / side)
                offset[a] = point[a] - cell[a] * side  # from the cell's corner
                key = (key << bits) | (np.int64(cell[a]) + half)
            if not inside:
                continue
            key = (key << KIND_BITS) | kind
            slot = hash_bits(key, RECENT_BITS)
            if recent[0, slot] == key:
                c = recent[1, slot]
            else:
                s = hash_slot(keys, key)
                if keys[s] == EMPTY_KEY:
                    keys[s] = key
                    index[s] = used
                    row_key[used] = key
                    used += 1
                c = index[s]
                recent[0, slot], recent[1, slot] = key, c
            # The sample's weight, offset from the cell's corner and scatter about it.
            stats[c, 0] += weight
            for a in range(d):
                stats[c, 1 + a] += weight * offset[a]
            v = 1 + d
            for a in range(d):
                for b in range(a, d):
                    stats[c, v] += weight * offset[a] * offset[b]
                    v += 1
    return last_ray, used


def _gather_rays(arguments: tuple, first: int, last: int) -> _CellTable:
    """The cells of the samples of rays first, ..., last - 1 (`arguments`: gather_kernel's from
    `origins` to `band`), in a table grown as they fill it."""
    dim, far, dense = arguments[1].shape[1], arguments[7], arguments[8]
    samples = int(far[first:last].sum() + dense[first:last].sum()) + 3 * (last - first)
    table = _CellTable.empty(samples // SAMPLES_PER_CELL, dim)
    ray = first
    while ray < last:
        if table.used + 3 + far[ray] + dense[ray] > len(table.key):
            table = table.grown()
        ray, table.used = gather_kernel(ray, last, *arguments, table.arrays(), table.used)
    return table


def cell_sides(config: MapConfig) -> tuple[float, float]:
    """(fine, coarse) cell sides, metres: the cluster radius of their kind over
    FINE_CELLS_PER_RADIUS and COARSE_CELLS_PER_RADIUS."""
    return (
        config.cluster_radius / FINE_CELLS_PER_RADIUS,
        config.free_cluster_radius / COARSE_CELLS_PER_RADIUS,
    )


def kind_sides(config: MapConfig) -> np.ndarray:
    """(4,) float64 metres, indexed by kind: the side of its cells. FREE_ALONG_RAY coarse,
    OCCUPIED (hits) fine, FREE_AT_SURFACE and OCCUPIED_BEHIND `surface_pooling` times fine."""
    fine, coarse = cell_sides(config)
    pooled = config.surface_pooling * fine
    return np.array([coarse, pooled, fine, pooled])


def behind_kind(config: MapConfig) -> int:
    """The kind of the occupied samples behind hits: OCCUPIED, in the hits' cells, unless they
    are clustered apart (`cluster_behind_apart`) or `surface_pooling` gathers them in wider
    cells of their own."""
    apart = config.cluster_behind_apart or config.surface_pooling > 1
    return OCCUPIED_BEHIND if apart else OCCUPIED


def gather_evidence(rays: ScanRays, config: MapConfig, rng: np.random.Generator) -> TrainingSamples:
    """The evidence of the `rays` of a batch of scans (ehm.core.observations.samples.scan_rays):
    their training samples, one weighted sample per cell and kind, with its scatter, in the
    order the cells were met, part by part."""
    randoms = ray_randoms(len(rays), rng)
    sides = kind_sides(config)
    dim = rays.directions.shape[1]
    bits = (63 - KIND_BITS) // dim
    _check_reach(rays, config, sides.min(), bits)
    box = learn_box(config, dim) if config.learn_box else np.zeros((0, dim))
    far, dense, dense_start = free_sample_counts(rays, randoms, config)
    arguments = (
        np.ascontiguousarray(rays.origins),
        rays.directions,
        rays.lengths,
        rays.hits,
        rays.free_start,
        dense_start,
        rays.spacing,
        far,
        dense,
        config.free_thinning,
        randoms,
        box,
        config.occupied_depth,
        config.surface_margin,
        config.front_reach,
        front_stretches(rays, config),
        front_clearances(rays, config),
        sides,
        behind_kind(config),
        bits,
        config.fine_free_band * config.free_cluster_radius,
    )
    samples_to = np.cumsum(far + dense + 3 * rays.hits)  # samples of the rays up to each
    total = samples_to[-1] if len(samples_to) else 0
    parts = GATHER_PARTS if total >= PARALLEL_MIN_SAMPLES else 1
    bounds = np.searchsorted(samples_to, total * np.arange(parts + 1) / parts)
    bounds[0], bounds[-1] = 0, len(rays)
    threads = min(parts, numba.get_num_threads())
    with ThreadPoolExecutor(threads) if threads > 1 else nullcontext() as pool:
        run = map if pool is None else pool.map  # one part: no thread to start
        tables = list(run(_gather_rays, repeat(arguments), bounds[:-1], bounds[1:]))
        kept = [np.ones(table.used, dtype=bool) for table in tables]
        for later, table in enumerate(tables[1:], 1):
            for earlier in tables[:later]:
                _fold_into(
                    earlier.keys, earlier.index, earlier.stats, table.key, table.stats, kept[later]
                )
        firsts = np.cumsum([0] + [int(rows.sum()) for rows in kept])
        n = firsts[-1]
        points, weight, scatter = np.empty((n, dim)), np.empty(n), np.empty((n, dim, dim))
        outputs = [
            (points[first:last], weight[first:last], scatter[first:last])
            for first, last in pairwise(firsts)
        ]
        list(run(_cell_samples_of, tables, kept, outputs, repeat((sides, bits))))
    keys = [table.key[: table.used][rows] for table, rows in zip(tables, kept, strict=True)]
    kinds = np.concatenate(keys) & KIND_MASK
    return samples_of_kinds(points, kinds, weight, scatter, config.cluster_behind_apart)


@numba.njit(cache=True, nogil=True)
def _fold_into(
    keys, index, stats, other_key, other_stats, other_kept
):  # pragma: no cover - compiled
    """Add the statistics of the cells of another table (other_key, other_stats, its first
    len(other_kept) rows) that are still kept (other_kept bool) and that a table (its keys,
    index and stats arrays, see _CellTable) holds too to its rows, and keep them no longer:
    the two measure offsets from the same corner."""
    for r in range(len(other_kept)):
        if other_kept[r]:
            s = hash_slot(keys, other_key[r])
            if keys[s] != EMPTY_KEY:
                c = index[s]
                for v in range(stats.shape[1]):
                    stats[c, v] += other_stats[r, v]
                other_kept[r] = False


def _cell_samples_of(
    table: _CellTable,
    kept: np.ndarray,
    outputs: tuple[np.ndarray, np.ndarray, np.ndarray],
    cells: tuple[np.ndarray, int],
) -> None:
    """Write the weighted samples of the `kept` (used,) bool cells of `table` to `outputs`
    (points, weight, scatter; see _cell_samples); cells: the side of each kind's cells (4,),
    metres, and the bits per axis of the table's keys."""
    used = table.used
    corners = np.empty((used, table.dim))
    cell_corners(table.key[:used], *cells, corners)
    _cell_samples(table.stats[:used], corners, kept, *outputs)


@numba.njit(cache=True, nogil=True)
def cell_corners(keys, sides, bits, corners):  # pragma: no cover - compiled
    """Write the low corner, metres, of the cell of each of `keys` (c,) int64 (gather_kernel's:
    `bits` per axis, then the kind; a kind's cells are sides[kind] (4,) metres wide) to
    corners (c, d)."""
    d = corners.shape[1]
    half = np.int64(1) << (bits - 1)
    mask = (np.int64(1) << bits) - 1
    for row in range(len(keys)):
        side = sides[keys[row] & KIND_MASK]
        packed = keys[row] >> KIND_BITS
        for a in range(d - 1, -1, -1):
            corners[row, a] = ((packed & mask) - half) * side
            packed >>= bits


@numba.njit(cache=True, nogil=True)
def _cell_samples(stats, corner, kept, points, weight, scatter):  # pragma: no cover - compiled
    """Write, for each of the cells that are `kept` (c,) bool one after the other, the mean of
    its samples to points (k, d) metres, their number to weight (k,) and their scatter about
    the mean to scatter (k, d, d) m^2, from the cell's row of statistics (see _CellTable) and
    its low corner (c, d)."""
    d = corner.shape[1]
    mean = np.empty(d)
    out = 0
    for row in range(len(kept)):
        if kept[row]:
            w = stats[row, 0]
            weight[out] = w
            for a in range(d):
                mean[a] = stats[row, 1 + a] / w
                points[out, a] = corner[row, a] + mean[a]
            v = 1 + d
            for a in range(d):
                for b in range(a, d):
                    moment = stats[row, v] - w * mean[a] * mean[b]
                    scatter[out, a, b] = scatter[out, b, a] = moment
                    v += 1
            out += 1


def sample_flags(kinds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(occupied, at_surface) (n,) bool of samples of `kinds` (n,) int64."""
    return kinds >= OCCUPIED, kinds != FREE_ALONG_RAY


def samples_of_kinds(
    points: np.ndarray,
    kinds: np.ndarray,
    weight: np.ndarray,
    scatter: np.ndarray | None = None,
    behind_apart: bool = True,
) -> TrainingSamples:
    """Training samples at `points` (n, d), metres, of `kinds` (n,) int64, with `weight` (n,)
    and `scatter` (n, d, d) m^2 or None. Those of the kind OCCUPIED_BEHIND are flagged behind
    where `behind_apart` (MapConfig.cluster_behind_apart); otherwise they are hits gathered in
    wider cells (`surface_pooling`), and the memory keeps them with the hits."""
    occupied, at_surface = sample_flags(kinds)
    behind = (kinds == OCCUPIED_BEHIND) & behind_apart
    return TrainingSamples(points, occupied, at_surface, weight, scatter, behind)


def kinds_of(samples: TrainingSamples) -> np.ndarray:
    """(n,) int64 kind of each sample, from its flags."""
    occupied = np.where(samples.behind, OCCUPIED_BEHIND, OCCUPIED)
    free = np.where(samples.at_surface, FREE_AT_SURFACE, FREE_ALONG_RAY)
    return np.where(samples.occupied, occupied, free).astype(np.int64)


def _check_reach(rays: ScanRays, config: MapConfig, side: float, bits: int) -> None:
    """InputError when a sample may lie beyond the cells' reach from the map's origin (its
    local origin: HilbertMap.local_origin_), naming the cause: a sensor that went too far, or
    rays too long."""
    half = 2.0 ** (bits - 1)
    if len(rays) == 0:
        return
    reach = (half - 1) * side
    sensor = np.abs(rays.origins).max()
    if sensor + config.occupied_depth >= reach:
        raise InputError(
            f"a sensor pose lies {sensor:.0f} m from the map's origin (near its first sensor "
            f"pose), beyond the {reach:.0f} m that cells of {side:g} m reach: map so long a "
            "trajectory in tiles (ehm map --tiles, ehm.tiles.TiledMap)"
        )
    far = sensor + rays.lengths.max() + config.occupied_depth
    if far >= reach:
        raise InputError(
            f"a training sample lies up to {far:.0f} m from the map's origin, beyond the "
            f"{reach:.0f} m that cells of {side:g} m reach, as rays reach "
            f"{rays.lengths.max():.0f} m: set max_range (ehm map --max-range) to cut rays "
            "longer than the sensor's"
        )


def evidence_reference(rays: ScanRays, randoms: np.ndarray, config: MapConfig) -> TrainingSamples:
    """Plain NumPy twin of `gather_evidence` for given rays and randoms, from the samples
    ehm.core.observations.samples draws, grouped by cell and kind (in the order of their keys, where
    the compiled pass gives them in the order it meets them)."""
    samples = samples_of_rays(rays, randoms, config.replace(learn_box=()))
    kind = kinds_of(samples)
    kind[1 : 3 * int(rays.hits.sum()) : 3] = behind_kind(config)  # each hit's second sample
    if config.learn_box:  # the samples around hits outside the box
        box = learn_box(config, rays.directions.shape[1])
        around_hit = np.arange(len(samples)) < 3 * int(rays.hits.sum())
        inside = ~around_hit | points_in_box(samples.points, box)
        samples, kind = samples.subset(inside), kind[inside]
    keys = packed_cell_keys(samples.points, kind_sides(config)[kind], kind, KIND_BITS)
    _, cell = np.unique(keys, return_inverse=True)
    cell = cell.ravel()
    weight = np.bincount(cell, samples.weight)
    dim = samples.points.shape[1]
    means = (
        np.stack([np.bincount(cell, samples.weight * samples.points[:, a]) for a in range(dim)], 1)
        / weight[:, None]
    )
    offsets = samples.points - means[cell]
    outer = np.einsum("n,ni,nj->nij", samples.weight, offsets, offsets).reshape(len(cell), -1)
    scatter = np.stack(
        [np.bincount(cell, outer[:, c], len(weight)) for c in range(dim * dim)], 1
    ).reshape(-1, dim, dim)
    first = np.zeros(len(weight), dtype=np.int64)
    first[cell] = np.arange(len(cell))
    return samples_of_kinds(means, kind[first], weight, scatter, config.cluster_behind_apart)
