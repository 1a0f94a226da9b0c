"""Occupancy grids by incremental grid reconstruction (Sec. 3.5, Eq. 17-18).

The local grids of a map's clusters (ehm.grid.local_grids) add up to a global score grid
s_g = sum_m w_m k(x_g, M_m) (Eq. 17), and p_g = sigmoid(s_g) (Eq. 18); a grid made with the
occupancy's standard deviation also sums what its variance needs (ehm.core.weights.uncertainty).
Kernel values are recomputed when needed rather than stored, which keeps a grid's memory at
its voxels.

A grid is fed snapshots of a map (ehm.core.snapshot), never the map itself, and keeps the
last one. `OccupancyGrid.update` takes out the old contribution of every cluster whose mean,
kernel or weight changed since, puts in the new one and adds new clusters; when that is more
work than starting over, or the snapshot comes from another map or a refit, it rebuilds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.core.primitives.logistic import sigmoid
from ehm.core.snapshot import MapSnapshot
from ehm.core.weights.uncertainty import logit_variance, occupancy_std
from ehm.errors import InputError
from ehm.grid.bounds import DEFAULT_MAX_BYTES, bytes_per_voxel, grid_shape, support_bounds
from ehm.grid.local_grids import Lattice, LocalGrids, accumulate_local_grids
from ehm.grid.mesh import marching_cubes


@dataclass(frozen=True)
class GridUpdate:
    """What one `OccupancyGrid.update` did: kind 'rebuild' or 'incremental'; local_grids and
    voxels: the local grids it recomputed and the voxels they cover (changed clusters count
    twice: out with the old, in with the new); rebuild_voxels: what a rebuild covers."""

    kind: str
    local_grids: int
    voxels: int
    rebuild_voxels: int


class OccupancyGrid:
    """Occupancy probabilities of a map on a regular grid of voxels, 2D or 3D.

    origin: (d,) metres, world frame, low corner of voxel (0, ..., 0). resolution: voxel side,
    metres. shape: voxels per axis. scores: array of `shape`, raw log-odds w^T phi at each voxel
    centre (Eq. 17); intercept and scale: log_odds = scale (scores + intercept), the map's
    calibrated log-odds (ehm.core.weights.calibration), as its point queries read them;
    probability: p(occupied) there (Eq. 18); std, for grids made with_std:
    the standard deviation of that probability. Build one with HilbertMap.grid or
    `OccupancyGrid.of`; `update` brings it up to date with a newer snapshot.
    """

    def __init__(
        self,
        origin: np.ndarray,
        resolution: float,
        shape: tuple[int, ...],
        with_std: bool = False,
    ) -> None:
        self.origin = np.asarray(origin, dtype=np.float64)
        self.resolution = float(resolution)
        # Field 0: the scores; with the std, fields 1 and 2: sum_m k^2 / lambda_m, sum_m k.
        self._fields = np.zeros((3 if with_std else 1, *shape))
        self.intercept = 0.0
        self.scale = 1.0
        self.prior_precision = 1.0
        self._probability: np.ndarray | None = None
        self._std: np.ndarray | None = None
        self._snapshot: MapSnapshot | None = None

    @classmethod
    def of(
        cls,
        snapshot: MapSnapshot,
        bounds: np.ndarray | None = None,
        resolution: float = 0.05,
        max_bytes: int = DEFAULT_MAX_BYTES,
        with_std: bool = False,
    ) -> OccupancyGrid:
        """The grid of a map's snapshot over `bounds` ((2, d) metres, [low corner, high
        corner]; None: the box holding every kernel's support) at `resolution` metres, with
        the occupancy's standard deviation when with_std. InputError for bad bounds or
        resolutions and for grids over `max_bytes`, before allocating."""
        if bounds is None:
            bounds = support_bounds(snapshot)
        origin, shape = grid_shape(
            bounds, resolution, snapshot.dim, max_bytes, bytes_per_voxel(with_std)
        )
        grid = cls(origin, resolution, shape, with_std)
        grid.update(snapshot)
        return grid

    @classmethod
    def of_clusters(
        cls,
        snapshot: MapSnapshot,
        rows: np.ndarray,
        origin: np.ndarray,
        resolution: float,
        shape: tuple[int, ...],
        with_std: bool = False,
    ) -> OccupancyGrid:
        """The grid summing only the snapshot's clusters `rows` (int64) over `shape` voxels from
        `origin` ((d,) metres, low corner): a whole map's grid wherever no other cluster
        reaches (the blocks of ehm.grid.blocks). `update` rebuilds it from all clusters."""
        grid = cls(origin, resolution, shape, with_std)
        grid.intercept, grid.scale = snapshot.intercept, snapshot.scale
        grid.prior_precision = snapshot.prior_precision
        lattice = Lattice.lift(grid.origin, grid.resolution, grid.shape)
        local = LocalGrids.of(snapshot, np.asarray(rows, dtype=np.int64), lattice, 1.0, with_std)
        accumulate_local_grids(grid._fields_3d(), lattice, local)
        return grid

    @classmethod
    def of_log_odds(
        cls,
        origin: np.ndarray,
        resolution: float,
        log_odds: np.ndarray,
        variance: np.ndarray | None = None,
        prior_precision: float = 1.0,
    ) -> OccupancyGrid:
        """A grid of given values, for maps that are not one snapshot (a TiledMap blends its
        tiles'): origin (d,) metres, world frame, low corner; log_odds, an array of the grid's
        shape, calibrated (the grid's scale is 1); variance, of the same shape, the log-odds'
        variance at each voxel (None: a grid without the std); prior_precision: the maps'
        (MapConfig.prior_precision). `variance_sums` then holds (variance, 1): the whole
        variance, no background share. `update` starts such a grid over from a snapshot."""
        log_odds = np.asarray(log_odds, dtype=np.float64)
        grid = cls(origin, resolution, log_odds.shape, variance is not None)
        grid.prior_precision = float(prior_precision)
        grid._fields[0] = log_odds
        if variance is not None:
            grid._fields[1] = variance
            grid._fields[2] = 1.0
        return grid

    @property
    def scores(self) -> np.ndarray:
        """Log-odds w^T phi at each voxel centre (Eq. 17), float64 array of `shape` (a view)."""
        return self._fields[0]

    @property
    def log_odds(self) -> np.ndarray:
        """The calibrated log-odds at each voxel centre, scale (scores + intercept), float64
        array of `shape` (a new array)."""
        return self.scale * (self.scores + self.intercept)

    @property
    def has_std(self) -> bool:
        return len(self._fields) == 3

    @property
    def variance_sums(self) -> np.ndarray:
        """(2,) + `shape` float64 (a view), sum_m k^2 / lambda_m and sum_m k at each voxel
        centre, from which `std` follows; InputError for a grid made without the std."""
        self._require_std()
        return self._fields[1:]

    @property
    def shape(self) -> tuple[int, ...]:
        return self._fields.shape[1:]

    @property
    def dim(self) -> int:
        return self.scores.ndim

    @property
    def bounds(self) -> np.ndarray:
        """(2, d) metres: low and high corner of the grid."""
        return np.stack([self.origin, self.origin + np.array(self.shape) * self.resolution])

    @property
    def probability(self) -> np.ndarray:
        """p(occupied) per voxel, float64 array of `shape` (computed once per update)."""
        if self._probability is None:
            self._probability = sigmoid(self.log_odds)
        return self._probability

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of p(occupied) per voxel under the weights' posterior
        (ehm.core.weights.uncertainty), float64 array of `shape` (computed once per update);
        InputError for a grid made without it."""
        if self._std is None:
            self._std = occupancy_std(self.log_odds, self.log_odds_variance)
        return self._std

    @property
    def log_odds_variance(self) -> np.ndarray:
        """Variance of `log_odds` per voxel under the weights' posterior, float64 array of
        `shape` (a new array); InputError for a grid made without the std."""
        self._require_std()
        variance = logit_variance(self._fields[1], self._fields[2], self.prior_precision)
        return self.scale**2 * variance

    def axis_centers(self, axis: int) -> np.ndarray:
        """(shape[axis],) metres: voxel centres along one axis."""
        return self.origin[axis] + (np.arange(self.shape[axis]) + 0.5) * self.resolution

    def centers(self) -> np.ndarray:
        """(n, d) float64 metres, world frame: voxel centres in `probability.ravel()` order."""
        axes = np.meshgrid(*(self.axis_centers(a) for a in range(self.dim)), indexing="ij")
        return np.column_stack([a.ravel() for a in axes])

    def mesh(self, level: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Surface where the probability crosses `level` (marching cubes, 3D grids): vertices
        (V, 3) float64 metres, world frame, and faces (F, 3) int64 vertex rows."""
        if self.dim != 3:
            raise InputError(
                "a mesh needs a 3D grid; a 2D map's grid is an image: render it or save the grid"
            )
        return marching_cubes(self.probability, self.origin, self.resolution, level)

    def __repr__(self) -> str:
        shape = " x ".join(str(n) for n in self.shape)
        origin = np.round(self.origin, 3).tolist()
        return f"OccupancyGrid({shape} voxels of {self.resolution} m, origin {origin})"

    # ------------------------------------------------------------ computing
    def update(self, snapshot: MapSnapshot) -> GridUpdate:
        """Bring the grid up to date with `snapshot`: recompute only the local grids of
        clusters whose weight, mean or kernel changed since the last update, of new clusters
        and of clusters merged away, or rebuild when that is less work (or the snapshot comes
        from another map, or the map was refitted)."""
        if snapshot.dim != self.dim:
            raise InputError(f"the grid is {self.dim}D, the map is {snapshot.dim}D")
        lattice = Lattice.lift(self.origin, self.resolution, self.shape)
        self.intercept, self.scale = snapshot.intercept, snapshot.scale
        self.prior_precision = snapshot.prior_precision
        self._probability = self._std = None
        with_std = self.has_std
        everything = LocalGrids.of(snapshot, np.arange(len(snapshot)), lattice, 1.0, with_std)
        old = self._snapshot
        if old is None or old.lineage is not snapshot.lineage:
            return self._rebuild(snapshot, lattice, everything)
        removed_rows, added_rows = snapshot.changes_from(old, with_std)
        removed = LocalGrids.of(old, removed_rows, lattice, -1.0, with_std)
        added = LocalGrids.of(snapshot, added_rows, lattice, 1.0, with_std)
        voxels = removed.voxels + added.voxels
        if voxels >= everything.voxels:
            return self._rebuild(snapshot, lattice, everything)
        accumulate_local_grids(self._fields_3d(), lattice, removed)
        accumulate_local_grids(self._fields_3d(), lattice, added)
        self._snapshot = snapshot
        return GridUpdate("incremental", len(removed) + len(added), voxels, everything.voxels)

    def _rebuild(
        self, snapshot: MapSnapshot, lattice: Lattice, everything: LocalGrids
    ) -> GridUpdate:
        self._fields[...] = 0.0
        accumulate_local_grids(self._fields_3d(), lattice, everything)
        self._snapshot = snapshot
        return GridUpdate("rebuild", len(everything), everything.voxels, everything.voxels)

    def _require_std(self) -> None:
        if not self.has_std:
            raise InputError("this grid was made without the std: make it with std=True")

    def _fields_3d(self) -> np.ndarray:
        """The fields as (C,) + the 3D shape the lattice describes (a view)."""
        return self._fields if self.dim == 3 else self._fields[..., None]
