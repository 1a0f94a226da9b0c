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
    the map is refitted, so a grid can tell a map that grew from one that started over. scale:
    what the map's log-odds are read times, w^T phi + intercept to calibrated log-odds
    (ehm.core.weights.calibration).
    """

    means: np.ndarray
    transforms: np.ndarray
    weights: np.ndarray
    precision: np.ndarray
    planar_kernel: np.ndarray
    intercept: float
    prior_precision: float
    lineage: object
    scale: float = 1.0

    def __post_init__(self) -> None:
        arrays = (self.means, self.transforms, self.weights, self.precision, self.planar_kernel)
        for array in arrays:
            array.flags.writeable = False

    @property
    def dim(self) -> int:
        return self.means.shape[1]

    def __len__(self) -> int:
        return len(self.means)

    def changes_from(
        self, old: MapSnapshot, with_precision: bool = False, with_weights: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """What changed since `old`, a snapshot of the same map (rows are clusters, kept in
        place; rows past the end were added or merged away): (rows of `old` whose kernel or
        weight changed or is gone, rows of this snapshot whose kernel or weight changed or is
        new), int64. with_precision: a changed precision counts as a change too;
        with_weights False: only kernels (means, transforms, kind) count."""
        n_both = min(len(old), len(self))
        differs = (
            (with_weights & (self.weights[:n_both] != old.weights[:n_both]))
            | np.any(self.means[:n_both] != old.means[:n_both], axis=1)
            | np.any(self.transforms[:n_both] != old.transforms[:n_both], axis=(1, 2))
            | (self.planar_kernel[:n_both] != old.planar_kernel[:n_both])
        )
        if with_precision:
            differs |= self.precision[:n_both] != old.precision[:n_both]
        changed = np.flatnonzero(differs)
        return (
            np.concatenate([changed, np.arange(n_both, len(old))]),
            np.concatenate([changed, np.arange(n_both, len(self))]),
        )
