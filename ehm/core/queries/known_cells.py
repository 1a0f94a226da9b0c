"""Cells wholly inside some kernel's support: space the map has evidence for all through, where
a ray that stops at never-seen space needs no query (ehm.core.queries.raycast.stop_at_unknown).

A kernel's support is convex (the ellipsoid |T (x - mu)| < 1, or the planar-surface kernel's
box max_a |(T (x - mu))_a| < 1, ehm.core.model.kernels), so a cell whose corners all lie in
it lies in it whole.

    cover = KnownCover.of_kernels(means, transforms, planar, side=0.24)
    cover.cells()                                   # a CandidateCells rays walk
    cover = cover.changed(removed, added)           # after an update
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.core.queries.cover import KernelCover, pack_cells
from ehm.core.queries.raycast import CandidateCells


@dataclass(frozen=True)
class KnownCover:
    """Cells wholly inside some kernel's support, with how many kernels hold each whole, kept
    as a KernelCover whose counts are those kernels (its sums count them too). It follows a
    map's updates by counting the kernels that changed out and in (`changed`); `cells` is
    what rays pass over."""

    cover: KernelCover

    @classmethod
    def of_kernels(
        cls, means: np.ndarray, transforms: np.ndarray, planar: np.ndarray, side: float
    ) -> KnownCover:
        """The cover of kernels: means (M, d) metres, transforms (M, d, d) 1/m, planar (M,);
        cells of `side` metres."""
        empty = np.zeros(0, dtype=np.int64)
        cover = cls(KernelCover(side, means.shape[1], empty, np.zeros(0), empty))
        nothing = (means[:0], transforms[:0], planar[:0])
        return cover.changed(nothing, (means, transforms, planar))

    @property
    def keys(self) -> np.ndarray:
        """(c,) int64, sorted, packed cell coordinates (63 // d bits per axis)."""
        return self.cover.keys

    @property
    def counts(self) -> np.ndarray:
        """(c,) int64, the kernels holding each cell whole."""
        return self.cover.counts

    def changed(
        self,
        removed: tuple[np.ndarray, np.ndarray, np.ndarray],
        added: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> KnownCover:
        """The cover without the kernels `removed` and with the kernels `added`, each
        (means, transforms, planar) (a changed kernel: its old self removed, its new self
        added)."""
        cover = self.cover
        keys_out = pack_cells(_kept(whole_cells(*removed, cover.side), cover.bits), cover.bits)
        keys_in = pack_cells(_kept(whole_cells(*added, cover.side), cover.bits), cover.bits)
        ones = np.ones(len(keys_out)), np.ones(len(keys_in))
        return KnownCover(cover.with_cells(keys_out, ones[0], keys_in, ones[1]))

    def cells(self) -> CandidateCells:
        """The cells, as rays walk them (CandidateCells.next_run)."""
        cover = self.cover
        return CandidateCells.of_keys(cover.keys, cover.side, cover.bits, cover.dim)


def whole_cells(
    means: np.ndarray, transforms: np.ndarray, planar: np.ndarray, side: float
) -> np.ndarray:
    """(n, d) int64: for each kernel in turn, the cells of `side` metres wholly inside its
    support (a cell in two kernels' supports listed twice)."""
    dim = means.shape[1]
    arguments = (
        np.ascontiguousarray(means, dtype=np.float64),
        np.ascontiguousarray(transforms, dtype=np.float64),
        np.ascontiguousarray(planar, dtype=np.bool_),
        float(side),
    )
    counts = _whole_cells(*arguments, np.zeros(1, dtype=np.int64), np.zeros((0, dim), np.int64))
    starts = np.concatenate([[0], np.cumsum(counts)])
    cells = np.empty((int(starts[-1]), dim), dtype=np.int64)
    _whole_cells(*arguments, starts, cells)
    return cells


def _kept(cells: np.ndarray, bits: int) -> np.ndarray:
    """The cells (n, d) within the keys' reach, `bits` an axis."""
    half = 1 << (bits - 1)
    return cells[np.all((cells > -half) & (cells < half - 1), axis=1)]


@numba.njit(cache=True, parallel=True)
def _whole_cells(means, transforms, planar, side, starts, out):  # pragma: no cover - compiled
    """Per kernel, the cells of its support's bounding box whose corners all lie in the
    support: counted (a `starts` of one element; returns (M,) counts) or written into `out`
    from row starts[m] on. A kernel whose support is narrower than a cell's diagonal along
    some axis of T (1 / a row's norm) holds no cell and is passed over."""
    m_count, d = means.shape
    count_only = len(starts) == 1
    counts = np.zeros(m_count, dtype=np.int64)
    diagonal = side * np.sqrt(d)
    for m in numba.prange(m_count):
        t = transforms[m]
        narrow = False
        for a in range(d):
            norm = 0.0
            for b in range(d):
                norm += t[a, b] * t[a, b]
            narrow = narrow or 1.0 / np.sqrt(norm) < 0.5 * diagonal
        if narrow:
            continue
        inverse = np.linalg.inv(t)
        low = np.empty(d, dtype=np.int64)
        span = np.empty(d, dtype=np.int64)
        for a in range(d):
            reach = 0.0
            for b in range(d):
                reach += abs(inverse[a, b]) if planar[m] else inverse[a, b] * inverse[a, b]
            reach = reach if planar[m] else np.sqrt(reach)
            low[a] = np.int64(np.floor((means[m, a] - reach) / side))
            span[a] = np.int64(np.floor((means[m, a] + reach) / side)) - low[a] + 1
        # T (corner - mean) of the bounding box's first corner, and its change a cell a step.
        base = np.empty(d)
        for a in range(d):
            base[a] = 0.0
            for b in range(d):
                base[a] += t[a, b] * (low[b] * side - means[m, b])
        total = 1
        for a in range(d):
            total *= span[a]
        u = np.empty(d)
        cell = np.empty(d, dtype=np.int64)
        written = 0 if count_only else starts[m]
        for index in range(total):
            rest = index
            for a in range(d):
                cell[a] = rest % span[a]
                rest //= span[a]
            whole = True
            for c in range(1 << d):  # the cell's corners
                inside = 0.0
                for a in range(d):
                    u[a] = base[a]
                    for b in range(d):
                        u[a] += t[a, b] * (cell[b] + ((c >> b) & 1)) * side
                    inside = max(inside, abs(u[a])) if planar[m] else inside + u[a] * u[a]
                if inside >= 1.0:
                    whole = False
                    break
            if whole:
                counts[m] += 1
                if not count_only:
                    for a in range(d):
                        out[written, a] = low[a] + cell[a]
                    written += 1
    return counts


def known_cells_reference(
    means: np.ndarray, transforms: np.ndarray, planar: np.ndarray, side: float
) -> CandidateCells:
    """Plain NumPy twin of `KnownCover.of_kernels(...).cells()`."""
    dim = means.shape[1]
    found = [np.zeros((0, dim), dtype=np.int64)]
    corners = np.array(np.meshgrid(*[[0, 1]] * dim, indexing="ij")).reshape(dim, -1).T
    for mean, t, flat in zip(means, transforms, planar, strict=True):
        inverse = np.linalg.inv(t)
        reach = np.abs(inverse).sum(axis=1) if flat else np.linalg.norm(inverse, axis=1)
        low = np.floor((mean - reach) / side).astype(np.int64)
        high = np.floor((mean + reach) / side).astype(np.int64)
        axes = [np.arange(lo, hi + 1) for lo, hi in zip(low, high, strict=True)]
        cells = np.array(np.meshgrid(*axes, indexing="ij")).reshape(dim, -1).T
        u = ((cells[:, None, :] + corners[None]) * side - mean) @ t.T
        inside = np.abs(u).max(axis=2) if flat else (u * u).sum(axis=2)
        found.append(cells[np.all(inside < 1.0, axis=1)])
    keys = np.unique(pack_cells(_kept(np.concatenate(found), 63 // dim), 63 // dim))
    return CandidateCells.of_keys(keys, side, 63 // dim, dim)
