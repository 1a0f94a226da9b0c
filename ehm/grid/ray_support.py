"""What rays march through (ehm.core.queries.raycast), kept with a map as it learns.

Two structures serve `raycast` and `segment_free`: the map's log-odds on a grid of voxels of
about a cluster radius, which rays march first, and per level the cells where a kernel could
lift the occupancy above it, which guide the rays the grid does not settle. The grid is made on
the first cast and then follows the map: after each update only the voxels of clusters that
changed are recomputed (OccupancyGrid.update), so a planner that casts rays right after the map
learned pays what it pays with the grid kept. It is made again on the next cast when the map
grew beyond it, or when it was too large to keep. The cells are made again on the next cast
after an update: they are cheap, and only rays the grid does not settle read them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ehm.core.model.kernels import kernel_reach
from ehm.core.queries.raycast import CandidateCells, GridLogOdds
from ehm.core.snapshot import MapSnapshot
from ehm.errors import InputError
from ehm.grid.bounds import support_bounds
from ehm.grid.occupancy_grid import OccupancyGrid

# The grid rays march is left out for maps whose grid would take more than this many bytes.
RAY_GRID_MAX_BYTES = 2**28


class RaySupport:
    """The grid and the cells rays march, for one map: voxels of `resolution` metres, cells of
    `cell_side` metres (see the module)."""

    def __init__(self, resolution: float, cell_side: float) -> None:
        self.resolution = resolution
        self.cell_side = cell_side
        self._grid: OccupancyGrid | None = None
        self._log_odds: GridLogOdds | None = None
        self._grid_tried = False  # a grid too large to keep is not tried again until an update
        self._cells: dict[float, CandidateCells | None] = {}

    def grid(self, snapshot: Callable[[], MapSnapshot]) -> GridLogOdds | None:
        """The log-odds at the grid's voxel centres (intercept included), made from the map's
        `snapshot()` when there is none; None when that grid would take over
        RAY_GRID_MAX_BYTES."""
        if self._log_odds is None and not self._grid_tried:
            self._grid_tried = True
            try:
                self._grid = OccupancyGrid.of(snapshot(), None, self.resolution, RAY_GRID_MAX_BYTES)
            except InputError:
                return None
            self._log_odds = GridLogOdds(
                self._grid.scores + self._grid.intercept, self._grid.origin, self.resolution
            )
        return self._log_odds

    def cells(self, snapshot: Callable[[], MapSnapshot], threshold: float) -> CandidateCells | None:
        """The cells where the map's kernels could lift the log-odds above `threshold` (None:
        every cell can), made from its `snapshot()` on the first call for that threshold."""
        if threshold not in self._cells:
            kernels = snapshot()
            self._cells[threshold] = CandidateCells.of_kernels(
                kernels.means,
                kernel_reach(kernels.transforms, kernels.planar_kernel),
                kernels.weights,
                kernels.intercept,
                threshold,
                self.cell_side,
            )
        return self._cells[threshold]

    @property
    def keeps_grid(self) -> bool:
        """A grid is kept, to follow the map's updates."""
        return self._grid is not None

    def update(self, snapshot: MapSnapshot | None) -> None:
        """Follow the map after it learned, to `snapshot` (None when no grid is kept): the
        grid's voxels of clusters that changed are recomputed, or the grid is dropped when the
        map now reaches beyond it; the cells are dropped."""
        self._cells = {}
        self._grid_tried = False
        if self._grid is None or snapshot is None:
            return
        reach, kept = support_bounds(snapshot), self._grid.bounds
        if np.any(reach[0] < kept[0]) or np.any(reach[1] > kept[1]):
            self._grid = self._log_odds = None
            return
        self._grid.update(snapshot)
        np.add(self._grid.scores, self._grid.intercept, out=self._log_odds.values)

    @property
    def nbytes(self) -> int:
        """Bytes kept: the grid (with the snapshot it follows) and its log-odds, and the
        cells' keys."""
        total = 0 if self._grid is None else self._grid.nbytes + self._log_odds.values.nbytes
        return total + sum(cells.keys.nbytes for cells in self._cells.values() if cells is not None)
