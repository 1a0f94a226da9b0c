"""The map's clusters and how a new scan's clusters join them (Alg. 2 lines 4-21)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ehm.config import MapConfig
from ehm.index import ClusterIndex
from ehm.kernels import (
    covariance_square_roots,
    kernel_reach,
    kernel_transforms,
    planar_clusters,
)


@dataclass
class ClusterSet:
    """Inducing points of the map, one row per cluster.

    means: (M, d) float64, metres, world frame. covariances: (M, d, d) float64, m^2.
    counts: (M,) float64, samples the statistics summarise. weights: (M,) float64, classifier
    weights. grad_sq: (M,) float64, AdaGrad accumulators. transforms: (M, d, d) float64, 1/m,
    kernel transforms derived from the covariances (see ehm.kernels). coarse: (M,) bool, True
    for clusters of open free space (see ehm.index). occupied: (M,) bool, True for clusters
    of occupied samples. planar: (M,) bool, the covariance is flat (see
    ehm.kernels.planar_clusters). planar_kernel: (M,) bool, the cluster uses the
    planar-surface kernel. Transforms and both planar flags follow from the covariances and
    the map's settings (`refresh`).
    """

    means: np.ndarray
    covariances: np.ndarray
    counts: np.ndarray
    weights: np.ndarray
    grad_sq: np.ndarray
    transforms: np.ndarray
    coarse: np.ndarray
    occupied: np.ndarray
    planar: np.ndarray
    planar_kernel: np.ndarray

    @classmethod
    def empty(cls, dim: int) -> ClusterSet:
        flags = [np.zeros(0, dtype=bool) for _ in range(4)]
        return cls(
            np.zeros((0, dim)),
            np.zeros((0, dim, dim)),
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
            np.zeros((0, dim, dim)),
            *flags,
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
    ) -> None:
        """Add clusters with weight 0 (no prior knowledge of their occupancy); `refresh` them
        before use."""
        n = len(means)
        self.means = np.concatenate([self.means, means])
        self.covariances = np.concatenate([self.covariances, covariances])
        self.counts = np.concatenate([self.counts, counts.astype(np.float64)])
        self.weights = np.concatenate([self.weights, np.zeros(n)])
        self.grad_sq = np.concatenate([self.grad_sq, np.zeros(n)])
        self.transforms = np.concatenate([self.transforms, np.zeros((n,) + means.shape[1:] * 2)])
        self.coarse = np.concatenate([self.coarse, np.asarray(coarse, dtype=bool)])
        self.occupied = np.concatenate([self.occupied, np.asarray(occupied, dtype=bool)])
        self.planar = np.concatenate([self.planar, np.zeros(n, dtype=bool)])
        self.planar_kernel = np.concatenate([self.planar_kernel, np.zeros(n, dtype=bool)])

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

    def index(self) -> ClusterIndex:
        """kd-trees over the current centres, bounded by the kernels' reach."""
        return ClusterIndex(self.means, self.coarse, self.reach())

    def refresh(self, rows: np.ndarray, config: MapConfig) -> None:
        """Recompute what follows from the statistics of clusters `rows` after they changed:
        planar flags and kernel transforms."""
        if len(rows) == 0:
            return
        self.planar[rows] = planar_clusters(self.covariances[rows], config.planar_ratio)
        self.planar_kernel[rows] = self.planar[rows] & config.planar_kernel
        self.transforms[rows] = kernel_transforms(
            self.covariances[rows], config.length_scale, config.min_std, self.planar_kernel[rows]
        )


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
            clusters.covariances.copy(),
            clusters.weights.copy(),
            clusters.counts.copy(),
            np.where(clusters.planar, "planar", "volumetric"),
            np.where(clusters.planar_kernel, "planar", "local"),
            np.where(clusters.coarse, "coarse", "fine"),
            clusters.occupied.copy(),
        )

    def __len__(self) -> int:
        return len(self.means)


def anisotropic_distances(
    means_a: np.ndarray, roots_a: np.ndarray, means_b: np.ndarray, roots_b: np.ndarray
) -> np.ndarray:
    """Eq. 14 between rows of a and rows of b: sqrt(mu^T Sigma^-1 mu), Sigma = (sqrt(Sigma_a) +
    sqrt(Sigma_b))^2, mu = mu_a - mu_b. Inputs (n, d) and (n, d, d); returns (n,)."""
    offsets = means_a - means_b
    solved = np.linalg.solve(roots_a + roots_b, offsets[..., None])[..., 0]
    return np.linalg.norm(solved, axis=-1)


def match_new_clusters(
    clusters: ClusterSet,
    index: ClusterIndex,
    new_means: np.ndarray,
    new_covariances: np.ndarray,
    new_coarse: np.ndarray,
    new_occupied: np.ndarray,
    threshold: float,
    min_std: float,
    candidates: int = 4,
) -> np.ndarray:
    """For each new cluster, the map cluster of the same scale and label (occupied or free)
    it merges into (anisotropic distance of Eq. 14 below `threshold`, nearest of `candidates`
    centres), or -1 to add it. Returns (n,) int64."""
    n = len(new_means)
    targets = np.full(n, -1, dtype=np.int64)
    if n == 0 or len(clusters) == 0:
        return targets
    nearest = np.empty((n, candidates), dtype=np.int64)
    for coarse in (False, True):
        rows = new_coarse == coarse
        nearest[rows] = index.nearest_of_scale(new_means[rows], coarse, candidates)
    found = nearest >= 0
    found[found] = (
        clusters.occupied[nearest[found]]
        == np.broadcast_to(new_occupied[:, None], found.shape)[found]
    )
    pair_new = np.nonzero(found)[0]
    pair_old = nearest[found]
    distances = np.full((n, candidates), np.inf)
    distances[found] = anisotropic_distances(
        new_means[pair_new],
        covariance_square_roots(new_covariances, min_std)[pair_new],
        clusters.means[pair_old],
        covariance_square_roots(clusters.covariances[pair_old], min_std),
    )
    best = np.argmin(distances, axis=1)
    closest = distances[np.arange(n), best]
    merging = closest < threshold
    targets[merging] = nearest[np.arange(n), best][merging]
    return targets


def merge_pooled(
    clusters: ClusterSet,
    targets: np.ndarray,
    means: np.ndarray,
    covariances: np.ndarray,
    counts: np.ndarray,
) -> None:
    """Merge new clusters into `targets` with the exact pooled mean and covariance of the
    union of their samples (each side's statistics weighted by its sample count)."""
    d = clusters.dim
    rows = np.unique(targets)
    n_old = clusters.counts[rows]
    old_mean = clusters.means[rows]
    # Sufficient statistics about the old mean, so the pooled update is order-free and exact.
    count = n_old.copy()
    first = np.zeros((len(rows), d))
    second = clusters.covariances[rows] * np.maximum(n_old - 1.0, 0.0)[:, None, None]
    slot = np.searchsorted(rows, targets)
    n_new = counts.astype(np.float64)
    offset = means - old_mean[slot]
    scatter = covariances * np.maximum(n_new - 1.0, 0.0)[:, None, None] + n_new[
        :, None, None
    ] * np.einsum("ni,nj->nij", offset, offset)
    np.add.at(count, slot, n_new)
    np.add.at(first, slot, n_new[:, None] * offset)
    np.add.at(second, slot, scatter)
    shift = first / count[:, None]
    clusters.means[rows] = old_mean + shift
    clusters.covariances[rows] = (
        second - count[:, None, None] * np.einsum("ni,nj->nij", shift, shift)
    ) / np.maximum(count - 1.0, 1.0)[:, None, None]
    clusters.counts[rows] = count


def merge_average(
    clusters: ClusterSet,
    targets: np.ndarray,
    means: np.ndarray,
    covariances: np.ndarray,
    counts: np.ndarray,
) -> None:
    """The paper's rule (Alg. 2 lines 19-20): mu_j <- (mu_i + mu_j) / 2 and Sigma_j <-
    (Sigma_i + Sigma_j) / 2, applied to each new cluster in turn. A target merged m times keeps
    2^-m of its old value and new cluster number q (1-based, in order) gets 2^-(m - q + 1)."""
    rows, times = np.unique(targets, return_counts=True)
    order = np.argsort(targets, kind="stable")
    slot = np.searchsorted(rows, targets[order])
    rank = np.arange(1, len(order) + 1) - np.repeat(np.cumsum(times) - times, times)
    share = 0.5 ** (times[slot] - rank + 1).astype(np.float64)
    keep = 0.5 ** times.astype(np.float64)
    new_mean = clusters.means[rows] * keep[:, None]
    new_cov = clusters.covariances[rows] * keep[:, None, None]
    np.add.at(new_mean, slot, means[order] * share[:, None])
    np.add.at(new_cov, slot, covariances[order] * share[:, None, None])
    clusters.means[rows] = new_mean
    clusters.covariances[rows] = new_cov
    np.add.at(clusters.counts, targets, counts.astype(np.float64))
