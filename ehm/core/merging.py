"""How a batch's new clusters join the map (Alg. 2 lines 4-21): each merges into the map's
nearest cluster of its scale and label when their anisotropic distance (Eq. 14) is below the
threshold, or joins with weight 0."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.clusters import ClusterSet
from ehm.core.grouping import NewClusters
from ehm.core.index import ClusterIndex
from ehm.core.kernels import covariance_square_roots


@dataclass(frozen=True)
class Absorbed:
    """What `absorb_clusters` did: changed, (R,) int64 rows of the clusters merged into or
    added; n_new clusters added; n_merged new clusters merged into the map's."""

    changed: np.ndarray
    n_new: int
    n_merged: int


def absorb_clusters(
    clusters: ClusterSet, index: ClusterIndex, new: NewClusters, config: MapConfig
) -> Absorbed:
    """Merge each new cluster into `clusters` (found through `index`, the map's search
    structure before this batch) or append it with weight 0 and the prior precision, with
    `config.merge_rule`; the kernels of every changed cluster are refreshed. In place."""
    targets = match_new_clusters(clusters, index, new, config.merge_threshold, config.min_std)
    merging = targets >= 0
    if merging.any():
        merge = merge_pooled if config.merge_rule == "pooled" else merge_average
        joining = new.subset(merging)
        merge(clusters, targets[merging], joining.means, joining.covariances, joining.counts)
    start = len(clusters)
    added = new.subset(~merging)
    clusters.append(
        added.means,
        added.covariances,
        added.counts,
        added.coarse,
        added.occupied,
        config.prior_precision,
    )
    changed = np.concatenate([np.unique(targets[merging]), np.arange(start, len(clusters))])
    clusters.refresh(changed, config)
    return Absorbed(changed, len(added), int(merging.sum()))


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
    new: NewClusters,
    threshold: float,
    min_std: float,
    candidates: int = 4,
) -> np.ndarray:
    """For each new cluster, the map cluster of the same scale and label (occupied or free)
    it merges into (anisotropic distance of Eq. 14 below `threshold`, nearest of `candidates`
    centres in `index`, the map's), or -1 to add it. Returns (n,) int64."""
    n = len(new)
    targets = np.full(n, -1, dtype=np.int64)
    if n == 0 or len(clusters) == 0:
        return targets
    nearest = np.empty((n, candidates), dtype=np.int64)
    for coarse in (False, True):
        rows = new.coarse == coarse
        nearest[rows] = index.nearest_of_scale(new.means[rows], coarse, candidates)
    found = nearest >= 0
    found[found] = (
        clusters.occupied[nearest[found]]
        == np.broadcast_to(new.occupied[:, None], found.shape)[found]
    )
    pair_new = np.nonzero(found)[0]
    pair_old = nearest[found]
    distances = np.full((n, candidates), np.inf)
    distances[found] = anisotropic_distances(
        new.means[pair_new],
        covariance_square_roots(new.covariances, min_std)[pair_new],
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
