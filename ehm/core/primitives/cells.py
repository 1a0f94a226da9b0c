"""Integer cells of a regular grid over a point set, and one linear key per cell."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.core.primitives.hashing import EMPTY_KEY, hash_slot, table_size
from ehm.errors import InputError


@dataclass(frozen=True)
class CellKeys:
    """cells: (n, d) int64 cell of each point, counted from the set's lower corner `low` (d,)
    metres. extents: (d,) cells per axis. strides: (d,) key step per axis. keys: (n,) int64,
    cells @ strides."""

    low: np.ndarray
    cells: np.ndarray
    extents: np.ndarray
    strides: np.ndarray
    keys: np.ndarray


def cell_keys(points: np.ndarray, cell: float) -> CellKeys:
    """Cells of side `cell` metres of (n >= 1, d) points, metres; InputError when the keys would
    overflow 64 bits."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    low, high = _bounds(points)
    extents = np.floor((high - low) / cell).astype(np.int64) + 1
    if np.prod(extents.astype(np.float64)) > 2.0**62:
        raise InputError(f"points span too many cells of {cell} m: cell keys overflow")
    strides = np.cumprod(np.concatenate([[1], extents[:-1]])).astype(np.int64)
    cells, keys = _cells_and_keys(points, low, float(cell), strides)
    return CellKeys(low, cells, extents, strides, keys)


def z_order_keys(keyed: CellKeys) -> np.ndarray:
    """(n,) int64 keys of the cells of `keyed`, one per cell, whose order is the Z-order
    (Morton) of the cells: cells that follow one another in it lie side by side, as they do
    not in the linear keys' order, whose rows run from one end of the set to the other. The
    linear keys where an axis spans more than 63 // d bits of cells."""
    d = keyed.cells.shape[1]
    if d not in (2, 3) or np.any(keyed.extents > 1 << (63 // d)):
        return keyed.keys
    return _z_order(keyed.cells)


# The bits of an axis spread d - 1 zero bits apart in five steps, x = (x | x << shift) & mask,
# from its low 31 bits in 2D (row 0) and 21 in 3D (row 1).
_SPREAD_LOW = np.array([0x7FFFFFFF, 0x1FFFFF], dtype=np.int64)
_SPREAD_SHIFTS = np.array([[16, 8, 4, 2, 1], [32, 16, 8, 4, 2]], dtype=np.int64)
_SPREAD_MASKS = np.array(
    [
        [0x0000FFFF0000FFFF, 0x00FF00FF00FF00FF, 0x0F0F0F0F0F0F0F0F, 0x3333333333333333,
         0x5555555555555555],
        [0x1F00000000FFFF, 0x1F0000FF0000FF, 0x100F00F00F00F00F, 0x10C30C30C30C30C3,
         0x1249249249249249],
    ],
    dtype=np.int64,
)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _z_order(cells):  # pragma: no cover - compiled
    """z_order_keys of (n, d) cells, d 2 or 3, each axis within its bits: bit b of every
    axis side by side, the first axis's highest."""
    n, d = cells.shape
    row = d - 2
    keys = np.zeros(n, dtype=np.int64)
    for i in range(n):
        for a in range(d):
            x = cells[i, a] & _SPREAD_LOW[row]
            for step in range(_SPREAD_SHIFTS.shape[1]):
                x = (x | (x << _SPREAD_SHIFTS[row, step])) & _SPREAD_MASKS[row, step]
            keys[i] |= x << (d - 1 - a)
    return keys


def z_order_keys_reference(cells: np.ndarray) -> np.ndarray:
    """Plain NumPy twin of `_z_order`: bit b of axis a at bit d b + d - 1 - a."""
    n, d = cells.shape
    keys = np.zeros(n, dtype=np.int64)
    for b in range(63 // d):
        for a in range(d):
            keys |= ((cells[:, a] >> b) & 1) << (d * b + d - 1 - a)
    return keys


@numba.njit(cache=True, nogil=True)
def _bounds(points):  # pragma: no cover - compiled
    """(d,) lowest and (d,) highest coordinate of (n >= 1, d) points along each axis."""
    low = points[0].copy()
    high = points[0].copy()
    for i in range(1, points.shape[0]):
        for a in range(points.shape[1]):
            low[a] = min(low[a], points[i, a])
            high[a] = max(high[a], points[i, a])
    return low, high


@numba.njit(cache=True, nogil=True)
def _cells_and_keys(points, low, cell, strides):  # pragma: no cover - compiled
    """(n, d) int64 cell of each point, floor((point - low) / cell), and (n,) its key, the
    cell's dot product with `strides`."""
    n, d = points.shape
    cells = np.empty((n, d), dtype=np.int64)
    keys = np.zeros(n, dtype=np.int64)
    for i in range(n):
        for a in range(d):
            cells[i, a] = np.int64(np.floor((points[i, a] - low[a]) / cell))
            keys[i] += cells[i, a] * strides[a]
    return cells, keys


def packed_cell_keys(
    points: np.ndarray, side: np.ndarray, kind: np.ndarray, kind_bits: int
) -> np.ndarray:
    """(n,) int64 key of the cell of side side[i] metres that holds each of (n, d) points,
    metres, world frame, with kind[i] (0 .. 2**kind_bits - 1) in its lowest bits: the cell's
    integer coordinates from the world origin take (63 - kind_bits) // d bits per axis.

    InputError when a point lies beyond the cells' reach."""
    bits = (63 - kind_bits) // points.shape[1]
    points = np.ascontiguousarray(points, dtype=np.float64)
    keys, inside = _packed_keys(
        points,
        np.asarray(side, dtype=np.float64),
        np.asarray(kind, dtype=np.int64),
        bits,
        kind_bits,
    )
    if not inside:
        _refuse_beyond_reach(points, side, bits)
    return keys


def packed_cell_keys_reference(
    points: np.ndarray, side: np.ndarray, kind: np.ndarray, kind_bits: int
) -> np.ndarray:
    """Plain NumPy twin of `packed_cell_keys`."""
    bits = (63 - kind_bits) // points.shape[1]
    cells = np.floor(points / side[:, None])
    half = 2.0 ** (bits - 1)
    if len(cells) and not (cells.min() >= -half and cells.max() < half):
        _refuse_beyond_reach(points, side, bits)
    keys = np.zeros(len(points), dtype=np.int64)
    for axis in range(points.shape[1]):
        keys = (keys << bits) | (cells[:, axis].astype(np.int64) + int(half))
    return (keys << kind_bits) | kind.astype(np.int64)


def _refuse_beyond_reach(points: np.ndarray, side: np.ndarray, bits: int) -> None:
    """InputError naming how far the farthest of `points` (n, d) lies beyond the reach of
    cells of `side` (n,) metres keyed with `bits` per axis."""
    half = 2.0 ** (bits - 1)
    cells = np.floor(points / side[:, None])
    outside = np.any((cells < -half) | (cells >= half), axis=1)
    far = np.max(np.abs(points[outside]))
    raise InputError(
        f"a training sample lies {far:.0f} m from the map's origin, beyond the "
        f"{half * side.min():.0f} m that cells of {side.min():g} m reach: set max_range "
        "(ehm map --max-range) to cut rays longer than the sensor's"
    )


@numba.njit(cache=True, parallel=True)
def _packed_keys(points, side, kind, bits, kind_bits):  # pragma: no cover - compiled
    """(keys (n,) int64 of packed_cell_keys, whether every point lies within the cells'
    reach); where one does not, its key is meaningless."""
    n, d = points.shape
    half = np.int64(1) << (bits - 1)
    keys = np.empty(n, dtype=np.int64)
    outside = np.zeros(n, dtype=np.bool_)
    for i in numba.prange(n):
        key = np.int64(0)
        for a in range(d):
            cell = np.floor(points[i, a] / side[i])
            outside[i] |= not (-half <= cell < half)
            key = (key << bits) | (np.int64(cell) + half)
        keys[i] = (key << kind_bits) | kind[i]
    return keys, not outside.any()


def in_neighbour_cells(anchors: np.ndarray, points: np.ndarray, side: float) -> np.ndarray | None:
    """(n,) bool: whether each of `points` (n, d), metres, lies in the cell of side `side`
    metres of one of `anchors` (m >= 1, d) or in a cell next to it (touching it at a face, an
    edge or a corner). Every point within `side` of an anchor does. None where the anchors
    span too many cells for their keys to fit 64 bits."""
    anchors = np.ascontiguousarray(anchors, dtype=np.float64)
    low = anchors.min(axis=0) - 1.5 * side  # the anchors in cells 1 on, their neighbours 0 on
    extents = np.floor((anchors.max(axis=0) - low) / side) + 2
    if np.prod(extents) > 2.0**62:
        return None
    extents = extents.astype(np.int64)
    strides = np.cumprod(np.concatenate([[1], extents[:-1]])).astype(np.int64)
    return _in_neighbour_cells(
        anchors, np.ascontiguousarray(points, dtype=np.float64), low, float(side), extents, strides
    )


def in_neighbour_cells_reference(
    anchors: np.ndarray, points: np.ndarray, side: float
) -> np.ndarray:
    """Plain NumPy twin of `in_neighbour_cells` (cells counted from the same corner)."""
    low = anchors.min(axis=0) - 1.5 * side
    of_anchors = np.floor((anchors - low) / side).astype(np.int64)
    of_points = np.floor((points - low) / side).astype(np.int64)
    apart = np.abs(of_points[:, None, :] - of_anchors[None, :, :]).max(axis=2)
    return (apart <= 1).any(axis=1)


@numba.njit(cache=True, nogil=True)
def _in_neighbour_cells(
    anchors, points, low, side, extents, strides
):  # pragma: no cover - compiled
    """in_neighbour_cells with cells counted from `low` (d,) metres, `extents` (d,) of them
    along each axis (every anchor's neighbours inside), keyed by `strides` (d,)."""
    m, d = anchors.shape
    table = np.full(table_size(m * 3**d), EMPTY_KEY, dtype=np.int64)
    cell = np.empty(d, dtype=np.int64)
    for i in range(m):
        for a in range(d):
            cell[a] = np.int64(np.floor((anchors[i, a] - low[a]) / side))
        for neighbour in range(3**d):
            key, step = np.int64(0), neighbour
            for a in range(d):
                key += (cell[a] + step % 3 - 1) * strides[a]
                step //= 3
            table[hash_slot(table, key)] = key
    inside = np.zeros(len(points), dtype=np.bool_)
    for i in range(len(points)):
        key, within = np.int64(0), True
        for a in range(d):
            c = np.floor((points[i, a] - low[a]) / side)
            within &= 0.0 <= c < extents[a]
            key += np.int64(c) * strides[a] if within else 0
        inside[i] = within and table[hash_slot(table, key)] != EMPTY_KEY
    return inside
