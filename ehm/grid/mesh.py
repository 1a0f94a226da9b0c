"""Surface meshes of occupancy grids by marching cubes (Lorensen & Cline, 1987)."""

from __future__ import annotations

from collections.abc import Iterable

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
    if min(probability.shape) < 2 or probability.max() <= level or probability.min() > level:
        return empty
    try:
        vertices, faces, _, _ = skimage_marching_cubes(
            probability, level, spacing=(resolution,) * 3, allow_degenerate=False
        )
    except RuntimeError:  # the crossing makes degenerate faces only, which are left out
        return empty
    vertices = vertices.astype(np.float64) + origin + 0.5 * resolution
    # scikit-image winds faces toward larger values; reverse them to face free space.
    return vertices, faces[:, ::-1].astype(np.int64)


def joined_meshes(
    meshes: Iterable[tuple[np.ndarray, np.ndarray]], resolution: float
) -> tuple[np.ndarray, np.ndarray]:
    """One mesh of meshes that meet along shared faces (the blocks of ehm.grid.blocks):
    vertices closer than a ten-thousandth of `resolution` become one, so the surface stays
    closed across the seams. Returns vertices (V, 3) float64 and faces (F, 3) int64."""
    all_vertices, all_faces, count = [], [], 0
    for vertices, faces in meshes:
        all_vertices.append(vertices)
        all_faces.append(faces + count)
        count += len(vertices)
    if count == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices, faces = np.concatenate(all_vertices), np.concatenate(all_faces)
    keys = np.round(vertices / (resolution * 1e-4)).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    faces = inverse.ravel()[faces]
    whole = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    return vertices[first], faces[whole]
