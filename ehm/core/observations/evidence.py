"""Evidence of a batch of scans, gathered per cell before it is learned.

Every ray gives the training samples the paper assumes (ehm.core.observations.samples describes
them): the hit and a point up to `occupied_depth` behind it are occupied, a point in the band in
front of it is free, and free points lie along the ray `free_spacing` apart. Drawn one by one they
are about twelve samples a ray, and every later step paid for each (a LiDAR sweep of 88,000 rays
gave 1.1 million). Here they are not kept: each is added where it falls to the statistics of its
cell and kind (weight, sum and scatter of positions), in one compiled pass over the rays, and a
batch leaves one weighted sample per cell and kind, at the mean of the samples that fell there, with
their scatter about it. Clustering pools the statistics exactly (ehm.core.clustering.quickmeans),
and the loss of a cell's samples is, to first order in the cell's size, the loss of its mean
weighted by their number.

Kinds: occupied samples and free samples in front of hits live in fine cells, free samples
along rays in coarse cells (`cell_sides`). Free samples along a ray are stratified, one in
each `spacing` of its length from a random offset, so a ray of length L gives L / spacing of
them in expectation, as independent draws would, with less noise. The cells are small against
the kernels they train (a quarter of a cluster radius, a third of a free cluster's): cells of
half a radius lost 0.005-0.016 held-out F1 in one batch (BENCHMARKS.md).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from itertools import repeat

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.observations.samples import (
    ScanRays,
    TrainingSamples,
    free_sample_counts,
    learn_box,
    ray_randoms,
    samples_of_rays,
)
from ehm.core.search.cells import packed_cell_keys
from ehm.core.search.hashing import EMPTY_KEY, hash_slot, key_part, table_size
from ehm.errors import InputError

# Kinds of samples, in the order the compiled pass numbers them: free samples along rays (in
# coarse cells), free samples in front of hits and occupied samples (in fine cells).
FREE_ALONG_RAY, FREE_AT_SURFACE, OCCUPIED = 0, 1, 2
# Bits of a cell key that hold the kind.
KIND_BITS = 2
# Cells of each kind across the cluster radius of its kind (`cluster_radius` around hits,
# `free_cluster_radius` along rays): 3 cm and 20 cm at the default 5 cm of detail. Measured
# over three seeds on every data set (BENCHMARKS.md): coarse cells of 30 cm lost 0.027
# held-out F1 on the PCL room scan by scan, 15 cm ones cost 40 % more cells for no gain.
FINE_CELLS_PER_RADIUS = 4
COARSE_CELLS_PER_RADIUS = 3
# A batch of at least PARALLEL_MIN_SAMPLES samples (a sweep of 88,000 rays gives 1.1 million)
# is gathered in GATHER_PARTS parts of its cells (key_part), each on a thread of its own as
# far as there are threads: every part places every sample and keeps those in its cells, in a
# table of its own. The parts do not follow the threads, so a map is the same on any machine.
PARALLEL_MIN_SAMPLES = 100_000
GATHER_PARTS = 2


@dataclass
class _CellTable:
    """Cells met so far: an open-addressing table of keys (ehm.core.search.hashing) pointing into
    value arrays filled in the order cells are met (see gather_kernel for their layout)."""

    keys: np.ndarray
    index: np.ndarray
    weight: np.ndarray
    sums: np.ndarray
    scatter: np.ndarray
    anchor: np.ndarray
    kind: np.ndarray
    used: int = 0

    @classmethod
    def empty(cls, capacity: int, dim: int) -> _CellTable:
        size = table_size(capacity)
        capacity = size // 2
        return cls(
            np.full(size, EMPTY_KEY, dtype=np.int64),
            np.zeros(size, dtype=np.int64),
            np.zeros(capacity),
            np.zeros((capacity, dim)),
            np.zeros((capacity, dim, dim)),
            np.zeros((capacity, dim)),
            np.zeros(capacity, dtype=np.int64),
        )

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(keys, index, weight, sums, scatter, anchor, kind), as the compiled pass takes them."""
        return self.keys, self.index, self.weight, self.sums, self.scatter, self.anchor, self.kind

    def grown(self) -> _CellTable:
        """The same cells in a table of twice the capacity."""
        table = _CellTable.empty(2 * len(self.weight), self.sums.shape[1])
        n = self.used
        for name in ("weight", "sums", "scatter", "anchor", "kind"):
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


@numba.njit(cache=True, inline="always")
def _add_sample(
    point, inv_side, side, kind, half, bits, part, parts, cell, table, used
):  # pragma: no cover - compiled
    """Add `point` (d,) to the statistics of its cell of `kind` in `table` (the arrays of a
    _CellTable, `used` cells filled) when the cell is in `part` of `parts`; returns the cells
    used."""
    keys, index, weight, sums, scatter, anchor, kinds = table
    d = point.shape[0]
    key = np.int64(0)
    for a in range(d):
        cell[a] = np.floor(point[a] * inv_side)
        key = (key << bits) | (np.int64(cell[a]) + half)
    key = (key << KIND_BITS) | kind
    if parts > 1 and key_part(key, parts) != part:
        return used
    s = hash_slot(keys, key)
    if keys[s] == EMPTY_KEY:
        keys[s] = key
        index[s] = used
        for a in range(d):
            anchor[used, a] = cell[a] * side
        kinds[used] = kind
        used += 1
    c = index[s]
    weight[c] += 1.0
    for a in range(d):
        cell[a] = point[a] - anchor[c, a]  # the offset from the cell's anchor
        sums[c, a] += cell[a]
    for a in range(d):
        for b in range(d):
            scatter[c, a, b] += cell[a] * cell[b]
    return used


@numba.njit(cache=True, nogil=True)
def gather_kernel(
    first_ray,
    origins,
    directions,
    lengths,
    hits,
    free_start,
    spacing,
    free_counts,
    random,
    box,
    occupied_depth,
    margin,
    fine_side,
    coarse_side,
    bits,
    part,
    parts,
    table,
    used,
):  # pragma: no cover - compiled
    """Add the samples of rays first_ray, first_ray + 1, ... to the cells of `table`: the
    arrays of a _CellTable (keys, index: the open-addressing table; weight (c,), sums (c, d)
    of offsets from each cell's anchor, scatter (c, d, d) about the anchor, anchor (c, d)
    metres, kinds (c,): values of the cells in the order met, `used` of them so far). Stops
    before a ray whose samples might fill the table over half or the value arrays; returns
    (the next ray, cells used).

    origins (n, d) metres, each ray's start; directions (n, d) unit; lengths (n,) metres to
    each ray's end; hits (n,) bool; free_start (n,) metres: where each ray's free samples
    begin, spacing (n,) metres between them, free_counts (n,) how many; random (n, 3)
    uniforms in [0, 1): depth behind the hit, depth in front, offset of the free samples
    (ehm.core.observations.samples.ray_randoms); box (2, d), or (0, d) for none: samples around hits
    outside it are left out; bits: bits per axis of a key; only the cells of part `part` of
    `parts` (ehm.core.search.hashing.key_part) are kept.
    """
    n, d = directions.shape
    half = np.int64(1) << (bits - 1)
    inv_fine, inv_coarse = 1.0 / fine_side, 1.0 / coarse_side
    capacity = min(len(table[2]), len(table[0]) // 2)
    point = np.empty(d)
    cell = np.empty(d)
    for r in range(first_ray, n):
        if used + 3 + free_counts[r] > capacity:
            return r, used
        if hits[r]:
            depths = (
                lengths[r],
                lengths[r] + occupied_depth * random[r, 0],
                lengths[r] - min(margin * (0.25 + 0.75 * random[r, 1]), lengths[r]),
            )
            for j in range(3):
                inside = True
                for a in range(d):
                    point[a] = origins[r, a] + directions[r, a] * depths[j]
                    if box.shape[0] == 2 and (point[a] < box[0, a] or point[a] > box[1, a]):
                        inside = False
                if inside:
                    kind = FREE_AT_SURFACE if j == 2 else OCCUPIED
                    used = _add_sample(
                        point, inv_fine, fine_side, kind, half, bits, part, parts, cell, table, used
                    )
        for k in range(free_counts[r]):
            t = free_start[r] + (k + random[r, 2]) * spacing[r]
            for a in range(d):
                point[a] = origins[r, a] + directions[r, a] * t
            used = _add_sample(
                point,
                inv_coarse,
                coarse_side,
                FREE_ALONG_RAY,
                half,
                bits,
                part,
                parts,
                cell,
                table,
                used,
            )
    return n, used


def _gather_part(arguments: tuple, part: int, parts: int) -> _CellTable:
    """The cells of part `part` of `parts` (see gather_kernel) of the samples of every ray
    (`arguments`: gather_kernel's from `origins` to `bits`), in a table grown as they fill it."""
    n, dim = arguments[1].shape
    table = _CellTable.empty(n, dim)
    counts = arguments[6]
    ray = 0
    while ray < n:
        if table.used + 3 + counts[ray] > len(table.weight):
            table = table.grown()
        ray, table.used = gather_kernel(ray, *arguments, part, parts, table.arrays(), table.used)
    return table


def cell_sides(config: MapConfig) -> tuple[float, float]:
    """(fine, coarse) cell sides, metres: the cluster radius of their kind over
    FINE_CELLS_PER_RADIUS and COARSE_CELLS_PER_RADIUS."""
    return (
        config.cluster_radius / FINE_CELLS_PER_RADIUS,
        config.free_cluster_radius / COARSE_CELLS_PER_RADIUS,
    )


def gather_evidence(rays: ScanRays, config: MapConfig, rng: np.random.Generator) -> TrainingSamples:
    """The evidence of the `rays` of a batch of scans (ehm.core.observations.samples.scan_rays):
    their training samples, one weighted sample per cell and kind, with its scatter, in the
    order the cells were met (part by part, for a batch gathered in parts)."""
    randoms = ray_randoms(len(rays), rng)
    fine, coarse = cell_sides(config)
    dim = rays.directions.shape[1]
    bits = (63 - KIND_BITS) // dim
    _check_reach(rays, config, fine, bits)
    box = learn_box(config, dim) if config.learn_box else np.zeros((0, dim))
    counts = free_sample_counts(rays, randoms, config.max_free_samples)
    arguments = (
        np.ascontiguousarray(rays.origins),
        rays.directions,
        rays.lengths,
        rays.hits,
        rays.free_start,
        rays.spacing,
        counts,
        randoms,
        box,
        config.occupied_depth,
        config.surface_margin,
        fine,
        coarse,
        bits,
    )
    parts = GATHER_PARTS if counts.sum() + 3 * rays.hits.sum() >= PARALLEL_MIN_SAMPLES else 1
    if parts == 1:
        return _evidence_of_table(_gather_part(arguments, 0, 1))
    with ThreadPoolExecutor(min(parts, numba.get_num_threads())) as pool:
        tables = pool.map(_gather_part, repeat(arguments), range(parts), repeat(parts))
        return TrainingSamples.concatenate([_evidence_of_table(table) for table in tables])


def _evidence_of_table(table: _CellTable) -> TrainingSamples:
    """The weighted samples of the cells of `table`."""
    n = table.used
    return _evidence_of_sums(
        table.weight[:n], table.sums[:n], table.scatter[:n], table.anchor[:n], table.kind[:n]
    )


def _evidence_of_sums(
    weight: np.ndarray, sums: np.ndarray, scatter: np.ndarray, anchor: np.ndarray, kind: np.ndarray
) -> TrainingSamples:
    """Weighted samples from the sums and scatter of offsets from each cell's anchor."""
    local_mean = sums / weight[:, None]
    scatter = scatter - weight[:, None, None] * np.einsum("ni,nj->nij", local_mean, local_mean)
    occupied, at_surface = sample_flags(kind)
    return TrainingSamples(anchor + local_mean, occupied, at_surface, weight, scatter)


def sample_flags(kinds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(occupied, at_surface) (n,) bool of samples of `kinds` (n,) int64."""
    return kinds == OCCUPIED, kinds != FREE_ALONG_RAY


def kinds_of(samples: TrainingSamples) -> np.ndarray:
    """(n,) int64 kind of each sample, from its flags."""
    return np.where(
        samples.occupied, OCCUPIED, np.where(samples.at_surface, FREE_AT_SURFACE, FREE_ALONG_RAY)
    ).astype(np.int64)


def _check_reach(rays: ScanRays, config: MapConfig, side: float, bits: int) -> None:
    """InputError when a sample may lie beyond the cells' reach from the world origin."""
    half = 2.0 ** (bits - 1)
    if len(rays) == 0:
        return
    far = np.abs(rays.origins).max() + rays.lengths.max() + config.occupied_depth
    if far >= (half - 1) * side:
        raise InputError(
            f"a training sample lies up to {far:.0f} m from the world origin, beyond the "
            f"{(half - 1) * side:.0f} m that cells of {side:g} m reach: set max_range "
            "(ehm map --max-range) to cut rays longer than the sensor's"
        )


def evidence_reference(rays: ScanRays, randoms: np.ndarray, config: MapConfig) -> TrainingSamples:
    """Plain NumPy twin of `gather_evidence` for given rays and randoms, from the samples
    ehm.core.observations.samples draws, grouped by cell and kind (in the order of their keys, where
    the compiled pass gives them in the order it meets them)."""
    samples = samples_of_rays(rays, randoms, config)
    kind = kinds_of(samples)
    fine, coarse = cell_sides(config)
    side = np.where(samples.at_surface, fine, coarse)
    keys = packed_cell_keys(samples.points, side, kind, KIND_BITS, "")
    _, cell, weight = np.unique(keys, return_inverse=True, return_counts=True)
    cell = cell.ravel()
    dim = samples.points.shape[1]
    anchor = np.floor(samples.points / side[:, None]) * side[:, None]
    offsets = samples.points - anchor
    sums = np.stack([np.bincount(cell, offsets[:, a], len(weight)) for a in range(dim)], 1)
    outer = np.einsum("ni,nj->nij", offsets, offsets).reshape(len(offsets), -1)
    scatter = np.stack(
        [np.bincount(cell, outer[:, c], len(weight)) for c in range(dim * dim)], 1
    ).reshape(-1, dim, dim)
    first = np.zeros(len(weight), dtype=np.int64)
    first[cell] = np.arange(len(cell))
    return _evidence_of_sums(
        weight.astype(np.float64), sums, scatter, anchor[first], kind[first].astype(np.int64)
    )
