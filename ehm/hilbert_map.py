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
from ehm.core.observations.samples import scan_rays
from ehm.core.queries.raycast import cast_rays
from ehm.core.search.kernel_search import ReadRows
from ehm.core.sensor.local_frame import in_frame, local_origin_for
from ehm.core.sensor.scan import Scan
from ehm.core.sensor.waiting_scans import WaitingScans, check_scan
from ehm.core.snapshot import MapSnapshot
from ehm.core.state import MapState
from ehm.core.timing import StageTimer
from ehm.core.update import update
from ehm.errors import EmptyMapError, InputError
from ehm.grid.blocks import grid_blocks
from ehm.grid.bounds import DEFAULT_MAX_BYTES, support_bounds
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.grid.planner_support import PlannerSupport
from ehm.io.map_file import read_map, write_map
from ehm.map_queries import DistanceQuery, MapQueries, RayQuery

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
    HilbertMap(cluster_radius=0.2); resolution=r and profile=p, in place of a config, start
    from MapConfig.for_resolution(r, p) (HilbertMap(resolution=0.2, max_range=80.0);
    HilbertMap(resolution=0.1, profile="realtime") learns faster). Learned state
    ends in an underscore: model_ (a LearnedModel: clusters, memory, anchors, bias, search;
    None before the first scan is learned), clusters_ and bias_ (its), local_origin_ (the
    world point, metres, the model is kept relative to, ehm.core.sensor.local_frame),
    n_scans_, timings_ (seconds per stage of the last update), last_update_ (clusters added
    and merged by it, its samples and those replayed from the memory) and time_ (seconds, the
    latest time stamp learned; None without). Everything the map takes and answers is in
    world frame, whatever its local origin.
    """

    def __init__(self, config: MapConfig | None = None, **overrides: Any) -> None:
        self.config = MapConfig.of(config, **overrides)
        self._reset()
        self._followers: weakref.WeakSet[OccupancyGrid] = weakref.WeakSet()

    def _reset(self) -> None:
        """Forget everything learned."""
        self.model_: LearnedModel | None = None
        self.local_origin_: np.ndarray | None = None
        self._waiting = WaitingScans(self.config.batch_rays)
        self.n_scans_ = 0
        self.timings_: dict[str, float] = {}
        self.last_update_: dict[str, int] = {}
        # Snapshots carry this token, so grids tell a map that was refitted from one that grew.
        self._lineage = object()
        # What rays and distances read, made when first needed, then following the map.
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
        """The learned clusters, metres, the map's own frame; None before learning."""
        return None if self.model_ is None else self.model_.clusters

    @property
    def bias_(self) -> float:
        """The learned bias, log-odds (added to queries when config.query_intercept)."""
        return 0.0 if self.model_ is None else self.model_.bias

    @property
    def time_(self) -> float | None:
        """Seconds, the latest time stamp of the scans learned; None without."""
        return None if self.model_ is None else self.model_.time

    def _learned(self, action: str) -> LearnedModel:
        """The model, after learning any scans waiting for their batch."""
        self.flush()
        if self.model_ is None:
            raise EmptyMapError(f"the map is empty: integrate a scan or fit before you {action}")
        return self.model_

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
        check_scan(scan, "scan", self.dim, "the map", self.config.forget_after)
        self.n_scans_ += 1
        self.timings_ = {}
        return self.flush() if self._waiting.add(scan) else self

    def flush(self) -> HilbertMap:
        """Learn the scans waiting for their batch (config.batch_rays) now, as one batch;
        returns self. Queries, grids and saves do this themselves."""
        if len(self._waiting):
            self._learn(self._waiting.take())
        return self

    def fit(self, scans: Iterable[Scan]) -> HilbertMap:
        """Single-batch mode (Table 5): forget what was learned and learn all scans at once."""
        scans = list(scans)
        if not scans:
            raise InputError("fit needs at least one scan, got none")
        for i, scan in enumerate(scans):
            dim = scans[0].dim if i else None
            check_scan(scan, f"scan {i}", dim, "scan 0", self.config.forget_after)
        self._reset()
        self._learn(scans)
        self.n_scans_ = len(scans)
        self._waiting.origins = [scan.origin for scan in scans]
        return self

    def _learn(self, scans: list[Scan]) -> None:
        """Alg. 2 on `scans` as one batch, in the map's own frame, whose origin the first
        scans learned choose; then every following grid and what rays march catch up."""
        if self.local_origin_ is None:
            self.local_origin_ = local_origin_for(scans[0].origin)
        if self.model_ is None:
            self.model_ = LearnedModel.empty(self.config, scans[0].dim)
        model, timer = self.model_, StageTimer()
        with timer("samples"):
            local_scans, config = in_frame(scans, self.config, self.local_origin_)
            rays = scan_rays(local_scans, config)
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
    def _log_odds(
        self, points: np.ndarray, mode: str, with_variance: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """The calibrated log-odds, the raw ones times the model's scale, and their variance."""
        model = self._learned("query it")
        log_odds, variance = model.log_odds(self._local(points), mode, with_variance)
        return model.scale * log_odds, model.scale**2 * variance

    def _gradient(self, points: np.ndarray, mode: str) -> np.ndarray:
        model = self._learned("query it")
        return model.scale * model.gradients(self._local(points), mode)

    def _raw_threshold(self, threshold: float) -> float:
        """The raw log-odds (w^T phi + intercept) at which the calibrated ones are
        `threshold`: planner queries march the raw ones."""
        return threshold / self._learned("query it").scale

    def _cast(self, rays: RayQuery) -> np.ndarray:
        """Rays guided by the planner support's grid and cells, read in wider query cells."""
        model, cell = self._learned("query it"), RAY_QUERY_CELLS * self.config.query_cell
        take, mode, stop = self._local_snapshot, rays.mode, rays.stop_at_unknown
        threshold = self._raw_threshold(rays.threshold)
        return cast_rays(
            lambda points: model.sums(points, False, mode, cell).scores,
            self._local(rays.origins),
            rays.directions,
            rays.max_range,
            threshold,
            self.config.cluster_radius,
            self._planner.grid(take),
            self._planner.cells(take, threshold),
            partial(self._known_local, mode=mode) if stop else None,
            self._planner.known_cells(take) if stop else None,
        )

    def _known_at(self, points: np.ndarray, mode: str) -> np.ndarray:
        return self._known_local(self._local(points), mode)

    def _known_local(self, points: np.ndarray, mode: str) -> np.ndarray:
        """`known` in the map's own frame: where the search truncates (nearest clusters), the
        cells known all through (ehm.core.queries.known_cells) answer first."""
        model = self._learned("query it")
        known = np.zeros(len(points), dtype=bool)
        if model.search.truncated:
            known = self._planner.known_cells(self._local_snapshot).contains(points)
        ask = np.flatnonzero(~known)
        sums = model.sums(points[ask], True, mode, self.config.query_cell)
        known[ask] = sums.variance_sums[:, 1] > 0.0
        return known

    def _distances(self, points: np.ndarray, query: DistanceQuery) -> tuple[np.ndarray, np.ndarray]:
        """From the planner support's field for the level and boxes, in the map's own frame."""
        boxes = [
            None if box is None else self._local(box)
            for box in (query.unknown_box, query.obstacle_box)
        ]
        return self._planner.distances(
            self._local_snapshot,
            self._local(points),
            self._raw_threshold(query.threshold),
            query.unknown_is_occupied,
            query.with_gradient,
            *boxes,
        )

    def _point_log_odds(self, points: np.ndarray) -> np.ndarray:
        """(n,) raw log-odds at (n, d) points of the map's own frame as `occupancy` reads each
        point alone (mode 'exact': a function of the point, whatever else is asked with it)."""
        return self._learned("query it").log_odds(points, "exact", False)[0]

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
        return self._learned(action).snapshot(self._lineage, self.local_origin_)

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
        dim, model = self.dim, self.model_
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
            tuple(self._waiting.scans),
            self.sensor_path,
            model.time,
            self.local_origin_,
            model.scale,
        )

    @classmethod
    def from_state(cls, state: MapState) -> HilbertMap:
        """The map whose learned state is `state`: it answers and goes on learning exactly as
        the map the state was taken from (when the state has its rng_state)."""
        hilbert_map = cls(state.config)
        hilbert_map.model_ = LearnedModel.of_state(state)
        hilbert_map.n_scans_ = state.n_scans
        # Maps saved before they kept a local origin keep their clusters in world frame.
        world = np.zeros(state.clusters.dim) if len(state.clusters) else None
        hilbert_map.local_origin_ = world if state.local_origin is None else state.local_origin
        path = () if state.sensor_path is None else state.sensor_path
        hilbert_map._waiting = WaitingScans(state.config.batch_rays, state.waiting, path)
        return hilbert_map

    # ------------------------------------------------------------------ looking
    @property
    def dim(self) -> int | None:
        if self.model_ is not None:
            return self.model_.clusters.dim
        return self._waiting.dim

    @property
    def n_waiting_scans(self) -> int:
        """Scans given but not learned yet: they wait for `config.batch_rays` rays, or for
        the next query, grid or `flush()`; a save keeps them waiting."""
        return len(self._waiting)

    @property
    def sensor_path(self) -> np.ndarray:
        """(n, d) float64, metres, world frame: the origin of every scan given, in order (for
        maps loaded from files older than format 11, only the scans given since)."""
        return self._waiting.sensor_path(self.dim or 3)

    @property
    def n_clusters(self) -> int:
        """Clusters the map has learned. Scans waiting for their batch are in none of them
        until a query, a grid or `flush()` learns them; looking learns nothing."""
        return 0 if self.model_ is None else len(self.model_.clusters)

    def __repr__(self) -> str:
        """The map as it stands, without learning the scans that wait for their batch."""
        defaults = MapConfig().to_dict()
        changed = {k: v for k, v in self.config.to_dict().items() if defaults[k] != v}
        parts = [f"dim={self.dim}", f"clusters={self.n_clusters}", f"scans={self.n_scans_}"]
        if len(self._waiting):
            parts.append(f"waiting={len(self._waiting)}")
        parts += [f"{k}={v!r}" for k, v in changed.items()]
        return f"HilbertMap({', '.join(parts)})"

    def clusters(self) -> ClusterView:
        """A copy of the learned clusters: centres, covariances, weights, kind ('planar' or
        'volumetric'), kernel, scale and label, one row per cluster (see ClusterView); scans
        waiting for their batch are not learned by looking."""
        if self.model_ is None:
            if len(self._waiting):
                raise EmptyMapError("no clusters learned yet: flush() learns the waiting scans")
            raise EmptyMapError("the map is empty: integrate a scan or fit before you look at it")
        offset, view = self.local_origin_, ClusterView.of(self.model_.clusters)
        return view if offset is None else replace(view, means=view.means + offset)

    def memory_bytes(self) -> int:
        """Bytes of everything the map keeps: cluster arrays, weights, optimiser state, the
        sample memory, anchor layers, the search structure over cluster centres, the sensor
        path, the scans waiting for their batch, and while kept, the grid and cells rays march
        (`raycast`). Counting learns nothing."""
        learned = 0 if self.model_ is None else self.model_.nbytes
        return learned + self._planner.nbytes + self._waiting.nbytes
