"""Signed distance fields on a grid as .npz files: distance and gradient at each voxel centre,
origin, resolution, the level and the rule for unknown space they were measured for."""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.io.files import read_archive

# Thickness, metres, of the slabs a distance grid is asked in.
SLAB_METRES = 8.0


@dataclass(frozen=True)
class DistanceGrid:
    """Signed distances at voxel centres. origin: (d,) metres, world frame, low corner of voxel
    (0, ..., 0); resolution: voxel side, metres; distance: float64 array of the grid's shape,
    metres to the nearest point whose occupancy reaches `level`, negative inside; gradient:
    that shape + (d,), unit vectors away from the nearest obstacle (0 beyond the map's reach);
    unknown_is_occupied: unknown space counted as an obstacle."""

    origin: np.ndarray
    resolution: float
    distance: np.ndarray
    gradient: np.ndarray
    level: float
    unknown_is_occupied: bool

    @classmethod
    def at_centres(
        cls,
        any_map,
        origin: np.ndarray,
        resolution: float,
        shape: tuple[int, ...],
        level: float = 0.5,
        unknown: str = "occupied",
    ) -> DistanceGrid:
        """The distances `any_map` (a HilbertMap or a TiledMap) tells at the centres of voxels
        of `resolution` metres, `shape` voxels per axis from `origin` ((d,) metres), unknown
        space an obstacle ("occupied") or free ("free"). Asked slab by slab, SLAB_METRES thick
        along x, so a map too large for one distance field answers each slab from a field
        around it (HilbertMap.distance)."""
        dim = len(shape)
        distance = np.empty(shape)
        gradient = np.empty((*shape, dim))
        axes = [origin[a] + (np.arange(n) + 0.5) * resolution for a, n in enumerate(shape)]
        slab = max(1, int(SLAB_METRES / resolution))
        for start in range(0, shape[0], slab):
            part = [axes[0][start : start + slab], *axes[1:]]
            centres = np.stack(np.meshgrid(*part, indexing="ij"), axis=-1).reshape(-1, dim)
            found, slope = any_map.distance(centres, level, True, unknown)
            rows = slice(start, start + len(part[0]))
            distance[rows] = found.reshape(len(part[0]), *shape[1:])
            gradient[rows] = slope.reshape(len(part[0]), *shape[1:], dim)
        return cls(
            np.asarray(origin, dtype=np.float64),
            float(resolution),
            distance,
            gradient,
            float(level),
            unknown == "occupied",
        )


def save_distance_grid(grid: DistanceGrid, path: str | PathLike[str]) -> None:
    """Write a distance grid as .npz: distance, gradient, origin, resolution, level,
    unknown_is_occupied."""
    np.savez_compressed(
        path,
        distance=grid.distance,
        gradient=grid.gradient,
        origin=grid.origin,
        resolution=grid.resolution,
        level=grid.level,
        unknown_is_occupied=grid.unknown_is_occupied,
    )


def load_distance_grid(path: str | PathLike[str]) -> DistanceGrid:
    """Read a distance grid written by save_distance_grid; FileReadError for a file that is
    not one."""
    names = {"distance", "gradient", "origin", "resolution", "level", "unknown_is_occupied"}
    arrays = read_archive(path, "an ehm distance file", names)
    distance, gradient = arrays["distance"], arrays["gradient"]
    if gradient.shape != (*distance.shape, distance.ndim) or arrays["origin"].shape != (
        distance.ndim,
    ):
        raise FileReadError(path, "not an ehm distance file (shapes that do not agree)")
    return DistanceGrid(
        arrays["origin"],
        float(arrays["resolution"]),
        distance,
        gradient,
        float(arrays["level"]),
        bool(arrays["unknown_is_occupied"]),
    )
