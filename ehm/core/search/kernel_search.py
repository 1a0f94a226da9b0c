"""The search for each point's kernels, one interface over the two a map can use
(MapConfig.features): every kernel whose support holds the point ('support', a SupportHash)
or the nearest clusters of each group of points ('nearest', a ClusterIndex, Sec. 3.4).

Learning, merging and queries ask a KernelSearch; only this module knows which one it is.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import (
    PointGroups,
    SparseFeatures,
    decision_values,
    group_by_cell,
    training_features,
)
from ehm.core.primitives.hashing import rows_by_rank
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.index import ClusterIndex
from ehm.core.search.supports import SupportHash

ReadRows = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""read(points (n, d) metres, rows (n,) int64) -> (n,) log-odds, each point read from the
kernels found for the place of its row (see KernelSearch.near_reader)."""


@dataclass(frozen=True)
class MergeCandidates:
    """Map clusters a new cluster may merge into, as pairs: pair_new (p,) int64 rows of new
    clusters, pair_old (p,) int64 rows of the map's clusters."""

    pair_new: np.ndarray
    pair_old: np.ndarray


@dataclass(frozen=True)
class KernelSums:
    """What a query reads at (n, d) points: scores (n,) float64 log-odds, the intercept plus
    w^T phi(x), and variance_sums (n, 2) float64 [sum_m phi_m^2 / lambda_m, sum_m phi_m] over
    the kernels found ((0, 2) when not asked for)."""

    scores: np.ndarray
    variance_sums: np.ndarray


class KernelSearch(ABC):
    """Finds the kernels of points among a map's clusters (ClusterSet, metres, the map's own
    frame) and reads what they sum to; kept up to date with `relist` as the clusters change."""

    # True when a point's features are the nearest clusters only, which may leave out a
    # kernel whose support holds it; False when they are every such kernel.
    truncated: bool

    @abstractmethod
    def relist(
        self, clusters: ClusterSet, anchors: AnchorLayers, changed: np.ndarray | None
    ) -> None:
        """Bring the search up to date after the clusters at rows `changed` ((R,) int64) were
        added or changed; None: every cluster (after rows moved)."""

    @abstractmethod
    def features(
        self, points: np.ndarray, clusters: ClusterSet, groups: PointGroups | None = None
    ) -> SparseFeatures:
        """Training features of (n, d) points, metres (Alg. 2 lines 22-25); groups, where
        the search shares one search per group (see `shares_searches`)."""

    @abstractmethod
    def merge_candidates(
        self, means: np.ndarray, coarse: np.ndarray, clusters: ClusterSet
    ) -> MergeCandidates:
        """The clusters each new cluster ((m, d) means, metres, (m,) bool scale) may merge
        into (Alg. 2 lines 4-21)."""

    @abstractmethod
    def rows(
        self, points: np.ndarray, clusters: ClusterSet, mode: str
    ) -> tuple[np.ndarray, np.ndarray]:
        """The clusters each of (n, d) points reads in query `mode`, as compressed rows:
        indptr (n + 1,) and rows (nnz,) int64 (see SparseFeatures)."""

    @abstractmethod
    def sums(
        self,
        points: np.ndarray,
        clusters: ClusterSet,
        intercept: float,
        with_variance: bool,
        mode: str,
        cell: float,
    ) -> KernelSums:
        """The log-odds at (n, d) finite points, metres (Alg. 3), plus `intercept`, and with
        `with_variance` their variance sums. mode 'batch' shares a search among the points of
        each cell `cell` metres wide, 'exact' searches for each point."""

    @abstractmethod
    def near_reader(
        self, places: np.ndarray, spread: float, clusters: ClusterSet, intercept: float
    ) -> ReadRows:
        """What reads the log-odds at points within `spread` metres of (m, d) `places`, as a
        query in mode 'exact' reads each point, from one search per place where the search
        needs one."""

    @property
    @abstractmethod
    def shares_searches(self) -> bool:
        """True when training points share one search per group of nearby points, so the
        features want the groups quick-means formed."""

    @property
    @abstractmethod
    def nbytes(self) -> int:
        """Bytes the search structures take."""

    def log_odds(self, points: np.ndarray, clusters: ClusterSet, intercept: float) -> np.ndarray:
        """(n,) log-odds at (n, d) finite points, each read alone (mode 'exact')."""
        return self.sums(points, clusters, intercept, False, "exact", 1.0).scores


def kernel_search(config: MapConfig, dim: int) -> KernelSearch:
    """The empty search `config.features` asks for, over clusters of `dim` (2 or 3) axes."""
    if config.features == "support":
        return SupportSearch(config, dim)
    return NearestSearch(config, dim)


def query_groups(points: np.ndarray, mode: str, cell: float) -> PointGroups:
    """The groups of (n, d) points that share one search in query `mode`: in 'batch', the
    points of each cell `cell` metres wide; in 'exact', each point alone."""
    if mode == "batch":
        return group_by_cell(points, cell)
    return PointGroups.singletons(points)


def _summed_arrays(clusters: ClusterSet, intercept: float, with_variance: bool) -> tuple:
    """What the compiled sums read of the clusters, in their order: means, transforms, planar
    kernel, weights, the intercept, 1 / precision (empty without variance), with_variance."""
    inverse_precision = 1.0 / clusters.precision if with_variance else np.zeros(0)
    kernels = (clusters.means, clusters.transforms, clusters.planar_kernel)
    return (*kernels, clusters.weights, intercept, inverse_precision, with_variance)


class SupportSearch(KernelSearch):
    """Every kernel whose support holds a point, from a SupportHash: one model for points,
    rays and grids."""

    truncated = False

    def __init__(self, config: MapConfig, dim: int) -> None:
        self._radii = (config.cluster_radius, config.free_cluster_radius)
        self._hash = SupportHash.of_radii(dim, *self._radii)

    def relist(
        self, clusters: ClusterSet, anchors: AnchorLayers, changed: np.ndarray | None
    ) -> None:
        if changed is None:
            self._hash = SupportHash.of_radii(clusters.dim, *self._radii)
            changed = np.arange(len(clusters))
        self._hash.update(
            changed, clusters.means, clusters.transforms, clusters.planar_kernel, clusters.coarse
        )

    def features(
        self, points: np.ndarray, clusters: ClusterSet, groups: PointGroups | None = None
    ) -> SparseFeatures:
        return self._hash.features(
            points, clusters.means, clusters.transforms, clusters.planar_kernel
        )

    def merge_candidates(
        self, means: np.ndarray, coarse: np.ndarray, clusters: ClusterSet
    ) -> MergeCandidates:
        """The clusters whose kernels are not zero at each new cluster's mean."""
        indptr, rows = self.rows(means, clusters, "exact")
        return MergeCandidates(np.repeat(np.arange(len(indptr) - 1), np.diff(indptr)), rows)

    def rows(
        self, points: np.ndarray, clusters: ClusterSet, mode: str
    ) -> tuple[np.ndarray, np.ndarray]:
        found = self.features(points, clusters)
        return found.indptr, found.rows

    def sums(
        self,
        points: np.ndarray,
        clusters: ClusterSet,
        intercept: float,
        with_variance: bool,
        mode: str,
        cell: float,
    ) -> KernelSums:
        arrays = _summed_arrays(clusters, intercept, with_variance)
        return KernelSums(*self._hash.decision_values(points, *arrays))

    def near_reader(
        self, places: np.ndarray, spread: float, clusters: ClusterSet, intercept: float
    ) -> ReadRows:
        return lambda points, rows: self.log_odds(points, clusters, intercept)

    @property
    def shares_searches(self) -> bool:
        return False

    @property
    def nbytes(self) -> int:
        return self._hash.nbytes


class NearestSearch(KernelSearch):
    """The config.neighbours nearest fine and config.coarse_neighbours nearest coarse
    clusters, searched once per group of nearby points (the paper's Alg. 3)."""

    truncated = True

    def __init__(self, config: MapConfig, dim: int) -> None:
        self._config = config
        self._index = ClusterIndex(np.zeros((0, dim)), np.zeros(0, dtype=bool))

    def relist(
        self, clusters: ClusterSet, anchors: AnchorLayers, changed: np.ndarray | None
    ) -> None:
        """The index is rebuilt whole, whatever changed."""
        self._index = ClusterIndex.of(clusters, anchors, self._config)

    def _group_neighbours(self, points: np.ndarray, groups: PointGroups) -> np.ndarray:
        """(G, k) int64 rows of the clusters each group's search found, -1 for none."""
        cfg = self._config
        return self._index.group_neighbours(points, groups, cfg.neighbours, cfg.coarse_neighbours)

    def features(
        self, points: np.ndarray, clusters: ClusterSet, groups: PointGroups | None = None
    ) -> SparseFeatures:
        groups = groups if groups is not None else PointGroups.singletons(points)
        return training_features(points, groups, self._group_neighbours(points, groups), clusters)

    def merge_candidates(
        self, means: np.ndarray, coarse: np.ndarray, clusters: ClusterSet, k: int = 4
    ) -> MergeCandidates:
        """The k nearest centres of each new cluster's scale (the paper's search)."""
        nearest = np.full((len(means), k), -1, dtype=np.int64)
        for scale in (False, True):
            rows = coarse == scale
            nearest[rows] = self._index.nearest_of_scale(means[rows], scale, k)
        pair_new, column = np.nonzero(nearest >= 0)
        return MergeCandidates(pair_new, nearest[pair_new, column])

    def rows(
        self, points: np.ndarray, clusters: ClusterSet, mode: str
    ) -> tuple[np.ndarray, np.ndarray]:
        groups = query_groups(points, mode, self._config.query_cell)
        neighbours = self._group_neighbours(points, groups)[groups.group_of_point]
        kept = neighbours >= 0
        indptr = np.zeros(len(points) + 1, dtype=np.int64)
        np.cumsum(kept.sum(axis=1), out=indptr[1:])
        return indptr, neighbours[kept]

    def sums(
        self,
        points: np.ndarray,
        clusters: ClusterSet,
        intercept: float,
        with_variance: bool,
        mode: str,
        cell: float,
    ) -> KernelSums:
        groups = query_groups(points, mode, cell)
        neighbours = self._group_neighbours(points, groups)
        # Read group by group, the groups in the Z-order of their cells (group_by_cell):
        # neighbouring groups find their clusters still in cache.
        _, order = rows_by_rank(groups.group_of_point, len(groups.centres))
        read = self._read(
            points[order],
            groups.group_of_point[order],
            neighbours,
            clusters,
            intercept,
            with_variance,
        )
        scores = np.empty_like(read.scores)
        scores[order] = read.scores
        variance_sums = np.empty_like(read.variance_sums)
        if with_variance:
            variance_sums[order] = read.variance_sums
        return KernelSums(scores, variance_sums)

    @staticmethod
    def _read(
        points: np.ndarray,
        group_of_point: np.ndarray,
        neighbours: np.ndarray,
        clusters: ClusterSet,
        intercept: float,
        with_variance: bool,
    ) -> KernelSums:
        arrays = _summed_arrays(clusters, intercept, with_variance)
        return KernelSums(*decision_values(points, group_of_point, neighbours, *arrays))

    def near_reader(
        self, places: np.ndarray, spread: float, clusters: ClusterSet, intercept: float
    ) -> ReadRows:
        """Each point from the nearest clusters of its place, found once per place, as a
        query in batch mode reads a group."""
        cfg = self._config
        neighbours = self._index.nearest(places, cfg.neighbours, cfg.coarse_neighbours, spread)
        return lambda points, rows: (
            self._read(points, rows, neighbours, clusters, intercept, False).scores
        )

    @property
    def shares_searches(self) -> bool:
        return self._config.train_search == "group"

    @property
    def nbytes(self) -> int:
        return self._index.nbytes
