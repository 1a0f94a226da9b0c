"""A map's grid in blocks: cubes of BLOCK_VOXELS voxels a side, on the lattice of multiples
of the resolution (OctoMap's voxels) or of a given box's grid, made only where some kernel's
support reaches. Outputs over maps far larger than any dense grid (a LiDAR sweep reaching
100 m, a street) are made block by block, each block summing only the clusters that reach it
(Eq. 17); a voxel reads the same as in one grid over the whole map.

    for block in grid_blocks(snapshot, 0.2): ...   # OccupancyGrids, one a block
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ehm.core.model.kernels import support_half_widths
from ehm.core.queries.cover import covered_cells
from ehm.core.snapshot import MapSnapshot
from ehm.errors import InputError
from ehm.grid.bounds import DEFAULT_MAX_BYTES, grid_shape
from ehm.grid.mesh import joined_meshes
from ehm.grid.occupancy_grid import OccupancyGrid

# Voxels along a block's edge: large enough that the per-block work is vectorised, small
# enough that blocks follow a surface instead of filling its bounding box.
BLOCK_VOXELS = 32
# Bytes a layout takes, while it is made, for each block a cluster reaches (its key, the
# cluster, the block and their order, int64 each, and sorting's copies).
_PAIR_BYTES = 96


@dataclass(frozen=True)
class BlockLayout:
    """Which blocks a map's kernels reach, and which clusters reach each.

    Voxel i (d integers) has its low corner at anchor + i resolution; block k holds voxels
    k size .. (k + 1) size - 1, and `overlap` more past its high faces (1 for marching cubes,
    whose cubes join neighbouring voxel centres), cut to voxels 0 .. limit - 1 where a limit
    is given. anchor: (d,) metres, world frame; resolution: metres; size: voxels along a
    block's edge; keys: (B, d) int64; start, rows: CSR lists, the clusters
    rows[start[b]:start[b + 1]] reach block b; limit: (d,) int64 voxels, or None."""

    anchor: np.ndarray
    resolution: float
    size: int
    overlap: int
    keys: np.ndarray
    start: np.ndarray
    rows: np.ndarray
    limit: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.keys)

    def voxels(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Block `index`'s first voxel and its voxels per axis ((d,) int64 each; a count of 0
        or less: the block lies past the limit)."""
        first = self.keys[index] * self.size
        stop = first + self.size + self.overlap
        if self.limit is not None:
            first, stop = np.maximum(first, 0), np.minimum(stop, self.limit)
        return first, stop - first


def block_layout(
    snapshot: MapSnapshot,
    resolution: float,
    bounds: np.ndarray | None = None,
    size: int = BLOCK_VOXELS,
    overlap: int = 0,
    closed_below: bool = False,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> BlockLayout:
    """The blocks of `snapshot`'s kernels at `resolution` metres within `bounds` ((2, d)
    metres: voxels from the low corner, as many as cover the box, as OccupancyGrid.of lays
    them; None: all, on multiples of the resolution from the world origin, OctoMap's voxels).
    closed_below: also every block just below one on any axis (the blocks a marching-cubes
    cube can start in, so that a surface at a block's low face is not lost). InputError when
    listing the blocks would take more than `max_bytes` (a resolution far finer than the
    map's), before it is made; blocks are then made one at a time."""
    dim = snapshot.dim
    anchor, limit = np.zeros(dim), None
    if bounds is not None:
        anchor, shape = grid_shape(bounds, resolution, dim, max_bytes=np.inf)
        limit = np.array(shape, dtype=np.int64)
    half = support_half_widths(snapshot.transforms, snapshot.planar_kernel)
    # Voxel i's centre is anchor + (i + 0.5) resolution: the first and last each support covers.
    first = np.ceil((snapshot.means - half - anchor) / resolution - 0.5 - 1e-9).astype(np.int64)
    last = np.floor((snapshot.means + half - anchor) / resolution - 0.5 + 1e-9).astype(np.int64)
    if limit is not None:
        first, last = np.maximum(first, 0), np.minimum(last, limit - 1)
    low = np.floor_divide(first - overlap, size)
    high = np.floor_divide(last, size)
    spans = np.maximum(high - low + 1, 0)
    counts = np.prod(spans, axis=1)
    pair_bytes = int(counts.sum()) * _PAIR_BYTES * (2**dim if closed_below else 1)
    if pair_bytes > max_bytes:
        raise InputError(
            f"listing the blocks the map's kernels reach at {resolution:g} m takes "
            f"{pair_bytes / 2**30:.2f} GiB, more than the limit of {max_bytes / 2**30:.2f} GiB: "
            "coarsen the resolution, shrink the bounds or raise the limit (max_bytes; "
            "--max-gib)"
        )
    reaching = np.flatnonzero(np.all(spans > 0, axis=1))  # clusters within the bounds
    pair_keys, owners = covered_cells(low[reaching], high[reaching])
    cluster = reaching[owners]  # each block a cluster reaches, and that cluster
    if closed_below:
        steps = np.array(np.meshgrid(*[[0, -1]] * dim, indexing="ij")).reshape(dim, -1).T
        extra = (pair_keys[:, None, :] + steps[None, 1:, :]).reshape(-1, dim)
        pair_keys = np.concatenate([pair_keys, extra])
        cluster = np.concatenate([cluster, np.full(len(extra), -1)])  # -1: reaches none
    keys, block = np.unique(pair_keys.reshape(-1, dim), axis=0, return_inverse=True)
    block = block.ravel()
    order = np.lexsort((cluster, block))
    block, cluster = block[order], cluster[order]
    real = cluster >= 0
    start = np.searchsorted(block[real], np.arange(len(keys) + 1))
    return BlockLayout(anchor, float(resolution), size, overlap, keys, start, cluster[real], limit)


def block_grids(
    snapshot: MapSnapshot, layout: BlockLayout, with_std: bool = False
) -> Iterator[tuple[int, OccupancyGrid]]:
    """(block index, its grid) for each block of `layout`, in key order: each grid sums the
    clusters that reach its block, which is what a grid over the whole map holds there."""
    for index in range(len(layout)):
        first, counts = layout.voxels(index)
        if np.any(counts <= 0):
            continue
        rows = layout.rows[layout.start[index] : layout.start[index + 1]]
        origin = layout.anchor + first * layout.resolution
        shape = tuple(int(n) for n in counts)
        grid = OccupancyGrid.of_clusters(snapshot, rows, origin, layout.resolution, shape, with_std)
        yield index, grid


def grid_blocks(
    snapshot: MapSnapshot,
    resolution: float,
    bounds: np.ndarray | None = None,
    with_std: bool = False,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> Iterator[OccupancyGrid]:
    """The grids of the blocks where `snapshot`'s kernels reach, at `resolution` metres,
    within `bounds`; InputError when listing them takes more than `max_bytes` (block_layout)."""
    layout = block_layout(snapshot, resolution, bounds, max_bytes=max_bytes)
    for _, grid in block_grids(snapshot, layout, with_std):
        yield grid


def block_mesh(
    snapshot: MapSnapshot,
    resolution: float,
    bounds: np.ndarray | None = None,
    level: float = 0.5,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> tuple[np.ndarray, np.ndarray]:
    """The surface where the snapshot's occupancy crosses `level`, by marching cubes block by
    block at `resolution` metres within `bounds` (see block_layout): the mesh of one grid over
    them, without ever holding that grid. Vertices (V, 3) float64, metres; faces (F, 3)."""
    layout = block_layout(
        snapshot, resolution, bounds, overlap=1, closed_below=True, max_bytes=max_bytes
    )
    meshes = (grid.mesh(level) for _, grid in block_grids(snapshot, layout))
    return joined_meshes(meshes, resolution)
