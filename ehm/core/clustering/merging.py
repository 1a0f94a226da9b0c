"""How a batch's new clusters join the map (Alg. 2 lines 4-21): each merges into the map's
nearest cluster of its scale and label when their anisotropic distance (Eq. 14) is below the
threshold, or joins with the weight its label gives it (MapConfig.initial_weight)."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.clustering.grouping import NewClusters
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.kernels import Eigen, covariance_square_roots, transform_square_roots
from ehm.core.primitives.eigen import symmetric_eigen
from ehm.core.primitives.hashing import sorted_distinct
from ehm.core.search.kernel_search import MergeCandidates


@dataclass(frozen=True)
class Absorbed:
    """What `absorb_clusters` did: changed, (R,) int64 rows of the clusters merged into or
    added; n_new clusters added; n_merged new clusters merged into the map's."""

    changed: np.ndarray
    n_new: int
    n_merged: int


def absorb_clusters(
    clusters: ClusterSet, candidates: MergeCandidates, new: NewClusters, config: MapConfig
) -> Absorbed:
    """Merge each new cluster into one of its `candidates` among `clusters` (the map's before
    this batch) or append it with the prior precision and, fine, `config.initial_weight` of its
    label's sign (coarse: 0), with `config.merge_rule`; the kernels of every changed cluster are
    refreshed. In place."""
    new_eigen = symmetric_eigen(new.covariances)
    targets = match_new_clusters(clusters, candidates, new, new_eigen, config)
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
        config.initial_weight,
    )
    merged, appended = sorted_distinct(targets[merging]), np.arange(start, len(clusters))
    clusters.refresh(merged, config)
    clusters.refresh(appended, config, tuple(part[~merging] for part in new_eigen))
    return Absorbed(np.concatenate([merged, appended]), len(added), int(merging.sum()))


def anisotropic_distances(
    means_a: np.ndarray,
    roots_a: np.ndarray,
    rows_a: np.ndarray,
    means_b: np.ndarray,
    roots_b: np.ndarray,
    rows_b: np.ndarray,
) -> np.ndarray:
    """Eq. 14 between the clusters rows_a (p,) int64 of a and rows_b (p,) of b, pair by pair:
    sqrt(mu^T Sigma^-1 mu), Sigma = (sqrt(Sigma_a) + sqrt(Sigma_b))^2, mu = mu_a - mu_b, from
    means (n, d) and symmetric covariance roots (n, d, d) of each side (2D or 3D). Returns
    (p,) float64."""
    return _anisotropic_distances(
        means_a,
        roots_a,
        np.asarray(rows_a, np.int64),
        means_b,
        roots_b,
        np.asarray(rows_b, np.int64),
    )


@numba.njit(cache=True, parallel=True)
def _anisotropic_distances(means_a, roots_a, rows_a, means_b, roots_b, rows_b):  # pragma: no cover
    n, d = len(rows_a), means_a.shape[1]
    distances = np.empty(n)
    for p in numba.prange(n):
        i, j = rows_a[p], rows_b[p]
        # |S^-1 mu| with S = root_a + root_b, symmetric: S^-1 = adj(S) / det(S).
        s00 = roots_a[i, 0, 0] + roots_b[j, 0, 0]
        s01 = roots_a[i, 0, 1] + roots_b[j, 0, 1]
        s11 = roots_a[i, 1, 1] + roots_b[j, 1, 1]
        m0 = means_a[i, 0] - means_b[j, 0]
        m1 = means_a[i, 1] - means_b[j, 1]
        if d == 2:
            det = s00 * s11 - s01 * s01
            x0 = (s11 * m0 - s01 * m1) / det
            x1 = (s00 * m1 - s01 * m0) / det
            distances[p] = np.sqrt(x0 * x0 + x1 * x1)
            continue
        s02 = roots_a[i, 0, 2] + roots_b[j, 0, 2]
        s12 = roots_a[i, 1, 2] + roots_b[j, 1, 2]
        s22 = roots_a[i, 2, 2] + roots_b[j, 2, 2]
        m2 = means_a[i, 2] - means_b[j, 2]
        c00 = s11 * s22 - s12 * s12
        c01 = s02 * s12 - s01 * s22
        c02 = s01 * s12 - s02 * s11
        c11 = s00 * s22 - s02 * s02
        c12 = s01 * s02 - s00 * s12
        c22 = s00 * s11 - s01 * s01
        det = s00 * c00 + s01 * c01 + s02 * c02
        x0 = (c00 * m0 + c01 * m1 + c02 * m2) / det
        x1 = (c01 * m0 + c11 * m1 + c12 * m2) / det
        x2 = (c02 * m0 + c12 * m1 + c22 * m2) / det
        distances[p] = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    return distances


def anisotropic_distances_reference(
    means_a: np.ndarray,
    roots_a: np.ndarray,
    rows_a: np.ndarray,
    means_b: np.ndarray,
    roots_b: np.ndarray,
    rows_b: np.ndarray,
) -> np.ndarray:
    """Plain NumPy twin of `anisotropic_distances`."""
    offsets = means_a[rows_a] - means_b[rows_b]
    solved = np.linalg.solve(roots_a[rows_a] + roots_b[rows_b], offsets[..., None])[..., 0]
    return np.linalg.norm(solved, axis=-1)


def match_new_clusters(
    clusters: ClusterSet,
    candidates: MergeCandidates,
    new: NewClusters,
    new_eigen: Eigen,
    config: MapConfig,
) -> np.ndarray:
    """For each new cluster, the map cluster it merges into: among its candidates of the same
    scale and label (occupied or free), the one at the smallest anisotropic distance (Eq. 14),
    when that is below `config.merge_threshold`; else -1 to add it. new_eigen: the new
    clusters' covariances decomposed. Returns (n,) int64."""
    targets = np.full(len(new), -1, dtype=np.int64)
    pair_new, pair_old = candidates.pair_new, candidates.pair_old
    alike = (clusters.occupied[pair_old] == new.occupied[pair_new]) & (
        clusters.coarse[pair_old] == new.coarse[pair_new]
    )
    pair_new, pair_old = pair_new[alike], pair_old[alike]
    if len(pair_new) == 0:
        return targets
    # Each covariance's square root once, however many pairs it is in; the map's from their
    # kernel transforms.
    old_rows, old_of_pair = np.unique(pair_old, return_inverse=True)
    old_roots = transform_square_roots(
        clusters.transforms[old_rows],
        clusters.planar_kernel[old_rows],
        clusters.length_scales(old_rows, config),
    )
    distances = anisotropic_distances(
        new.means,
        covariance_square_roots(new.covariances, config.min_std, new_eigen),
        pair_new,
        clusters.means[old_rows],
        old_roots,
        old_of_pair.ravel(),
    )
    # The closest candidate of each new cluster: the first of its pairs by distance.
    order = np.lexsort((distances, pair_new))
    first = order[np.r_[True, pair_new[order][1:] != pair_new[order][:-1]]]
    close = first[distances[first] < config.merge_threshold]
    targets[pair_new[close]] = pair_old[close]
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
    rows = sorted_distinct(targets)
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
