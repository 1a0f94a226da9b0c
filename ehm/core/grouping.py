"""The clustering step of Alg. 2 (lines 1-3): quick-means (Alg. 1) over one batch of training
samples, giving the new clusters and the groups of samples that share a neighbour search."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.features import PointGroups
from ehm.core.quickmeans import kmeans_refine, quick_means
from ehm.core.samples import TrainingSamples


@dataclass(frozen=True)
class NewClusters:
    """Clusters found in one batch of samples, not yet in the map. means (C, d) metres,
    covariances (C, d, d) m^2, counts (C,) samples within the outer radius, coarse (C,) bool
    scale, occupied (C,) bool label (the majority of the samples each seed took)."""

    means: np.ndarray
    covariances: np.ndarray
    counts: np.ndarray
    coarse: np.ndarray
    occupied: np.ndarray

    def __len__(self) -> int:
        return len(self.means)

    def subset(self, rows: np.ndarray) -> NewClusters:
        """The clusters at `rows` (boolean mask or indices)."""
        return NewClusters(
            self.means[rows],
            self.covariances[rows],
            self.counts[rows],
            self.coarse[rows],
            self.occupied[rows],
        )


@dataclass(frozen=True)
class SampleGroups:
    """Samples grouped for neighbour search, and the new clusters found among them.

    groups: one group per quick-means seed, centred on its mean (also the seeds too small to
    be clusters). clusters: the seeds kept as clusters proper. in_cluster: (n,) bool, the
    seed that took each sample is one of them.
    """

    groups: PointGroups
    clusters: NewClusters
    in_cluster: np.ndarray


def group_samples(
    samples: TrainingSamples, config: MapConfig, rng: np.random.Generator
) -> SampleGroups:
    """Quick-means over the samples. With `cluster_free_apart`, occupied samples, free samples
    around hits (both fine, `cluster_radius`) and free samples along rays (coarse,
    `free_cluster_radius`) are clustered each on their own; otherwise all at once (fine)."""
    if config.cluster_free_apart:
        free = ~samples.occupied
        parts = [
            (np.flatnonzero(samples.occupied), config.cluster_radius, False),
            (np.flatnonzero(free & samples.at_surface), config.cluster_radius, False),
            (np.flatnonzero(free & ~samples.at_surface), config.free_cluster_radius, True),
        ]
    else:
        parts = [(np.arange(len(samples)), config.cluster_radius, False)]
    group_of_point = np.empty(len(samples), dtype=np.int64)
    in_cluster = np.empty(len(samples), dtype=bool)
    centres, means, covariances, counts, coarse, occupied = [], [], [], [], [], []
    n_groups = 0
    for rows, radius, is_coarse in parts:
        points = samples.points[rows]
        outer = radius * config.outer_radius_factor
        weights = samples.weight[rows]
        scatter = None if samples.scatter is None else samples.scatter[rows]
        result = quick_means(points, radius, outer, config.min_cluster_size, rng, weights, scatter)
        result = kmeans_refine(points, result, config.kmeans_iterations, weights, scatter)
        group_of_point[rows] = result.owner + n_groups
        in_cluster[rows] = result.kept[result.owner]
        n_groups += len(result.means)
        centres.append(result.means)
        means.append(result.means[result.kept])
        covariances.append(result.covariances[result.kept])
        counts.append(result.counts[result.kept])
        coarse.append(np.full(int(result.kept.sum()), is_coarse))
        # Label: the majority of the samples each seed took out of the pool.
        n_seeds = len(result.means)
        n_occupied = np.bincount(result.owner, weights * samples.occupied[rows], n_seeds)
        majority = 2 * n_occupied > np.bincount(result.owner, weights, n_seeds)
        occupied.append(majority[result.kept])
    return SampleGroups(
        PointGroups(group_of_point, np.concatenate(centres)),
        NewClusters(
            np.concatenate(means),
            np.concatenate(covariances),
            np.concatenate(counts),
            np.concatenate(coarse),
            np.concatenate(occupied),
        ),
        in_cluster,
    )
