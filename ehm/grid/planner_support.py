"""What planner queries keep with a map as it learns: rays (`raycast`, `segment_free`) and
distances (`distance`).

One grid of the map's log-odds, at voxels of about a cluster radius, serves both. Rays march it
first, and the cells kernels of positive weight reach with their summed weight
(ehm.core.queries.cover), from which the cells where the occupancy may pass a level, guide the
rays the grid does not settle. Distance fields (ehm.core.queries.distance), one per level,
rule for unknown space and boxes asked for, are made from its log-odds, the means of the
clusters of positive weight (where obstacles thinner than a voxel peak) and the map's log-odds
as point queries read them, which place the surface.

Each is made on first use and then follows the map: after each update only what clusters that
changed cover is counted again (OccupancyGrid.update, KernelCover.changed), and a distance
field looks again only within its reach of the box of voxels whose log-odds changed. The grid
reaches somewhat beyond the map, and at least a distance field's reach; a map that grows
beyond that has it made again as it learns, and a grid too large to keep is tried again at the
next query after an update (distances are then read from a grid around the points asked, and
rays march point queries). Keeping a distance field costs a search of nearest clusters per
surfel an update moves: much where the map is large and every scan changes most of it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ehm.core.model.kernels import kernel_reach, support_half_widths
from ehm.core.queries.cover import KernelCover
from ehm.core.queries.distance import DistanceField
from ehm.core.queries.known_cells import KnownCover
from ehm.core.queries.raycast import CandidateCells, GridLogOdds
from ehm.core.queries.surfels import NearLogOdds, ReadNear
from ehm.core.snapshot import MapSnapshot
from ehm.errors import InputError
from ehm.grid.bounds import support_bounds
from ehm.grid.local_grids import Lattice
from ehm.grid.occupancy_grid import OccupancyGrid

# A box's corners' coordinates, [low, high] flattened (a key of the distance fields kept), or
# None for everywhere.
FlatBox = tuple[float, ...] | None

# The grid is left out for maps whose grid would take more than this many bytes.
RAY_GRID_MAX_BYTES = 2**28
# Side of the cells known all through that rays pass over without a query, in voxels (a
# cluster radius each): half the cells of the voxels' side cost eight times the work to find.
KNOWN_CELLS_PER_VOXEL = 2.0
# The grid reaches this share of the map's extent beyond it on each side (and at least the
# distance fields' reach), so that a map that grows a little keeps its grid; one that grows
# more has it made again as it learns.
GRID_SLACK = 0.1


class PlannerSupport:
    """The grid, the cells rays march and the distance fields, for one map: voxels of
    `resolution` metres, cells of `cell_side` metres, distances kept up to `reach` metres,
    surfaces put where the map's `log_odds` ((n, d) metres -> (n,), as point queries read
    them) meet the level (see the module)."""

    def __init__(
        self,
        resolution: float,
        cell_side: float,
        reach: float,
        log_odds: Callable[[np.ndarray], np.ndarray],
        near_log_odds: NearLogOdds,
    ) -> None:
        self.resolution = resolution
        self.cell_side = cell_side
        self.reach = reach
        self._log_odds_at = log_odds
        self._near_log_odds = near_log_odds
        self._grid: OccupancyGrid | None = None
        self._log_odds: GridLogOdds | None = None
        self._grid_tried = False  # a grid too large to keep is not tried again until an update
        self._cover: KernelCover | None = None
        self._kernels: MapSnapshot | None = None  # the map's, as the grid and cover count them
        self._cells: dict[float, CandidateCells | None] = {}
        self._known: CandidateCells | None = None
        self._known_cover: KnownCover | None = None
        # Where the map's grid is too large: a grid around the points last asked their
        # distance, and its fields, until the map learns.
        self._near: tuple[OccupancyGrid, dict] | None = None
        # Distance fields by (raw log-odds level, unknown space is an obstacle, the box it is
        # one in, the box obstacles count in).
        self._fields: dict[tuple[float, bool, FlatBox, FlatBox], DistanceField] = {}

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
        support = support_bounds(snapshot)
        slack = np.maximum(GRID_SLACK * (support[1] - support[0]), self.reach)
        bounds = support + np.stack([-slack, slack]) + 2 * self.resolution * np.array([[-1], [1]])
        try:
            self._grid = OccupancyGrid.of(snapshot, bounds, self.resolution, RAY_GRID_MAX_BYTES)
        except InputError:
            self._grid = self._log_odds = None
            self._fields = {}
            return
        self._log_odds = self._grid_log_odds()
        self._fields = {key: self._new_field(self._grid, *key) for key in self._fields}

    def _grid_log_odds(self) -> GridLogOdds:
        """The grid's log-odds as rays march them: its scores (not copied) and intercept."""
        grid = self._grid
        return GridLogOdds(grid.scores, grid.intercept, grid.origin, self.resolution)

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

    def known_cells(self, take_snapshot: Callable[[], MapSnapshot]) -> CandidateCells:
        """The cells of KNOWN_CELLS_PER_VOXEL voxels a side wholly inside some kernel's
        support (known space all through, ehm.core.queries.known_cells), counted on the first
        call and then followed through updates."""
        if self._known is None:
            if self._known_cover is None:
                kernels = self._kernels_of(take_snapshot)
                self._known_cover = KnownCover.of_kernels(
                    kernels.means,
                    kernels.transforms,
                    kernels.planar_kernel,
                    KNOWN_CELLS_PER_VOXEL * self.resolution,
                )
            self._known = self._known_cover.cells()
        return self._known

    def distances(
        self,
        take_snapshot: Callable[[], MapSnapshot],
        points: np.ndarray,
        threshold: float,
        unknown_is_occupied: bool,
        with_gradient: bool,
        unknown_box: np.ndarray | None = None,
        obstacle_box: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) signed distances, metres, from (n, d) float64 points, metres, world frame, to
        the surface where the map's log-odds (kernels from `take_snapshot()`) reach
        `threshold`, and with_gradient their (n, d) gradients (else (0, d)); the field is made
        on the first call for a threshold, rule and boxes. unknown_box, obstacle_box: (2, d)
        metres, or None: with unknown_is_occupied, unknown space is an obstacle only inside
        the first; only obstacles inside the second count (DistanceField).
        Where the map's grid would be too large to keep (an outdoor map at a fine
        resolution), the field is made on a grid around the points asked, reaching the field's
        reach beyond them, and kept for later points within it until the map learns;
        InputError when that grid too would pass RAY_GRID_MAX_BYTES."""
        self.grid(take_snapshot)
        grid, fields = self._grid, self._fields
        if grid is None:
            grid, fields = self._grid_around(self._kernels_of(take_snapshot), points)
        if not unknown_is_occupied:
            unknown_box = None  # it changes nothing
        key = (threshold, unknown_is_occupied, _flat(unknown_box), _flat(obstacle_box))
        if key not in fields:
            fields[key] = self._new_field(grid, *key)
        lifted = points if grid.dim == 3 else np.column_stack([points, np.zeros(len(points))])
        distance, gradient = fields[key].distances(lifted, _scores_3d(grid), with_gradient)
        return distance, gradient[:, : grid.dim]

    def _grid_around(
        self, snapshot: MapSnapshot, points: np.ndarray
    ) -> tuple[OccupancyGrid, dict[tuple[float, bool, FlatBox, FlatBox], DistanceField]]:
        """A grid of the voxels within the distance fields' reach of `points` (and two
        voxels more), and its fields: the one kept while it holds them, else a new one."""
        margin = self.reach + 2 * self.resolution
        box = np.stack([points.min(axis=0) - margin, points.max(axis=0) + margin])
        kept = self._near
        if kept is not None and np.all((box >= kept[0].bounds[0]) & (box <= kept[0].bounds[1])):
            return kept
        try:
            grid = OccupancyGrid.of(snapshot, box, self.resolution, RAY_GRID_MAX_BYTES)
        except InputError:
            raise InputError(
                f"the map is too large for one distance field at {self.resolution:g} m voxels, "
                f"and so are the points asked, {np.ptp(points, axis=0).round(1).tolist()} m "
                f"across with the fields' reach (over {RAY_GRID_MAX_BYTES / 2**20:.0f} MiB): "
                "ask them in parts, or tile the map (ehm.tiles.TiledMap)"
            ) from None
        self._near = (grid, {})
        return self._near

    def _new_field(
        self,
        grid: OccupancyGrid,
        threshold: float,
        unknown_is_occupied: bool,
        unknown_box: FlatBox,
        obstacle_box: FlatBox,
    ) -> DistanceField:
        """A distance field of `grid` as it stands."""
        lattice = Lattice.lift(grid.origin, self.resolution, grid.shape)
        field = DistanceField(
            lattice.origin,
            self.resolution,
            lattice.shape,
            threshold,
            unknown_is_occupied,
            self.reach,
            _lifted_box(unknown_box),
            _lifted_box(obstacle_box),
        )
        field.update(
            _scores_3d(grid),
            grid.intercept,
            self._lifted_log_odds,
            self._peaks(grid),
            near=self._lifted_near,
        )
        return field

    def _peaks(self, grid: OccupancyGrid) -> np.ndarray:
        """(P, 3) float64 metres, world frame (a 2D map's at the height of `grid`'s lattice):
        the means of the map's clusters of positive weight, where thin obstacles peak."""
        kernels = self._kernels
        means = kernels.means[kernels.weights > 0.0]
        if kernels.dim == 3:
            return means
        lattice = Lattice.lift(grid.origin, self.resolution, grid.shape)
        return np.column_stack(
            [means, np.full(len(means), lattice.origin[2] + self.resolution / 2)]
        )

    def _lifted_log_odds(self, points: np.ndarray) -> np.ndarray:
        """The map's log-odds at (n, 3) points of the 3D lattice (a 2D map's: their x, y)."""
        return self._log_odds_at(np.ascontiguousarray(points[:, : self._kernels.dim]))

    def _lifted_near(self, places: np.ndarray, spread: float) -> ReadNear:
        """The map's NearLogOdds around (m, 3) places of the 3D lattice (a 2D map's: their
        x, y)."""
        dim = self._kernels.dim
        read = self._near_log_odds(np.ascontiguousarray(places[:, :dim]), spread)
        return lambda points, rows: read(np.ascontiguousarray(points[:, :dim]), rows)

    def _changed_voxels(self, old: MapSnapshot | None, snapshot: MapSnapshot) -> np.ndarray | None:
        """(2, 3) int64, the box of the grid's voxels [low, high) whose log-odds the clusters
        that changed since `old` reach; None: everything (a refit or a first snapshot)."""
        if old is None or old.lineage is not snapshot.lineage:
            return None
        removed, added = snapshot.changes_from(old)
        means = np.concatenate([old.means[removed], snapshot.means[added]])
        if len(means) == 0:
            return np.zeros((2, 3), dtype=np.int64)
        half = np.concatenate(
            [
                support_half_widths(old.transforms[removed], old.planar_kernel[removed]),
                support_half_widths(snapshot.transforms[added], snapshot.planar_kernel[added]),
            ]
        )
        lattice = Lattice.lift(self._grid.origin, self.resolution, self._grid.shape)
        box = np.stack([(means - half).min(axis=0), (means + half).max(axis=0)])
        if snapshot.dim == 2:
            box = np.column_stack([box, lattice.origin[2] + [0.0, self.resolution]])
        low = np.floor((box[0] - lattice.origin) / self.resolution).astype(np.int64)
        high = np.floor((box[1] - lattice.origin) / self.resolution).astype(np.int64) + 1
        shape = np.array(lattice.shape)
        return np.stack([np.clip(low, 0, shape), np.clip(high, 0, shape)])

    @property
    def follows(self) -> bool:
        """A grid or a cover is kept, to follow the map's updates."""
        kept = (self._grid, self._cover, self._known_cover)
        return any(thing is not None for thing in kept)

    def update(self, snapshot: MapSnapshot | None) -> None:
        """Follow the map after it learned, to `snapshot` (None when nothing follows): the
        grid's voxels and the cover's cells of clusters that changed are counted again, or
        the grid is made again when the map now reaches beyond it."""
        self._cells = {}
        self._known = None
        self._near = None
        self._grid_tried = False
        old, self._kernels = self._kernels, snapshot
        if snapshot is None:
            return
        if old is not None and old.scale != snapshot.scale:
            # Queries ask calibrated levels: a raw level other than 0 now stands for another.
            self._fields = {key: field for key, field in self._fields.items() if key[0] == 0.0}
        if self._cover is not None:
            self._cover = self._cover_update(old, snapshot)
        if self._known_cover is not None:
            self._known_cover = self._known_update(old, snapshot)
        if self._grid is None:
            return
        support, kept = support_bounds(snapshot), self._grid.bounds
        within = kept + self.reach * np.array([[1.0], [-1.0]])
        if np.any(support[0] < within[0]) or np.any(support[1] > within[1]):
            self._make_grid(snapshot)  # the map grew beyond the grid's slack
            return
        changed = self._changed_voxels(old, snapshot)
        self._grid.update(snapshot)
        self._log_odds = self._grid_log_odds()
        peaks = self._peaks(self._grid) if self._fields else np.zeros((0, 3))
        for field in self._fields.values():
            field.update(
                _scores_3d(self._grid),
                self._grid.intercept,
                self._lifted_log_odds,
                peaks,
                changed,
                self._lifted_near,
            )

    def _cover_update(self, old: MapSnapshot | None, snapshot: MapSnapshot) -> KernelCover | None:
        """The cover followed from `old` to `snapshot`: out with the kernels that changed or
        are gone, in with those that changed or are new; None (made again when needed) after a
        refit."""
        if old is None or old.lineage is not snapshot.lineage:
            return None
        removed, added = snapshot.changes_from(old)
        return self._cover.changed(_kernels(old, removed), _kernels(snapshot, added))

    def _known_update(self, old: MapSnapshot | None, snapshot: MapSnapshot) -> KnownCover | None:
        """The known cells followed from `old` to `snapshot`: out with the kernels whose
        shape or place changed or that are gone, in with the changed and new; None (counted
        again when needed) after a refit."""
        if old is None or old.lineage is not snapshot.lineage:
            return None
        removed, added = snapshot.changes_from(old, with_weights=False)
        return self._known_cover.changed(
            (old.means[removed], old.transforms[removed], old.planar_kernel[removed]),
            (snapshot.means[added], snapshot.transforms[added], snapshot.planar_kernel[added]),
        )

    @property
    def nbytes(self) -> int:
        """Bytes kept: the map's kernels they count, the grid's scores (rays march them with
        the intercept) and fields, the cover and the cells' keys, a grid around asked points
        and its fields."""
        total = 0
        if self._kernels is not None and self.follows:
            kept = self._kernels
            arrays = (kept.means, kept.transforms, kept.weights, kept.precision)
            total += sum(array.nbytes for array in arrays)
        if self._grid is not None:
            total += self._grid.scores.nbytes
        if self._cover is not None:
            total += self._cover.keys.nbytes + self._cover.sums.nbytes + self._cover.counts.nbytes
        total += sum(field.nbytes for field in self._fields.values())
        if self._known_cover is not None:
            total += self._known_cover.keys.nbytes + self._known_cover.counts.nbytes
        if self._near is not None:
            near_grid, near_fields = self._near
            total += near_grid.scores.nbytes + sum(f.nbytes for f in near_fields.values())
        return total + sum(cells.keys.nbytes for cells in self._cells.values() if cells is not None)


def _scores_3d(grid: OccupancyGrid) -> np.ndarray:
    """A grid's scores as a 3D array (a view; a 2D grid is one voxel thick)."""
    return grid.scores if grid.scores.ndim == 3 else grid.scores[..., None]


def _kernels(snapshot: MapSnapshot, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(means, reach, weights) of the kernels of `snapshot` at `rows`, as KernelCover takes
    them."""
    reach = kernel_reach(snapshot.transforms[rows], snapshot.planar_kernel[rows])
    return snapshot.means[rows], reach, snapshot.weights[rows]


def _flat(box: np.ndarray | None) -> FlatBox:
    """A (2, d) box's corners as a FlatBox."""
    return None if box is None else tuple(np.asarray(box, dtype=np.float64).ravel())


def _lifted_box(box: FlatBox) -> np.ndarray | None:
    """(2, 3) corners, metres, of a flattened box, or None: a 2D map's box reaches through its
    lattice's one voxel."""
    if box is None:
        return None
    corners = np.reshape(box, (2, -1))
    if corners.shape[1] == 3:
        return corners
    return np.hstack([corners, np.array([[-np.inf], [np.inf]])])
