"""A bounded memory of past training samples, kept per cell of space, so that learning scan by
scan does not forget.

Stochastic gradient steps over one scan's samples pull the weights it reaches towards that
scan's view. With the memory, each scan is learned together with past samples from the same
places, in the proportions in which they were seen, as learning all scans in one batch would.

Every cell keeps a uniform random subset of at most `per_cell` of the samples that fell in it
(each sample draws a random priority; the lowest stay) and counts the samples it has seen.
Replay draws, among the cells a new scan's samples fall in, a cell in proportion to that count,
then one of its kept samples uniformly: each past sample there comes back about as often as it
would among all samples seen so far, while memory grows with the mapped space, not with the
number of scans.

It draws from cells around hits as many samples as the scan has there, the rest from cells
along rays. Every scan's rays cross open space that earlier scans crossed too: drawn in
proportion alone, the replay was 89-96 % free samples along rays against 72-83 % in the scans
(the warehouse), which pushed the bias, left out of queries, below one batch's and the
occupied region into free space (near-surface precision 0.461 against 0.506 with the kinds
matched; held-out F1 on the Intel lab 0.923 against 0.909). Replay stays where the scan is:
drawn from the whole map it scored lower where scans are small (held-out F1 on the Intel lab
0.890 against 0.920) and made every scan change weights everywhere, so grids that follow the
map would be rebuilt after each scan.

Samples that formed no cluster when they came (their quick-means seed took too few samples)
are marked. They join the clustering again when a later scan brings samples to their cell, so
sparse scans (a 2D laser with 180 rays) build clusters their samples could not build alone
(still fewer than one batch: on the Intel lab 8,900 against 9,620).

Samples around hits live in cells `cluster_radius` on a side, free samples along rays in cells
`free_cluster_radius` on a side. A cell is named by one 64-bit key: its integer coordinates in
20 bits per axis in 3D (31 in 2D) and a bit for its kind, so a memory reaches about half a
million cells from the world origin along each axis (63 km with 0.12 m cells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.cells import packed_cell_keys, rank_in_runs
from ehm.core.samples import TrainingSamples

# Priority of an empty slot; samples draw theirs below it.
EMPTY = np.uint32(2**32 - 1)


@dataclass(frozen=True)
class PendingSamples:
    """Kept samples that formed no cluster yet, in the cells a new batch of samples reaches.
    samples: their TrainingSamples; cells, slots: (p,) int64, where the memory keeps each."""

    samples: TrainingSamples
    cells: np.ndarray
    slots: np.ndarray


@dataclass(frozen=True)
class Visit:
    """Where a batch of samples falls in a memory. keys: (u,) int64 sorted distinct keys of
    their cells; key_of_sample: (n,) int64 index of each sample's key; cells: (u,) int64 row of
    each key's cell, -1 where the memory has none yet; near: (c,) int64 rows of the cells, of
    either kind, that hold any of the samples."""

    samples: TrainingSamples
    keys: np.ndarray
    key_of_sample: np.ndarray
    cells: np.ndarray
    near: np.ndarray


class SampleMemory:
    """Past training samples of a map, at most `per_cell` per cell of space (per_cell = 0 keeps
    none). `sides`: (side of the cells of samples around hits, side of the cells of free
    samples along rays), metres.

    Per cell, rows 0..n_cells-1: seen (float64, weight of the samples that fell in it), filled
    (int64, kept samples, slots 0..filled-1), at_surface (bool, its kind). Per kept sample,
    (cells, per_cell) arrays: points (float32, metres, world frame, one more axis), occupied
    and clustered (bool), priority (uint32, EMPTY in an empty slot). keys: (n_cells,) int64 sorted
    cell keys, and cell_of_key the row of each.
    """

    def __init__(self, dim: int, per_cell: int, sides: tuple[float, float]) -> None:
        self.dim = dim
        self.per_cell = per_cell
        self.sides = (float(sides[0]), float(sides[1]))
        self.keys = np.zeros(0, dtype=np.int64)
        self.cell_of_key = np.zeros(0, dtype=np.int64)
        self.n_cells = 0
        self._allocate(0)

    @classmethod
    def of_config(cls, dim: int, config: MapConfig) -> SampleMemory:
        """An empty memory for a dim-dimensional map with `config`'s settings."""
        return cls(dim, config.memory_per_cell, (config.cluster_radius, config.free_cluster_radius))

    def _allocate(self, capacity: int) -> None:
        k, d = self.per_cell, self.dim
        self.seen = np.zeros(capacity)
        self.filled = np.zeros(capacity, dtype=np.int64)
        self.at_surface = np.zeros(capacity, dtype=bool)
        self.points = np.zeros((capacity, k, d), dtype=np.float32)
        self.occupied = np.zeros((capacity, k), dtype=bool)
        self.clustered = np.zeros((capacity, k), dtype=bool)
        self.priority = np.full((capacity, k), EMPTY, dtype=np.uint32)

    def _reserve(self, n_cells: int) -> None:
        """Room for n_cells cells, growing by doubling so appends cost amortized O(1)."""
        capacity = len(self.seen)
        if n_cells <= capacity:
            return
        old = self.cell_arrays()
        self._allocate(max(n_cells, 2 * capacity, 64))
        for name, array in old.items():
            getattr(self, name)[: len(array)] = array

    def cell_arrays(self) -> dict[str, np.ndarray]:
        """The per-cell arrays of the n_cells cells in use (views)."""
        names = ("seen", "filled", "at_surface", "points", "occupied", "clustered", "priority")
        return {name: getattr(self, name)[: self.n_cells] for name in names}

    def __len__(self) -> int:
        """Samples kept."""
        return int(self.filled[: self.n_cells].sum())

    @property
    def nbytes(self) -> int:
        """Bytes allocated, spare capacity included."""
        arrays = [self.keys, self.cell_of_key, self.seen, self.filled, self.at_surface]
        arrays += [self.points, self.occupied, self.clustered, self.priority]
        return sum(a.nbytes for a in arrays)

    # ------------------------------------------------------------------ cells
    def cell_keys(self, points: np.ndarray, at_surface: np.ndarray) -> np.ndarray:
        """(n,) int64 key of the cell of each of (n, d) points, metres, of the given kinds."""
        side = np.where(at_surface, self.sides[0], self.sides[1])
        remedy = "set memory_per_cell=0 to map without the sample memory"
        return packed_cell_keys(points, side, at_surface, 1, remedy)

    def _find(self, keys: np.ndarray) -> np.ndarray:
        """(n,) int64 cell row of each of `keys` (n,) int64, -1 where there is none yet."""
        cells = np.full(len(keys), -1, dtype=np.int64)
        position = np.searchsorted(self.keys, keys)
        inside = np.flatnonzero(position < len(self.keys))
        found = inside[self.keys[position[inside]] == keys[inside]]
        cells[found] = self.cell_of_key[position[found]]
        return cells

    # -------------------------------------------------------------- learning
    def visit(self, samples: TrainingSamples) -> Visit:
        """Where `samples` fall in this memory: the start of every step below."""
        if self.per_cell == 0:
            none = np.zeros(0, dtype=np.int64)
            return Visit(samples, none, np.zeros(len(samples), dtype=np.int64), none, none)
        keys = self.cell_keys(samples.points, samples.at_surface)
        unique, key_of_sample = np.unique(keys, return_inverse=True)
        cells = self._find(unique)
        other_kind = self._find(np.unique(self.cell_keys(samples.points, ~samples.at_surface)))
        near = np.union1d(cells[cells >= 0], other_kind[other_kind >= 0])
        return Visit(samples, unique, key_of_sample.ravel(), cells, near)

    def pending(self, visit: Visit) -> PendingSamples:
        """The kept samples not yet in any cluster, in the cells the visit's samples fall in."""
        cells = visit.cells[visit.cells >= 0]
        waiting = ~self.clustered[cells] & (self.priority[cells] != EMPTY)
        row, slots = np.nonzero(waiting)
        cells = cells[row]
        return PendingSamples(self._samples_at(cells, slots), cells, slots)

    def mark_clustered(self, pending: PendingSamples, clustered: np.ndarray) -> None:
        """Record which `pending` samples ((p,) bool `clustered`) have now formed clusters."""
        self.clustered[pending.cells[clustered], pending.slots[clustered]] = True

    def replay(self, ratio: float, visit: Visit, rng: np.random.Generator) -> TrainingSamples:
        """`ratio` past samples per sample of the visit, from the cells, of either kind, that
        hold any of the visit's samples: of each kind of cell as many as the visit has samples
        of that kind, times ratio (all from one kind when the other has no cells there), each
        cell drawn in proportion to the samples it has seen (their weights), then one of its
        kept samples uniformly (none when there are no such cells). Each weighs the mean
        weight of the visit's samples of its kind."""
        samples = visit.samples
        n = round(ratio * len(samples))
        n_surface = round(ratio * int(samples.at_surface.sum()))
        kinds = self.at_surface[visit.near]
        if not kinds.all() and kinds.any():
            counts = ((True, n_surface), (False, n - n_surface))
        else:
            counts = ((bool(kinds.all()), n),)
        chosen, slots, weights = [], [], []
        for at_surface, n_kind in counts:
            cells = visit.near[kinds == at_surface]
            if len(cells) == 0 or n_kind == 0:
                continue
            cumulative = np.cumsum(self.seen[cells])
            drawn = np.searchsorted(cumulative, rng.random(n_kind) * cumulative[-1], side="right")
            chosen.append(cells[np.minimum(drawn, len(cells) - 1)])
            slots.append((rng.random(n_kind) * self.filled[chosen[-1]]).astype(np.int64))
            # Each weighs as the visit's samples of its kind do on average.
            same_kind = samples.weight[samples.at_surface == at_surface]
            weights.append(np.full(n_kind, same_kind.mean() if len(same_kind) else 1.0))
        if not chosen:
            none = np.zeros(0, dtype=np.int64)
            return self._samples_at(none, none)
        replayed = self._samples_at(np.concatenate(chosen), np.concatenate(slots))
        return TrainingSamples(
            replayed.points, replayed.occupied, replayed.at_surface, np.concatenate(weights)
        )

    def insert(self, visit: Visit, clustered: np.ndarray, rng: np.random.Generator) -> None:
        """Offer the visit's samples to the memory; clustered: (n,) bool, each formed part of a
        cluster. Each cell keeps the per_cell lowest priorities among its samples and the new
        ones."""
        samples = visit.samples
        if self.per_cell == 0 or len(samples) == 0:
            return
        cells = self._add_cells(visit)
        self.seen[cells] += np.bincount(visit.key_of_sample, samples.weight, len(cells))
        k, d = self.per_cell, self.dim
        # A new sample can stay only below the highest kept priority of a full cell.
        cell_of_sample = cells[visit.key_of_sample]
        priority = rng.integers(0, EMPTY, len(samples), dtype=np.uint32)
        full = self.filled[cells] == k
        ceiling = np.where(full, self.priority[cells].max(axis=1), EMPTY)
        new = np.flatnonzero(priority < ceiling[visit.key_of_sample])
        touched = np.unique(cell_of_sample[new])
        # Candidates per touched cell: its kept slots (empty ones at EMPTY), then new samples.
        cell_of = np.concatenate([np.repeat(touched, k), cell_of_sample[new]])
        priority = np.concatenate([self.priority[touched].ravel(), priority[new]])
        points = np.concatenate(
            [self.points[touched].reshape(-1, d), samples.points[new].astype(np.float32)]
        )
        occupied = np.concatenate([self.occupied[touched].ravel(), samples.occupied[new]])
        was_clustered = np.concatenate([self.clustered[touched].ravel(), clustered[new]])
        order = np.argsort((cell_of << 32) | priority.astype(np.int64))
        rank = rank_in_runs(cell_of[order])
        keep = order[rank < k]
        target_cell, slot = cell_of[keep], rank[rank < k]
        self.priority[target_cell, slot] = priority[keep]
        self.points[target_cell, slot] = points[keep]
        self.occupied[target_cell, slot] = occupied[keep]
        self.clustered[target_cell, slot] = was_clustered[keep]
        self.filled[touched] = np.sum(self.priority[touched] != EMPTY, axis=1)

    def _add_cells(self, visit: Visit) -> np.ndarray:
        """(u,) int64 rows of the visit's cells, adding the ones it found missing."""
        cells = visit.cells.copy()
        missing = cells < 0
        n_missing = int(missing.sum())
        if n_missing:
            self._reserve(self.n_cells + n_missing)
            cells[missing] = np.arange(self.n_cells, self.n_cells + n_missing)
            position = np.searchsorted(self.keys, visit.keys[missing])
            self.keys = np.insert(self.keys, position, visit.keys[missing])
            self.cell_of_key = np.insert(self.cell_of_key, position, cells[missing])
            self.at_surface[cells[missing]] = (visit.keys[missing] & 1).astype(bool)
            self.n_cells += n_missing
        return cells

    def _samples_at(self, cells: np.ndarray, slots: np.ndarray) -> TrainingSamples:
        return TrainingSamples(
            self.points[cells, slots].astype(np.float64),
            self.occupied[cells, slots].copy(),
            self.at_surface[cells].copy(),
        )

    # ------------------------------------------------------------ persistence
    def arrays(self) -> dict[str, np.ndarray]:
        """Everything the memory holds, trimmed to the cells in use (for map files)."""
        return {"keys": self.keys, "cell_of_key": self.cell_of_key, **self.cell_arrays()}

    @classmethod
    def from_arrays(
        cls, dim: int, config: MapConfig, arrays: dict[str, np.ndarray]
    ) -> SampleMemory:
        """The memory whose `arrays()` these are, for a map with `config`."""
        memory = cls.of_config(dim, config)
        memory.keys = arrays["keys"]
        memory.cell_of_key = arrays["cell_of_key"]
        memory.n_cells = len(memory.keys)
        memory._reserve(memory.n_cells)
        for name, array in arrays.items():
            if name not in ("keys", "cell_of_key"):
                getattr(memory, name)[: memory.n_cells] = array
        return memory
