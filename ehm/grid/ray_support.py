"""What rays march through (ehm.core.queries.raycast), kept with a map as it learns.

Two structures serve `raycast` and `segment_free`: the map's log-odds on a grid of voxels of
about a cluster radius, which rays march first, and the cells kernels of positive weight
reach with their summed weight (ehm.core.queries.cover), from which the cells where the
occupancy may pass a level guide the rays the grid does not settle. Both are made on the first
cast and then follow the map: after each update only what clusters that changed cover is
counted again (OccupancyGrid.update, KernelCover.changed), so a planner that casts rays right
after the map learned pays what it pays with them kept. The grid reaches somewhat beyond the
map; a map that grows beyond that has it made again as it learns, and a grid too large to keep
is tried again at the next cast after an update.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ehm.core.model.kernels import kernel_reach
from ehm.core.queries.cover import KernelCover
from ehm.core.queries.raycast import CandidateCells, GridLogOdds
from ehm.core.snapshot import MapSnapshot
from ehm.errors import InputError
from ehm.grid.bounds import support_bounds
from ehm.grid.occupancy_grid import OccupancyGrid

# The grid rays march is left out for maps whose grid would take more than this many bytes.
RAY_GRID_MAX_BYTES = 2**28
# The grid reaches this share of the map's extent beyond it on each side, so that a map that
# grows a little keeps its grid; one that grows more has it made again as it learns.
GRID_SLACK = 0.1


class RaySupport:
    """The grid and the cells rays march, for one map: voxels of `resolution` metres, cells of
    `cell_side` metres (see the module)."""

    def __init__(self, resolution: float, cell_side: float) -> None:
        self.resolution = resolution
        self.cell_side = cell_side
        self._grid: OccupancyGrid | None = None
        self._log_odds: GridLogOdds | None = None
        self._grid_tried = False  # a grid too large to keep is not tried again until an update
        self._cover: KernelCover | None = None
        self._kernels: MapSnapshot | None = None  # the map's, as the grid and cover count them
        self._cells: dict[float, CandidateCells | None] = {}

    def grid(self, take_snapshot: Callable[[], MapSnapshot]) -> GridLogOdds | None:
        """The log-odds at the grid's voxel centres (intercept included), made from the map's
        kernels (`take_snapshot()`) when there is none; None when that grid would take over
        RAY_GRID_MAX_BYTES."""
        if self._log_odds is None and not self._grid_tried:
            self._grid_tried = True
            self._make_grid(self._kernels_of(take_snapshot))
        return self._log_odds

    def _kernels_of(self, take_snapshot: Callable[[], MapSnapshot]) -> MapSnapshot:
        """The map's kernels since its last update: taken once, shared by the grid and the
        cover."""
        if self._kernels is None:
            self._kernels = take_snapshot()
        return self._kernels

    def _make_grid(self, snapshot: MapSnapshot) -> None:
        """The grid of `snapshot` over its kernels' supports and GRID_SLACK of their extent
        more on each side, or none when it would take over RAY_GRID_MAX_BYTES."""
        reach = support_bounds(snapshot)
        slack = np.maximum(GRID_SLACK * (reach[1] - reach[0]), 2 * self.resolution)
        bounds = reach + np.stack([-slack, slack])
        try:
            self._grid = OccupancyGrid.of(snapshot, bounds, self.resolution, RAY_GRID_MAX_BYTES)
        except InputError:
            self._grid = self._log_odds = None
            return
        self._log_odds = GridLogOdds(
            self._grid.scores + self._grid.intercept, self._grid.origin, self.resolution
        )

    def cells(
        self, take_snapshot: Callable[[], MapSnapshot], threshold: float
    ) -> CandidateCells | None:
        """The cells where the map's kernels (`take_snapshot()`) could lift the log-odds above
        `threshold` (None: every cell can), from their cover, made on the first call."""
        if threshold not in self._cells:
            kernels = self._kernels_of(take_snapshot)
            if self._cover is None:
                reach = kernel_reach(kernels.transforms, kernels.planar_kernel)
                self._cover = KernelCover.of_kernels(
                    kernels.means, reach, kernels.weights, self.cell_side
                )
            self._cells[threshold] = CandidateCells.of_cover(
                self._cover, kernels.intercept, threshold
            )
        return self._cells[threshold]

    @property
    def follows(self) -> bool:
        """A grid or a cover is kept, to follow the map's updates."""
        return self._grid is not None or self._cover is not None

    def update(self, snapshot: MapSnapshot | None) -> None:
        """Follow the map after it learned, to `snapshot` (None when nothing follows): the
        grid's voxels and the cover's cells of clusters that changed are counted again, or
        the grid is made again when the map now reaches beyond it."""
        self._cells = {}
        self._grid_tried = False
        old, self._kernels = self._kernels, snapshot
        if snapshot is None:
            return
        if self._cover is not None:
            self._cover = self._cover_update(old, snapshot)
        if self._grid is None:
            return
        reach, kept = support_bounds(snapshot), self._grid.bounds
        if np.any(reach[0] < kept[0]) or np.any(reach[1] > kept[1]):
            self._make_grid(snapshot)  # the map grew beyond the grid's slack
            return
        self._grid.update(snapshot)
        np.add(self._grid.scores, self._grid.intercept, out=self._log_odds.values)

    def _cover_update(self, old: MapSnapshot | None, snapshot: MapSnapshot) -> KernelCover | None:
        """The cover followed from `old` to `snapshot`: out with the kernels that changed or
        are gone, in with those that changed or are new; None (made again when needed) after a
        refit."""
        if old is None or old.lineage is not snapshot.lineage:
            return None
        removed, added = snapshot.changes_from(old)
        return self._cover.changed(_kernels(old, removed), _kernels(snapshot, added))

    @property
    def nbytes(self) -> int:
        """Bytes kept: the map's kernels they count, the grid's fields and log-odds, the cover
        and the cells' keys."""
        total = 0
        if self._kernels is not None and self.follows:
            kept = self._kernels
            arrays = (kept.means, kept.transforms, kept.weights, kept.precision)
            total += sum(array.nbytes for array in arrays)
        if self._grid is not None:
            total += self._grid.scores.nbytes + self._log_odds.values.nbytes
        if self._cover is not None:
            total += self._cover.keys.nbytes + self._cover.sums.nbytes + self._cover.counts.nbytes
        return total + sum(cells.keys.nbytes for cells in self._cells.values() if cells is not None)


def _kernels(snapshot: MapSnapshot, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(means, reach, weights) of the kernels of `snapshot` at `rows`, as KernelCover takes
    them."""
    reach = kernel_reach(snapshot.transforms[rows], snapshot.planar_kernel[rows])
    return snapshot.means[rows], reach, snapshot.weights[rows]
