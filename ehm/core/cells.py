"""Integer cells of a regular grid over a point set, and one linear key per cell."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CellKeys:
    """cells: (n, d) int64 cell of each point, counted from the set's lower corner. extents:
    (d,) cells per axis. strides: (d,) key step per axis. keys: (n,) int64, cells @ strides."""

    cells: np.ndarray
    extents: np.ndarray
    strides: np.ndarray
    keys: np.ndarray


def cell_keys(points: np.ndarray, cell: float) -> CellKeys:
    """Cells of side `cell` metres of (n >= 1, d) points, metres; ValueError when the keys would
    overflow 64 bits."""
    cells = np.floor((points - points.min(axis=0)) / cell).astype(np.int64)
    extents = cells.max(axis=0) + 1
    if np.prod(extents.astype(np.float64)) > 2.0**62:
        raise ValueError(f"points span too many cells of {cell} m: cell keys overflow")
    strides = np.cumprod(np.concatenate([[1], extents[:-1]])).astype(np.int64)
    return CellKeys(cells, extents, strides, cells @ strides)
