"""How a tiled map cuts the world: square (2D) or cubic (3D) tiles, the box each one learns
from, the part of a scan each one sees, and the weights that blend tiles across borders."""

from __future__ import annotations

from itertools import product

import numpy as np

from ehm.core.sensor.boxes import ray_box_intervals
from ehm.core.sensor.scan import Scan
from ehm.errors import SettingsError

TileKey = tuple[int, ...]


class Tiling:
    """Tiles of side `size` metres keyed by integer indices: tile k's core is the box
    [(k - 1/2) size, (k + 1/2) size) on every axis (tile 0 is centred on the world origin),
    and it learns from its core grown by `overlap` metres on every side (its learn box).

    A point is answered by the tiles whose learn box holds it, blended with weights that
    fall smoothly from 1 to 0 across the band of 2 overlap around each border and sum to 1
    everywhere: at a border both tiles weigh 1/2, at `overlap` inside a tile it alone counts.
    """

    def __init__(self, size: float, overlap: float) -> None:
        if not (isinstance(size, int | float) and 0.0 < size < np.inf):
            raise SettingsError(f"tile size must be a positive number of metres, got {size!r}")
        if not (isinstance(overlap, int | float) and 0.0 < overlap <= size / 2.0):
            raise SettingsError(
                f"tile overlap must be above 0 and at most half the tile size ({size / 2.0:g} "
                f"m), got {overlap!r}"
            )
        self.size, self.overlap = float(size), float(overlap)

    def __repr__(self) -> str:
        return f"Tiling(size={self.size:g}, overlap={self.overlap:g})"

    def core_box(self, key: TileKey) -> np.ndarray:
        """(2, d) metres, world frame: the tile's core, [low corner, high corner]."""
        centre = np.asarray(key, dtype=np.float64) * self.size
        return np.stack([centre - self.size / 2.0, centre + self.size / 2.0])

    def learn_box(self, key: TileKey) -> np.ndarray:
        """(2, d) metres, world frame: the box the tile learns from, its core and margin."""
        return self.core_box(key) + np.array([[-self.overlap], [self.overlap]])

    def keys_meeting(self, box: np.ndarray) -> list[TileKey]:
        """The tiles whose learn box meets `box` ((2, d) metres), in index order."""
        box = np.asarray(box, dtype=np.float64)
        first = np.ceil((box[0] - self.overlap) / self.size - 0.5).astype(np.int64)
        last = np.floor((box[1] + self.overlap) / self.size + 0.5).astype(np.int64)
        ranges = [range(int(a), int(b) + 1) for a, b in zip(first, last, strict=True)]
        return [tuple(key) for key in product(*ranges)]

    def blend(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tiles that answer each of (n, d) points, metres: rows (m,) int64 (which point),
        keys (m, d) int64 (which tile) and weights (m,) float64 in (0, 1], summing to 1 over
        each point's entries; up to 2^d entries per point, none for non-finite rows."""
        points = np.asarray(points, dtype=np.float64)
        finite = np.flatnonzero(np.all(np.isfinite(points), axis=1))
        local = points[finite] / self.size + 0.5
        own = np.floor(local).astype(np.int64)
        offset = (local - own) * self.size  # metres from the core's low face, [0, size)
        band = 2.0 * self.overlap
        low, high = offset < self.overlap, offset > self.size - self.overlap
        depth = np.where(low, offset, np.where(high, self.size - offset, self.overlap))
        own_weight = _smoothstep((depth + self.overlap) / band)
        other = own - low + high
        rows, keys, weights = [], [], []
        for choice in product((False, True), repeat=points.shape[1]):
            choice = np.array(choice)
            weight = np.prod(np.where(choice, 1.0 - own_weight, own_weight), axis=1)
            kept = weight > 0.0
            rows.append(finite[kept])
            keys.append(np.where(choice, other, own)[kept])
            weights.append(weight[kept])
        return np.concatenate(rows), np.concatenate(keys), np.concatenate(weights)

    def weights(self, points: np.ndarray, key: TileKey) -> np.ndarray:
        """(n,) float64 in [0, 1]: tile `key`'s blending weight at (n, d) points, metres (as
        `blend` gives it)."""
        core = self.core_box(key)
        inside = np.minimum(points - core[0], core[1] - points)  # < 0 outside the core
        return np.prod(_smoothstep((inside + self.overlap) / (2.0 * self.overlap)), axis=1)

    def weight_gradients(self, points: np.ndarray, key: TileKey) -> np.ndarray:
        """(n, d) float64, 1/m: the gradient of tile `key`'s blending weight (`weights`) at
        (n, d) points, metres."""
        core = self.core_box(key)
        below, above = points - core[0], core[1] - points
        inside = np.minimum(below, above)
        band = 2.0 * self.overlap
        t = (inside + self.overlap) / band
        factors = _smoothstep(t)
        slopes = np.where((t > 0.0) & (t < 1.0), 6.0 * t * (1.0 - t), 0.0) / band
        slopes *= np.where(below <= above, 1.0, -1.0)  # d(inside)/dx: +1 near low, -1 near high
        gradients = np.empty_like(points, dtype=np.float64)
        for axis in range(points.shape[1]):
            others = np.prod(np.delete(factors, axis, axis=1), axis=1)
            gradients[:, axis] = slopes[:, axis] * others
        return gradients

    def clip(self, scan: Scan, key: TileKey) -> Scan | None:
        """The rays of `scan` that cross tile `key`'s learn box (None if none does). The rays
        are whole; a map with MapConfig.learn_box set to that box learns only their part in
        it (ehm.core.observations.samples)."""
        offsets = scan.points_world - scan.origin
        lengths = np.linalg.norm(offsets, axis=1)
        directions = offsets / np.where(lengths > 0, lengths, 1.0)[:, None]
        start, end = ray_box_intervals(scan.origin, directions, lengths, self.learn_box(key))
        crossing = start <= end
        if not crossing.any():
            return None
        return scan if crossing.all() else scan.subset(crossing)


def scan_box(scan: Scan) -> np.ndarray:
    """(2, d) metres: the box holding a scan's origin and every ray end."""
    low = np.minimum(scan.points_world.min(axis=0), scan.origin)
    high = np.maximum(scan.points_world.max(axis=0), scan.origin)
    return np.stack([low, high])


def _smoothstep(t: np.ndarray) -> np.ndarray:
    """3 t^2 - 2 t^3 on [0, 1]: 0 to 1 with flat ends, and s(t) + s(1 - t) = 1."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)
