"""Occupancy grids as .npz files: probability, scores, intercept, origin, resolution, and for
grids with the occupancy's standard deviation, std and the variance sums it comes from."""

from __future__ import annotations

import io
import zipfile
from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.io.files import read_bytes


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
    """Read a grid written by save_grid (it no longer follows any map); FileReadError for a
    file that is not one."""
    try:
        with np.load(io.BytesIO(read_bytes(path))) as data:
            missing = {"scores", "intercept", "origin", "resolution"} - set(data.files)
            if missing:
                message = f"not an ehm grid file (no {', '.join(sorted(missing))})"
                raise FileReadError(path, message)
            with_std = "variance_sums" in data.files
            if with_std and "prior_precision" not in data.files:
                message = "not an ehm grid file (variance_sums without prior_precision)"
                raise FileReadError(path, message)
            shape = data["scores"].shape
            grid = OccupancyGrid(data["origin"], float(data["resolution"]), shape, with_std)
            grid.scores[...] = data["scores"]
            grid.intercept = float(data["intercept"])
            if with_std:
                grid.variance_sums[...] = data["variance_sums"]
                grid.prior_precision = float(data["prior_precision"])
    except (OSError, EOFError, KeyError, TypeError, ValueError, zipfile.BadZipFile) as error:
        if isinstance(error, FileReadError):
            raise
        raise FileReadError(path, f"not an ehm grid file ({error})") from None
    return grid
