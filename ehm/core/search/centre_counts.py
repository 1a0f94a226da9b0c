"""How many cluster centres lie near a point, read in a few lookups: the centres counted in the
cells of a grid over them and summed along every axis (a summed-area table), so that the count
of any box of cells is 2^d lookups apart.

A search for a point's nearest clusters within a bound (ehm.core.search.index) finds none when
no centre lies within the bound, and a k-d tree takes about as long to find none as to find
eight, while in open space most points are beyond every fine kernel's reach. The box of cells
around a point that holds its ball of the bound tells which points can be left out: none of
its centres, no neighbour.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

# Cells a table may hold (1 MB of counts); over a larger box the cells grow.
MAX_CELLS = 1 << 18


@dataclass(frozen=True)
class CentreCounts:
    """Centres counted in cells of `side` metres from `low` (d,) metres: sums (n_0 + 1, ...,
    n_(d-1) + 1) int32, sums[i + 1, j + 1, ...] the centres in cells [0, i] x [0, j] x ...;
    the first row along each axis is zeros."""

    low: np.ndarray
    side: float
    sums: np.ndarray

    @classmethod
    def of(cls, centres: np.ndarray, side: float) -> CentreCounts:
        """The table of (m >= 1, d) centres, metres, in cells of `side` > 0 metres or wider
        (MAX_CELLS)."""
        if not side > 0.0:
            raise ValueError(f"cells must be wider than 0 m, got {side}")
        low = centres.min(axis=0)
        extent = centres.max(axis=0) - low
        while np.prod(np.floor(extent / side) + 1) > MAX_CELLS:
            side *= 2.0
        cells = np.floor((centres - low) / side).astype(np.int64)
        shape = tuple(int(n) + 2 for n in cells.max(axis=0))  # a row of zeros before each axis
        flat = np.ravel_multi_index(tuple((cells + 1).T), shape)
        sums = np.bincount(flat, minlength=int(np.prod(shape))).astype(np.int32).reshape(shape)
        for axis in range(len(shape)):
            np.cumsum(sums, axis=axis, out=sums)
        return cls(low, float(side), sums)

    def any_within(self, points: np.ndarray, radius: float) -> np.ndarray:
        """(n,) bool: whether any centre may lie within `radius` metres of each of (n, d)
        points, metres; False only where none does (the cells around the ball hold none).
        Points with a coordinate that is not finite are True."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        return _any_within(points, float(radius), self.low, self.side, self.sums)


# Points `_any_within` answers on one thread at a time, with one set of scratch rows.
CHUNK = 4096


@numba.njit(cache=True, parallel=True)
def _any_within(points, radius, low, side, sums):  # pragma: no cover - compiled
    """See CentreCounts.any_within (low, side and sums its table's)."""
    n, d = points.shape
    shape = np.array(sums.shape, dtype=np.int64)
    strides = np.ones(d, dtype=np.int64)
    for a in range(d - 2, -1, -1):
        strides[a] = strides[a + 1] * shape[a + 1]
    flat = sums.ravel()
    found = np.empty(n, dtype=np.bool_)
    for chunk in numba.prange((n + CHUNK - 1) // CHUNK):
        first = np.empty(d, dtype=np.int64)  # the box of cells, in the table's rows
        last = np.empty(d, dtype=np.int64)
        for i in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n)):
            found[i] = _box_holds_any(
                points[i], radius, low, side, shape, strides, flat, first, last
            )
    return found


@numba.njit(cache=True, inline="always")
def _box_holds_any(
    point, radius, low, side, shape, strides, flat, first, last
):  # pragma: no cover - compiled
    """Whether the box of cells around `point`'s ball holds a centre (True for a point that
    is not finite); first and last (d,) int64 scratch rows."""
    d = len(point)
    for a in range(d):
        if not np.isfinite(point[a]):
            return True
    for a in range(d):
        lo = max(np.floor((point[a] - radius - low[a]) / side), 0.0)
        hi = min(np.floor((point[a] + radius - low[a]) / side), shape[a] - 2.0)
        if hi < lo:
            return False
        first[a] = np.int64(lo)  # the row before the box's first cell
        last[a] = np.int64(hi) + 1
    # Inclusion and exclusion over the box's 2^d corners.
    total = 0
    for corner in range(1 << d):
        index = 0
        sign = 1
        for a in range(d):
            if corner >> a & 1:
                index += first[a] * strides[a]
                sign = -sign
            else:
                index += last[a] * strides[a]
        total += sign * np.int64(flat[index])
    return total > 0


def any_within_reference(
    counts: CentreCounts, centres: np.ndarray, points: np.ndarray, radius: float
) -> np.ndarray:
    """Plain NumPy twin of `counts.any_within`, from the (m, d) centres it was made of: whether
    any centre's cell lies in the box of cells around each point's ball."""
    cells = np.floor((centres - counts.low) / counts.side)
    with np.errstate(invalid="ignore"):
        lo = np.floor((points - radius - counts.low) / counts.side)
        hi = np.floor((points + radius - counts.low) / counts.side)
    inside = np.all(
        (cells[None, :, :] >= lo[:, None, :]) & (cells[None, :, :] <= hi[:, None, :]), axis=2
    )
    return np.any(inside, axis=1) | ~np.all(np.isfinite(points), axis=1)
