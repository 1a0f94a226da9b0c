"""Occupancy grids as .npz files: probability, scores, intercept, origin, resolution."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.grid.occupancy_grid import OccupancyGrid


def save_grid(grid: OccupancyGrid, path: str | PathLike[str]) -> None:
    """Write a grid as .npz: probability, scores, intercept, origin, resolution."""
    np.savez_compressed(
        path,
        probability=grid.probability,
        scores=grid.scores,
        intercept=grid.intercept,
        origin=grid.origin,
        resolution=grid.resolution,
    )


def load_grid(path: str | PathLike[str]) -> OccupancyGrid:
    """Read a grid written by save_grid (it no longer follows any map); ValueError for a file
    that lacks its arrays."""
    with np.load(path) as data:
        missing = {"scores", "intercept", "origin", "resolution"} - set(data.files)
        if missing:
            raise ValueError(f"{path}: not an ehm grid file (no {', '.join(sorted(missing))})")
        grid = OccupancyGrid(data["origin"], float(data["resolution"]), data["scores"].shape)
        grid.scores[...] = data["scores"]
        grid.intercept = float(data["intercept"])
    return grid
