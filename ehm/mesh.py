"""Surface meshes of occupancy grids by marching cubes (Lorensen & Cline, 1987)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ehm.grid import OccupancyGrid


def marching_cubes(grid: OccupancyGrid, level: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Iso-surface of a 3D grid's probability at `level`: vertices (V, 3) float64, metres,
    world frame, and faces (F, 3) int64 rows of `vertices`. A face (a, b, c) is wound so that
    (b - a) x (c - a) points from occupied (p > level) into free space. Both are empty when the
    probability never crosses `level`."""
    from skimage.measure import marching_cubes as skimage_marching_cubes

    if grid.dim != 3:
        raise ValueError(
            "a mesh needs a 3D grid; a 2D map's grid is an image: render it or save the grid"
        )
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be a probability between 0 and 1, got {level}")
    probability = grid.probability
    empty = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if min(grid.shape) < 2 or probability.max() <= level or probability.min() >= level:
        return empty
    vertices, faces, _, _ = skimage_marching_cubes(
        probability, level, spacing=(grid.resolution,) * 3, allow_degenerate=False
    )
    vertices = vertices.astype(np.float64) + grid.origin + 0.5 * grid.resolution
    # scikit-image winds faces toward larger values; reverse them to face free space.
    return vertices, faces[:, ::-1].astype(np.int64)
