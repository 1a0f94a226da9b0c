"""The keys of the evidence memory's cells (ehm.core.observations.memory): which region of the
cluster radius a cell lies in, of which kind it is, and which of the region's cells it is.

A key packs, from the high bits down, the region's integer coordinates counted from the world
origin ((62 - REGION_BITS) // d bits an axis), one bit for regions along rays, the kind
(KIND_BITS) and the cell within the region (SUB_BITS): the entries of a region are one run of
sorted keys. Regions around hits hold FINE_CELLS_PER_RADIUS cells along each axis, regions along
rays COARSE_CELLS_PER_RADIUS.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.core.observations.evidence import (
    COARSE_CELLS_PER_RADIUS,
    FINE_CELLS_PER_RADIUS,
    FREE_ALONG_RAY,
    FREE_AT_SURFACE,
    KIND_BITS,
)
from ehm.errors import InputError

# Bits of a key for the cell within its region (FINE_CELLS_PER_RADIUS ** 3 of them at most),
# and for those and the kind.
SUB_BITS = 3 * (FINE_CELLS_PER_RADIUS - 1).bit_length()
REGION_BITS = KIND_BITS + SUB_BITS
assert REGION_BITS <= 8, "an entry's kind and cell in its region are kept in one byte"

_OUT_OF_REACH = (
    "evidence lies beyond the reach of the memory's cells: set max_range "
    "(ehm map --max-range) to cut rays longer than the sensor's"
)


def region_bits(dim: int) -> int:
    """Bits of a key for each axis of a region's coordinates."""
    return (63 - 1 - REGION_BITS) // dim


def memory_keys(points: np.ndarray, kinds: np.ndarray, sides: tuple[float, float]) -> np.ndarray:
    """(n,) int64 key of the evidence cell of each of (n, d) points, metres, world frame, of
    `kinds` (n,) int64; `sides` (fine, coarse) metres. InputError for a point whose region is
    beyond the keys' reach."""
    keys, inside = _memory_keys(
        np.ascontiguousarray(points, dtype=np.float64),
        np.asarray(kinds, dtype=np.int64),
        float(sides[0]),
        float(sides[1]),
    )
    if not inside:
        raise InputError(_OUT_OF_REACH)
    return keys


@numba.njit(cache=True, nogil=True)
def _memory_keys(points, kinds, fine_side, coarse_side):  # pragma: no cover - compiled
    """(keys (n,) int64, whether every region is within reach) of `memory_keys`."""
    n, d = points.shape
    bits = (63 - 1 - REGION_BITS) // d
    half = np.int64(1) << (bits - 1)
    keys = np.empty(n, dtype=np.int64)
    inside = True
    for i in range(n):
        along_ray = kinds[i] == FREE_ALONG_RAY
        per_region = COARSE_CELLS_PER_RADIUS if along_ray else FINE_CELLS_PER_RADIUS
        side = coarse_side if along_ray else fine_side
        key = np.int64(0)
        sub = np.int64(0)
        for a in range(d):
            cell = np.int64(np.floor(points[i, a] / side))
            region = cell // per_region
            if region < -half or region >= half:
                inside = False
            key = (key << bits) | (region + half)
            sub = sub * FINE_CELLS_PER_RADIUS + (cell - region * per_region)
        key = (key << 1) | np.int64(along_ray)
        keys[i] = (key << REGION_BITS) | (kinds[i] << SUB_BITS) | sub
    return keys, inside


def memory_keys_reference(
    points: np.ndarray, kinds: np.ndarray, sides: tuple[float, float]
) -> np.ndarray:
    """Plain NumPy twin of `memory_keys`."""
    along_ray = kinds == FREE_ALONG_RAY
    per_region = np.where(along_ray, COARSE_CELLS_PER_RADIUS, FINE_CELLS_PER_RADIUS)
    side = np.where(along_ray, sides[1], sides[0])
    cells = np.floor(points / side[:, None]).astype(np.int64)
    regions = np.floor_divide(cells, per_region[:, None])
    sub = np.zeros(len(points), dtype=np.int64)
    for axis in range(points.shape[1]):
        sub = sub * FINE_CELLS_PER_RADIUS + (cells[:, axis] - regions[:, axis] * per_region)
    return _region_keys(regions, along_ray) | (kinds.astype(np.int64) << SUB_BITS) | sub


def reached_regions(
    points: np.ndarray, along_ray: np.ndarray, sides: tuple[float, float]
) -> np.ndarray:
    """(n,) int64: the region holding each of (n, d) points (a key shifted right by
    REGION_BITS), of the regions along rays where along_ray (n,) bool, else of the regions
    around hits."""
    kinds = np.where(along_ray, FREE_ALONG_RAY, FREE_AT_SURFACE)
    return memory_keys(points, kinds, sides) >> REGION_BITS


def _region_keys(regions: np.ndarray, along_ray: np.ndarray) -> np.ndarray:
    """(n,) int64: the integer `regions` (n, d), counted from the world origin, packed as the
    keys' high bits; InputError for a region beyond their reach."""
    bits = region_bits(regions.shape[1])
    half = 1 << (bits - 1)
    if len(regions) and not (regions.min() >= -half and regions.max() < half):
        raise InputError(_OUT_OF_REACH)
    keys = np.zeros(len(regions), dtype=np.int64)
    for axis in range(regions.shape[1]):
        keys = (keys << bits) | (regions[:, axis] + half)
    return ((keys << 1) | along_ray) << REGION_BITS


def key_sides(keys: np.ndarray, sides: tuple[float, float]) -> np.ndarray:
    """(n,) metres: the side of the evidence cell of each of `keys` (n,) int64; `sides`
    (fine, coarse) metres."""
    along_ray = (keys >> SUB_BITS) & (2**KIND_BITS - 1) == FREE_ALONG_RAY
    return np.where(along_ray, sides[1], sides[0])


def cell_corners(keys: np.ndarray, dim: int, sides: tuple[float, float]) -> np.ndarray:
    """(n, dim) metres, world frame: the low corner of the evidence cell of each of `keys`
    (n,) int64; `sides` (fine, coarse) metres."""
    return _cell_corners(np.asarray(keys, dtype=np.int64), dim, float(sides[0]), float(sides[1]))


@numba.njit(cache=True, nogil=True)
def _cell_corners(keys, dim, fine_side, coarse_side):  # pragma: no cover - compiled
    corners = np.empty((len(keys), dim))
    for i in range(len(keys)):
        cell_corner(keys[i], fine_side, coarse_side, corners[i])
    return corners


@numba.njit(cache=True, inline="always")
def cell_corner(key, fine_side, coarse_side, corner):  # pragma: no cover - compiled
    """Write the low corner of the evidence cell of `key` to `corner` (d,), metres, world
    frame; returns the cell's side, metres."""
    dim = len(corner)
    bits = (63 - 1 - REGION_BITS) // dim
    half = np.int64(1) << (bits - 1)
    mask = (np.int64(1) << bits) - 1
    along_ray = (key >> SUB_BITS) & ((1 << KIND_BITS) - 1) == FREE_ALONG_RAY
    per_region = COARSE_CELLS_PER_RADIUS if along_ray else FINE_CELLS_PER_RADIUS
    side = coarse_side if along_ray else fine_side
    sub = key & ((1 << SUB_BITS) - 1)
    rest = key >> (REGION_BITS + 1)
    for a in range(dim - 1, -1, -1):
        region = (rest & mask) - half
        rest >>= bits
        corner[a] = (region * per_region + sub % FINE_CELLS_PER_RADIUS) * side
        sub //= FINE_CELLS_PER_RADIUS
    return side


def cell_corners_reference(keys: np.ndarray, dim: int, sides: tuple[float, float]) -> np.ndarray:
    """Plain NumPy twin of `cell_corners`."""
    along_ray = (keys >> SUB_BITS) & (2**KIND_BITS - 1) == FREE_ALONG_RAY
    per_region = np.where(along_ray, COARSE_CELLS_PER_RADIUS, FINE_CELLS_PER_RADIUS)
    side = np.where(along_ray, sides[1], sides[0])
    bits = region_bits(dim)
    half = 1 << (bits - 1)
    sub = keys & (2**SUB_BITS - 1)
    rest = keys >> (REGION_BITS + 1)
    cells = np.empty((len(keys), dim))
    for axis in range(dim - 1, -1, -1):
        region = (rest & ((1 << bits) - 1)) - half
        rest = rest >> bits
        cells[:, axis] = region * per_region + sub % FINE_CELLS_PER_RADIUS
        sub = sub // FINE_CELLS_PER_RADIUS
    return cells * side[:, None]
