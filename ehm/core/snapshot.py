"""A read-only copy of a map's kernel field: what grids and pictures need to know of a map,
without the map (its clusters' kernels and weights, and the intercept queries add)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class MapSnapshot:
    """The kernels of a map at one moment, as read-only arrays, one row per cluster.

    means: (M, d) float64, metres, world frame. transforms: (M, d, d) float64, 1/m, kernel
    transforms (see ehm.core.model.kernels). weights: (M,) float64. precision: (M,) float64, each
    weight's posterior precision, and prior_precision the background feature's (see
    ehm.core.weights.uncertainty). planar_kernel: (M,) bool, the planar-surface kernel. intercept:
    log-odds every query adds. lineage: identifies the map's learning history; it changes when
    the map is refitted, so a grid can tell a map that grew from one that started over.
    """

    means: np.ndarray
    transforms: np.ndarray
    weights: np.ndarray
    precision: np.ndarray
    planar_kernel: np.ndarray
    intercept: float
    prior_precision: float
    lineage: object

    def __post_init__(self) -> None:
        arrays = (self.means, self.transforms, self.weights, self.precision, self.planar_kernel)
        for array in arrays:
            array.flags.writeable = False

    @property
    def dim(self) -> int:
        return self.means.shape[1]

    def __len__(self) -> int:
        return len(self.means)
