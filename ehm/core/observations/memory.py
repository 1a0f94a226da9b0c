"""What a map keeps of past evidence so that learning scan by scan does not forget: per cell and
kind of ehm.core.observations.evidence, the weight of the samples that fell there and their mean.

Stochastic gradient steps over one batch pull the weights it reaches towards that batch's
view. With the memory, each batch is learned together with the past evidence of the places it
reaches, in the proportions in which it was seen, as learning all scans in one batch would:
the replay. From the cells around hits comes as much weight as the batch has there, from cells
along rays the rest (ratio times the batch's own), each cell in proportion to what it has
seen. Every batch's rays cross open space that earlier ones crossed too: in proportion alone
the replay would be far more free samples along rays than the scans hold, moving the occupied
boundary into free space.

Evidence that formed no cluster when it came (its quick-means seed gathered too little) waits
in the memory and joins the clustering again when a later batch brings evidence to its cell,
so sparse scans (a 2D laser's 180 rays) build the clusters their evidence could not build
alone.

The cells the replay and the waiting evidence are drawn from are the regions a batch reaches:
cells of the cluster radius of each kind (`cluster_radius` around hits, `free_cluster_radius`
along rays), each holding FINE_CELLS_PER_RADIUS (COARSE_CELLS_PER_RADIUS) evidence cells along
every axis. An entry's key (ehm.core.observations.memory_keys) is its region's, then its kind,
then its cell within the region (REGION_BITS, one byte), so the entries of a region are one run
of sorted keys, and the memory keeps each region's key once with how many entries it holds.
Per entry, about 11 bytes in 3D: its kind and cell in the region (one byte), its share of its
region's key and count, the weight seen (float32), the mean's place in its cell (a byte per
axis, in 1/255 of the side: 0.1 mm in a 3 cm cell, 0.8 mm in a 20 cm one) and whether it
formed part of a cluster.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.observations.evidence import (
    KIND_BITS,
    OCCUPIED,
    cell_sides,
    kinds_of,
    sample_flags,
    samples_of_kinds,
)
from ehm.core.observations.memory_keys import (
    REGION_BITS,
    SUB_BITS,
    cell_corner,
    cell_corners,
    cell_corners_reference,
    key_sides,
    memory_keys,
    reached_regions,
)
from ehm.core.observations.samples import TrainingSamples
from ehm.core.primitives.hashing import row_of, row_table, sorted_distinct

# Steps of an entry's place along each side of its cell.
OFFSET_STEPS = 255
# Least weight an entry keeps: evidence retracted below it is dropped.
MIN_WEIGHT = 0.01
# Bits of an entry's flags.
CLUSTERED, PASSED = 1, 2


def _find(sorted_keys: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """(n,) int64 row of each of `keys` in `sorted_keys`, -1 where it is not there."""
    found = np.full(len(keys), -1, dtype=np.int64)
    position = np.searchsorted(sorted_keys, keys)
    inside = np.flatnonzero(position < len(sorted_keys))
    hit = inside[sorted_keys[position[inside]] == keys[inside]]
    found[hit] = position[hit]
    return found


def _in_ranges(keys: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(m,) int64 rows of sorted `keys` inside any of the ranges [low, high)."""
    start, stop = np.searchsorted(keys, low), np.searchsorted(keys, high)
    lengths = stop - start
    return np.repeat(start - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())


@numba.njit(cache=True, nogil=True)
def visit_rows(
    table_keys, table_rows, region_first, region_sizes, cells, keys, reached
):  # pragma: no cover - compiled
    """Where a batch falls in a memory (its regions' table, EvidenceMemory.region_table;
    region_first (R,), region_sizes (R,) and cells (m,) from it): keys (n,) int64 of the
    batch's cells, reached (k,) int64 regions around them (reached_regions). Returns (entries
    (n,) int64, the row of each key's entry, -1 where there is none; near (c,) int64 sorted,
    the rows of every entry in the reached regions)."""
    entries = np.full(len(keys), -1, dtype=np.int64)
    for i in range(len(keys)):
        r = row_of(table_keys, table_rows, keys[i] >> REGION_BITS)
        if r < 0:
            continue
        cell = keys[i] & ((1 << REGION_BITS) - 1)
        for e in range(region_first[r], region_first[r] + region_sizes[r]):
            if cells[e] >= cell:
                if cells[e] == cell:
                    entries[i] = e
                break
    marked = np.zeros(len(region_sizes), dtype=np.bool_)
    count = 0
    for region in reached:
        r = row_of(table_keys, table_rows, region)
        if r >= 0 and not marked[r]:
            marked[r] = True
            count += region_sizes[r]
    near = np.empty(count, dtype=np.int64)
    k = 0
    for r in range(len(region_sizes)):
        if marked[r]:
            for e in range(region_first[r], region_first[r] + region_sizes[r]):
                near[k] = e
                k += 1
    return entries, near


def visit_rows_reference(
    memory_keys: np.ndarray, keys: np.ndarray, reached: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `visit_rows`, from the memory's sorted keys (m,) int64."""
    low = np.unique(reached) << REGION_BITS
    return _find(memory_keys, keys), _in_ranges(memory_keys, low, low + (1 << REGION_BITS))


@numba.njit(cache=True)
def region_layout(keys):  # pragma: no cover - compiled
    """Sorted keys (n,) int64, one per entry, as the memory keeps them: the distinct regions
    (R,) int64 (keys shifted right by REGION_BITS), the entries of each (R,) uint8 and each
    entry's cell in its region (n,) uint8 (the key's low REGION_BITS)."""
    n = len(keys)
    count = 0
    for i in range(n):
        count += i == 0 or keys[i] >> REGION_BITS != keys[i - 1] >> REGION_BITS
    regions = np.empty(count, dtype=np.int64)
    sizes = np.zeros(count, dtype=np.uint8)
    cells = np.empty(n, dtype=np.uint8)
    r = -1
    for i in range(n):
        region = keys[i] >> REGION_BITS
        if i == 0 or region != regions[r]:
            r += 1
            regions[r] = region
        sizes[r] += 1
        cells[i] = keys[i] & ((1 << REGION_BITS) - 1)
    return regions, sizes, cells


def region_layout_reference(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plain NumPy twin of `region_layout`."""
    regions, sizes = np.unique(keys >> REGION_BITS, return_counts=True)
    return regions, sizes.astype(np.uint8), (keys & (2**REGION_BITS - 1)).astype(np.uint8)


# Parts a merge, and a batch's sums per cell, are split into by ranges of keys, for the
# threads to share.
MERGE_PARTS = 8


@numba.njit(cache=True, parallel=True)
def merge_entries(
    keys, weight, place, flags, new_keys, new_weight, place_sums, formed
):  # pragma: no cover - compiled
    """The entries (keys (m,) sorted, weight (m,) float32, place (m, d) uint8, flags (m,)
    uint8) with new evidence added: new_keys (n,) sorted distinct, new_weight (n,) its weight
    (> 0), place_sums (n, d) the sum of weight times place of its samples (in OFFSET_STEPS),
    formed (n,) bool. An entry given new evidence is CLUSTERED where it formed part of a
    cluster before or now, and no longer PASSED. Returns the four arrays, with an entry for
    every key but those of weight 0 (all their evidence taken back or faded) that get no new
    evidence. The keys are merged in MERGE_PARTS ranges side by side: part p takes the entries
    from row p m / MERGE_PARTS on and the new keys from the first not below that row's key."""
    m, n, d = len(keys), len(new_keys), place.shape[1]
    first_old = np.zeros(MERGE_PARTS + 1, dtype=np.int64)
    first_new = np.zeros(MERGE_PARTS + 1, dtype=np.int64)
    for p in range(1, MERGE_PARTS):
        first_old[p] = p * m // MERGE_PARTS
        # An empty memory: every new key to the first part.
        first_new[p] = n if m == 0 else np.searchsorted(new_keys, keys[first_old[p]])
    first_old[MERGE_PARTS], first_new[MERGE_PARTS] = m, n
    sizes = np.zeros(MERGE_PARTS + 1, dtype=np.int64)
    for p in numba.prange(MERGE_PARTS):
        i, end = first_old[p], first_old[p + 1]
        size = 0
        for j in range(first_new[p], first_new[p + 1]):
            while i < end and keys[i] < new_keys[j]:
                size += weight[i] != 0.0
                i += 1
            if i < end and keys[i] == new_keys[j]:
                i += 1
            size += 1
        for rest in range(i, end):
            size += weight[rest] != 0.0
        sizes[p + 1] = size
    out_first = np.cumsum(sizes)
    out_keys = np.empty(out_first[-1], dtype=np.int64)
    out_weight = np.empty(out_first[-1], dtype=np.float32)
    out_place = np.empty((out_first[-1], d), dtype=np.uint8)
    out_flags = np.empty(out_first[-1], dtype=np.uint8)
    for p in numba.prange(MERGE_PARTS):
        i, end = first_old[p], first_old[p + 1]
        j, new_end = first_new[p], first_new[p + 1]
        o = out_first[p]
        while i < end or j < new_end:
            take_new = i == end or (j < new_end and new_keys[j] <= keys[i])
            if not take_new and weight[i] == 0.0:  # emptied, and nothing new comes to it
                i += 1
                continue
            old_w = 0.0
            if i < end and (not take_new or keys[i] == new_keys[j]):
                out_keys[o] = keys[i]
                out_weight[o] = weight[i]
                for a in range(d):
                    out_place[o, a] = place[i, a]
                out_flags[o] = flags[i]
                old_w = np.float64(weight[i])
                i += 1
            else:
                out_keys[o] = new_keys[j]
                out_flags[o] = 0
            if take_new:
                total = old_w + new_weight[j]
                for a in range(d):
                    value = np.rint((old_w * out_place[o, a] + place_sums[j, a]) / total)
                    out_place[o, a] = min(max(value, 0.0), OFFSET_STEPS)
                out_weight[o] = total
                out_flags[o] = (out_flags[o] & CLUSTERED) | (CLUSTERED if formed[j] else 0)
                j += 1
            o += 1
    return out_keys, out_weight, out_place, out_flags


@numba.njit(cache=True, parallel=True)
def batch_entries(
    keys, order, weight, points, clustered, fine_side, coarse_side
):  # pragma: no cover - compiled
    """A batch's evidence per memory cell: keys (n,) sorted, the cell of each sample in
    `order` (n,) int64 (rows of weight (n,), points (n, d) metres and clustered (n,) bool).
    Returns the distinct keys (c,), the weight of each (c,), the sum of weight times place of
    its samples (c, d) (in OFFSET_STEPS of the cell's side from its corner) and whether any of
    them formed part of a cluster (c,) bool: merge_entries' new evidence. The keys are summed
    in MERGE_PARTS ranges side by side, each from a change of key on, so a cell's samples are
    added in their order in one range."""
    n, d = points.shape
    first = np.empty(MERGE_PARTS + 1, dtype=np.int64)
    for p in range(MERGE_PARTS):
        t = p * n // MERGE_PARTS
        while 0 < t < n and keys[t] == keys[t - 1]:
            t += 1
        first[p] = t
    first[MERGE_PARTS] = n
    counts = np.zeros(MERGE_PARTS + 1, dtype=np.int64)
    for p in numba.prange(MERGE_PARTS):
        for t in range(first[p], first[p + 1]):
            counts[p + 1] += t == 0 or keys[t] != keys[t - 1]
    cell_first = np.cumsum(counts)
    cells = cell_first[-1]
    new_keys = np.empty(cells, dtype=np.int64)
    new_weight = np.zeros(cells)
    place_sums = np.zeros((cells, d))
    formed = np.zeros(cells, dtype=np.bool_)
    for p in numba.prange(MERGE_PARTS):
        c = cell_first[p] - 1
        for t in range(first[p], first[p + 1]):
            if t == 0 or keys[t] != keys[t - 1]:
                c += 1
                new_keys[c] = keys[t]
            i = order[t]
            new_weight[c] += weight[i]
            for a in range(d):
                place_sums[c, a] += weight[i] * points[i, a]
            formed[c] |= clustered[i]
        corner = np.empty(d)
        for c in range(cell_first[p], cell_first[p + 1]):
            steps = OFFSET_STEPS / cell_corner(new_keys[c], fine_side, coarse_side, corner)
            for a in range(d):
                place_sums[c, a] = (place_sums[c, a] - new_weight[c] * corner[a]) * steps
    return new_keys, new_weight, place_sums, formed


def batch_entries_reference(
    keys: np.ndarray,
    order: np.ndarray,
    weight: np.ndarray,
    points: np.ndarray,
    clustered: np.ndarray,
    fine_side: float,
    coarse_side: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Plain NumPy twin of `batch_entries`."""
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    new_keys = keys[starts]
    weight = weight[order]
    w = np.add.reduceat(weight, starts)
    sums = np.add.reduceat(weight[:, None] * points[order], starts)
    corners = cell_corners_reference(new_keys, points.shape[1], (fine_side, coarse_side))
    steps = OFFSET_STEPS / key_sides(new_keys, (fine_side, coarse_side))
    formed = np.logical_or.reduceat(clustered[order], starts)
    return new_keys, w, (sums - w[:, None] * corners) * steps[:, None], formed


def merge_entries_reference(
    keys: np.ndarray,
    weight: np.ndarray,
    place: np.ndarray,
    flags: np.ndarray,
    new_keys: np.ndarray,
    new_weight: np.ndarray,
    place_sums: np.ndarray,
    formed: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Plain NumPy twin of `merge_entries`."""
    missing = ~np.isin(new_keys, keys)
    position = np.searchsorted(keys, new_keys[missing])
    keys = np.insert(keys, position, new_keys[missing])
    weight = np.insert(weight, position, 0.0)
    place = np.insert(place, position, 0, axis=0)
    flags = np.insert(flags, position, 0)
    rows = np.searchsorted(keys, new_keys)
    old_w = weight[rows].astype(np.float64)
    total = old_w + new_weight
    value = np.rint((old_w[:, None] * place[rows] + place_sums) / total[:, None])
    place[rows] = np.clip(value, 0.0, OFFSET_STEPS)
    weight[rows] = total
    flags[rows] = (flags[rows] & CLUSTERED) | np.where(formed, CLUSTERED, 0).astype(np.uint8)
    kept = weight != 0.0
    return keys[kept], weight[kept], place[kept], flags[kept]


def threshold_draw(
    weight: np.ndarray, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """`count` of (n > count,) positive weights, each row standing for its own weight in
    expectation: rows of at least a threshold keep their weight, and the lighter ones are
    drawn by systematic resampling, the threshold apart along their running sum from one
    random offset, each drawn one standing for the threshold; the threshold is the one that
    leaves `count` rows (heavy_threshold). Returns (rows (k,) int64 sorted, k = count but for
    a light row that rounding gives two draws, the weight (k,) each stands for); their sum is
    the weights'."""
    threshold, heavy = heavy_threshold(weight, count)
    drawn = count - np.count_nonzero(heavy)
    # Draws at (offset + j) t, j < drawn: those below each light row's running sum, less
    # those below the row before's, fell on it.
    running = np.cumsum(np.where(heavy, 0.0, weight)) / threshold - rng.random()
    below = np.clip(np.ceil(running), 0, drawn).astype(np.int64)
    draws = np.diff(below, prepend=0)
    stands_for = np.where(heavy, weight, draws * threshold)
    rows = np.flatnonzero(stands_for > 0)
    return rows, stands_for[rows]


def heavy_threshold(weight: np.ndarray, count: int) -> tuple[float, np.ndarray]:
    """The threshold t of (n > count,) positive weights at which the rows of at least t and
    the lighter ones' total in steps of t make `count`: (t, (n,) bool the rows of at least t).
    Found from above: t starts at the mean per row kept, and each row at or above it is taken
    out of the total it shares, which lowers t, until no lighter row reaches it."""
    total = weight.sum()
    threshold = total / count
    heavy = weight >= threshold
    while True:
        threshold = (total - weight[heavy].sum()) / (count - np.count_nonzero(heavy))
        reached = weight >= threshold
        if np.array_equal(reached, heavy):
            return float(threshold), heavy
        heavy = reached


@dataclass(frozen=True)
class Visit:
    """Where a batch of evidence falls in a memory. samples: the batch; keys: (n,) int64 the
    key of each sample's cell; entries: (n,) int64 row of that cell's entry, -1 where the
    memory has none yet; near: (c,) int64 rows of the entries, of any kind, in the cells the
    batch reaches; memory_keys: (m,) int64 the key of every entry of the memory visited."""

    samples: TrainingSamples
    keys: np.ndarray
    entries: np.ndarray
    near: np.ndarray
    memory_keys: np.ndarray


@dataclass(frozen=True)
class Retraction:
    """Evidence taken back from a memory: entries (k,) int64, and the weight of each before
    and after (k,) float64."""

    entries: np.ndarray
    before: np.ndarray
    after: np.ndarray


@dataclass(frozen=True)
class PendingSamples:
    """Past evidence that formed no cluster yet, in the cells a batch reaches: samples, and
    entries (p,) int64, the memory's row of each."""

    samples: TrainingSamples
    entries: np.ndarray


class EvidenceMemory:
    """Past evidence of a map, one weighted mean per cell and kind (ehm.core.observations.evidence);
    an empty memory that keeps nothing when `enabled` is False.

    Entries are sorted by key and kept region by region: regions (R,) int64 sorted, the key of
    each region holding entries shifted right by REGION_BITS, region_sizes (R,) uint8 its
    entries (at most 128: two kinds in 64 cells around hits, one in 27 along rays), cells (n,)
    uint8 each entry's kind and cell in its region (the low REGION_BITS of its key). weight (n,)
    float32; place (n, d) uint8, the mean's offset from its cell's corner in OFFSET_STEPS of the
    cell's side; flags (n,) uint8: CLUSTERED, the entry formed part of a cluster; PASSED,
    rays passed through it in an earlier batch (ehm.core.observations.passes) and it has had
    no new evidence since. seen (R,) float64, seconds, when `timed` (for MapConfig.forget_after;
    else empty): the time stamp of the latest batch that brought each region evidence, NaN when
    none had one.
    """

    def __init__(
        self, dim: int, enabled: bool, sides: tuple[float, float], timed: bool = False
    ) -> None:
        self.dim = dim
        self.enabled = enabled
        self.timed = timed
        self.sides = (float(sides[0]), float(sides[1]))
        self.regions = np.zeros(0, dtype=np.int64)
        self.region_sizes = np.zeros(0, dtype=np.uint8)
        self.cells = np.zeros(0, dtype=np.uint8)
        self.weight = np.zeros(0, dtype=np.float32)
        self.place = np.zeros((0, dim), dtype=np.uint8)
        self.flags = np.zeros(0, dtype=np.uint8)
        self.seen = np.zeros(0)
        self._forget_region_table()

    @classmethod
    def of_config(cls, dim: int, config: MapConfig) -> EvidenceMemory:
        """An empty memory for a dim-dimensional map with `config`'s settings."""
        return cls(dim, config.keep_evidence, cell_sides(config), config.forget_after is not None)

    def __len__(self) -> int:
        """Entries kept."""
        return len(self.cells)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays().values())

    def region_first(self) -> np.ndarray:
        """(R,) int64: the row of each region's first entry."""
        return np.cumsum(self.region_sizes, dtype=np.int64) - self.region_sizes

    def region_table(self) -> tuple[np.ndarray, np.ndarray]:
        """The table (ehm.core.primitives.hashing.row_table) that finds each region's row from its
        key shifted right by REGION_BITS; made once for the regions as they stand, for a
        batch's visit and its passes alike."""
        if self._table_of is not self.regions:
            self._table, self._table_of = row_table(self.regions), self.regions
        return self._table

    def _forget_region_table(self) -> None:
        """Let go of the regions' table: it is kept from a batch's visit to its insert only."""
        self._table: tuple[np.ndarray, np.ndarray] = (np.zeros(0, np.int64),) * 2
        self._table_of: np.ndarray | None = None

    def keys(self) -> np.ndarray:
        """(n,) int64 sorted: the key of every entry."""
        regions = np.repeat(self.regions, self.region_sizes)
        return (regions << REGION_BITS) | self.cells

    def region_keys(self, samples: TrainingSamples) -> np.ndarray:
        """(n,) int64: the region of this memory's cells that each of `samples` falls in, and
        its kind; a region is a cluster radius wide around hits, a free cluster radius along
        rays."""
        return memory_keys(samples.points, kinds_of(samples), self.sides) >> SUB_BITS

    def _keep_keys(self, keys: np.ndarray) -> None:
        """Keep sorted `keys` (n,) int64, one per entry, region by region."""
        self.regions, self.region_sizes, self.cells = region_layout(keys)
        self._forget_region_table()

    # -------------------------------------------------------------- learning
    def visit(self, samples: TrainingSamples) -> Visit:
        """Where `samples` fall in this memory: the start of every step below."""
        none = np.zeros(0, dtype=np.int64)
        if not self.enabled:
            return Visit(samples, none, np.full(len(samples), -1, dtype=np.int64), none, none)
        keys = memory_keys(samples.points, kinds_of(samples), self.sides)
        if len(self) == 0:
            return Visit(samples, keys, np.full(len(samples), -1, dtype=np.int64), none, none)
        n = len(samples)
        # The regions of both kinds around every sample.
        points = np.concatenate([samples.points, samples.points])
        reached = reached_regions(points, np.repeat([False, True], n), self.sides)
        table_keys, table_rows = self.region_table()
        entries, near = visit_rows(
            table_keys,
            table_rows,
            self.region_first(),
            self.region_sizes,
            self.cells,
            keys,
            reached,
        )
        return Visit(samples, keys, entries, near, self.keys())

    def pending(self, visit: Visit) -> PendingSamples:
        """The entries that formed no cluster yet, in the cells of the visit's samples (none
        whose evidence was all retracted)."""
        entries = sorted_distinct(visit.entries[visit.entries >= 0])
        entries = entries[(self.flags[entries] & CLUSTERED == 0) & (self.weight[entries] > 0)]
        return PendingSamples(self._samples_at(entries, visit.memory_keys), entries)

    def mark_clustered(self, pending: PendingSamples, clustered: np.ndarray) -> None:
        """Record which `pending` entries ((p,) bool `clustered`) now formed clusters."""
        self.flags[pending.entries[clustered]] |= CLUSTERED

    def replay(
        self,
        ratio: float,
        visit: Visit,
        cap: float | None = None,
        rng: np.random.Generator | None = None,
    ) -> TrainingSamples:
        """The entries near the visit's samples as weighted samples: those around hits weigh
        `ratio` times the visit's weight there in all, those along rays the rest of ratio times
        the visit's weight (all to one group when the other has no entries near), each entry
        in proportion to the weight it has seen. With `cap`, at most cap times as many as the
        visit's samples, drawn from `rng` in proportion to their weight (threshold_draw)."""
        samples = visit.samples
        near = visit.near
        if len(near) == 0 or ratio == 0:
            return self._samples_at(near[:0], visit.memory_keys)
        _, groups = sample_flags((visit.memory_keys[near] >> SUB_BITS) & (2**KIND_BITS - 1))
        seen = self.weight[near].astype(np.float64)
        total = ratio * samples.weight.sum()
        at_surface_total = ratio * samples.weight[samples.at_surface].sum()
        weight = np.zeros(len(near))
        in_group = [groups & (seen > 0), ~groups & (seen > 0)]
        if not (in_group[0].any() and in_group[1].any()):
            weight = total * seen / max(seen.sum(), np.finfo(float).tiny)
        else:
            shares = (at_surface_total, total - at_surface_total)
            for rows, share in zip(in_group, shares, strict=True):
                weight[rows] = share * seen[rows] / seen[rows].sum()
        kept = np.flatnonzero(weight > 0)
        weight = weight[kept]
        if cap is not None and len(kept) > cap * len(samples):
            if rng is None:
                raise ValueError("a replay with a cap draws its entries: give it rng")
            drawn, weight = threshold_draw(weight, max(1, int(cap * len(samples))), rng)
            kept = kept[drawn]
        replayed = self._samples_at(near[kept], visit.memory_keys)
        return TrainingSamples(
            replayed.points, replayed.occupied, replayed.at_surface, weight, None, replayed.behind
        )

    def insert(self, visit: Visit, clustered: np.ndarray, time: float = np.nan) -> None:
        """Add the visit's samples to the memory; clustered: (n,) bool, each formed part of a
        cluster; time: seconds, the batch's time stamp, which the regions it reaches keep as
        seen (NaN: none)."""
        samples = visit.samples
        if not self.enabled or len(samples) == 0:
            return
        # A batch's samples lie one to a cell and kind (ehm.core.observations.evidence): their
        # keys are distinct, and a sort that is not stable serves (faster than a stable one);
        # where keys repeat, their sums do not depend on the order.
        order = np.argsort(visit.keys)
        new_keys, w, place_sums, formed = batch_entries(
            visit.keys[order],
            order,
            samples.weight,
            np.ascontiguousarray(samples.points),
            clustered,
            *self.sides,
        )
        keys, self.weight, self.place, self.flags = merge_entries(
            visit.memory_keys,
            self.weight,
            self.place,
            self.flags,
            new_keys,
            w,
            place_sums,
            formed,
        )
        regions = self.regions
        self._keep_keys(keys)
        if self.timed:
            self._keep_seen(regions, new_keys >> REGION_BITS, time)

    def _keep_seen(self, regions: np.ndarray, visited: np.ndarray, time: float) -> None:
        """Carry the time seen of `regions` (the regions before an insert) over to the
        regions now kept, and mark the `visited` regions seen at `time`."""
        seen = np.full(len(self.regions), np.nan)
        rows = np.searchsorted(self.regions, regions)
        still = rows < len(self.regions)
        still[still] = self.regions[rows[still]] == regions[still]
        seen[rows[still]] = self.seen[still]
        seen[np.searchsorted(self.regions, visited)] = time
        self.seen = seen

    # ------------------------------------------------------------ retraction
    def retract(
        self, entries: np.ndarray, passes: np.ndarray, share: float, protected: np.ndarray
    ) -> Retraction:
        """Take back evidence from `entries` (k,) int64 that rays passed through, `passes` (k,)
        float64 rays each (ehm.core.observations.passes.occupied_passes), except where
        `protected` (k,) bool (the batch hits the entry again). A first batch of passes only
        marks an entry PASSED; from a second on, each pass takes `share` of its weight,
        weight * (1 - share) ** passes, and a weight that falls below MIN_WEIGHT becomes 0 (the
        entry goes at the next insert)."""
        self.flags[entries[protected]] &= ~np.uint8(PASSED)
        entries, passes = entries[~protected], passes[~protected]
        confirmed = self.flags[entries] & PASSED != 0
        self.flags[entries] |= PASSED
        entries, passes = entries[confirmed], passes[confirmed]
        before = self.weight[entries].astype(np.float64)
        after = before * (1.0 - share) ** passes
        after[after < MIN_WEIGHT] = 0.0
        self.weight[entries] = after
        return Retraction(entries, before, after)

    def fade(self, shares: np.ndarray) -> None:
        """Keep `shares` (R,) float64 of the weight of every entry of each region (1: all); a
        weight that falls below MIN_WEIGHT becomes 0 (the entry goes at the next insert). For a
        `timed` memory."""
        faded = np.repeat(shares < 1.0, self.region_sizes)
        weight = self.weight[faded] * np.repeat(shares, self.region_sizes)[faded]
        weight[weight < MIN_WEIGHT] = 0.0
        self.weight[faded] = weight

    def occupied_near(self, entries: np.ndarray) -> np.ndarray:
        """(m,) int64 sorted: the occupied entries in the regions of `entries` (k,) int64."""
        first = self.region_first()
        regions = sorted_distinct(np.searchsorted(first, entries, side="right") - 1)
        sizes = self.region_sizes[regions].astype(np.int64)
        rows = np.repeat(first[regions] - np.cumsum(sizes) + sizes, sizes) + np.arange(sizes.sum())
        return rows[self.cells[rows] >> SUB_BITS >= OCCUPIED]

    def points_at(self, entries: np.ndarray) -> np.ndarray:
        """(k, d) float64 metres, world frame: the mean of each of `entries` (k,) int64."""
        return self._means(entries, self._keys_at(entries))

    def corners_at(self, entries: np.ndarray) -> np.ndarray:
        """(k, d) float64 metres, world frame: the low corner of the evidence cell of each of
        `entries` (k,) int64."""
        return self._corners(self._keys_at(entries))

    def _keys_at(self, entries: np.ndarray) -> np.ndarray:
        """(k,) int64: the key of each of `entries` (k,) int64."""
        regions = np.searchsorted(self.region_first(), entries, side="right") - 1
        return (self.regions[regions] << REGION_BITS) | self.cells[entries]

    def _means(self, entries: np.ndarray, keys: np.ndarray) -> np.ndarray:
        """(e, d) float64 metres, world frame: the means of `entries` (e,) with `keys` (e,)."""
        offset = self.place[entries] * (key_sides(keys, self.sides) / OFFSET_STEPS)[:, None]
        return self._corners(keys) + offset

    def _corners(self, keys: np.ndarray) -> np.ndarray:
        """(n, d) metres, world frame: the low corner of each key's evidence cell."""
        return cell_corners(keys, self.dim, self.sides)

    def samples(self) -> TrainingSamples:
        """Every entry as a weighted sample at its mean (metres, world frame)."""
        return self._samples_at(np.arange(len(self)), self.keys())

    def _samples_at(self, entries: np.ndarray, memory_keys: np.ndarray) -> TrainingSamples:
        """The entries (e,) int64 as weighted samples; memory_keys: (n,) the key of every
        entry."""
        keys = memory_keys[entries]
        kinds = (keys >> SUB_BITS) & (2**KIND_BITS - 1)
        weight = self.weight[entries].astype(np.float64)
        return samples_of_kinds(self._means(entries, keys), kinds, weight)

    # ------------------------------------------------------------ persistence
    @classmethod
    def of_samples(
        cls, dim: int, config: MapConfig, samples: TrainingSamples, clustered: np.ndarray
    ) -> EvidenceMemory:
        """A memory holding `samples` (each its weight), `clustered` (n,) bool those that
        formed part of a cluster: how maps of formats before 13, which kept samples, go on."""
        memory = cls.of_config(dim, config)
        memory.insert(memory.visit(samples), clustered)
        return memory

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "regions": self.regions,
            "region_sizes": self.region_sizes,
            "cells": self.cells,
            "weight": self.weight,
            "place": self.place,
            "flags": self.flags,
            "seen": self.seen,
        }

    @classmethod
    def from_arrays(
        cls, dim: int, config: MapConfig, arrays: dict[str, np.ndarray]
    ) -> EvidenceMemory:
        """The memory of `arrays` (see `arrays`); a memory of format 13 (keys (n,) int64, place
        (n, d) uint16 in 65535 steps) is kept region by region, its places to OFFSET_STEPS; one
        of formats 13 and 14 (clustered (n,) bool) has no entry PASSED."""
        memory = cls.of_config(dim, config)
        arrays = dict(arrays)
        if "clustered" in arrays:
            arrays["flags"] = np.where(arrays.pop("clustered"), CLUSTERED, 0).astype(np.uint8)
        if "keys" in arrays:
            memory._keep_keys(arrays.pop("keys"))
            place = arrays.pop("place").astype(np.float64) * (OFFSET_STEPS / 65535)
            arrays["place"] = np.rint(place).astype(np.uint8)
        for name, array in arrays.items():
            setattr(memory, name, array)
        if memory.timed and "seen" not in arrays:
            memory.seen = np.full(len(memory.regions), np.nan)
        return memory
