"""HilbertMap: clusters, weights and optimiser of an Efficient Hilbert Map.

m = HilbertMap(neighbours=8)
m.integrate(points_world, origin)      # one scan, Alg. 2
p = m.occupancy(query_points)          # (n,) probability of occupied, Alg. 3
g = m.grid(resolution=0.05)            # OccupancyGrid over the mapped region (Sec. 3.5)
m.save("room.ehm"); m2 = ehm.load("room.ehm")
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable
from dataclasses import dataclass
from os import PathLike
from typing import Any

import numpy as np

from ehm.anchors import AnchorLayers
from ehm.clusters import ClusterSet, ClusterView, match_new_clusters, merge_average, merge_pooled
from ehm.config import MapConfig
from ehm.coplanar import merge_coplanar
from ehm.features import decision_values, group_by_cell, group_spread, kernel_values
from ehm.grid import DEFAULT_MAX_BYTES, OccupancyGrid, grid_shape, support_bounds
from ehm.index import ClusterIndex, KernelRanking
from ehm.quickmeans import kmeans_refine, quick_means
from ehm.scan import Scan, TrainingSamples
from ehm.sgd import sgd_pass
from ehm.timing import StageTimer


@dataclass(frozen=True)
class SampleGroups:
    """Samples grouped for neighbour search, and the new clusters found among them.

    group_of_point: (n,) int64. centres: (G, d) float64, metres. new_means (C, d),
    new_covariances (C, d, d), new_counts (C,), new_coarse (C,), new_occupied (C,): statistics,
    scale and label of the clusters proper.
    """

    group_of_point: np.ndarray
    centres: np.ndarray
    new_means: np.ndarray
    new_covariances: np.ndarray
    new_counts: np.ndarray
    new_coarse: np.ndarray
    new_occupied: np.ndarray


class HilbertMap:
    """Continuous occupancy map learned from range scans (Guizilini & Ramos, IJRR 2018).

    config: a MapConfig; keyword overrides replace single settings, for example
    HilbertMap(cluster_radius=0.2). Learned state ends in an underscore: clusters_ (a
    ClusterSet), anchors_ (AnchorLayers, empty unless config.anchor_layers > 1), bias_,
    n_scans_, and timings_ (seconds per stage of the last update).
    """

    def __init__(self, config: MapConfig | None = None, **overrides: Any) -> None:
        base = config if config is not None else MapConfig()
        self.config = base.replace(**overrides) if overrides else base
        self._reset()

    def _reset(self) -> None:
        """Forget everything learned."""
        self.clusters_: ClusterSet | None = None
        self.bias_state_ = np.zeros(2)
        self.n_scans_ = 0
        self.timings_: dict[str, float] = {}
        self.last_update_: dict[str, int] = {}
        self._index = ClusterSet.empty(1).index()
        self.anchors_ = AnchorLayers()
        self._rng = np.random.default_rng(self.config.seed)
        # Grids compare this token to tell a map that was refitted from one that grew.
        self._lineage = object()
        self._followers: weakref.WeakSet[OccupancyGrid] = weakref.WeakSet()

    # ------------------------------------------------------------------ state
    @property
    def dim(self) -> int | None:
        return None if self.clusters_ is None else self.clusters_.dim

    @property
    def bias_(self) -> float:
        return float(self.bias_state_[0])

    @property
    def n_clusters(self) -> int:
        return 0 if self.clusters_ is None else len(self.clusters_)

    def __repr__(self) -> str:
        changed = {k: v for k, v in self.config.to_dict().items() if getattr(MapConfig(), k) != v}
        settings = ", ".join(f"{k}={v!r}" for k, v in changed.items())
        return f"HilbertMap(dim={self.dim}, clusters={self.n_clusters}, scans={self.n_scans_}" + (
            f", {settings})" if settings else ")"
        )

    def clusters(self) -> ClusterView:
        """A copy of the clusters: centres, covariances, weights, kind ('planar' or
        'volumetric'), kernel, scale and label, one row per cluster (see ClusterView)."""
        if self.clusters_ is None:
            raise RuntimeError("the map is empty: integrate a scan or fit first")
        return ClusterView.of(self.clusters_)

    def memory_bytes(self) -> int:
        """Bytes of everything the map keeps: cluster arrays, weights, optimiser state, anchor
        layers and the search structure over cluster centres."""
        clusters = 0 if self.clusters_ is None else self.clusters_.nbytes
        return clusters + self.bias_state_.nbytes + self._index.nbytes + self.anchors_.nbytes

    def _restore(
        self, clusters: ClusterSet, bias_state: np.ndarray, n_scans: int, anchors: AnchorLayers
    ) -> None:
        """Install learned state (used by ehm.load)."""
        self.clusters_ = clusters
        self.bias_state_ = np.asarray(bias_state, dtype=np.float64).copy()
        self.n_scans_ = n_scans
        self.anchors_ = anchors
        self._index = self._build_index()

    # --------------------------------------------------------------- training
    def integrate(
        self,
        points_world: np.ndarray,
        origin: np.ndarray,
        hit_mask: np.ndarray | None = None,
    ) -> HilbertMap:
        """Learn one scan (Alg. 2); returns self.

        points_world: (N, d) float, metres, world frame; origin: (d,) sensor centre, world
        frame; hit_mask: (N,) bool, False for rays without return (None: all returned).
        """
        return self.integrate_scan(Scan(points_world, origin, hit_mask))

    def integrate_scan(self, scan: Scan) -> HilbertMap:
        """Learn one Scan (Alg. 2); returns self."""
        self._check_dim(scan.dim, "scan")
        timer = StageTimer()
        with timer("samples"):
            samples = scan.training_samples(self.config, self._rng)
        self._learn(samples, timer)
        self.n_scans_ += 1
        self._update_followers()
        return self

    def fit(self, scans: Iterable[Scan]) -> HilbertMap:
        """Single-batch mode (Table 5): forget what was learned and learn all scans at once."""
        scans = list(scans)
        if not scans:
            raise ValueError("fit needs at least one scan, got none")
        for i, scan in enumerate(scans):
            if not isinstance(scan, Scan):
                raise ValueError(f"scan {i}: expected ehm.Scan, got {type(scan).__name__}")
            if scan.dim != scans[0].dim:
                raise ValueError(f"scan {i}: points are {scan.dim}D, scan 0 is {scans[0].dim}D")
        followers = list(self._followers)
        self._reset()
        self._followers.update(followers)
        timer = StageTimer()
        with timer("samples"):
            samples = TrainingSamples.concatenate(
                [s.training_samples(self.config, self._rng) for s in scans]
            )
        self._learn(samples, timer)
        self.n_scans_ = len(scans)
        self._update_followers()
        return self

    def _check_dim(self, dim: int, what: str) -> None:
        if self.dim is not None and dim != self.dim:
            raise ValueError(f"{what} points are {dim}D, the map is {self.dim}D")

    def _learn(self, samples: TrainingSamples, timer: StageTimer) -> None:
        cfg = self.config
        with timer("clustering"):
            groups = self._group_samples(samples)
        with timer("length_scales"):
            touched = self._absorb(groups)
        if cfg.merge_coplanar:
            with timer("coplanar"):
                merge = merge_coplanar(self.clusters_, touched, cfg)
            self.last_update_["coplanar_merged"] = merge.merged
            self.anchors_.drop_clusters(merge.source)
        with timer("index"):
            self._index = self._build_index()
        clusters = self.clusters_
        with timer("features"):
            if cfg.train_search == "point":
                group_of_point, centres = np.arange(len(samples)), samples.points
            else:
                group_of_point, centres = groups.group_of_point, groups.centres
            spread = group_spread(samples.points, group_of_point, centres)
            neighbours = self._index.nearest(centres, cfg.neighbours, cfg.coarse_neighbours, spread)
            values = kernel_values(
                samples.points,
                group_of_point,
                neighbours,
                clusters.means,
                clusters.transforms,
                clusters.planar_kernel,
            )
        with timer("sgd"):
            labels = samples.occupied.astype(np.float64)
            class_weights = self._class_weights(samples.occupied)
            for _ in range(cfg.epochs):
                sgd_pass(
                    values,
                    group_of_point,
                    neighbours,
                    labels,
                    class_weights,
                    self._rng.permutation(len(labels)),
                    clusters.weights,
                    clusters.grad_sq,
                    self.bias_state_,
                    cfg.learning_rate,
                    cfg.l2,
                )
        self.timings_ = dict(timer.seconds)

    def _class_weights(self, occupied: np.ndarray) -> np.ndarray:
        """Loss weights [free, occupied]: equal total weight per class when balancing, so the
        density of free samples does not move the 0.5 boundary."""
        n_occupied = int(occupied.sum())
        n_free = len(occupied) - n_occupied
        if not self.config.balance_classes or n_occupied == 0 or n_free == 0:
            return np.ones(2)
        return len(occupied) / (2.0 * np.array([n_free, n_occupied], dtype=np.float64))

    def _group_samples(self, samples: TrainingSamples) -> SampleGroups:
        """Quick-means over the samples. Apart: occupied samples, free samples around hits (both
        fine) and free samples along rays (coarse) each on their own; together: all at once."""
        cfg = self.config
        if cfg.cluster_free_apart:
            free = ~samples.occupied
            parts = [
                (np.flatnonzero(samples.occupied), cfg.cluster_radius, False),
                (np.flatnonzero(free & samples.at_surface), cfg.cluster_radius, False),
                (np.flatnonzero(free & ~samples.at_surface), cfg.free_cluster_radius, True),
            ]
        else:
            parts = [(np.arange(len(samples)), cfg.cluster_radius, False)]
        group_of_point = np.empty(len(samples), dtype=np.int64)
        centres, means, covariances, counts, coarse, occupied = [], [], [], [], [], []
        n_groups = 0
        for rows, radius, is_coarse in parts:
            points = samples.points[rows]
            result = quick_means(
                points, radius, radius * cfg.outer_radius_factor, cfg.min_cluster_size, self._rng
            )
            result = kmeans_refine(points, result, cfg.kmeans_iterations)
            group_of_point[rows] = result.owner + n_groups
            n_groups += len(result.means)
            centres.append(result.means)
            means.append(result.means[result.kept])
            covariances.append(result.covariances[result.kept])
            counts.append(result.counts[result.kept])
            coarse.append(np.full(int(result.kept.sum()), is_coarse))
            # Label: the majority of the samples each seed took out of the pool.
            n_seeds = len(result.means)
            n_occupied = np.bincount(result.owner, samples.occupied[rows], n_seeds)
            majority = 2 * n_occupied > np.bincount(result.owner, None, n_seeds)
            occupied.append(majority[result.kept])
        return SampleGroups(
            group_of_point,
            np.concatenate(centres),
            np.concatenate(means),
            np.concatenate(covariances),
            np.concatenate(counts),
            np.concatenate(coarse),
            np.concatenate(occupied),
        )

    def _build_index(self) -> ClusterIndex:
        """The search structure over the clusters that config asks for, placing new clusters
        in the anchor layers first."""
        cfg, clusters = self.config, self.clusters_
        ranking = None
        if cfg.anisotropic_search:
            ranking = KernelRanking(
                clusters.means,
                clusters.transforms,
                clusters.planar_kernel,
                cfg.anisotropic_candidates,
            )
        if cfg.anchor_layers == 1:
            return ClusterIndex(clusters.means, clusters.coarse, clusters.reach(), ranking)
        self.anchors_.extend(
            clusters.means,
            clusters.coarse,
            (cfg.cluster_radius, cfg.free_cluster_radius),
            cfg.anchor_radius_factor,
            cfg.anchor_layers - 1,
        )
        return ClusterIndex(
            clusters.means, clusters.coarse, clusters.reach(), ranking, self.anchors_
        )

    def _absorb(self, groups: SampleGroups) -> np.ndarray:
        """Merge each new cluster into the map's or add it with weight 0 (Alg. 2 lines 4-21).
        Returns the rows of the clusters that changed or are new."""
        cfg = self.config
        if self.clusters_ is None:
            self.clusters_ = ClusterSet.empty(groups.centres.shape[1])
        clusters = self.clusters_
        targets = match_new_clusters(
            clusters,
            self._index,
            groups.new_means,
            groups.new_covariances,
            groups.new_coarse,
            groups.new_occupied,
            cfg.merge_threshold,
            cfg.min_std,
        )
        merging = targets >= 0
        if merging.any():
            merge = merge_pooled if cfg.merge_rule == "pooled" else merge_average
            merge(
                clusters,
                targets[merging],
                groups.new_means[merging],
                groups.new_covariances[merging],
                groups.new_counts[merging],
            )
        start = len(clusters)
        clusters.append(
            groups.new_means[~merging],
            groups.new_covariances[~merging],
            groups.new_counts[~merging],
            groups.new_coarse[~merging],
            groups.new_occupied[~merging],
        )
        changed = np.concatenate([np.unique(targets[merging]), np.arange(start, len(clusters))])
        clusters.refresh(changed, cfg)
        self.last_update_ = {
            "new_clusters": int((~merging).sum()),
            "merged_clusters": int(merging.sum()),
        }
        return changed

    # ---------------------------------------------------------------- queries
    def occupancy(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n,) float64 probability that each point is occupied.

        points: (n, d) float, metres, world frame. mode: 'batch' (Alg. 3: one neighbour search
        per group of nearby points) or 'exact' (one per point); default config.query_mode.
        Rows with NaN or infinite coordinates give NaN.
        """
        return 1.0 / (1.0 + np.exp(-self.decision_function(points, mode)))

    def predict_proba(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n, 2) float64 [p(free), p(occupied)] per point, scikit-learn style."""
        occupied = self.occupancy(points, mode)
        return np.column_stack([1.0 - occupied, occupied])

    def decision_function(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n,) float64 log-odds of occupancy: w^T phi(x), plus the intercept b when
        config.query_intercept is set."""
        if self.clusters_ is None:
            raise RuntimeError("the map is empty: integrate a scan or fit before querying")
        mode = mode or self.config.query_mode
        if mode not in ("batch", "exact"):
            raise ValueError(f"query mode must be 'batch' or 'exact', got {mode!r}")
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != self.dim:
            raise ValueError(
                f"query points must have shape (n, {self.dim}), got {tuple(points.shape)}"
            )
        finite = np.all(np.isfinite(points), axis=1)
        scores = np.full(len(points), np.nan)
        query = np.ascontiguousarray(points[finite])
        if mode == "batch":
            group_of_point, centres = group_by_cell(query, self.config.query_cell)
        else:
            group_of_point, centres = np.arange(len(query)), query
        neighbours = self._index.nearest(
            centres,
            self.config.neighbours,
            self.config.coarse_neighbours,
            group_spread(query, group_of_point, centres),
        )
        clusters = self.clusters_
        scores[finite] = decision_values(
            query,
            group_of_point,
            neighbours,
            clusters.means,
            clusters.transforms,
            clusters.planar_kernel,
            clusters.weights,
            self.bias_ if self.config.query_intercept else 0.0,
        )
        return scores

    # ------------------------------------------------------------------ grids
    def grid(
        self,
        bounds: np.ndarray | None = None,
        resolution: float = 0.05,
        follow: bool = False,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ) -> OccupancyGrid:
        """Occupancy grid by incremental grid reconstruction (Sec. 3.5).

        bounds: (2, d) metres, world frame, [low corner, high corner]; None: the box holding
        every kernel's support. resolution: voxel side, metres. follow: keep the grid up to
        date after every integrate or fit, for as long as it is referenced (several grids,
        at any resolutions, can follow one map). max_bytes: refuse larger grids (ValueError)
        before allocating.
        """
        if self.clusters_ is None:
            raise RuntimeError("the map is empty: integrate a scan or fit before building a grid")
        if bounds is None:
            bounds = support_bounds(
                self.clusters_.means, self.clusters_.transforms, self.clusters_.planar_kernel
            )
        origin, shape = grid_shape(bounds, resolution, self.dim, max_bytes)
        grid = OccupancyGrid(origin, resolution, shape)
        grid.update(self)
        if follow:
            self._followers.add(grid)
        return grid

    def _update_followers(self) -> None:
        """Bring every following grid up to date, timed as the stage 'grids'."""
        if len(self._followers) == 0:
            return
        timer = StageTimer()
        with timer("grids"):
            for grid in self._followers:
                grid.update(self)
        self.timings_.update(timer.seconds)

    # ------------------------------------------------------------ persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Write the map to `path` atomically (see ehm.io.map_file)."""
        from ehm.io.map_file import save_map

        save_map(self, path)
