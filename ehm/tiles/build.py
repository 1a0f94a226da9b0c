"""Learning a tiled map on Dask (dask.distributed): scans binned into tiles, one task per tile.

    bin scans 0-15  ─┐                               ┌─> learn tile (0, 0, 0) ─> write tile
    bin scans 16-31 ─┼─> client: tile -> scans ──────┼─> learn tile (1, 0, 0) ─> write tile
    ...             ─┘   (and rays, the tile's cost) └─> ...  largest first     ─> index

Workers read the scans themselves (source.read), twice: a binning task reads a chunk and
tells, for each scan, its origin and how many of its rays cross each tile; a tile's task
reads the scans that cross it, one at a time, clips them to the tile and learns them into the
tile's map (MapConfig.learn_box), in scan order. The client holds only the bins and one
learned tile at a time, which it writes to the map directory as it comes (or keeps, for a map
in memory). A worker holds one tile and one scan per task, whatever the scene's size.
"""

from __future__ import annotations

import logging
import os
import resource
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from os import PathLike
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ehm.config import MapConfig
from ehm.errors import InputError
from ehm.hilbert_map import HilbertMap
from ehm.io.map_file import map_bytes, map_state_of_bytes
from ehm.tiles.sources import ScanSource, scan_source
from ehm.tiles.store import TileKey, TileRecord, TileStore
from ehm.tiles.tiled_map import tile_record
from ehm.tiles.tiling import Tiling, scan_box

if TYPE_CHECKING:
    from ehm.core.scan import Scan
    from ehm.tiles.tiled_map import TiledMap

# Scans each binning task reads.
BIN_CHUNK = 16
INSTALL_HINT = "building a tiled map needs dask.distributed: pip install 'ehm[tiles]'"


@dataclass(frozen=True)
class ScanBins:
    """One scan as binning found it: its index, dim, origin ((d,) metres), its rays, and
    how many of them cross each tile's learn box."""

    index: int
    dim: int
    origin: np.ndarray
    n_rays: int
    rays: dict[TileKey, int]


@dataclass(frozen=True)
class TileResult:
    """A tile as its task learned it: key, data (its map file's bytes), record, the seconds
    spent learning it (clipping scans, learning, writing its bytes) and the rays learned."""

    key: TileKey
    data: bytes
    record: TileRecord
    seconds: float
    n_rays: int


@dataclass(frozen=True)
class TaskResult:
    """What one task did: its tiles; wall-clock seconds in all and reading scans; scans
    read; the worker process's id and its peak resident memory so far, bytes."""

    tiles: list[TileResult]
    seconds: float
    read_seconds: float
    n_scans_read: int
    worker_pid: int
    worker_peak_bytes: int


@dataclass
class BuildReport:
    """What a build did: scans and rays binned; workers; seconds binning and learning (wall
    clock); and each task's TaskResult (its tiles without their data)."""

    n_scans: int = 0
    n_rays: int = 0
    workers: int = 0
    binning_seconds: float = 0.0
    learning_seconds: float = 0.0
    tasks: list[TaskResult] = field(default_factory=list)

    @property
    def seconds(self) -> float:
        return self.binning_seconds + self.learning_seconds

    @property
    def tiles(self) -> list[TileResult]:
        return [tile for task in self.tasks for tile in task.tiles]


class BuildObserver(Protocol):
    """Told how a build goes, as it goes."""

    def binning(self, done: int, total: int | None) -> None:
        """`done` scans of `total` (None: unknown until read) are binned."""

    def learning(self, done: int, total: int, result: TileResult | None) -> None:
        """`done` tiles of `total` are learned; `result`: the one just learned (None at the
        start)."""


def bin_scans(source: ScanSource, indices: Iterable[int] | None, tiling: Tiling) -> list[ScanBins]:
    """The bins of the scans of `source` at `indices` (None: all): a task of its own."""
    bins = []
    for index, scan in source.read(indices):
        rays = {}
        for key in tiling.keys_meeting(scan_box(scan)):
            part = tiling.clip(scan, key)
            if part is not None:
                rays[key] = len(part)
        bins.append(ScanBins(index, scan.dim, scan.origin, len(scan), rays))
    return bins


@dataclass(frozen=True)
class TileJob:
    """One tile for a task to learn: its key, the scans that cross it (ascending indices),
    its settings, the bytes of its map so far (None: a new tile) and the version to write."""

    key: TileKey
    indices: list[int]
    config: MapConfig
    data: bytes | None
    version: int


def learn_tiles(source: ScanSource, jobs: list[TileJob], tiling: Tiling) -> TaskResult:
    """Learn a block of neighbouring tiles, a task of its own: each scan that crosses any of
    them is read once, in order, clipped to each tile it crosses and learned into that tile's
    map."""
    start = time.perf_counter()
    maps = [
        HilbertMap(job.config)
        if job.data is None
        else HilbertMap.from_state(map_state_of_bytes(job.data, f"tile {job.key}"))
        for job in jobs
    ]
    wanted = [set(job.indices) for job in jobs]
    seconds, rays = [0.0] * len(jobs), [0] * len(jobs)
    n_scans, read_seconds = 0, 0.0
    scans = source.read(sorted(set().union(*wanted)))
    while True:
        read_start = time.perf_counter()
        index, scan = next(scans, (None, None))
        read_seconds += time.perf_counter() - read_start
        if scan is None:
            break
        n_scans += 1
        for t, job in enumerate(jobs):
            if index in wanted[t]:
                tile_start = time.perf_counter()
                part = tiling.clip(scan, job.key)
                if part is not None:
                    maps[t].integrate_scan(part)
                    rays[t] += len(part)
                seconds[t] += time.perf_counter() - tile_start
    tiles = []
    for t, job in enumerate(jobs):
        tile_start = time.perf_counter()
        maps[t].flush()
        data = map_bytes(maps[t].state())
        record = tile_record(maps[t], job.version, len(data))
        seconds[t] += time.perf_counter() - tile_start
        tiles.append(TileResult(job.key, data, record, seconds[t], rays[t]))
        maps[t] = None  # each tile's memory goes once it is written
    return TaskResult(
        tiles,
        time.perf_counter() - start,
        read_seconds,
        n_scans,
        os.getpid(),
        peak_resident_bytes(),
    )


def peak_resident_bytes() -> int:
    """The peak resident memory of this process so far, bytes (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def build_tiles(
    tiled_map: TiledMap,
    scans: ScanSource | Iterable[Scan],
    client: Any = None,
    workers: int | None = None,
    directory: str | PathLike[str] | None = None,
    observer: BuildObserver | None = None,
    block: int = 2,
) -> BuildReport:
    """Learn `scans` into `tiled_map` on Dask; returns what was done.

    scans: a ScanSource (ScanFiles, CityDrive: read by the workers) or scans in memory.
    client: a dask.distributed Client, or a scheduler's address ('tcp://host:8786'), whose
    workers must be able to read the scans; None: a LocalCluster of `workers` processes
    (None: this machine's cores), one thread each, closed after. directory: the map
    directory to write tiles into as they come (see TiledMap.save); None: the map's own, or
    memory for a map without one. observer: told of each binned chunk and learned tile.
    block: each task learns a block of up to block^d neighbouring tiles, reading each scan
    that crosses them once (1: a task per tile; larger blocks read less, in fewer tasks).
    """
    try:
        from dask.distributed import as_completed
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    source = scan_source(scans)
    if not (isinstance(block, int) and block >= 1):
        raise InputError(f"block must be an integer >= 1, got {block!r}")
    if directory is not None:
        _write_into(tiled_map, directory)
    report = BuildReport()
    with _dask_client(client, workers) as dask_client:
        report.workers = len(dask_client.scheduler_info()["workers"])
        shared = dask_client.scatter(source, broadcast=True, hash=False)
        start = time.perf_counter()
        bins = _binned(dask_client, shared, source, tiled_map.tiling, observer, as_completed)
        report.binning_seconds = time.perf_counter() - start
        if not bins:
            raise InputError("no scans to build the map from")
        for scan_bins in bins:
            tiled_map._take_dim(scan_bins.dim)
        report.n_scans = len(bins)
        report.n_rays = sum(scan_bins.n_rays for scan_bins in bins)
        start = time.perf_counter()
        blocks = _blocks(tiled_map, _scans_per_tile(bins), block)
        futures = [
            dask_client.submit(
                learn_tiles, shared, jobs, tiled_map.tiling, priority=rays, pure=False
            )
            for jobs, rays in blocks
        ]
        n_tiles, done = sum(len(jobs) for jobs, _ in blocks), 0
        if observer is not None:
            observer.learning(0, n_tiles, None)
        for future in as_completed(futures):
            task = future.result()
            future.release()
            for tile in task.tiles:
                tiled_map._learned_tile(tile.key, tile.data, tile.record)
            task = replace(task, tiles=[replace(tile, data=b"") for tile in task.tiles])
            report.tasks.append(task)
            for tile in task.tiles:
                done += 1
                if observer is not None:
                    observer.learning(done, n_tiles, tile)
        report.learning_seconds = time.perf_counter() - start
    tiled_map._origins += [scan_bins.origin for scan_bins in bins]
    tiled_map.n_scans_ += len(bins)
    if tiled_map._store is not None:
        tiled_map._store.write_index(tiled_map._index(tiled_map._records))
    return report


def _binned(
    dask_client: Any,
    shared: Any,
    source: ScanSource,
    tiling: Tiling,
    observer: BuildObserver | None,
    as_completed: Any,
) -> list[ScanBins]:
    """Every scan's bins, in scan order: tasks of BIN_CHUNK scans (one task reading all of
    a source that cannot tell its count)."""
    total = source.count()
    chunks: list[range | None] = (
        [None]
        if total is None
        else [range(i, min(i + BIN_CHUNK, total)) for i in range(0, total, BIN_CHUNK)]
    )
    futures = [dask_client.submit(bin_scans, shared, chunk, tiling, pure=False) for chunk in chunks]
    bins: list[ScanBins] = []
    if observer is not None:
        observer.binning(0, total)
    for future in as_completed(futures):
        bins += future.result()
        future.release()
        if observer is not None:
            observer.binning(len(bins), total)
    return sorted(bins, key=lambda scan_bins: scan_bins.index)


def _scans_per_tile(bins: list[ScanBins]) -> dict[TileKey, tuple[list[int], int]]:
    """Per tile crossed: the scans that cross it, in order, and their rays in it."""
    tiles: dict[TileKey, tuple[list[int], int]] = {}
    for scan_bins in bins:
        for key, rays in scan_bins.rays.items():
            indices, total = tiles.get(key, ([], 0))
            indices.append(scan_bins.index)
            tiles[key] = (indices, total + rays)
    return tiles


def _blocks(
    tiled_map: TiledMap, tiles: dict[TileKey, tuple[list[int], int]], block: int
) -> list[tuple[list[TileJob], int]]:
    """The tasks: tiles grouped into blocks of `block` tiles a side, each block's jobs and
    rays, largest first (so the longest tasks start first and none is left to the end)."""
    grouped: dict[TileKey, tuple[list[TileJob], int]] = {}
    for key, (indices, rays) in sorted(tiles.items()):
        old = tiled_map._records.get(key)
        job = TileJob(
            key,
            indices,
            tiled_map.tile_config(key),
            tiled_map._tile_bytes(key),
            (old.version if old else 0) + 1,
        )
        block_key = tuple(k // block for k in key)
        jobs, total = grouped.get(block_key, ([], 0))
        grouped[block_key] = ([*jobs, job], total + rays)
    return sorted(grouped.values(), key=lambda item: -item[1])


def _write_into(tiled_map: TiledMap, directory: str | PathLike[str]) -> None:
    """Make `directory` the map's directory: its tiles so far are saved there first."""
    if tiled_map.directory is not None or tiled_map.tile_keys:
        tiled_map.save(directory)
        return
    store = TileStore(directory)
    store.prepare()
    tiled_map._store = store


@contextmanager
def _dask_client(client: Any, workers: int | None) -> Iterator[Any]:
    """The client to run on: `client`, one connected to the address `client`, or one of a
    LocalCluster of `workers` single-threaded processes, closed on leaving."""
    from dask.distributed import Client, LocalCluster

    if client is not None and not isinstance(client, str):
        yield client
        return
    if isinstance(client, str):
        with Client(client) as connected:
            yield connected
        return
    n_workers = workers if workers is not None else os.cpu_count() or 1
    if not (isinstance(n_workers, int) and n_workers >= 1):
        raise InputError(f"workers must be an integer >= 1, got {workers!r}")
    with (
        LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as local,
    ):
        yield local
