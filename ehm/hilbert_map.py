"""HilbertMap: an Efficient Hilbert Map, learned scan by scan or in one batch, and queried.

m = HilbertMap(neighbours=8)
m.integrate(points_world, origin)      # one scan, Alg. 2
p = m.occupancy(query_points)          # (n,) probability of occupied, Alg. 3
g = m.grid()                           # OccupancyGrid at the map's resolution (Sec. 3.5)
m.save("room.ehm"); m2 = ehm.load("room.ehm")

Each method calls one function per step of the paper's algorithms (ehm.core); the map holds
the learned state and hands grids a snapshot of it.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Iterator
from dataclasses import replace
from functools import partial
from os import PathLike
from typing import Any

import numpy as np

from ehm.config import MapConfig
from ehm.core.clustering.coplanar import merge_coplanar
from ehm.core.clustering.grouping import group_samples
from ehm.core.clustering.merging import MergeCandidates, absorb_clusters
from ehm.core.model.clusters import ClusterSet, ClusterView
from ehm.core.model.features import (
    PointGroups,
    SparseFeatures,
    decision_values,
    group_by_cell,
    training_features,
)
from ehm.core.observations.evidence import gather_evidence
from ehm.core.observations.memory import EvidenceMemory, Visit
from ehm.core.observations.passes import PASS_REACH_CELLS, hit_again, occupied_passes
from ehm.core.observations.samples import ScanRays, TrainingSamples, scan_rays
from ehm.core.primitives.logistic import sigmoid
from ehm.core.queries.gradient import logit_gradients
from ehm.core.queries.raycast import (
    checked_rays,
    first_crossings,
    log_odds_level,
    refine_guesses,
    segment_rays,
    stop_at_unknown,
    unknown_is_obstacle,
)
from ehm.core.queries.surfels import ReadNear
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.index import ClusterIndex
from ehm.core.search.supports import SupportHash
from ehm.core.sensor.scan import Scan
from ehm.core.snapshot import MapSnapshot
from ehm.core.state import MapState
from ehm.core.timing import StageTimer
from ehm.core.weights.forgetting import fade, fade_shares, forget, mark_seen, standing_shares
from ehm.core.weights.posterior import update_posterior
from ehm.core.weights.sgd import loss_weights, train_weights
from ehm.core.weights.uncertainty import add_curvature, logit_variance, occupancy_std
from ehm.errors import EmptyMapError, InputError
from ehm.grid.blocks import grid_blocks
from ehm.grid.bounds import DEFAULT_MAX_BYTES, support_bounds
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.grid.planner_support import PlannerSupport
from ehm.io.map_file import read_map, write_map

# Side of the cells that tell rays where the occupancy may rise above the level, in cluster
# radii (ehm.core.queries.raycast.CandidateCells).
RAY_CELLS_PER_RADIUS = 4.0
# How far beyond the grid's crossing a ray looks for the exact one before it marches the exact
# log-odds from its start, in cluster radii (voxels of the grid): the grid, interpolated
# between voxel centres, crosses early where a surface is sharper than a voxel.
RAY_GUESS_BEHIND = 4.0
# Rays read the log-odds in batch mode in groups of cells this many times `query_cell` wide:
# a ray's samples lie a few centimetres apart, and smaller cells make a search each.
RAY_QUERY_CELLS = 2.0


class HilbertMap:
    """Continuous occupancy map learned from range scans (Guizilini & Ramos, IJRR 2018): it
    answers p(occupied) anywhere, with its uncertainty, and learns scan by scan.

    Example:
        ```python
        import numpy as np
        import ehm

        m = ehm.HilbertMap(resolution=0.1)  # metres; every setting: ehm.MapConfig
        directions = np.random.default_rng(0).normal(size=(20_000, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        origin = np.array([0.0, 0.0, 1.0])  # the sensor, metres, world frame
        m.integrate(origin + 3.0 * directions, origin)  # hits (N, 3) ending rays from origin
        p = m.occupancy(np.array([[3.0, 0.0, 1.0], [1.0, 0.0, 1.0]]))  # on the sphere, inside
        distance = m.distance(np.array([[1.0, 0.0, 1.0]]))  # metres to the nearest obstacle
        m.save("sphere.ehm")  # ehm.load("sphere.ehm") reads it back
        ```

    config: a MapConfig; keyword overrides replace single settings, for example
    HilbertMap(cluster_radius=0.2); resolution=r, in place of a config, starts from
    MapConfig.for_resolution(r) (HilbertMap(resolution=0.2, max_range=80.0)). Learned state
    ends in an underscore: clusters_ (a ClusterSet), anchors_ (AnchorLayers, empty unless
    config.anchor_layers > 1), bias_, local_origin_ (the world point, metres, clusters_ and
    the memory are kept relative to, see local_origin_for; None before the first scan is
    learned), n_scans_, timings_ (seconds per stage of the last update), last_update_
    (clusters added and merged by it, its samples and those replayed from the memory) and
    time_ (seconds, the latest time stamp of the scans learned; None without). Everything the
    map takes and answers is in world frame, whatever its local origin.
    """

    def __init__(self, config: MapConfig | None = None, **overrides: Any) -> None:
        if "resolution" in overrides:
            if config is not None:
                raise InputError(
                    "give a resolution or a config, not both: the config holds its resolution"
                )
            config = MapConfig.for_resolution(overrides.pop("resolution"))
        base = config if config is not None else MapConfig()
        self.config = base.replace(**overrides) if overrides else base
        self._reset()
        self._followers: weakref.WeakSet[OccupancyGrid] = weakref.WeakSet()

    def _reset(self) -> None:
        """Forget everything learned."""
        self.clusters_: ClusterSet | None = None
        self.memory_: EvidenceMemory | None = None
        self.local_origin_: np.ndarray | None = None
        # Scans given but not learned yet, waiting for config.batch_rays rays.
        self._waiting: list[Scan] = []
        self._waiting_rays = 0
        self.bias_state_ = np.zeros(2)
        self.n_scans_ = 0
        self.time_: float | None = None
        # The origin of every scan given, in order (see sensor_path).
        self._origins: list[np.ndarray] = []
        self.timings_: dict[str, float] = {}
        self.last_update_: dict[str, int] = {}
        self.anchors_ = AnchorLayers()
        # The search for each point's kernels: the support hash (config.features 'support')
        # or the index of nearest centres ('nearest'); both empty until the first scan.
        self._supports = SupportHash.of_radii(1, 1.0, 1.0)
        self._index = ClusterIndex(np.zeros((0, 1)), np.zeros(0, dtype=bool))
        self._rng = np.random.default_rng(self.config.seed)
        # Snapshots carry this token, so grids tell a map that was refitted from one that grew.
        self._lineage = object()
        # What rays march and distances are read from, made when first needed and kept up to
        # date as it learns.
        self._planner = PlannerSupport(
            self.config.cluster_radius,
            RAY_CELLS_PER_RADIUS * self.config.cluster_radius,
            self.config.distance_reach,
            self._point_log_odds,
            self._near_log_odds,
        )

    def _local_snapshot(self) -> MapSnapshot:
        """The snapshot in the map's own frame (local_origin_ at its origin), as the planner
        support keeps it."""
        clusters = self._learned("take a snapshot")
        return MapSnapshot(
            clusters.means.copy(),
            clusters.transforms.copy(),
            clusters.weights.copy(),
            clusters.precision.copy(),
            clusters.planar_kernel.copy(),
            self._query_intercept(),
            self.config.prior_precision,
            self._lineage,
        )

    def _memory(self) -> EvidenceMemory:
        """The memory of past evidence, made with the clusters: there is one whenever there are
        clusters."""
        if self.memory_ is None:
            raise EmptyMapError("the map has no memory of past evidence before it has learned")
        return self.memory_

    def _learned(self, action: str) -> ClusterSet:
        """The clusters, after learning any scans waiting for their batch."""
        self.flush()
        if self.clusters_ is None:
            raise EmptyMapError(f"the map is empty: integrate a scan or fit before you {action}")
        return self.clusters_

    def _relist(self, changed: np.ndarray | None) -> None:
        """Bring the search for each point's kernels up to date after the clusters at rows
        `changed` were added or changed (None: every cluster, for example after rows moved):
        the support hash re-lists just those; the nearest-centre index is rebuilt."""
        clusters, cfg = self._learned("search it"), self.config
        if cfg.features == "nearest":
            self._index = ClusterIndex.of(clusters, self.anchors_, cfg)
            return
        if changed is None:
            self._supports = SupportHash.of_radii(
                clusters.dim, cfg.cluster_radius, cfg.free_cluster_radius
            )
            changed = np.arange(len(clusters))
        self._supports.update(
            changed, clusters.means, clusters.transforms, clusters.planar_kernel, clusters.coarse
        )

    def _features(self, points: np.ndarray, groups: PointGroups | None) -> SparseFeatures:
        """Training features of (n, d) points, metres: every kernel not zero at each, or with
        'nearest' those of the nearest clusters of each of `groups` (None: one per point)."""
        clusters, cfg = self._learned("search it"), self.config
        if cfg.features == "support":
            return self._supports.features(
                points, clusters.means, clusters.transforms, clusters.planar_kernel
            )
        groups = groups if groups is not None else PointGroups.singletons(points)
        neighbours = self._index.group_neighbours(
            points, groups, cfg.neighbours, cfg.coarse_neighbours
        )
        return training_features(points, groups, neighbours, clusters)

    def _query_intercept(self) -> float:
        """The log-odds every query adds: the bias when config.query_intercept, else 0."""
        return self.bias_ if self.config.query_intercept else 0.0

    # --------------------------------------------------------------- training
    def integrate(
        self,
        points_world: np.ndarray,
        origin: np.ndarray,
        hit_mask: np.ndarray | None = None,
        time: float | None = None,
    ) -> HilbertMap:
        """Learn one scan (Alg. 2); returns self.

        points_world: (N, d) float, metres, world frame; origin: (d,) sensor centre, world
        frame; hit_mask: (N,) bool, False for rays without return (None: all returned); time:
        seconds, when the scan was taken (needed with config.forget_after).
        """
        return self.integrate_scan(Scan(points_world, origin, hit_mask, time))

    def integrate_scan(self, scan: Scan) -> HilbertMap:
        """Learn one Scan (Alg. 2); returns self. With config.batch_rays, the scan waits
        until the waiting scans hold that many rays, and they are learned together."""
        if not isinstance(scan, Scan):
            raise InputError(f"expected ehm.Scan, got {type(scan).__name__}")
        if self.dim is not None and scan.dim != self.dim:
            raise InputError(f"scan points are {scan.dim}D, the map is {self.dim}D")
        self._check_time(scan, "the scan")
        self._waiting.append(scan)
        self._waiting_rays += len(scan)
        self._origins.append(scan.origin)
        self.n_scans_ += 1
        self.timings_ = {}
        if self._waiting_rays >= self.config.batch_rays:
            self.flush()
        return self

    def flush(self) -> HilbertMap:
        """Learn the scans waiting for their batch (config.batch_rays) now, as one batch;
        returns self. Queries, grids and saves do this themselves."""
        if not self._waiting:
            return self
        scans, self._waiting, self._waiting_rays = self._waiting, [], 0
        timer = StageTimer()
        with timer("samples"):
            rays, samples = self._evidence(scans)
        self._learn(rays, samples, timer, _latest_time(scans))
        self._update_followers()
        return self

    def fit(self, scans: Iterable[Scan]) -> HilbertMap:
        """Single-batch mode (Table 5): forget what was learned and learn all scans at once."""
        scans = list(scans)
        if not scans:
            raise InputError("fit needs at least one scan, got none")
        for i, scan in enumerate(scans):
            if not isinstance(scan, Scan):
                raise InputError(f"scan {i}: expected ehm.Scan, got {type(scan).__name__}")
            if scan.dim != scans[0].dim:
                raise InputError(f"scan {i}: points are {scan.dim}D, scan 0 is {scans[0].dim}D")
            self._check_time(scan, f"scan {i}")
        self._reset()
        timer = StageTimer()
        with timer("samples"):
            rays, samples = self._evidence(scans)
        self._learn(rays, samples, timer, _latest_time(scans))
        self.n_scans_ = len(scans)
        self._origins = [scan.origin for scan in scans]
        self._update_followers()
        return self

    def _evidence(self, scans: list[Scan]) -> tuple[ScanRays, TrainingSamples]:
        """The rays and training samples of `scans` (world frame) in the map's own frame,
        whose origin the first scans learned choose (local_origin_for)."""
        if self.local_origin_ is None:
            self.local_origin_ = local_origin_for(scans[0].origin)
        config = self.config
        if self.local_origin_.any():
            offset = self.local_origin_
            scans = [
                Scan(scan.points_world - offset, scan.origin - offset, scan.hit_mask, scan.time)
                for scan in scans
            ]
            if config.learn_box:
                box = np.asarray(config.learn_box).reshape(2, -1) - offset
                config = config.replace(learn_box=tuple(box.ravel()))
        rays = scan_rays(scans, config)
        return rays, gather_evidence(rays, config, self._rng)

    def _local(self, points: np.ndarray) -> np.ndarray:
        """World points (n, d) in the map's own frame; anything else as given (the query's
        checks then name what is wrong with it)."""
        offset = self.local_origin_
        points = np.asarray(points, dtype=np.float64)
        if offset is None or not offset.any() or points.shape[-1:] != offset.shape:
            return points
        return points - offset

    def _world(self, points: np.ndarray) -> np.ndarray:
        """Points (n, d) of the map's own frame in world frame."""
        offset = self.local_origin_
        return points if offset is None or not offset.any() else points + offset

    def _check_time(self, scan: Scan, what: str) -> None:
        """InputError for a scan without time stamp given to a map that fades."""
        if self.config.forget_after is not None and scan.time is None:
            raise InputError(
                f"{what} has no time stamp, and the map forgets what it has not seen for "
                f"{self.config.forget_after} s (MapConfig.forget_after): give each scan its time "
                "(integrate(..., time=seconds))"
            )

    def _learn(
        self, rays: ScanRays, samples: TrainingSamples, timer: StageTimer, time: float | None
    ) -> None:
        """Alg. 2 from the batch's evidence on (one weighted sample per cell and kind,
        ehm.core.observations.evidence, of `rays`, taken at `time`, seconds), one step per stage
        of the paper's Table 2, with the past evidence of the places it reaches
        (ehm.core.observations.memory): what has gone unseen too long fades first
        (config.forget_after), the occupied evidence its rays pass through is taken back, what
        formed no cluster yet joins the clustering, and all of it is replayed with the new."""
        cfg = self.config
        if self.clusters_ is None or self.memory_ is None:
            dim = samples.points.shape[1]
            self.clusters_ = ClusterSet.empty(dim)
            self.memory_ = EvidenceMemory.of_config(dim, cfg)
            self._relist(None)
        clusters, memory = self.clusters_, self.memory_
        n_new = len(samples)
        with timer("memory_lookup"):
            visit = memory.visit(samples)
        with timer("forgetting"):
            faded = self._fade(clusters, memory, time)
            forgetting = self._retract(rays, visit)
        with timer("clustering"):
            pending = memory.pending(visit)
            grouped = group_samples(samples + pending.samples, cfg, self._rng)
        with timer("merging"):
            new = grouped.clusters
            if cfg.features == "support":
                at_means = self._features(new.means, None)
                candidates = MergeCandidates.covering(at_means)
            else:
                candidates = MergeCandidates.nearest(self._index, new)
            absorbed = absorb_clusters(clusters, candidates, new, cfg)
        self.last_update_ = {
            "new_clusters": absorbed.n_new,
            "merged_clusters": absorbed.n_merged,
            "forgetting_clusters": forgetting,
            "faded_clusters": faded,
        }
        fading = cfg.forget_after is not None and time is not None
        if fading:
            clusters.seen[absorbed.changed] = time
        changed: np.ndarray | None = absorbed.changed
        if cfg.merge_coplanar:
            with timer("coplanar"):
                merge = merge_coplanar(clusters, absorbed.changed, cfg)
            self.anchors_.drop_clusters(merge.source)
            self.last_update_["coplanar_merged"] = merge.merged
            changed = None  # rows moved into the holes of merged clusters
        with timer("index"):
            if cfg.anchor_layers > 1:
                self.anchors_.extend(
                    clusters.means,
                    clusters.coarse,
                    (cfg.cluster_radius, cfg.free_cluster_radius),
                    cfg.anchor_radius_factor,
                    cfg.anchor_layers - 1,
                )
            self._relist(changed)
        with timer("replay"):
            replayed = memory.replay(cfg.replay_ratio, visit, cfg.replay_cap, self._rng)
            self.last_update_.update(new_samples=n_new, replayed_samples=len(replayed))
            # Shuffled once here, SGD reads the features in order
            # (ehm.core.weights.sgd.blocked_order).
            shuffle = self._rng.permutation(n_new + len(replayed))
            train = (samples.without_scatter() + replayed).subset(shuffle)
            groups = None
            if cfg.features == "nearest" and cfg.train_search == "group":
                new_groups = PointGroups(
                    grouped.groups.group_of_point[:n_new], grouped.groups.centres
                )
                # Quick-means groups beat one group per memory cell: held-out F1 on the Intel
                # lab 0.925 / 0.922 against 0.910 / 0.911 (seeds 1, 2), PCL room +0.005.
                groups = new_groups + group_samples(replayed, cfg, self._rng).groups
                groups = PointGroups(groups.group_of_point[shuffle], groups.centres)
        with timer("features"):
            features = self._features(train.points, groups)
        with timer(cfg.update_rule):
            weights = loss_weights(train.occupied, train.weight, cfg.balance_classes)
            if cfg.update_rule == "posterior":
                update_posterior(features, train.occupied, weights, clusters, self.bias_state_, cfg)
            else:
                train_weights(
                    features, train.occupied, weights, clusters, self.bias_state_, cfg, self._rng
                )
        with timer("precision"):
            # The new samples' curvature, once each: replayed ones were counted when new.
            new_weights = np.where(shuffle < n_new, weights, 0.0)
            add_curvature(features, new_weights, clusters.weights, self.bias_, clusters.precision)
        with timer("memory_insert"):
            if fading:
                mark_seen(clusters, features, shuffle < n_new, time)
            memory.mark_clustered(pending, grouped.in_cluster[n_new:])
            memory.insert(visit, grouped.in_cluster[:n_new], np.nan if time is None else time)
        if time is not None:
            self.time_ = time if self.time_ is None else max(self.time_, time)
        self.timings_ = dict(timer.seconds)

    def _fade(self, clusters: ClusterSet, memory: EvidenceMemory, time: float | None) -> int:
        """Let what has gone unseen longer than config.forget_after fade, from the latest time
        learned to `time` (ehm.core.weights.forgetting); returns how many clusters faded."""
        forget_after, before = self.config.forget_after, self.time_
        if forget_after is None or time is None or before is None or time <= before:
            return 0
        memory.fade(fade_shares(memory.seen, before, time, forget_after))
        shares = fade_shares(clusters.seen, before, time, forget_after)
        return len(fade(clusters, shares, self.config.prior_precision))

    def _retract(self, rays: ScanRays, visit: Visit) -> int:
        """Take back the memory's occupied evidence that `rays` pass through, where the
        visit's samples bring no new hit to its cell and no hit of `rays` lands near it
        (ehm.core.observations.passes), and let the occupied clusters it stood behind forget
        it in the same measure (ehm.core.weights.forgetting); returns how many clusters forgot
        anything."""
        memory, clusters, cfg = self._memory(), self._learned("search it"), self.config
        if cfg.pass_retraction == 0 or len(memory) == 0:
            return 0
        reach = PASS_REACH_CELLS * memory.sides[0]
        entries, passes = occupied_passes(memory, rays, reach, cfg.occupied_depth)
        hit = visit.entries[visit.samples.occupied]
        standing = np.isin(entries, hit[hit >= 0])
        searched = np.flatnonzero(~standing)  # the others the batch hits in their own cell
        standing[searched] = hit_again(memory, entries[searched], rays, reach)
        retraction = memory.retract(entries, passes, cfg.pass_retraction, standing)
        if len(retraction.entries) == 0:
            return 0
        near = memory.occupied_near(retraction.entries)
        after = memory.weight[near].astype(np.float64)
        before = after.copy()
        before[np.searchsorted(near, retraction.entries)] = retraction.before
        points = memory.points_at(near)
        features = self._features(points, self._query_groups(points, cfg.query_mode))
        share = standing_shares(features, before, after, len(clusters))
        return len(forget(clusters, share, cfg.prior_precision))

    # ---------------------------------------------------------------- queries
    def occupancy(
        self, points: np.ndarray, mode: str | None = None, return_std: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) float64 probability that each point is occupied; with return_std, the pair
        (probability, std): std (n,) float64 is the standard deviation of the occupancy
        probability under the weights' Gaussian posterior (ehm.core.weights.uncertainty), high where
        nothing was observed (0.21 with prior_precision 1) and shrinking as a place is seen
        again.

        points: (n, d) float, metres, world frame. mode: 'batch' (Alg. 3: one neighbour search
        per group of nearby points) or 'exact' (one per point); default config.query_mode.
        Rows with NaN or infinite coordinates give NaN.
        """
        scores, variance = self._scores(self._local(points), mode, return_std)
        if not return_std:
            return sigmoid(scores)
        return sigmoid(scores), occupancy_std(scores, variance)

    def predict_proba(
        self, points: np.ndarray, mode: str | None = None, return_std: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n, 2) float64 [p(free), p(occupied)] per point, scikit-learn style; with
        return_std, also the (n,) standard deviation of either (see `occupancy`)."""
        scores, variance = self._scores(self._local(points), mode, return_std)
        occupied = sigmoid(scores)
        proba = np.column_stack([1.0 - occupied, occupied])
        if not return_std:
            return proba
        return proba, occupancy_std(scores, variance)

    def decision_function(
        self, points: np.ndarray, mode: str | None = None, return_variance: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) float64 log-odds of occupancy: w^T phi(x), plus the intercept b when
        config.query_intercept is set (Alg. 3); with return_variance, the pair (log-odds,
        variance): (n,) float64 variance of the log-odds under the weights' posterior, from
        which `occupancy`'s std follows (ehm.core.weights.uncertainty.occupancy_std)."""
        scores, variance = self._scores(self._local(points), mode, return_variance)
        return (scores, variance) if return_variance else scores

    def gradient(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n, d) float64 gradient of the occupancy log-odds (`decision_function`) with respect to
        position, 1/m, world frame, at (n, d) points, metres: it points toward more occupied space,
        and p(1 - p) times it is the gradient of the probability. Over the same kernels as
        `decision_function` in `mode`; planar-surface kernels are flat (0 or 1) and add nothing
        (ehm.core.queries.gradient). NaN rows where points are not finite."""
        clusters = self._learned("query it")
        points, finite, query = self._query_points(self._local(points))
        indptr, rows = self._query_clusters(
            query, self._checked_mode(mode or self.config.query_mode)
        )
        out = np.full(points.shape, np.nan)
        out[finite] = logit_gradients(
            query,
            indptr,
            rows,
            clusters.means,
            clusters.transforms,
            clusters.planar_kernel,
            clusters.weights,
        )
        return out

    def raycast(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_range: float | np.ndarray,
        level: float = 0.5,
        mode: str | None = None,
        unknown: str = "occupied",
    ) -> np.ndarray:
        """(n,) distance, metres, along each ray to the first point whose occupancy rises
        above `level`, or with unknown 'occupied' (the default) to the first point of unknown
        space (see `known`) where that is nearer, as OctoMap's castRay stops there; inf where
        neither comes within `max_range`. origins: (n, d) or one (d,)
        point, metres, world frame; directions: (n, d), any length but 0; max_range: metres,
        one for all rays or (n,). Rays march cluster_radius / 2 apart through a grid of the
        log-odds (made on the first call, then kept up to date as the map learns, in each
        update's stage 'grids': ehm.grid.planner_support), and the crossing near the grid's is
        found in the exact log-odds and located to cluster_radius / 10
        (ehm.core.queries.raycast); in mode 'batch' the rays' points share neighbour searches
        in cells RAY_QUERY_CELLS times query_cell wide. A ray starting inside reads 0. With
        unknown 'free', unknown space reads as its occupancy, 0.5: it stops no ray at the
        default level."""
        self._learned("cast rays through it")
        stop = unknown_is_obstacle(unknown)
        origins, directions, max_range = checked_rays(origins, directions, max_range, self.dim)
        origins = self._local(origins)
        threshold = log_odds_level(level)
        mode = self._checked_mode(mode or self.config.query_mode)
        radius = self.config.cluster_radius

        def log_odds(points: np.ndarray) -> np.ndarray:
            return self._scores(points, mode, False, RAY_QUERY_CELLS * self.config.query_cell)[0]

        distance = np.full(len(origins), np.nan)
        ray_grid = self._planner.grid(self._local_snapshot)
        if ray_grid is not None:
            guess = ray_grid.crossings(origins, directions, max_range, threshold, radius / 2.0)
            guided = np.flatnonzero(np.isfinite(guess))
            # The exact crossing, looked for from two voxels before the grid's to two after, and
            # where none is, on to RAY_GUESS_BEHIND voxels after.
            low = np.maximum(guess[guided] - 2.0 * radius, 0.0)
            high = np.minimum(guess[guided] + 2.0 * radius, max_range[guided])
            further = np.minimum(guess[guided] + RAY_GUESS_BEHIND * radius, max_range[guided])
            distance[guided] = refine_guesses(
                log_odds,
                origins[guided],
                directions[guided],
                low,
                high,
                threshold,
                radius / 2.0,
                radius / 10.0,
                further,
            )
        rest = np.flatnonzero(np.isnan(distance))
        distance[rest] = first_crossings(
            log_odds,
            origins[rest],
            directions[rest],
            max_range[rest],
            threshold,
            radius / 2.0,
            radius / 10.0,
            self._planner.cells(self._local_snapshot, threshold),
        )
        if stop:
            known = partial(self._known, mode=mode)
            known_runs = self._planner.known_cells(self._local_snapshot)
            return stop_at_unknown(
                known,
                origins,
                directions,
                distance,
                max_range,
                radius / 2.0,
                radius / 10.0,
                known_runs,
            )
        return distance

    def segment_free(
        self,
        starts: np.ndarray,
        ends: np.ndarray,
        level: float = 0.5,
        mode: str | None = None,
        unknown: str = "occupied",
    ) -> np.ndarray:
        """(n,) bool: True where no point of the segment from starts[i] to ends[i] ((n, d) or
        one (d,) point each, metres, world frame) has occupancy above `level`, as `raycast`
        finds it; with unknown 'occupied' (the default), nor lies in unknown space (see
        `known`): never-seen space is never free. unknown 'free' lets segments cross it."""
        starts, directions, lengths = segment_rays(starts, ends, self.dim)
        return np.isinf(self.raycast(starts, directions, lengths, level, mode, unknown))

    def known(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n,) bool: True where the map has evidence at each of (n, d) points, metres, world
        frame: some cluster's kernel reaches it (clusters form where scans gave samples, free
        and occupied); False where none does (no ray came near: occupancy reads 0.5 there, std
        the prior's) and for rows that are not finite. Planner queries stop there unless
        asked not to (`raycast`, `segment_free`)."""
        return self._known(self._local(points), mode)

    def _known(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """`known` of points in the map's own frame. With 'nearest' features a query sums the
        nearest clusters only, which may leave out the one whose support holds a point: the
        cells known all through (ehm.core.queries.known_cells) say so first."""
        points = self._query_points(points)[0]
        known = np.zeros(len(points), dtype=bool)
        ask = np.arange(len(points))
        if self.config.features == "nearest":
            known = self._planner.known_cells(self._local_snapshot).contains(points)
            ask = np.flatnonzero(~known)
        _, sums = self._summed(points[ask], mode, with_variance=True)
        known[ask] = sums[:, 1] > 0.0
        return known

    def distance(
        self,
        points: np.ndarray,
        level: float = 0.5,
        return_gradient: bool = False,
        unknown: str = "occupied",
        unknown_box: np.ndarray | None = None,
        obstacle_box: np.ndarray | None = None,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) signed Euclidean distance, metres, from each of (n, d) points (metres, world
        frame) to the nearest point whose occupancy is at or above `level`: positive outside,
        negative inside; with return_gradient, also its (n, d) gradient (unit vectors away from
        the nearest obstacle; 0 beyond reach). Distances are kept up to
        config.distance_reach: farther points read that. Unknown space (no kernel reaches it)
        is an obstacle, as raycast and segment_free stop at it (unknown="occupied"), or free
        (unknown="free"); unknown_box, (2, d) metres [low, high] corners,
        world frame, makes it an obstacle only inside that box (a planner's workspace);
        obstacle_box, alike, counts obstacles (occupied, and unknown when asked) only inside
        it (a tile's core). Read from a signed distance field of surfels on
        cluster_radius voxels, put where the log-odds meet the level as point queries read
        them, from one search of nearest clusters around each surfel
        (ehm.core.queries.distance, ehm.grid.planner_support), made on the first call for a
        level and boxes and kept up to date as the map learns (each update's stage 'grids',
        which on large maps learned scan by scan can cost more than the update itself).
        NaN rows for points that are not finite; InputError for a box of another shape or
        with low > high, and for maps whose grid would be too large to keep (tile them)."""
        self._learned("measure distances in it")
        threshold = log_odds_level(level)
        points, finite, query = self._query_points(self._local(points))
        distance = np.full(len(points), np.nan)
        found, gradient = self._planner.distances(
            self._local_snapshot,
            query,
            threshold,
            unknown_is_obstacle(unknown),
            return_gradient,
            self._checked_box("unknown_box", unknown_box),
            self._checked_box("obstacle_box", obstacle_box),
        )
        distance[finite] = found
        if not return_gradient:
            return distance
        gradients = np.full(points.shape, np.nan)
        gradients[finite] = gradient
        return distance, gradients

    def _checked_box(self, name: str, box: np.ndarray | None) -> np.ndarray | None:
        """A (2, d) float64 box of [low, high] corners, metres, world frame, in the map's own
        frame, or None; InputError naming `name` for another shape, NaN or low > high."""
        if box is None:
            return None
        box = np.asarray(box, dtype=np.float64)
        if box.shape != (2, self.dim):
            raise InputError(f"{name} must have shape (2, {self.dim}), got {box.shape}")
        if np.isnan(box).any() or np.any(box[0] > box[1]):
            raise InputError(
                f"{name} must be [low corner, high corner] with low <= high and no NaN, "
                f"got {box.tolist()}"
            )
        return self._local(box)

    def _point_log_odds(self, points: np.ndarray) -> np.ndarray:
        """(n,) log-odds at (n, d) points as `occupancy` reads each point alone (mode 'exact':
        a function of the point, whatever else is asked with it)."""
        return self._scores(points, "exact", False)[0]

    def _near_log_odds(self, places: np.ndarray, spread: float) -> ReadNear:
        """What reads the log-odds at points within `spread` metres of (m, d) `places`, metres
        (ehm.core.queries.surfels.NearLogOdds): with 'nearest' features, each point from the
        nearest clusters of its place, found once per place (as a query in batch mode reads a
        group); with 'support', each point alone (the same)."""
        if self.config.features == "support":
            return lambda points, rows: self._point_log_odds(points)
        clusters, cfg = self._learned("query it"), self.config
        neighbours = self._index.nearest(places, cfg.neighbours, cfg.coarse_neighbours, spread)
        kernels = (clusters.means, clusters.transforms, clusters.planar_kernel)
        learned = (clusters.weights, self._query_intercept(), np.zeros(0), False)

        def read(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
            return decision_values(points, rows, neighbours, *kernels, *learned)[0]

        return read

    def _query_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Checked (n, d) float64 points, which rows are finite, and those rows (contiguous)."""
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != self.dim:
            raise InputError(
                f"query points must have shape (n, {self.dim}), got {tuple(points.shape)}"
            )
        finite = np.all(np.isfinite(points), axis=1)
        return points, finite, np.ascontiguousarray(points[finite])

    @staticmethod
    def _checked_mode(mode: str) -> str:
        if mode not in ("batch", "exact"):
            raise InputError(f"query mode must be 'batch' or 'exact', got {mode!r}")
        return mode

    def _query_groups(self, query: np.ndarray, mode: str, cell: float | None = None) -> PointGroups:
        """The groups that share one neighbour search in `mode` (features 'nearest'): in
        'batch', the points of each cell of `cell` metres (default config.query_cell)."""
        if mode == "batch":
            return group_by_cell(query, cell or self.config.query_cell)
        return PointGroups.singletons(query)

    def _query_clusters(self, query: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray]:
        """The clusters each of (n, d) points takes in queries, as compressed rows: indptr
        (n + 1,) and rows (nnz,) int64 (see SparseFeatures)."""
        if self.config.features == "support":
            found = self._supports.features(
                query, self.clusters_.means, self.clusters_.transforms, self.clusters_.planar_kernel
            )
            return found.indptr, found.rows
        groups = self._query_groups(query, mode)
        neighbours = self._index.group_neighbours(
            query, groups, self.config.neighbours, self.config.coarse_neighbours
        )[groups.group_of_point]
        kept = neighbours >= 0
        indptr = np.zeros(len(query) + 1, dtype=np.int64)
        np.cumsum(kept.sum(axis=1), out=indptr[1:])
        return indptr, neighbours[kept]

    def _scores(
        self,
        points: np.ndarray,
        mode: str | None,
        with_variance: bool,
        cell: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) log-odds at `points` and, when with_variance, (n,) their variance under the
        weights' posterior (else an empty array); NaN for rows that are not finite. cell:
        metres, the query groups' cells in mode 'batch' (default config.query_cell)."""
        scores, sums = self._summed(points, mode, with_variance, cell)
        variance = np.zeros(0)
        if with_variance:
            variance = logit_variance(sums[:, 0], sums[:, 1], self.config.prior_precision)
        return scores, variance

    def _summed(
        self,
        points: np.ndarray,
        mode: str | None,
        with_variance: bool,
        cell: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) log-odds at (n, d) points and, when with_variance, their (n, 2) sums
        [sum_m phi_m^2 / lambda_m, sum_m phi_m] over the kernels that reach them (else (0, 2));
        NaN for rows that are not finite (see `_scores`)."""
        clusters = self._learned("query it")
        mode = self._checked_mode(mode or self.config.query_mode)
        points, finite, query = self._query_points(points)
        kernels = (clusters.means, clusters.transforms, clusters.planar_kernel)
        learned = (
            clusters.weights,
            self._query_intercept(),
            1.0 / clusters.precision if with_variance else np.zeros(0),
            with_variance,
        )
        if self.config.features == "support":
            found, variance_sums = self._supports.decision_values(query, *kernels, *learned)
        else:
            groups = self._query_groups(query, mode, cell)
            neighbours = self._index.group_neighbours(
                query, groups, self.config.neighbours, self.config.coarse_neighbours
            )
            found, variance_sums = decision_values(
                query, groups.group_of_point, neighbours, *kernels, *learned
            )
        scores = np.full(len(points), np.nan)
        scores[finite] = found
        sums = np.full((len(points), 2), np.nan) if with_variance else variance_sums
        if with_variance:
            sums[finite] = variance_sums
        return scores, sums

    # ------------------------------------------------------------------ grids
    def grid(
        self,
        bounds: np.ndarray | None = None,
        resolution: float | None = None,
        follow: bool = False,
        max_bytes: int = DEFAULT_MAX_BYTES,
        std: bool = False,
    ) -> OccupancyGrid:
        """Occupancy grid by incremental grid reconstruction (Sec. 3.5).

        bounds: (2, d) metres, world frame, [low corner, high corner]; None: the box holding
        every kernel's support. resolution: voxel side, metres (None: the map's own,
        config.resolution). follow: keep the grid up to
        date whenever the map learns (each batch of scans, see MapConfig.batch_rays, and each
        fit), for as long as it is referenced (several grids, at any resolutions, can follow
        one map); its bounds stay as they were made. max_bytes:
        refuse larger grids (InputError) before allocating. std: also the standard deviation
        of each voxel's occupancy (`grid.std`, see `occupancy`), at 40 bytes a voxel instead
        of 16.
        """
        self._learned("build a grid")
        voxel = self.config.resolution if resolution is None else resolution
        grid = OccupancyGrid.of(self.snapshot(), bounds, voxel, max_bytes, std)
        if follow:
            self._followers.add(grid)
        return grid

    def grid_blocks(
        self,
        bounds: np.ndarray | None = None,
        resolution: float | None = None,
        max_bytes: int = DEFAULT_MAX_BYTES,
        std: bool = False,
    ) -> Iterator[OccupancyGrid]:
        """The map's grid in blocks of 32^3 voxels (ehm.grid.blocks), made one at a time and
        only where kernels reach: what `grid` holds there, for maps whose extent no single
        grid fits (a LiDAR sweep to 100 m). bounds: (2, d) metres, the voxels of `grid` over
        them; None: every kernel, on multiples of the resolution (OctoMap's voxels).
        resolution: metres (None: config.resolution). InputError, before any block is made,
        when listing the blocks would take more than `max_bytes` (a resolution far finer than
        the map's); memory holds one block at a time."""
        voxel = self.config.resolution if resolution is None else resolution
        return grid_blocks(self.snapshot(), voxel, bounds, std, max_bytes)

    def _update_followers(self) -> None:
        """Bring every following grid and what rays march up to date, timed as the stage
        'grids'."""
        if len(self._followers) == 0 and not self._planner.follows:
            self._planner.update(None)
            return
        timer = StageTimer()
        with timer("grids"):
            self._planner.update(self._local_snapshot())
            if len(self._followers):
                snapshot = self.snapshot()
                for grid in self._followers:
                    grid.update(snapshot)
        self.timings_.update(timer.seconds)

    # ------------------------------------------------------------ persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Write the map to `path` atomically (see ehm.io.map_file), with the scans waiting
        for their batch: saving learns nothing, so a map saved and loaded along the way ends
        where one never saved does."""
        write_map(self.state(), path)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> HilbertMap:
        """The map in a file written by `save`; it answers and goes on learning exactly as
        the saved map would. ehm.io.map_file.MapFileError names what is wrong with a bad
        file. (ehm.load opens either kind of map.)"""
        return cls.from_state(read_map(path))

    def extent(self) -> np.ndarray:
        """(2, d) metres, world frame: the box holding every kernel's support."""
        return support_bounds(self.snapshot())

    # ------------------------------------------------------------------ state
    @property
    def dim(self) -> int | None:
        if self.clusters_ is not None:
            return self.clusters_.dim
        return self._waiting[0].dim if self._waiting else None

    @property
    def n_waiting_scans(self) -> int:
        """Scans given but not learned yet: they wait for `config.batch_rays` rays, or for
        the next query, grid or `flush()`; a save keeps them waiting."""
        return len(self._waiting)

    @property
    def sensor_path(self) -> np.ndarray:
        """(n, d) float64, metres, world frame: the origin of every scan given, in order (for
        maps loaded from files older than format 11, only the scans given since)."""
        if not self._origins:
            return np.zeros((0, self.dim or 3))
        return np.stack(self._origins)

    @property
    def bias_(self) -> float:
        return float(self.bias_state_[0])

    @property
    def n_clusters(self) -> int:
        """Clusters the map has learned. Scans waiting for their batch are in none of them
        until a query, a grid or `flush()` learns them; looking learns nothing."""
        return 0 if self.clusters_ is None else len(self.clusters_)

    def __repr__(self) -> str:
        """The map as it stands, without learning the scans that wait for their batch."""
        defaults = MapConfig().to_dict()
        changed = {k: v for k, v in self.config.to_dict().items() if defaults[k] != v}
        parts = [f"dim={self.dim}"]
        parts.append(f"clusters={0 if self.clusters_ is None else len(self.clusters_)}")
        parts.append(f"scans={self.n_scans_}")
        if self._waiting:
            parts.append(f"waiting={len(self._waiting)}")
        parts += [f"{k}={v!r}" for k, v in changed.items()]
        return f"HilbertMap({', '.join(parts)})"

    def clusters(self) -> ClusterView:
        """A copy of the learned clusters: centres, covariances, weights, kind ('planar' or
        'volumetric'), kernel, scale and label, one row per cluster (see ClusterView); scans
        waiting for their batch are not learned by looking."""
        if self.clusters_ is None:
            if self._waiting:
                raise EmptyMapError("no clusters learned yet: flush() learns the waiting scans")
            raise EmptyMapError("the map is empty: integrate a scan or fit before you look at it")
        view = ClusterView.of(self.clusters_)
        return replace(view, means=self._world(view.means))

    def memory_bytes(self) -> int:
        """Bytes of everything the map keeps: cluster arrays, weights, optimiser state, the
        sample memory, anchor layers, the search structure over cluster centres, the sensor
        path, the scans waiting for their batch, and while kept, the grid and cells rays march
        (`raycast`). Counting learns nothing."""
        clusters = 0 if self.clusters_ is None else self.clusters_.nbytes
        memory = 0 if self.memory_ is None else self.memory_.nbytes
        learned = clusters + memory + self.bias_state_.nbytes + self.anchors_.nbytes
        search = self._supports if self.config.features == "support" else self._index
        path = sum(origin.nbytes for origin in self._origins)
        waiting = sum(scan.points_world.nbytes + scan.hit_mask.nbytes for scan in self._waiting)
        return learned + search.nbytes + self._planner.nbytes + path + waiting

    def state(self) -> MapState:
        """Everything the map has learned and the scans waiting for their batch, as plain data
        (shared, not copied). Taking it learns nothing."""
        dim = self.dim
        if dim is None:
            raise EmptyMapError("the map is empty: integrate a scan or fit before you save it")
        empty = self.clusters_ is None
        return MapState(
            self.config,
            ClusterSet.empty(dim) if empty else self.clusters_,
            self.anchors_,
            self.bias_state_,
            self.n_scans_,
            self._rng.bit_generator.state,
            EvidenceMemory.of_config(dim, self.config) if empty else self._memory(),
            tuple(self._waiting),
            self.sensor_path,
            self.time_,
            self.local_origin_,
        )

    @classmethod
    def from_state(cls, state: MapState) -> HilbertMap:
        """The map whose learned state is `state`: it answers and goes on learning exactly as
        the map the state was taken from (when the state has its rng_state)."""
        hilbert_map = cls(state.config)
        hilbert_map.clusters_ = state.clusters
        hilbert_map.bias_state_ = np.array(state.bias_state, dtype=np.float64)
        hilbert_map.n_scans_ = state.n_scans
        hilbert_map.time_ = state.time
        hilbert_map.anchors_ = state.anchors
        hilbert_map.memory_ = state.memory
        hilbert_map.local_origin_ = state.local_origin
        if state.rng_state is not None:
            hilbert_map._rng.bit_generator.state = state.rng_state
        hilbert_map._relist(None)
        hilbert_map._waiting = list(state.waiting)
        if state.sensor_path is not None:
            hilbert_map._origins = list(state.sensor_path)
        hilbert_map._waiting_rays = sum(len(scan) for scan in state.waiting)
        return hilbert_map

    def snapshot(self) -> MapSnapshot:
        """A read-only copy of the map's kernels and weights, for grids and pictures, in world
        frame."""
        local = self._local_snapshot()
        if self.local_origin_ is None or not self.local_origin_.any():
            return local
        return replace(local, means=local.means + self.local_origin_)


# A map whose first scan's sensor stands farther than this from the world origin, metres,
# keeps its clusters relative to a point near that sensor (LOCAL_ORIGIN_STEP metres apart):
# cells keyed by integers from the origin reach 15 km at the finest resolutions.
LOCAL_ORIGIN_BEYOND = 10_000.0
LOCAL_ORIGIN_STEP = 1024.0


def local_origin_for(sensor: np.ndarray) -> np.ndarray:
    """(d,) metres, world frame: the origin of a map's own frame, for the sensor position of
    its first scan: the world origin, unless the sensor stands farther than
    LOCAL_ORIGIN_BEYOND from it (georeferenced data: UTM, State Plane), then the sensor's
    position rounded to LOCAL_ORIGIN_STEP, a power of two, so shifting by it is exact."""
    sensor = np.asarray(sensor, dtype=np.float64)
    if np.abs(sensor).max() <= LOCAL_ORIGIN_BEYOND:
        return np.zeros_like(sensor)
    return np.round(sensor / LOCAL_ORIGIN_STEP) * LOCAL_ORIGIN_STEP


def _latest_time(scans: list[Scan]) -> float | None:
    """The latest time stamp of `scans`, seconds; None when none has one."""
    times = [scan.time for scan in scans if scan.time is not None]
    return max(times) if times else None
