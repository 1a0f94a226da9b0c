"""Occupancy grids by incremental grid reconstruction (Sec. 3.5, Eq. 17-18).

The local grids of a map's clusters (ehm.grid.local_grids) add up to a global score grid
s_g = sum_m w_m k(x_g, M_m) (Eq. 17), and p_g = sigmoid(s_g) (Eq. 18). Kernel values are
recomputed when needed rather than stored, which keeps a grid's memory at its voxels.

A grid is fed snapshots of a map (ehm.core.snapshot), never the map itself, and keeps the
last one. `OccupancyGrid.update` takes out the old contribution of every cluster whose mean,
kernel or weight changed since, puts in the new one and adds new clusters; when that is more
work than starting over, or the snapshot comes from another map or a refit, it rebuilds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.core.logistic import sigmoid
from ehm.core.snapshot import MapSnapshot
from ehm.grid.bounds import DEFAULT_MAX_BYTES, grid_shape, support_bounds
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
    metres. shape: voxels per axis. scores: array of `shape`, log-odds w^T phi at each voxel
    centre (Eq. 17); probability: p(occupied) there (Eq. 18). Build one with
    HilbertMap.grid or `OccupancyGrid.of`; `update` brings it up to date with a newer snapshot.
    """

    def __init__(self, origin: np.ndarray, resolution: float, shape: tuple[int, ...]) -> None:
        self.origin = np.asarray(origin, dtype=np.float64)
        self.resolution = float(resolution)
        self.scores = np.zeros(shape)
        self.intercept = 0.0
        self._probability: np.ndarray | None = None
        self._snapshot: MapSnapshot | None = None

    @classmethod
    def of(
        cls,
        snapshot: MapSnapshot,
        bounds: np.ndarray | None = None,
        resolution: float = 0.05,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ) -> OccupancyGrid:
        """The grid of a map's snapshot over `bounds` ((2, d) metres, [low corner, high
        corner]; None: the box holding every kernel's support) at `resolution` metres.
        ValueError for bad bounds or resolutions and for grids over `max_bytes`, before
        allocating."""
        if bounds is None:
            bounds = support_bounds(snapshot)
        origin, shape = grid_shape(bounds, resolution, snapshot.dim, max_bytes)
        grid = cls(origin, resolution, shape)
        grid.update(snapshot)
        return grid

    @property
    def shape(self) -> tuple[int, ...]:
        return self.scores.shape

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
            self._probability = sigmoid(self.scores + self.intercept)
        return self._probability

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
            raise ValueError(
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
            raise ValueError(f"the grid is {self.dim}D, the map is {snapshot.dim}D")
        lattice = Lattice.lift(self.origin, self.resolution, self.shape)
        self.intercept = snapshot.intercept
        self._probability = None
        everything = LocalGrids.of(snapshot, np.arange(len(snapshot)), lattice)
        old = self._snapshot
        if old is None or old.lineage is not snapshot.lineage:
            return self._rebuild(snapshot, lattice, everything)
        n_old, n_new = len(old), len(snapshot)
        n_both = min(n_old, n_new)
        # Rows present before and now that differ, rows only before (clusters merged away)
        # and rows only now (new clusters).
        changed = np.flatnonzero(
            (snapshot.weights[:n_both] != old.weights[:n_both])
            | np.any(snapshot.means[:n_both] != old.means[:n_both], axis=1)
            | np.any(snapshot.transforms[:n_both] != old.transforms[:n_both], axis=(1, 2))
            | (snapshot.planar_kernel[:n_both] != old.planar_kernel[:n_both])
        )
        removed_rows = np.concatenate([changed, np.arange(n_both, n_old)])
        removed = LocalGrids.of(old, removed_rows, lattice, sign=-1.0)
        added_rows = np.concatenate([changed, np.arange(n_both, n_new)])
        added = LocalGrids.of(snapshot, added_rows, lattice)
        voxels = removed.voxels + added.voxels
        if voxels >= everything.voxels:
            return self._rebuild(snapshot, lattice, everything)
        accumulate_local_grids(self._scores_3d(), lattice, removed)
        accumulate_local_grids(self._scores_3d(), lattice, added)
        self._snapshot = snapshot
        return GridUpdate("incremental", len(removed) + len(added), voxels, everything.voxels)

    def _rebuild(
        self, snapshot: MapSnapshot, lattice: Lattice, everything: LocalGrids
    ) -> GridUpdate:
        self.scores[...] = 0.0
        accumulate_local_grids(self._scores_3d(), lattice, everything)
        self._snapshot = snapshot
        return GridUpdate("rebuild", len(everything), everything.voxels, everything.voxels)

    def _scores_3d(self) -> np.ndarray:
        """The scores as the 3D array the lattice describes (a view)."""
        return self.scores if self.dim == 3 else self.scores[:, :, None]
