"""Maps for navigation stacks: each cell occupied, free or unknown, as nav2's map_server and the
planners on grids take them.

A cell is occupied where the map reads p(occupied) above 0.5 anywhere in it, taken at the
SUBCELLS^d cell centres of a grid SUBCELLS times finer: a wall then occupies every cell its
surface crosses, as a voxel map marks the voxel each hit falls in (at the map's detail,
MapConfig.for_resolution; cells twice as coarse miss thin walls between their points). A cell
is free where p stays at most 0.5 all over it and the map has evidence there: the variance
of its log-odds, averaged over the cell, is at most KNOWN_VARIANCE_SHARE of the prior's (far
from anything observed it keeps the prior's, ehm.core.weights.uncertainty). Every other cell
is unknown.

How these maps read held-out free points and hits against OctoMap's is measured by
benchmarks/nav2_maps.py.

    nav = navigation_grid(hilbert_map, resolution=0.05)
    write_map_server(nav, "floor.pgm")
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ehm.core.weights.uncertainty import logit_variance
from ehm.errors import EmptyMapError, InputError, assumed
from ehm.grid.bounds import DEFAULT_MAX_BYTES, bytes_per_voxel, grid_shape
from ehm.grid.occupancy_grid import OccupancyGrid

OCCUPIED, FREE, UNKNOWN = 1, 0, -1
SUBCELLS = 2
"""Cells of the fine grid along each axis of a navigation cell."""
FLOOR_SEARCH = 10.0
"""Metres below the sensor that floor_below searches for the floor."""
FLOOR_CLEARANCE, BAND_TOP = 0.3, 2.0
"""The default band a 3D map projects, metres above its floor: from above the floor's own
surface (which reads occupied a voxel or two thick), kerbs and ground noise, to above a
ground robot."""
KNOWN_VARIANCE_SHARE = 0.8
"""A cell is known, and may read free, where its log-odds variance is at most this share of the
prior's, 1 / prior_precision: lower reads less of the explored space free, higher more of the
unseen space."""


class GriddedMap(Protocol):
    """What navigation_grid asks of a map: HilbertMap and TiledMap answer it."""

    @property
    def dim(self) -> int | None: ...

    def extent(self) -> np.ndarray: ...

    def grid(
        self, bounds: np.ndarray | None, resolution: float, *, max_bytes: int, std: bool
    ) -> OccupancyGrid: ...

    def occupancy(self, points: np.ndarray) -> np.ndarray: ...

    @property
    def sensor_path(self) -> np.ndarray: ...

    def grid_blocks(
        self, bounds: np.ndarray | None, resolution: float, *, max_bytes: int, std: bool
    ) -> Iterable[OccupancyGrid]: ...


@dataclass(frozen=True)
class NavigationGrid:
    """Cells that are occupied, free or unknown. origin: (d,) float64, metres, world frame, the
    low corner of cell (0, ..., 0); resolution: cell side, metres; states: int8 array of the
    grid's shape, OCCUPIED (1), FREE (0) or UNKNOWN (-1)."""

    origin: np.ndarray
    resolution: float
    states: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return self.states.shape

    @property
    def dim(self) -> int:
        return self.states.ndim

    @classmethod
    def of_fine_grid(cls, fine: OccupancyGrid) -> NavigationGrid:
        """The cells of SUBCELLS^d voxels each of `fine`, a grid made with its std whose shape
        is a multiple of SUBCELLS along every axis."""
        if not fine.has_std:
            raise ValueError("a navigation grid is made from a grid with its std")
        shape = tuple(n // SUBCELLS for n in fine.shape)
        if any(n * SUBCELLS != m for n, m in zip(shape, fine.shape, strict=True)):
            raise ValueError(f"a grid of shape {fine.shape} does not split into cells")
        # Axes (n0, SUBCELLS, n1, SUBCELLS, ...): each cell's voxels along the odd axes.
        split = tuple(size for n in shape for size in (n, SUBCELLS))
        within = tuple(range(1, 2 * fine.dim, 2))
        reached = fine.scores != 0.0
        occupied = ((fine.probability > 0.5) & reached).reshape(split).any(axis=within)
        reached = reached.reshape(split).any(axis=within)
        sums = fine.variance_sums
        variance = logit_variance(sums[0], sums[1], fine.prior_precision)
        prior_variance = 1.0 / fine.prior_precision
        known = variance.reshape(split).mean(axis=within) <= KNOWN_VARIANCE_SHARE * prior_variance
        states = np.where(occupied, OCCUPIED, np.where(known & reached, FREE, UNKNOWN))
        return cls(fine.origin.copy(), fine.resolution * SUBCELLS, states.astype(np.int8))


def navigation_grid(
    any_map: GriddedMap,
    bounds: np.ndarray | None = None,
    resolution: float = 0.05,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> NavigationGrid:
    """The navigation grid of a HilbertMap or TiledMap over `bounds` ((2, d) metres, world
    frame, [low corner, high corner], widened to whole cells; None: the map's extent) at
    `resolution` metres. InputError for bad bounds or resolutions and for grids whose fine
    grid would take more than `max_bytes`, before allocating."""
    if any_map.dim is None:
        raise EmptyMapError("the map is empty: integrate scans before you make a navigation grid")
    if bounds is None:
        bounds = any_map.extent()
    dim = any_map.dim
    voxel_bytes = bytes_per_voxel(True) * SUBCELLS**dim
    origin, shape = grid_shape(bounds, resolution, dim, max_bytes, voxel_bytes)
    fine_bounds = np.stack([origin, origin + np.array(shape) * resolution])
    fine = any_map.grid(fine_bounds, resolution / SUBCELLS, max_bytes=max_bytes, std=True)
    return NavigationGrid.of_fine_grid(fine)


def projected_navigation_grid(
    any_map: GriddedMap,
    heights: tuple[float, float],
    bounds: np.ndarray | None = None,
    resolution: float = 0.05,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> NavigationGrid:
    """The 2D navigation grid of a 3D map's band of `heights` (z_min, z_max, metres, world
    frame), as octomap_server's projected map: a column is occupied where any of its cells in
    the band is (cells as navigation_grid reads them), free where none is and some is free,
    else unknown. bounds: (2, 2) metres, x and y (None: the map's extent); resolution: cell
    side, metres. Made block by block (HilbertMap.grid_blocks); InputError when the blocks
    of the band's finer grid would hold more than `max_bytes`."""
    z_min, z_max = (float(h) for h in heights)
    if not (np.isfinite(z_min) and np.isfinite(z_max) and z_min < z_max):
        raise InputError(f"heights must be finite with z_min < z_max, got {z_min}, {z_max}")
    if any_map.dim != 3:
        raise InputError("a height band is projected from a 3D map; a 2D map is already flat")
    box = any_map.extent()[:, :2] if bounds is None else np.asarray(bounds, dtype=np.float64)
    band = np.column_stack([box, [z_min, z_max]])
    origin, shape = grid_shape(band, resolution, 3, max_bytes=np.inf)
    fine_box = np.stack([origin, origin + np.array(shape) * resolution])
    blocks = any_map.grid_blocks(fine_box, resolution / SUBCELLS, max_bytes=max_bytes, std=True)
    occupied = np.zeros(shape[:2], dtype=bool)
    free = np.zeros(shape[:2], dtype=bool)
    for fine in blocks:
        cells = NavigationGrid.of_fine_grid(fine)
        first = np.round((cells.origin[:2] - origin[:2]) / resolution).astype(int)
        part = tuple(slice(a, a + n) for a, n in zip(first, cells.shape[:2], strict=True))
        occupied[part] |= (cells.states == OCCUPIED).any(axis=2)
        free[part] |= (cells.states == FREE).any(axis=2)
    states = np.where(occupied, OCCUPIED, np.where(free, FREE, UNKNOWN)).astype(np.int8)
    return NavigationGrid(origin[:2].copy(), float(resolution), states)


def default_heights(any_map: GriddedMap, resolution: float) -> tuple[float, float]:
    """The band projected_navigation_grid takes by default: from FLOOR_CLEARANCE to
    BAND_TOP above the floor under the map's first sensor pose (floor_below), said in an
    AssumptionWarning. InputError when no floor is found there."""
    path = any_map.sensor_path
    floor = None if len(path) == 0 else floor_below(any_map, path[0], resolution)
    if floor is None:
        raise InputError(
            "no floor found under the first sensor pose to place the height band on: give the "
            "heights to project (--z-min, --z-max)"
        )
    heights = (floor + FLOOR_CLEARANCE, floor + BAND_TOP)
    assumed(
        f"projected heights {heights[0]:.2f} to {heights[1]:.2f} m: {FLOOR_CLEARANCE} to "
        f"{BAND_TOP} m above the floor found at {floor:.2f} m under the first sensor pose "
        "(set them with --z-min and --z-max)"
    )
    return heights


def floor_below(any_map: GriddedMap, position: np.ndarray, resolution: float) -> float | None:
    """Height, metres, of the floor under `position` ((3,) metres, world frame): the median,
    over columns 2 to 10 m around it (past the vehicle and a LiDAR's blind spot), of the top
    of the lowest surface the map reads occupied in each, searched FLOOR_SEARCH metres down in
    steps of half `resolution`; None when fewer than a quarter of the columns meet one."""
    heights = position[2] - np.arange(0.0, FLOOR_SEARCH, resolution / 2)
    turns = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    radii = np.array([2.0, 3.0, 4.0, 6.0, 8.0, 10.0])
    offsets = (radii[:, None, None] * np.stack([np.cos(turns), np.sin(turns)], axis=1)).reshape(
        -1, 2
    )
    columns = np.empty((len(offsets), len(heights), 3))
    columns[..., :2] = position[:2] + offsets[:, None, :]
    columns[..., 2] = heights
    occupied = (any_map.occupancy(columns.reshape(-1, 3)) > 0.5).reshape(len(offsets), -1)
    floors = []
    for column in occupied:
        found = np.flatnonzero(column)
        if len(found):
            # The lowest run of occupied heights, and its top (heights fall along the column).
            gaps = np.flatnonzero(np.diff(found) > 1)
            floors.append(heights[found[gaps[-1] + 1] if len(gaps) else found[0]])
    return float(np.median(floors)) if len(floors) >= len(offsets) / 4 else None
