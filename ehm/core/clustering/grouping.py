"""The clustering step of Alg. 2 (lines 1-3): quick-means (Alg. 1) over one batch of training
samples, giving the new clusters and the groups of samples that share a neighbour search."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.model.features import PointGroups
from ehm.core.observations.samples import TrainingSamples
from ehm.core.primitives.quickmeans import QuickMeansResult, kmeans_refine, quick_means_in_order


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


@dataclass(frozen=True)
class _Part:
    """Samples clustered on their own: their rows, inner radius (metres), the least weight of
    a cluster and whether their clusters are coarse."""

    rows: np.ndarray
    radius: float
    min_size: float
    coarse: bool = False


def _cluster_part(
    samples: TrainingSamples, part: _Part, order: np.ndarray, config: MapConfig
) -> QuickMeansResult:
    """Quick-means (and k-means refinement) of the samples of `part`, seeds drawn in
    `order`."""
    points = samples.points[part.rows]
    weights = samples.weight[part.rows]
    scatter = None if samples.scatter is None else samples.scatter[part.rows]
    outer = part.radius * config.outer_radius_factor
    result = quick_means_in_order(
        points, part.radius, outer, part.min_size, order, weights, scatter
    )
    return kmeans_refine(points, result, config.kmeans_iterations, weights, scatter)


def _fine_parts(
    kinds: list[tuple[np.ndarray, float]], levels: np.ndarray | None, radius: float
) -> list[_Part]:
    """The parts of fine samples clustered apart: each of `kinds` ((n,) bool, the least weight
    of its clusters), level by level (its samples of level l with 2^l times `radius`), for the
    levels some sample has."""
    if levels is None or not levels.any():
        return [_Part(np.flatnonzero(kind), radius, min_size) for kind, min_size in kinds]
    present = np.flatnonzero(np.bincount(levels))  # counted: a sort costs more
    return [
        _Part(np.flatnonzero(kind & (levels == level)), radius * 2.0**level, min_size)
        for kind, min_size in kinds
        for level in present
    ]


def group_samples(
    samples: TrainingSamples,
    config: MapConfig,
    rng: np.random.Generator,
    levels: np.ndarray | None = None,
) -> SampleGroups:
    """Quick-means over the samples. With `cluster_free_apart`, occupied samples, free samples
    around hits (both fine, `cluster_radius`) and free samples along rays (coarse,
    `free_cluster_radius`) are clustered each on their own, and with `cluster_behind_apart`
    the occupied samples behind hits apart from the rest; otherwise all at once (fine).
    levels: (n,) int64, fine samples of level l are clustered apart, with 2^l times the
    radius (ehm.core.clustering.footprints); None: all of level 0."""
    least = config.min_cluster_size
    if config.cluster_free_apart:
        free = ~samples.occupied
        hit_least = config.min_hit_cluster_size
        if config.cluster_behind_apart:
            # Hits and the samples behind them come in pairs: each half of a cluster the two
            # made together needs half its weight.
            hits = samples.occupied & ~samples.behind
            occupied = [(hits, hit_least / 2.0), (samples.behind, hit_least / 2.0)]
        else:
            occupied = [(samples.occupied, hit_least)]
        fine = [*occupied, (free & samples.at_surface, least)]
        along_rays = np.flatnonzero(free & ~samples.at_surface)
        coarse = [_Part(along_rays, config.free_cluster_radius, least, coarse=True)]
    else:
        fine, coarse = [(np.ones(len(samples), dtype=bool), least)], []
    parts = _fine_parts(fine, levels, config.cluster_radius) + coarse
    group_of_point = np.empty(len(samples), dtype=np.int64)
    in_cluster = np.empty(len(samples), dtype=bool)
    centres, means, covariances, counts, coarse, occupied = [], [], [], [], [], []
    n_groups = 0
    # Each kind is clustered on a thread of its own as far as there are threads, with its seed
    # order drawn here, one after the other, so the threads do not share `rng`. The largest
    # kind starts first: the others follow one another on the other thread (the warehouse's
    # free samples along rays are half its samples; started last, they kept one thread busy
    # alone for most of the stage).
    orders = [rng.permutation(len(part.rows)) for part in parts]
    with ThreadPoolExecutor(min(len(parts), numba.get_num_threads())) as pool:
        started = {
            kind: pool.submit(_cluster_part, samples, parts[kind], orders[kind], config)
            for kind in sorted(range(len(parts)), key=lambda kind: -len(parts[kind].rows))
        }
        results = [started[kind].result() for kind in range(len(parts))]
        for part, result in zip(parts, results, strict=True):
            rows = part.rows
            weights = samples.weight[rows]
            group_of_point[rows] = result.owner + n_groups
            in_cluster[rows] = result.kept[result.owner]
            n_groups += len(result.means)
            centres.append(result.means)
            means.append(result.means[result.kept])
            covariances.append(result.covariances[result.kept])
            counts.append(result.counts[result.kept])
            coarse.append(np.full(int(result.kept.sum()), part.coarse))
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
