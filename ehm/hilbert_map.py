"""HilbertMap: an Efficient Hilbert Map, learned scan by scan or in one batch, and queried.

m = HilbertMap(neighbours=8)
m.integrate(points_world, origin)      # one scan, Alg. 2
p = m.occupancy(query_points)          # (n,) probability of occupied, Alg. 3
g = m.grid()                           # OccupancyGrid at the map's resolution (Sec. 3.5)
m.save("room.ehm"); m2 = ehm.load("room.ehm")

The map holds what it learned (ehm.core.learned_model), in a frame of its own near its data
(ehm.core.sensor.local_frame); an update is one call of ehm.core.update, queries ask the
model's kernel search (ehm.core.search.kernel_search), and planners' rays and distances read
what ehm.grid.planner_support keeps up to date with it.
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
from ehm.core.learned_model import LearnedModel
from ehm.core.model.clusters import ClusterSet, ClusterView
from ehm.core.observations.evidence import gather_evidence
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.observations.samples import scan_rays
from ehm.core.queries.gradient import logit_gradients
from ehm.core.queries.raycast import cast_rays, log_odds_level, unknown_is_obstacle
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.kernel_search import KernelSums, ReadRows
from ehm.core.sensor.local_frame import local_origin_for, scans_from
from ehm.core.sensor.scan import Scan
from ehm.core.snapshot import MapSnapshot
from ehm.core.state import MapState
from ehm.core.timing import StageTimer
from ehm.core.update import update
from ehm.core.weights.uncertainty import logit_variance
from ehm.errors import EmptyMapError, InputError
from ehm.grid.blocks import grid_blocks
from ehm.grid.bounds import DEFAULT_MAX_BYTES, support_bounds
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.grid.planner_support import PlannerSupport
from ehm.io.map_file import read_map, write_map
from ehm.map_queries import MapQueries, finite_rows

# Side of the cells that tell rays where the occupancy may rise above the level, in cluster
# radii (ehm.core.queries.raycast.CandidateCells).
RAY_CELLS_PER_RADIUS = 4.0
# Rays read the log-odds in batch mode in groups of cells this many times `query_cell` wide:
# a ray's samples lie a few centimetres apart, and smaller cells make a search each.
RAY_QUERY_CELLS = 2.0


class HilbertMap(MapQueries):
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
    ends in an underscore: clusters_ (a ClusterSet), memory_, anchors_ (AnchorLayers, empty
    unless config.anchor_layers > 1), bias_, local_origin_ (the world point, metres, clusters_
    and the memory are kept relative to, see ehm.core.sensor.local_frame; None before the
    first scan is learned), n_scans_, timings_ (seconds per stage of the last update),
    last_update_ (clusters added and merged by it, its samples and those replayed from the
    memory) and time_ (seconds, the latest time stamp of the scans learned; None without).
    Everything the map takes and answers is in world frame, whatever its local origin.
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
        self._model: LearnedModel | None = None
        self.local_origin_: np.ndarray | None = None
        # Scans given but not learned yet, waiting for config.batch_rays rays.
        self._waiting: list[Scan] = []
        self._waiting_rays = 0
        self.n_scans_ = 0
        # The origin of every scan given, in order (see sensor_path).
        self._origins: list[np.ndarray] = []
        self.timings_: dict[str, float] = {}
        self.last_update_: dict[str, int] = {}
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

    # ------------------------------------------------------------ learned state
    @property
    def clusters_(self) -> ClusterSet | None:
        return None if self._model is None else self._model.clusters

    @property
    def memory_(self) -> EvidenceMemory | None:
        return None if self._model is None else self._model.memory

    @property
    def anchors_(self) -> AnchorLayers:
        return AnchorLayers() if self._model is None else self._model.anchors

    @property
    def bias_state_(self) -> np.ndarray:
        return np.zeros(2) if self._model is None else self._model.bias_state

    @property
    def bias_(self) -> float:
        return float(self.bias_state_[0])

    @property
    def time_(self) -> float | None:
        return None if self._model is None else self._model.time

    def _learned(self, action: str) -> LearnedModel:
        """The model, after learning any scans waiting for their batch."""
        self.flush()
        if self._model is None:
            raise EmptyMapError(f"the map is empty: integrate a scan or fit before you {action}")
        return self._model

    def _query_dim(self, action: str) -> int:
        return self._learned(action).clusters.dim

    # ---------------------------------------------------------------- training
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
        self._check_scan(scan, "scan", self.dim, "the map")
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
        if self._waiting:
            scans, self._waiting, self._waiting_rays = self._waiting, [], 0
            self._learn(scans)
        return self

    def fit(self, scans: Iterable[Scan]) -> HilbertMap:
        """Single-batch mode (Table 5): forget what was learned and learn all scans at once."""
        scans = list(scans)
        if not scans:
            raise InputError("fit needs at least one scan, got none")
        for i, scan in enumerate(scans):
            self._check_scan(scan, f"scan {i}", scans[0].dim if i else None, "scan 0")
        self._reset()
        self._learn(scans)
        self.n_scans_ = len(scans)
        self._origins = [scan.origin for scan in scans]
        return self

    def _check_scan(self, scan: Scan, what: str, dim: int | None, holder: str) -> None:
        """InputError for what is not a Scan, a scan of other than `dim` axes (those of
        `holder`), and a scan without time stamp given to a map that fades."""
        if not isinstance(scan, Scan):
            raise InputError(f"{what}: expected ehm.Scan, got {type(scan).__name__}")
        if dim is not None and scan.dim != dim:
            raise InputError(f"{what} points are {scan.dim}D, {holder} is {dim}D")
        if self.config.forget_after is not None and scan.time is None:
            raise InputError(
                f"{what} has no time stamp, and the map forgets what it has not seen for "
                f"{self.config.forget_after} s (MapConfig.forget_after): give each scan its time "
                "(integrate(..., time=seconds))"
            )

    def _learn(self, scans: list[Scan]) -> None:
        """Alg. 2 on `scans` as one batch, in the map's own frame, whose origin the first
        scans learned choose; then every following grid and what rays march catch up."""
        if self.local_origin_ is None:
            self.local_origin_ = local_origin_for(scans[0].origin)
        if self._model is None:
            self._model = LearnedModel.empty(self.config, scans[0].dim)
        model, config, timer = self._model, self.config, StageTimer()
        if config.learn_box and self.local_origin_.any():
            box = np.asarray(config.learn_box).reshape(2, -1) - self.local_origin_
            config = config.replace(learn_box=tuple(box.ravel()))
        with timer("samples"):
            rays = scan_rays(scans_from(scans, self.local_origin_), config)
            samples = gather_evidence(rays, config, model.rng)
        times = [scan.time for scan in scans if scan.time is not None]
        self.last_update_ = update(model, rays, samples, max(times, default=None), timer)
        if len(self._followers) == 0 and not self._planner.follows:
            self._planner.update(None)
        else:
            with timer("grids"):
                self._planner.update(self._local_snapshot())
                if len(self._followers):
                    snapshot = self.snapshot()
                    for grid in self._followers:
                        grid.update(snapshot)
        self.timings_ = dict(timer.seconds)

    def _local(self, points: np.ndarray) -> np.ndarray:
        """World points (n, d) in the map's own frame."""
        offset = self.local_origin_
        return points if offset is None or not offset.any() else points - offset

    # ---------------------------------------------------------------- queries
    def _summed(
        self, points: np.ndarray, mode: str, with_variance: bool, cell: float
    ) -> KernelSums:
        """The log-odds at (n, d) points of the map's own frame and with_variance their
        variance sums (see KernelSums), NaN for rows that are not finite."""
        finite, query = finite_rows(points)
        found = self._learned("query it").sums(query, with_variance, mode, cell)
        scores = np.full(len(points), np.nan)
        scores[finite] = found.scores
        if not with_variance:
            return KernelSums(scores, found.variance_sums)
        sums = np.full((len(points), 2), np.nan)
        sums[finite] = found.variance_sums
        return KernelSums(scores, sums)

    def _log_odds(
        self, points: np.ndarray, mode: str, with_variance: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        found = self._summed(self._local(points), mode, with_variance, self.config.query_cell)
        if not with_variance:
            return found.scores, np.zeros(0)
        sums = found.variance_sums
        return found.scores, logit_variance(sums[:, 0], sums[:, 1], self.config.prior_precision)

    def gradient(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n, d) float64 gradient of the occupancy log-odds (`decision_function`) with respect to
        position, 1/m, world frame, at (n, d) points, metres: it points toward more occupied space,
        and p(1 - p) times it is the gradient of the probability. Over the same kernels as
        `decision_function` in `mode`; planar-surface kernels are flat (0 or 1) and add nothing
        (ehm.core.queries.gradient). NaN rows where points are not finite."""
        points = self._checked_points(points)
        model = self._learned("query it")
        finite, query = finite_rows(self._local(points))
        indptr, rows = model.search.rows(query, model.clusters, self._mode(mode))
        out = np.full(points.shape, np.nan)
        clusters = model.clusters
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

    def _cast(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_range: np.ndarray,
        threshold: float,
        mode: str,
        stop_at_unknown: bool,
    ) -> np.ndarray:
        """Rays guided by the planner support's grid and candidate cells, read in mode 'batch'
        in cells RAY_QUERY_CELLS times query_cell wide, stopped by the known cells."""
        cell = RAY_QUERY_CELLS * self.config.query_cell
        take = self._local_snapshot
        return cast_rays(
            lambda points: self._summed(points, mode, False, cell).scores,
            self._local(origins),
            directions,
            max_range,
            threshold,
            self.config.cluster_radius,
            self._planner.grid(take),
            self._planner.cells(take, threshold),
            partial(self._known, mode=mode) if stop_at_unknown else None,
            self._planner.known_cells(take) if stop_at_unknown else None,
        )

    def known(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n,) bool: True where the map has evidence at each of (n, d) points, metres, world
        frame: some cluster's kernel reaches it (clusters form where scans gave samples, free
        and occupied); False where none does (no ray came near: occupancy reads 0.5 there, std
        the prior's) and for rows that are not finite. Planner queries stop there unless
        asked not to (`raycast`, `segment_free`)."""
        return self._known(self._local(self._checked_points(points)), mode)

    def _known(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """`known` of points in the map's own frame. A search of the nearest clusters may
        leave out the one whose support holds a point: the cells known all through
        (ehm.core.queries.known_cells) say so first."""
        model = self._learned("query it")
        known = np.zeros(len(points), dtype=bool)
        if model.search.truncated:
            known = self._planner.known_cells(self._local_snapshot).contains(points)
        ask = np.flatnonzero(~known)
        sums = self._summed(points[ask], self._mode(mode), True, self.config.query_cell)
        known[ask] = sums.variance_sums[:, 1] > 0.0
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
        points = self._checked_points(points, "measure distances in it")
        finite, query = finite_rows(self._local(points))
        found, gradient = self._planner.distances(
            self._local_snapshot,
            query,
            log_odds_level(level),
            unknown_is_obstacle(unknown),
            return_gradient,
            self._checked_box("unknown_box", unknown_box),
            self._checked_box("obstacle_box", obstacle_box),
        )
        distance = np.full(len(points), np.nan)
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
        """(n,) log-odds at (n, d) points of the map's own frame as `occupancy` reads each
        point alone (mode 'exact': a function of the point, whatever else is asked with it)."""
        return self._summed(points, "exact", False, self.config.query_cell).scores

    def _near_log_odds(self, places: np.ndarray, spread: float) -> ReadRows:
        """What reads the log-odds at points within `spread` metres of (m, d) `places`, metres,
        the map's own frame, as `_point_log_odds` does (KernelSearch.near_reader)."""
        model = self._learned("query it")
        return model.search.near_reader(places, spread, model.clusters, model.intercept)

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
        config.resolution). follow: keep the grid up to date whenever the map learns (each
        batch of scans, see MapConfig.batch_rays, and each fit), for as long as it is
        referenced (several grids, at any resolutions, can follow one map); its bounds stay as
        they were made. max_bytes: refuse larger grids (InputError) before allocating. std:
        also the standard deviation of each voxel's occupancy (`grid.std`, see `occupancy`),
        at 40 bytes a voxel instead of 16.
        """
        voxel = self.config.resolution if resolution is None else resolution
        grid = OccupancyGrid.of(self.snapshot("build a grid"), bounds, voxel, max_bytes, std)
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

    def snapshot(self, action: str = "take a snapshot") -> MapSnapshot:
        """A read-only copy of the map's kernels and weights, for grids and pictures, in world
        frame."""
        origin = self.local_origin_
        shift = origin if origin is not None and origin.any() else None
        return self._learned(action).snapshot(self._lineage, shift)

    def _local_snapshot(self) -> MapSnapshot:
        """The snapshot in the map's own frame, as the planner support keeps it."""
        return self._learned("take a snapshot").snapshot(self._lineage)

    def extent(self) -> np.ndarray:
        """(2, d) metres, world frame: the box holding every kernel's support."""
        return support_bounds(self.snapshot())

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

    def state(self) -> MapState:
        """Everything the map has learned and the scans waiting for their batch, as plain data
        (shared, not copied). Taking it learns nothing."""
        dim, model = self.dim, self._model
        if dim is None:
            raise EmptyMapError("the map is empty: integrate a scan or fit before you save it")
        if model is None:  # waiting scans only: the model they will start
            model = LearnedModel.empty(self.config, dim)
        return MapState(
            self.config,
            model.clusters,
            model.anchors,
            model.bias_state,
            self.n_scans_,
            model.rng_state,
            model.memory,
            tuple(self._waiting),
            self.sensor_path,
            model.time,
            self.local_origin_,
        )

    @classmethod
    def from_state(cls, state: MapState) -> HilbertMap:
        """The map whose learned state is `state`: it answers and goes on learning exactly as
        the map the state was taken from (when the state has its rng_state)."""
        hilbert_map = cls(state.config)
        hilbert_map._model = LearnedModel.of_state(state)
        hilbert_map.n_scans_ = state.n_scans
        hilbert_map.local_origin_ = state.local_origin
        hilbert_map._waiting = list(state.waiting)
        hilbert_map._waiting_rays = sum(len(scan) for scan in state.waiting)
        if state.sensor_path is not None:
            hilbert_map._origins = list(state.sensor_path)
        return hilbert_map

    # ------------------------------------------------------------------ looking
    @property
    def dim(self) -> int | None:
        if self._model is not None:
            return self._model.clusters.dim
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
    def n_clusters(self) -> int:
        """Clusters the map has learned. Scans waiting for their batch are in none of them
        until a query, a grid or `flush()` learns them; looking learns nothing."""
        return 0 if self._model is None else len(self._model.clusters)

    def __repr__(self) -> str:
        """The map as it stands, without learning the scans that wait for their batch."""
        defaults = MapConfig().to_dict()
        changed = {k: v for k, v in self.config.to_dict().items() if defaults[k] != v}
        parts = [f"dim={self.dim}", f"clusters={self.n_clusters}", f"scans={self.n_scans_}"]
        if self._waiting:
            parts.append(f"waiting={len(self._waiting)}")
        parts += [f"{k}={v!r}" for k, v in changed.items()]
        return f"HilbertMap({', '.join(parts)})"

    def clusters(self) -> ClusterView:
        """A copy of the learned clusters: centres, covariances, weights, kind ('planar' or
        'volumetric'), kernel, scale and label, one row per cluster (see ClusterView); scans
        waiting for their batch are not learned by looking."""
        if self._model is None:
            if self._waiting:
                raise EmptyMapError("no clusters learned yet: flush() learns the waiting scans")
            raise EmptyMapError("the map is empty: integrate a scan or fit before you look at it")
        view = ClusterView.of(self._model.clusters)
        offset = self.local_origin_
        return (
            view if offset is None or not offset.any() else replace(view, means=view.means + offset)
        )

    def memory_bytes(self) -> int:
        """Bytes of everything the map keeps: cluster arrays, weights, optimiser state, the
        sample memory, anchor layers, the search structure over cluster centres, the sensor
        path, the scans waiting for their batch, and while kept, the grid and cells rays march
        (`raycast`). Counting learns nothing."""
        learned = 0 if self._model is None else self._model.nbytes
        path = sum(origin.nbytes for origin in self._origins)
        waiting = sum(scan.points_world.nbytes + scan.hit_mask.nbytes for scan in self._waiting)
        return learned + self._planner.nbytes + path + waiting
