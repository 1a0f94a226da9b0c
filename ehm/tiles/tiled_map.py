"""TiledMap: a map cut into overlapping square or cubic tiles, each an ordinary HilbertMap,
learned one process per tile and answered by blending the tiles across their borders.

    m = TiledMap(tile_size=25.0, config=MapConfig.for_resolution(0.2))
    m.build(ScanFiles("sequences/00"), workers=4, directory="city.ehm")  # Dask, ehm.tiles.build
    p = m.occupancy(points)                 # (n,) blended across tile borders, no seams
    g = m.grid(bounds, resolution=0.2)      # an OccupancyGrid, as HilbertMap.grid gives
    m2 = ehm.load("city.ehm")               # lazy: a query reads only the tiles it touches

Each tile learns from the rays that cross its learn box, free samples only along their part
inside it (MapConfig.learn_box), so where tiles overlap both learned the same data; the
blending weights (ehm.tiles.tiling) make the answer run smoothly from one to the other.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Iterable, Iterator
from dataclasses import replace
from functools import partial
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from ehm.config import MapConfig
from ehm.core.queries.raycast import cast_rays
from ehm.core.sensor.scan import Scan
from ehm.core.sensor.waiting_scans import check_scan
from ehm.errors import EmptyMapError, InputError, SettingsError
from ehm.grid.bounds import DEFAULT_MAX_BYTES, aligned_bounds, bytes_per_voxel, grid_shape
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.hilbert_map import HilbertMap
from ehm.io.map_file import map_bytes, map_state_of_bytes
from ehm.map_queries import DistanceQuery, MapQueries, RayQuery
from ehm.tiles.build import (
    BuildObserver,
    BuildReport,
    NoObserver,
    TileJob,
    binned_scans,
    dask_client,
    learn_into_tiles,
    learned_tasks,
    scans_per_tile,
    tile_blocks,
)
from ehm.tiles.sources import ScanSource, scan_source
from ehm.tiles.store import TileIndex, TileKey, TileRecord, TileStore
from ehm.tiles.tiling import Tiling, scan_box

DEFAULT_TILE_SIZE = 25.0
# The default overlap, in free-space cluster radii (the widest clusters): tiles then learn
# the same clusters where they meet, so the blend runs between two maps that agree.
OVERLAP_IN_FREE_RADII = 2.0
# Tiles kept in memory at most, least recently used dropped first (those not saved stay).
MAX_LOADED_TILES = 64
# A build into a map directory writes its index at least this often, seconds, as tiles come.
INDEX_EVERY_SECONDS = 10.0


class TiledMap(MapQueries):
    """A continuous occupancy map cut into tiles (see the module's docstring).

    tile_size: side of the square (2D) or cubic (3D) tiles, metres; overlap: how far each
    tile learns beyond its core, metres, at most tile_size / 2 (None: two free-space cluster
    radii, MapConfig.free_cluster_radius); config and keyword overrides: the settings of
    every tile, as for HilbertMap. max_loaded_tiles: saved tiles kept in memory at once, the
    least recently used dropped first; tiles that learned since the map was last saved stay
    until `save` writes them (a build into a directory writes each as it comes).
    """

    def __init__(
        self,
        tile_size: float = DEFAULT_TILE_SIZE,
        overlap: float | None = None,
        config: MapConfig | None = None,
        max_loaded_tiles: int = MAX_LOADED_TILES,
        **overrides: Any,
    ) -> None:
        self.config = MapConfig.of(config, **overrides)
        if self.config.learn_box:
            raise SettingsError("a tiled map sets each tile's learn_box itself: leave it empty")
        if overlap is None:
            overlap = OVERLAP_IN_FREE_RADII * self.config.free_cluster_radius
        self.tiling = Tiling(tile_size, overlap)
        if not (isinstance(max_loaded_tiles, int) and max_loaded_tiles >= 1):
            raise SettingsError(
                f"max_loaded_tiles must be an integer >= 1, got {max_loaded_tiles!r}"
            )
        self.max_loaded_tiles = max_loaded_tiles
        self._dim: int | None = None
        self._records: dict[TileKey, TileRecord] = {}
        self._store: TileStore | None = None
        self._loaded: OrderedDict[TileKey, HilbertMap] = OrderedDict()
        self._changed: set[TileKey] = set()
        self._origins: list[np.ndarray] = []
        self.n_scans_ = 0

    # ------------------------------------------------------------------ state
    @property
    def tile_size(self) -> float:
        return self.tiling.size

    @property
    def overlap(self) -> float:
        return self.tiling.overlap

    @property
    def dim(self) -> int | None:
        return self._dim

    @property
    def directory(self) -> Path | None:
        """The map directory tiles are read from and written to (None: all in memory)."""
        return None if self._store is None else self._store.directory

    @property
    def tile_keys(self) -> list[TileKey]:
        """Every tile's key (integer indices, ehm.tiles.tiling), sorted."""
        return sorted(set(self._records) | self._changed)

    @property
    def n_tiles(self) -> int:
        return len(self.tile_keys)

    @property
    def n_loaded_tiles(self) -> int:
        """Tiles in memory now."""
        return len(self._loaded)

    @property
    def n_clusters(self) -> int:
        """Clusters all tiles have learned (a cluster in two tiles' overlap counts twice).
        Scans waiting in a tile are in none of them until a query, a grid or `flush()`
        learns them; looking learns nothing."""
        return sum(self.tile_record(key).n_clusters for key in self.tile_keys)

    @property
    def sensor_path(self) -> np.ndarray:
        """(n, d) float64, metres, world frame: the origin of every scan given, in order."""
        if not self._origins:
            return np.zeros((0, self.dim or 3))
        return np.stack(self._origins)

    def __repr__(self) -> str:
        where = f", directory={str(self.directory)!r}" if self._store is not None else ""
        return (
            f"TiledMap(dim={self.dim}, tiles={self.n_tiles}, scans={self.n_scans_}, "
            f"tile_size={self.tile_size:g}, overlap={self.overlap:g}{where})"
        )

    def tile_config(self, key: TileKey) -> MapConfig:
        """The settings of tile `key`: the map's, learning inside the tile's learn box."""
        return self.config.replace(learn_box=tuple(self.tiling.learn_box(key).ravel()))

    def tile(self, key: Iterable[int]) -> HilbertMap:
        """Tile `key`'s map, read from the map directory when first asked for; InputError
        for a tile the map does not have."""
        key = tuple(int(k) for k in key)
        if key in self._loaded:
            self._loaded.move_to_end(key)
            return self._loaded[key]
        if key not in self._records or self._store is None:
            raise InputError(f"the map has no tile {key}")
        data = self._store.read_tile(key)
        tile_map = HilbertMap.from_state(map_state_of_bytes(data, self._store.tile_path(key)))
        self._keep(key, tile_map)
        return tile_map

    def tile_record(self, key: TileKey) -> TileRecord:
        """What is known of tile `key` without reading it: from the index, or from the tile
        in memory where it learned since."""
        if key in self._changed:
            old = self._records.get(key)
            return TileRecord.of_map(self._loaded[key], old.version if old else 0, 0)
        return self._records[key]

    def _keep(self, key: TileKey, tile_map: HilbertMap) -> None:
        """Hold a tile in memory, dropping the least recently used saved ones over the cap."""
        self._loaded[key] = tile_map
        self._loaded.move_to_end(key)
        while len(self._loaded) > self.max_loaded_tiles:
            saved = next((k for k in self._loaded if k not in self._changed), None)
            if saved is None:
                break
            del self._loaded[saved]

    def memory_bytes(self) -> int:
        """Bytes of the tiles in memory now (HilbertMap.memory_bytes) and the sensor path."""
        tiles = sum(tile_map.memory_bytes() for tile_map in self._loaded.values())
        return tiles + sum(origin.nbytes for origin in self._origins)

    def extent(self) -> np.ndarray:
        """(2, d) metres: the box holding every tile's kernels (within its learn box);
        EmptyMapError for a map without clusters."""
        self.flush()
        boxes = [np.asarray(self.tile_record(k).extent) for k in self.tile_keys]
        boxes = [box for box in boxes if box.size]
        if not boxes:
            raise EmptyMapError("the map is empty: it has no clusters")
        return np.stack(
            [np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)]
        )

    # --------------------------------------------------------------- learning
    def integrate(
        self,
        points_world: np.ndarray,
        origin: np.ndarray,
        hit_mask: np.ndarray | None = None,
        time: float | None = None,
    ) -> TiledMap:
        """Learn one scan in this process, into the tiles its rays cross; returns self.
        points_world: (N, d) float, metres, world frame; origin: (d,) metres; hit_mask: (N,)
        bool, False for rays without return (None: all returned); time: seconds, when it was
        taken. `build` learns many scans on a cluster."""
        return self.integrate_scan(Scan(points_world, origin, hit_mask, time))

    def integrate_scan(self, scan: Scan) -> TiledMap:
        """Learn one Scan in this process, into the tiles its rays cross; returns self."""
        # Checked before any tile learns, so a bad scan leaves every tile as it was.
        check_scan(scan, "scan", self._dim, "the map", self.config.forget_after)
        self._take_dim(scan.dim)
        keys = self.tiling.keys_meeting(scan_box(scan))
        self._changed.update(learn_into_tiles(scan, self.tiling, keys, self._learning_tile))
        self._origins.append(scan.origin)
        self.n_scans_ += 1
        return self

    def flush(self) -> TiledMap:
        """Learn the scans waiting for their batch in the tiles in memory; returns self."""
        for key in self._changed:
            self._loaded[key].flush()
        return self

    def build(
        self,
        scans: ScanSource | Iterable[Scan],
        client: Any = None,
        workers: int | None = None,
        directory: str | PathLike[str] | None = None,
        observer: BuildObserver | None = None,
        block: int = 2,
    ) -> BuildReport:
        """Learn `scans` on Dask (ehm.tiles.build): a task per block of tiles, tiles the
        scans do not cross left as they are; returns what was done. Needs dask.distributed
        (pip install 'ehm[tiles]').

        scans: a ScanSource (ScanFiles, CityDrive: read by the workers) or scans in memory.
        client: a dask.distributed Client, or a scheduler's address ('tcp://host:8786'),
        whose workers can read the scans; None: a LocalCluster of `workers` processes (None:
        this machine's cores), one thread each, closed after. directory: the map directory
        to write tiles into as they come, index last (see save); None: the map's own, or
        memory for a map without one. observer: told of each binned chunk and learned tile.
        block: each task learns a block of up to block^d neighbouring tiles, reading each
        scan that crosses them once (1: a task per tile; larger blocks read less, in fewer
        tasks).
        """
        source = scan_source(scans)
        if not (isinstance(block, int) and block >= 1):
            raise InputError(f"block must be an integer >= 1, got {block!r}")
        observer = observer if observer is not None else NoObserver()
        report = BuildReport()
        with dask_client(client, workers) as on:
            if directory is not None:
                self._write_into(directory)
            report.workers = len(on.scheduler_info()["workers"])
            shared = on.scatter(source, broadcast=True, hash=False)
            start = time.perf_counter()
            bins = binned_scans(on, shared, source, self.tiling, observer)
            report.binning_seconds = time.perf_counter() - start
            if not bins:
                raise InputError("no scans to build the map from")
            for scan_bins in bins:
                self._take_dim(scan_bins.dim)
            report.n_scans = len(bins)
            report.n_rays = sum(scan_bins.n_rays for scan_bins in bins)
            start = time.perf_counter()
            tiles = scans_per_tile(bins)
            blocks = tile_blocks({key: rays for key, (_, rays) in tiles.items()}, block)
            tasks = [
                ([self._job(key, tiles[key][0]) for key in keys], cost) for keys, cost in blocks
            ]
            observer.learning(0, len(tiles), None)
            done, indexed = 0, time.perf_counter()
            for task in learned_tasks(on, shared, tasks, self.tiling):
                for tile in task.tiles:
                    self._learned_tile(tile.key, tile.data, tile.record)
                    done += 1
                    observer.learning(done, len(tiles), replace(tile, data=b""))
                report.tasks.append(replace(task, tiles=[replace(t, data=b"") for t in task.tiles]))
                if self._store is not None and time.perf_counter() - indexed > INDEX_EVERY_SECONDS:
                    # An interrupted build leaves an index that matches the tile files.
                    self._store.write_index(self._index(self._records))
                    indexed = time.perf_counter()
            report.learning_seconds = time.perf_counter() - start
        self._origins += [scan_bins.origin for scan_bins in bins]
        self.n_scans_ += len(bins)
        if self._store is not None:
            self._store.write_index(self._index(self._records))
            self._store.remove_tiles_except(set(self._records) | self._changed)
        return report

    def _job(self, key: TileKey, indices: list[int]) -> TileJob:
        """What a task needs to learn the scans at `indices` into tile `key`."""
        old = self._records.get(key)
        version = (old.version if old else 0) + 1
        return TileJob(key, indices, self.tile_config(key), self._tile_bytes(key), version)

    def _write_into(self, directory: str | PathLike[str]) -> None:
        """Make `directory` the map's directory, its tiles so far saved there first."""
        if self._store is not None or self.tile_keys:
            self.save(directory)
            return
        store = TileStore(directory)
        store.prepare()
        self._store = store

    def _take_dim(self, dim: int) -> None:
        if self._dim is None:
            self._dim = dim
        elif dim != self._dim:
            raise InputError(f"scan points are {dim}D, the map is {self._dim}D")

    def _learning_tile(self, key: TileKey) -> HilbertMap:
        """Tile `key` to learn into: its map, or a new one."""
        if key in self._loaded or key in self._records:
            return self.tile(key)
        tile_map = HilbertMap(self.tile_config(key))
        self._changed.add(key)
        self._keep(key, tile_map)
        return tile_map

    def _learned_tile(self, key: TileKey, data: bytes, record: TileRecord) -> None:
        """Take a tile learned elsewhere (a build's task): into the map directory, or into
        memory for a map without one."""
        if self._store is not None:
            self._store.write_tile(key, data)
            self._records[key] = record
            self._loaded.pop(key, None)
            self._changed.discard(key)
            return
        tile_map = HilbertMap.from_state(map_state_of_bytes(data, f"tile {key}"))
        self._changed.add(key)
        self._keep(key, tile_map)

    def _tile_bytes(self, key: TileKey) -> bytes | None:
        """Tile `key` as the bytes of its file, to learn on elsewhere (None: no such tile)."""
        if key in self._changed:
            return map_bytes(self._loaded[key].state())
        if key in self._records and self._store is not None:
            return self._store.read_tile(key)
        return None

    # ---------------------------------------------------------------- queries
    def _log_odds(
        self, points: np.ndarray, mode: str, with_variance: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """The tiles' log-odds (and variance) weighted by their blending weights."""
        rows, keys, weights = self.tiling.blend(points)
        finite = np.all(np.isfinite(points), axis=1)
        log_odds = np.where(finite, 0.0, np.nan)
        variance = np.where(finite, 0.0, np.nan) if with_variance else np.zeros(0)
        for key, entries in _by_tile(np.arange(len(rows)), keys):
            tile_map = self._answering(key)
            chosen, weight = rows[entries], weights[entries]
            if tile_map is None:  # nothing learned here: log-odds 0, the prior's variance
                if with_variance:
                    variance[chosen] += weight / self.config.prior_precision
                continue
            found = tile_map.decision_function(points[chosen], mode, with_variance)
            if with_variance:
                log_odds[chosen] += weight * found[0]
                variance[chosen] += weight * found[1]
            else:
                log_odds[chosen] += weight * found
        return log_odds, variance

    def _gradient(self, points: np.ndarray, mode: str) -> np.ndarray:
        """The tiles' gradients blended as the log-odds are, plus each tile's log-odds times
        the gradient of its weight."""
        rows, keys, weights = self.tiling.blend(points)
        finite = np.all(np.isfinite(points), axis=1)
        out = np.where(finite[:, None], np.zeros(points.shape), np.nan)
        for key, entries in _by_tile(np.arange(len(rows)), keys):
            tile_map = self._answering(key)
            if tile_map is None:  # log-odds 0 everywhere: nothing to add
                continue
            chosen = rows[entries]
            at = points[chosen]
            slope = self.tiling.weight_gradients(at, key)
            out[chosen] += weights[entries, None] * tile_map.gradient(at, mode)
            out[chosen] += tile_map.decision_function(at, mode)[:, None] * slope
        return out

    def _cast(self, rays: RayQuery) -> np.ndarray:
        """Rays march the blended log-odds all the way (a single map's grid and candidate
        cells are not kept across tiles); with stop_at_unknown they stop where no tile knows
        (`known`)."""
        return cast_rays(
            partial(self.decision_function, mode=rays.mode),
            rays.origins,
            rays.directions,
            rays.max_range,
            rays.threshold,
            self.config.cluster_radius,
            known=partial(self._known_at, mode=rays.mode) if rays.stop_at_unknown else None,
        )

    def _known_at(self, points: np.ndarray, mode: str) -> np.ndarray:
        """True where a tile that weighs in the blend at a point knows it."""
        rows, keys, weights = self.tiling.blend(points)
        found = np.zeros(len(points), dtype=bool)
        for key, entries in _by_tile(np.arange(len(rows)), keys):
            tile_map = self._answering(key)
            chosen = rows[entries][weights[entries] > 0]
            if tile_map is not None and len(chosen):
                found[chosen] |= tile_map.known(points[chosen], mode)
        return found

    def _distances(self, points: np.ndarray, query: DistanceQuery) -> tuple[np.ndarray, np.ndarray]:
        """Each tile tells of the obstacles in its core (where it weighs most in the blend)
        within obstacle_box; points in the core of a tile that learned nothing read -reach
        when unknown space is an obstacle there. Each tile keeps its field as it learns."""
        reach = self.config.distance_reach
        distance, gradient = np.full(len(points), reach), np.zeros(points.shape)
        if len(points) == 0:
            return distance, gradient
        box = np.stack([points.min(axis=0) - reach, points.max(axis=0) + reach])
        meeting = set(self.tiling.keys_meeting(box))
        for key in (key for key in self.tile_keys if key in meeting):
            core = _overlap(self.tiling.core_box(key), query.obstacle_box)
            if core is None:  # no obstacle of this tile counts
                continue
            near = np.all((points > core[0] - reach) & (points < core[1] + reach), axis=1)
            near = np.flatnonzero(near)
            tile_map = self._answering(key) if len(near) else None
            if tile_map is None:
                continue
            tile_query = replace(query, with_gradient=True, obstacle_box=core)
            found, slope = tile_map._distances(points[near], tile_query)
            wins = _nearer(found, distance[near])
            distance[near[wins]], gradient[near[wins]] = found[wins], slope[wins]
        if query.unknown_is_occupied:
            keys = np.floor(points / self.tiling.size + 0.5).astype(np.int64)
            for key, entries in _by_tile(np.arange(len(points)), keys):
                if self._answering(key) is None:
                    inside = _inside(points[entries], query.unknown_box)
                    inside &= _inside(points[entries], query.obstacle_box)
                    distance[entries[inside]], gradient[entries[inside]] = -reach, 0.0
        return distance, gradient

    def _answering(self, key: TileKey) -> HilbertMap | None:
        """The map that answers for tile `key`, its waiting scans learned first, or None where
        it learned no cluster."""
        if key not in self._records and key not in self._changed:
            return None
        tile_map = self.tile(key).flush()
        return tile_map if tile_map.n_clusters > 0 else None

    def _query_dim(self, action: str) -> int:
        if self._dim is None or not self.tile_keys:
            raise EmptyMapError(f"the map is empty: integrate or build scans before you {action}")
        return self._dim

    # ------------------------------------------------------------------ grids
    def grid_blocks(
        self,
        bounds: np.ndarray | None = None,
        resolution: float | None = None,
        max_bytes: int = DEFAULT_MAX_BYTES,
        std: bool = False,
    ) -> Iterator[OccupancyGrid]:
        """The grid over `bounds` (None: `extent()`, widened to multiples of the resolution,
        OctoMap's voxels) as HilbertMap.grid_blocks gives it; a tiled map's is one grid,
        refused over `max_bytes`."""
        resolution = self.config.resolution if resolution is None else resolution
        if bounds is None:
            bounds = aligned_bounds(self.extent(), resolution)
        yield self.grid(bounds, resolution, max_bytes=max_bytes, std=std)

    def grid(
        self,
        bounds: np.ndarray | None = None,
        resolution: float | None = None,
        max_bytes: int = DEFAULT_MAX_BYTES,
        std: bool = False,
    ) -> OccupancyGrid:
        """Occupancy grid over `bounds` ((2, d) metres, world frame; None: `extent()`) at
        `resolution` metres (None: the map's own, config.resolution): each tile's grid
        (HilbertMap.grid, Sec. 3.5) over its part, blended as `occupancy` blends; with std,
        also each voxel's standard deviation.
        InputError for grids over `max_bytes`, before allocating. Reads the tiles it needs;
        memory holds the grid and one tile's part of it."""
        dim = self._query_dim("build a grid")
        resolution = self.config.resolution if resolution is None else resolution
        if bounds is None:
            bounds = self.extent()
        origin, shape = grid_shape(bounds, resolution, dim, max_bytes, bytes_per_voxel(std))
        log_odds = np.zeros(shape)
        variance = np.zeros(shape) if std else None
        high = origin + np.array(shape) * resolution
        for key in self.tiling.keys_meeting(np.stack([origin, high])):
            box = self.tiling.learn_box(key)
            first = np.clip(np.floor((box[0] - origin) / resolution), 0, shape).astype(int)
            last = np.clip(np.ceil((box[1] - origin) / resolution), 0, shape).astype(int)
            if np.any(last <= first):
                continue
            part = tuple(slice(a, b) for a, b in zip(first, last, strict=True))
            part_box = np.stack([origin + first * resolution, origin + last * resolution])
            centres = [
                origin[a] + (np.arange(first[a], last[a]) + 0.5) * resolution for a in range(dim)
            ]
            mesh = np.meshgrid(*centres, indexing="ij")
            points = np.column_stack([axis.ravel() for axis in mesh])
            weight = self.tiling.weights(points, key).reshape(last - first)
            tile_map = self._answering(key)
            if tile_map is None:
                if std:
                    variance[part] += weight / self.config.prior_precision
                continue
            tile_grid = tile_map.grid(part_box, resolution, max_bytes=max_bytes, std=std)
            log_odds[part] += weight * tile_grid.log_odds
            if std:
                variance[part] += weight * tile_grid.log_odds_variance
        return OccupancyGrid.of_log_odds(
            origin, resolution, log_odds, variance, self.config.prior_precision
        )

    # ------------------------------------------------------------ persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Write the map as a map directory at `path` (ehm.tiles.store): each tile that
        learned since it was last written (or every tile, to a new directory), atomically,
        then the index. Saving learns nothing: scans waiting in a tile stay waiting."""
        self._query_dim("save it")
        store = TileStore(path)
        same = self._store is not None and _same_folder(self._store.directory, store.directory)
        store.prepare()
        records = {}
        for key in self.tile_keys:
            old = self._records.get(key)
            if key in self._changed:
                data = map_bytes(self._loaded[key].state())
                store.write_tile(key, data)
                records[key] = TileRecord.of_map(
                    self._loaded[key], (old.version if old else 0) + 1, len(data)
                )
            else:
                if not same:
                    store.write_tile(key, self._store.read_tile(key))
                records[key] = old
        store.write_index(self._index(records))
        store.remove_tiles_except(set(records))
        self._store, self._records = store, records
        self._changed.clear()

    def _index(self, records: dict[TileKey, TileRecord]) -> TileIndex:
        return TileIndex(
            self.tile_size,
            self.overlap,
            self._dim,
            self.config.to_dict(),
            self.n_scans_,
            self.sensor_path.tolist(),
            records,
        )

    @classmethod
    def open(cls, path: str | PathLike[str], max_loaded_tiles: int = MAX_LOADED_TILES) -> TiledMap:
        """The tiled map in directory `path`, its tiles read when first needed; TileIndexError
        (a FileReadError) names what is wrong with it."""
        store = TileStore(path)
        index = store.read_index()
        config = MapConfig.from_dict(index.config)
        tiled_map = cls(index.tile_size, index.overlap, config, max_loaded_tiles)
        tiled_map._dim = index.dim
        tiled_map._store, tiled_map._records = store, dict(index.tiles)
        tiled_map.n_scans_ = index.n_scans
        tiled_map._origins = [np.asarray(origin, dtype=np.float64) for origin in index.sensor_path]
        return tiled_map


def _by_tile(values: np.ndarray, keys: np.ndarray) -> Iterator[tuple[TileKey, np.ndarray]]:
    """Each tile key of (m, d) `keys` with the (m,) `values` of its rows."""
    if len(keys) == 0:
        return
    order = np.lexsort(keys.T[::-1])
    starts = np.flatnonzero(np.r_[True, np.any(keys[order][1:] != keys[order][:-1], axis=1)])
    for first, end in zip(starts, np.r_[starts[1:], len(order)], strict=True):
        yield tuple(keys[order[first]].tolist()), values[order[first:end]]


def _overlap(box: np.ndarray, other: np.ndarray | None) -> np.ndarray | None:
    """(2, d) the part of `box` inside `other` ([low, high] corners each; None: everywhere),
    or None where they do not meet."""
    if other is None:
        return box
    part = np.stack([np.maximum(box[0], other[0]), np.minimum(box[1], other[1])])
    return part if np.all(part[0] <= part[1]) else None


def _inside(points: np.ndarray, box: np.ndarray | None) -> np.ndarray:
    """(n,) bool: each of (n, d) points lies in `box` (None: everywhere)."""
    if box is None:
        return np.ones(len(points), dtype=bool)
    return np.all((points >= box[0]) & (points <= box[1]), axis=1)


def _nearer(found: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """(n,) bool: signed distances `found` tell more than `kept`: inside (negative) and deeper,
    or both outside and nearer."""
    return np.where(found < 0.0, found < kept, (kept >= 0.0) & (found < kept))


def _same_folder(a: Path, b: Path) -> bool:
    return a.resolve() == b.resolve()
