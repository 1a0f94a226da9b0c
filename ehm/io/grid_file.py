"""Occupancy grids as .npz files: probability, scores, intercept, scale, origin, resolution,
and for grids with the occupancy's standard deviation, std and the variance sums it comes
from. Files without a scale (written before maps could calibrate their log-odds) read scale 1."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.io.files import read_archive


def save_grid(grid: OccupancyGrid, path: str | PathLike[str]) -> None:
    """Write a grid as .npz: probability, scores, intercept, scale, origin, resolution; with the std
    also std, variance_sums ((2,) + shape: sum k^2 / lambda, sum k) and prior_precision."""
    arrays = {
        "probability": grid.probability,
        "scores": grid.scores,
        "intercept": grid.intercept,
        "scale": grid.scale,
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
    """Read a grid written by save_grid (it no longer follows any map); FileReadError for a
    file that is not one."""
    names = {"scores", "intercept", "origin", "resolution"}
    arrays = read_archive(path, "an ehm grid file", names)
    with_std = "variance_sums" in arrays
    if with_std and "prior_precision" not in arrays:
        raise FileReadError(path, "not an ehm grid file (variance_sums without prior_precision)")
    try:
        shape = arrays["scores"].shape
        grid = OccupancyGrid(arrays["origin"], float(arrays["resolution"]), shape, with_std)
        grid.scores[...] = arrays["scores"]
        grid.intercept = float(arrays["intercept"])
        grid.scale = float(arrays["scale"]) if "scale" in arrays else 1.0
        if with_std:
            grid.variance_sums[...] = arrays["variance_sums"]
            grid.prior_precision = float(arrays["prior_precision"])
    except (TypeError, ValueError) as error:  # EhmError too
        raise FileReadError(path, f"not an ehm grid file ({error})") from None
    return grid
