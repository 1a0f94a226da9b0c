"""What changed between two maps of one place, for a site inspected over days: the voxels that
became occupied and those that became free.

Both maps are read on one grid (HilbertMap.grid or TiledMap.grid: the same voxels, over the
box holding both unless bounds are given). A voxel appeared where the new map reads it
occupied (p at least `occupied`) and the old one reads it and every voxel next to it free (p at
most `free`), and vanished the other way round: two maps of one place put a surface's edge up
to a voxel apart, and a calibrated map's occupancy (MapConfig.calibrate) passes from free to
occupied within a voxel, so a surface that stayed is no change. Where either map reads a
voxel unknown, between the two levels, nothing is said to have changed: a place one of them
has not seen is no change. The levels default to those of nav2's map_server.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

from ehm.errors import InputError
from ehm.grid.bounds import DEFAULT_MAX_BYTES
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.hilbert_map import HilbertMap
from ehm.io.exports import MAP_SERVER_FREE, MAP_SERVER_OCCUPIED
from ehm.tiles.tiled_map import TiledMap


@dataclass(frozen=True)
class MapChanges:
    """appeared, vanished, stayed: (n, d) float64 metres, world frame, the centres of the
    voxels that became occupied, that became free, and that are occupied in both maps.
    resolution: voxel side, metres; bounds: (2, d) metres, the grid's low and high corners;
    occupied, free: the levels of p(occupied) used."""

    appeared: np.ndarray
    vanished: np.ndarray
    stayed: np.ndarray
    resolution: float
    bounds: np.ndarray
    occupied: float
    free: float

    @property
    def dim(self) -> int:
        return self.bounds.shape[1]

    def __repr__(self) -> str:
        volume = self.resolution**self.dim
        unit = "m^3" if self.dim == 3 else "m^2"
        return (
            f"MapChanges({len(self.appeared)} voxels appeared ({len(self.appeared) * volume:.3g} "
            f"{unit}), {len(self.vanished)} vanished ({len(self.vanished) * volume:.3g} {unit}), "
            f"{len(self.stayed)} occupied in both, {self.resolution} m voxels)"
        )


def diff(
    old: HilbertMap | TiledMap,
    new: HilbertMap | TiledMap,
    resolution: float = 0.05,
    bounds: np.ndarray | None = None,
    occupied: float = MAP_SERVER_OCCUPIED,
    free: float = MAP_SERVER_FREE,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> MapChanges:
    """What changed from map `old` to map `new` of the same place, in one world frame (see
    the module's docstring): voxels of `resolution` metres over `bounds` ((2, d) metres; None:
    the box holding both maps). InputError for maps of different dimensions, levels that are
    not 0 <= free < occupied <= 1, or a grid over `max_bytes` (each map's)."""
    if old.dim != new.dim:
        raise InputError(f"the old map is {old.dim}D, the new one {new.dim}D")
    if not 0.0 <= free < occupied <= 1.0:
        raise InputError(
            f"levels must be 0 <= free < occupied <= 1, got free {free!r}, occupied {occupied!r}"
        )
    if bounds is None:
        old_box, new_box = old.extent(), new.extent()
        bounds = np.stack([np.minimum(old_box[0], new_box[0]), np.maximum(old_box[1], new_box[1])])
    before = old.grid(bounds, resolution, max_bytes=max_bytes)
    after = new.grid(bounds, resolution, max_bytes=max_bytes)
    was, now = before.probability.ravel(), after.probability.ravel()
    # The most occupied of each voxel and the voxels next to it, in either map.
    was_around = maximum_filter(before.probability, size=3, mode="nearest").ravel()
    now_around = maximum_filter(after.probability, size=3, mode="nearest").ravel()
    return MapChanges(
        _centres(after, (was_around <= free) & (now >= occupied)),
        _centres(after, (was >= occupied) & (now_around <= free)),
        _centres(after, (was >= occupied) & (now >= occupied)),
        after.resolution,
        after.bounds,
        occupied,
        free,
    )


def _centres(grid: OccupancyGrid, chosen: np.ndarray) -> np.ndarray:
    """(k, d) float64 metres, world frame: the centres of the grid's voxels where `chosen`
    (n,) bool, in probability.ravel() order."""
    index = np.unravel_index(np.flatnonzero(chosen), grid.shape)
    return grid.origin + (np.column_stack(index) + 0.5) * grid.resolution
