"""The map's clusters: the inducing points of its features, one row per cluster (Eq. 10-12)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.kernels import (
    Eigen,
    kernel_reach,
    kernel_transforms,
    planar_clusters,
)
from ehm.core.primitives.eigen import symmetric_eigen

# The arrays of a ClusterSet kept in 32 bits, computed in 64: the clusters' shapes, statistics
# and optimiser state (a cluster keeps 128 bytes in 3D, not 212). Means, weights and time
# stamps keep 64.
STORED_AS = {
    "covariances": np.float32,
    "counts": np.float32,
    "grad_sq": np.float32,
    "precision": np.float32,
    "transforms": np.float32,
}


@dataclass
class ClusterSet:
    """Inducing points of the map, one row per cluster.

    means: (M, d) float64, metres, world frame. covariances: (M, d, d) float32, m^2. counts: (M,)
    float32, samples the statistics summarise. weights: (M,) float64, classifier weights. grad_sq:
    (M,) float32, AdaGrad accumulators. precision: (M,) float32, precision of each weight's Gaussian
    posterior (ehm.core.weights.posterior). transforms: (M, d, d) float32, 1/m, kernel transforms
    derived from the covariances (see ehm.core.model.kernels). coarse: (M,) bool, True for clusters
    of open free space (see ehm.core.search.index). occupied: (M,) bool, True for clusters of
    occupied samples. planar: (M,) bool, the covariance is flat (see
    ehm.core.model.kernels.planar_clusters). planar_kernel: (M,) bool, the cluster uses the
    planar-surface kernel. Transforms and both planar flags follow from the covariances and the
    map's settings (`refresh`). seen: (M,) float64, seconds, the time stamp of the latest scan
    that brought the cluster evidence, NaN when none did (kept with MapConfig.forget_after).
    Shapes, statistics and optimiser state are kept in 32 bits (see STORED_AS): they are
    computed in 64 and rounded when stored, a relative 6e-8.
    """

    means: np.ndarray
    covariances: np.ndarray
    counts: np.ndarray
    weights: np.ndarray
    grad_sq: np.ndarray
    precision: np.ndarray
    transforms: np.ndarray
    coarse: np.ndarray
    occupied: np.ndarray
    planar: np.ndarray
    planar_kernel: np.ndarray
    seen: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in STORED_AS.items():
            setattr(self, name, np.asarray(getattr(self, name), dtype=dtype))

    @classmethod
    def empty(cls, dim: int) -> ClusterSet:
        flags = [np.zeros(0, dtype=bool) for _ in range(4)]
        return cls(
            np.zeros((0, dim)),
            np.zeros((0, dim, dim)),
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
            np.zeros((0, dim, dim)),
            *flags,
            np.zeros(0),
        )

    def __len__(self) -> int:
        return len(self.means)

    @property
    def dim(self) -> int:
        return self.means.shape[1]

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays().values())

    def append(
        self,
        means: np.ndarray,
        covariances: np.ndarray,
        counts: np.ndarray,
        coarse: np.ndarray,
        occupied: np.ndarray,
        precision: float = 0.0,
        initial_weight: float = 0.0,
    ) -> None:
        """Add clusters with posterior `precision`, no time seen and weight +initial_weight
        where `occupied`, -initial_weight where fine and free, 0 where `coarse` (no prior
        knowledge of their occupancy); `refresh` them before use."""
        n = len(means)
        coarse, occupied = np.asarray(coarse, dtype=bool), np.asarray(occupied, dtype=bool)
        added = {
            "means": means,
            "covariances": covariances,
            "counts": counts,
            "weights": np.where(coarse, 0.0, np.where(occupied, initial_weight, -initial_weight)),
            "grad_sq": np.zeros(n),
            "precision": np.full(n, float(precision)),
            "transforms": np.zeros((n,) + means.shape[1:] * 2),
            "coarse": coarse,
            "occupied": occupied,
            "planar": np.zeros(n, dtype=bool),
            "planar_kernel": np.zeros(n, dtype=bool),
            "seen": np.full(n, np.nan),
        }
        for name, rows in added.items():
            joined = np.concatenate([getattr(self, name), rows], dtype=STORED_AS.get(name))
            setattr(self, name, joined)

    def remove(self, rows: np.ndarray) -> np.ndarray:
        """Drop clusters `rows` ((R,) int64, distinct). The last clusters move into the holes,
        so every other cluster keeps its row. Returns (M - R,) int64: the old row of each."""
        dropped = np.zeros(len(self), dtype=bool)
        dropped[rows] = True
        n_after = len(self) - len(rows)
        source = np.arange(n_after)
        holes = np.flatnonzero(dropped[:n_after])
        source[holes] = np.flatnonzero(~dropped[n_after:]) + n_after
        for name, array in self.arrays().items():
            setattr(self, name, array[source])
        return source

    def reach(self) -> np.ndarray:
        """(M,) metres: how far from its mean each cluster's kernel is non-zero."""
        return kernel_reach(self.transforms, self.planar_kernel)

    def refresh(self, rows: np.ndarray, config: MapConfig, eigen: Eigen | None = None) -> None:
        """Recompute what follows from the statistics of clusters `rows` after they changed:
        planar flags and kernel transforms; `eigen`: their covariances decomposed, when it is
        known."""
        if len(rows) == 0:
            return
        covariances = self.covariances[rows]
        if eigen is None:
            eigen = symmetric_eigen(covariances)  # once, for both
        self.planar[rows] = planar_clusters(covariances, config.planar_ratio, eigen)
        self.planar_kernel[rows] = self.planar[rows] & config.planar_kernel
        self.transforms[rows] = kernel_transforms(
            covariances,
            self.length_scales(rows, config),
            config.min_std,
            self.planar_kernel[rows],
            eigen,
        )

    def length_scales(self, rows: np.ndarray, config: MapConfig) -> np.ndarray:
        """(k,) the standard deviations the k_SP kernels of clusters `rows` span:
        config.occupied_length_scale for occupied clusters, config.length_scale for free."""
        return np.where(self.occupied[rows], config.occupied_length_scale, config.length_scale)


@dataclass(frozen=True)
class ClusterView:
    """A copy of a map's clusters for users, one row per cluster.

    means: (M, d) float64, metres, world frame. covariances: (M, d, d) float64, m^2.
    weights: (M,) float64, log-odds each kernel adds at its peak. counts: (M,) float64,
    samples behind each cluster. kind: (M,) str, 'planar' (walls, floors: flat clusters) or
    'volumetric'. kernel: (M,) str, 'planar' (Eq. 13) or 'local' (k_SP with localized
    length-scales). scale: (M,) str, 'fine' or 'coarse' (open free space along rays).
    occupied: (M,) bool, built from occupied samples (else free ones).
    """

    means: np.ndarray
    covariances: np.ndarray
    weights: np.ndarray
    counts: np.ndarray
    kind: np.ndarray
    kernel: np.ndarray
    scale: np.ndarray
    occupied: np.ndarray

    @classmethod
    def of(cls, clusters: ClusterSet) -> ClusterView:
        return cls(
            clusters.means.copy(),
            clusters.covariances.astype(np.float64),
            clusters.weights.copy(),
            clusters.counts.astype(np.float64),
            np.where(clusters.planar, "planar", "volumetric"),
            np.where(clusters.planar_kernel, "planar", "local"),
            np.where(clusters.coarse, "coarse", "fine"),
            clusters.occupied.copy(),
        )

    def __len__(self) -> int:
        return len(self.means)
