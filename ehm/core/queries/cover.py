"""Where kernels of positive weight reach: per cubic cell, the summed weight of those whose
support box touches it, kept up to date as the kernels change.

Rays skip the cells where no sum could lift the log-odds above their level
(ehm.core.queries.raycast.CandidateCells). Sums do not depend on the level, so one cover serves
every level, and after an update only the cells of kernels that changed are counted again: out
with a kernel's old weight and box, in with its new ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class KernelCover:
    """Cells of side `side` metres, in `dim` dimensions, that kernels of positive weight reach.
    keys: (c,) int64, sorted, packed cell coordinates (`bits` per axis, offset by
    2**(bits - 1)); sums: (c,) float64, the summed weights of the kernels reaching each;
    counts: (c,) int64, how many do. Kernels whose box reaches beyond what keys hold
    (2**(bits - 1) cells from the origin: 500 km for 0.5 m cells in 3D) are left out."""

    side: float
    dim: int
    keys: np.ndarray
    sums: np.ndarray
    counts: np.ndarray

    @classmethod
    def of_kernels(
        cls, means: np.ndarray, reach: np.ndarray, weights: np.ndarray, side: float
    ) -> KernelCover:
        """The cover of kernels centred at means (M, d), metres, reaching reach (M,) metres,
        with weights (M,)."""
        empty = np.zeros(0, dtype=np.int64)
        cover = cls(side, means.shape[1], empty, np.zeros(0), empty)
        return cover.changed((means[:0], reach[:0], weights[:0]), (means, reach, weights))

    def changed(
        self,
        removed: tuple[np.ndarray, np.ndarray, np.ndarray],
        added: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> KernelCover:
        """The cover without the kernels `removed` and with the kernels `added`, each
        (means, reach, weights) as of_kernels takes them (a changed kernel: its old self
        removed, its new self added)."""
        return self.with_cells(*self._cells_of(*removed), *self._cells_of(*added))

    def with_cells(
        self,
        keys_out: np.ndarray,
        weights_out: np.ndarray,
        keys_in: np.ndarray,
        weights_in: np.ndarray,
    ) -> KernelCover:
        """The cover with one kernel less at each cell of `keys_out` ((n,) packed keys, one a
        kernel and cell) and its weight taken off, and one more at each of `keys_in` with its
        weight added; cells no kernel covers any more are left out."""
        keys = np.concatenate([keys_out, keys_in])
        weights = np.concatenate([-weights_out, weights_in])
        counts = np.concatenate([np.full(len(keys_out), -1), np.ones(len(keys_in), np.int64)])
        distinct, inverse = np.unique(keys, return_inverse=True)
        delta_sums = np.bincount(inverse, weights, len(distinct))
        delta_counts = np.bincount(inverse, counts, len(distinct)).astype(np.int64)
        at = np.searchsorted(self.keys, distinct)
        known = at < len(self.keys)
        known[known] = self.keys[at[known]] == distinct[known]
        sums, counts = self.sums.copy(), self.counts.copy()
        sums[at[known]] += delta_sums[known]  # distinct keys: each cell once
        counts[at[known]] += delta_counts[known]
        new = ~known
        keys = np.insert(self.keys, at[new], distinct[new])
        sums = np.insert(sums, at[new], delta_sums[new])
        counts = np.insert(counts, at[new], delta_counts[new])
        kept = counts > 0
        return KernelCover(self.side, self.dim, keys[kept], sums[kept], counts[kept])

    @property
    def bits(self) -> int:
        """Bits of a key per axis."""
        return 63 // self.dim

    def _cells_of(
        self, means: np.ndarray, reach: np.ndarray, weights: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Keys and weights, one per cell that a kernel of positive weight reaches (the box
        of its support)."""
        half = 2 ** (self.bits - 1)
        with np.errstate(invalid="ignore", over="ignore"):
            low = np.floor((means - reach[:, None]) / self.side)
            high = np.floor((means + reach[:, None]) / self.side)
            usable = (weights > 0) & np.all((low >= -half) & (high < half), axis=1)
        cells, owners = covered_cells(low[usable].astype(np.int64), high[usable].astype(np.int64))
        return pack_cells(cells, self.bits), weights[usable][owners]


def covered_cells(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every cell of each box [low[m], high[m]] (inclusive, (M, d) int64) and its box."""
    d = low.shape[1]
    extent = high - low + 1
    counts = np.prod(extent, axis=1)
    owners = np.repeat(np.arange(len(low)), counts)
    rank = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    cells = np.empty((len(owners), d), dtype=np.int64)
    for axis in range(d):
        cells[:, axis] = low[owners, axis] + rank % extent[owners, axis]
        rank //= extent[owners, axis]
    return cells, owners


def pack_cells(cells: np.ndarray, bits: int) -> np.ndarray:
    """(n,) int64 keys of (n, d) int64 cells, `bits` per axis."""
    keys = np.zeros(len(cells), dtype=np.int64)
    for axis in range(cells.shape[1]):
        keys |= (cells[:, axis] + (1 << (bits - 1))) << (bits * axis)
    return keys


def unpack_cells(keys: np.ndarray, bits: int, d: int) -> np.ndarray:
    """(n, d) int64 cells of (n,) keys, `bits` per axis."""
    mask = (1 << bits) - 1
    return np.column_stack([((keys >> (bits * a)) & mask) - (1 << (bits - 1)) for a in range(d)])
