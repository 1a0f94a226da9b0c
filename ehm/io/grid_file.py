"""Occupancy grids as .npz files: probability, scores, intercept, origin, resolution, and for
grids with the occupancy's standard deviation, std and the variance sums it comes from."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.grid.occupancy_grid import OccupancyGrid


def save_grid(grid: OccupancyGrid, path: str | PathLike[str]) -> None:
    """Write a grid as .npz: probability, scores, intercept, origin, resolution; with the std
    also std, variance_sums ((2,) + shape: sum k^2 / lambda, sum k) and prior_precision."""
    arrays = {
        "probability": grid.probability,
        "scores": grid.scores,
        "intercept": grid.intercept,
        "origin": grid.origin,
        "resolution": grid.resolution,
    }
    if grid.has_std:
        arrays |= {
            "std": grid.std,
            "variance_sums": grid.variance_sums,
            "prior_precision": grid.prior_precision,
        }
    np.savez_compressed(path, **arrays)


def load_grid(path: str | PathLike[str]) -> OccupancyGrid:
    """Read a grid written by save_grid (it no longer follows any map); ValueError for a file
    that lacks its arrays."""
    with np.load(path) as data:
        missing = {"scores", "intercept", "origin", "resolution"} - set(data.files)
        if missing:
            raise ValueError(f"{path}: not an ehm grid file (no {', '.join(sorted(missing))})")
        with_std = "variance_sums" in data.files
        if with_std and "prior_precision" not in data.files:
            raise ValueError(
                f"{path}: not an ehm grid file (variance_sums without prior_precision)"
            )
        shape = data["scores"].shape
        grid = OccupancyGrid(data["origin"], float(data["resolution"]), shape, with_std)
        grid.scores[...] = data["scores"]
        grid.intercept = float(data["intercept"])
        if with_std:
            grid.variance_sums[...] = data["variance_sums"]
            grid.prior_precision = float(data["prior_precision"])
    return grid
