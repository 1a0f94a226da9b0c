"""Surface meshes of occupancy grids by marching cubes (Lorensen & Cline, 1987)."""

from __future__ import annotations

import numpy as np

from ehm.errors import InputError


def marching_cubes(
    probability: np.ndarray, origin: np.ndarray, resolution: float, level: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Iso-surface at `level` of a 3D grid of probabilities (nx, ny, nz) whose voxel (0, 0, 0)
    has its low corner at `origin` (3,), metres, world frame, voxels `resolution` metres wide.

    Returns vertices (V, 3) float64, metres, world frame, and faces (F, 3) int64 rows of
    `vertices`. A face (a, b, c) is wound so that (b - a) x (c - a) points from occupied
    (p > level) into free space. Both are empty when the probability never crosses `level`."""
    from skimage.measure import marching_cubes as skimage_marching_cubes

    if probability.ndim != 3:
        raise InputError(f"marching cubes needs a 3D grid, got {probability.ndim} dimensions")
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be a probability between 0 and 1, got {level}")
    empty = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if min(probability.shape) < 2 or probability.max() <= level or probability.min() >= level:
        return empty
    vertices, faces, _, _ = skimage_marching_cubes(
        probability, level, spacing=(resolution,) * 3, allow_degenerate=False
    )
    vertices = vertices.astype(np.float64) + origin + 0.5 * resolution
    # scikit-image winds faces toward larger values; reverse them to face free space.
    return vertices, faces[:, ::-1].astype(np.int64)
