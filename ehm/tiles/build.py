"""Learning a tiled map on Dask (dask.distributed): scans binned into tiles, then one task
per block of neighbouring tiles. TiledMap.build runs these steps.

    bin scans 0-15  ─┐                               ┌─> learn block A's tiles ─> write them
    bin scans 16-31 ─┼─> client: tile -> scans ──────┼─> learn block B's tiles ─> write them
    ...             ─┘   (and rays, the tile's cost) └─> ...  largest first     ─> index

Workers read the scans themselves (source.read), twice: a binning task reads a chunk and
tells, for each scan, its origin and how many of its rays cross each tile; a block's task
reads the scans that cross its tiles, each once, in order, and learns the part of each that
crosses a tile into that tile's map (MapConfig.learn_box). The client holds only the bins and
one task's learned tiles at a time, which it writes to the map directory as they come (or
keeps, for a map in memory). A worker holds one block of tiles and one scan per task,
whatever the scene's size.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import resource
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.errors import InputError
from ehm.hilbert_map import HilbertMap
from ehm.io.map_file import map_bytes, map_state_of_bytes
from ehm.tiles.sources import ScanSource
from ehm.tiles.store import TileKey, TileRecord
from ehm.tiles.tiling import Tiling, scan_box

if TYPE_CHECKING:
    from ehm.core.sensor.scan import Scan

# Scans each binning task reads.
BIN_CHUNK = 16
INSTALL_HINT = "building a tiled map needs dask.distributed: pip install 'ehm[tiles]'"
MAIN_GUARD_HINT = (
    "Dask starts its worker processes by spawning them, and each imports the script that "
    'started the build: put the script\'s code under `if __name__ == "__main__":`'
)


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
    """A tile as its task learned it: key, data (its map file's bytes), record, and the
    rays it learned."""

    key: TileKey
    data: bytes
    record: TileRecord
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
    one_core_per_task()
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
    them is read once, in order, and its rays that cross each tile learned into its map."""
    one_core_per_task()
    start = time.perf_counter()
    maps = {
        job.key: HilbertMap(job.config)
        if job.data is None
        else HilbertMap.from_state(map_state_of_bytes(job.data, f"tile {job.key}"))
        for job in jobs
    }
    wanting: dict[int, list[TileKey]] = {}
    for job in jobs:
        for index in job.indices:
            wanting.setdefault(index, []).append(job.key)
    rays = dict.fromkeys(maps, 0)
    n_scans, read_seconds = 0, 0.0
    scans = source.read(sorted(wanting))
    while True:
        read_start = time.perf_counter()
        index, scan = next(scans, (None, None))
        read_seconds += time.perf_counter() - read_start
        if scan is None:
            break
        n_scans += 1
        for key, n_rays in learn_into_tiles(scan, tiling, wanting[index], maps.__getitem__).items():
            rays[key] += n_rays
    tiles = []
    for job in jobs:
        tile_map = maps.pop(job.key)  # each tile's memory goes once it is written
        tile_map.flush()
        data = map_bytes(tile_map.state())
        record = TileRecord.of_map(tile_map, job.version, len(data))
        tiles.append(TileResult(job.key, data, record, rays[job.key]))
    return TaskResult(
        tiles,
        time.perf_counter() - start,
        read_seconds,
        n_scans,
        os.getpid(),
        peak_resident_bytes(),
    )


def learn_into_tiles(
    scan: Scan,
    tiling: Tiling,
    keys: Iterable[TileKey],
    tile_of: Callable[[TileKey], HilbertMap],
) -> dict[TileKey, int]:
    """Learn the rays of `scan` that cross each tile of `keys` into its map, `tile_of(key)`
    (asked for only for tiles the scan crosses); returns the rays learned per tile crossed."""
    learned = {}
    for key in keys:
        part = tiling.clip(scan, key)
        if part is not None:
            tile_of(key).integrate_scan(part)
            learned[key] = len(part)
    return learned


def one_core_per_task() -> None:
    """Run this thread's parallel kernels on one core: a cluster gives each task one, and
    tasks that each spread over all cores would only contend."""
    numba.set_num_threads(1)


def peak_resident_bytes() -> int:
    """The peak resident memory of this process's program so far, bytes: Linux's VmHWM, which
    starts afresh when a process starts a program (ru_maxrss carries the peak of the process
    that started it over); elsewhere ru_maxrss."""
    try:
        status = Path("/proc/self/status").read_text()
    except OSError:
        status = ""
    for line in status.splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024  # kB
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def binned_scans(
    client: Any, shared: Any, source: ScanSource, tiling: Tiling, observer: BuildObserver
) -> list[ScanBins]:
    """Every scan's bins, in scan order, from tasks of BIN_CHUNK scans (one task reading all
    of a source that cannot tell its count). shared: the source, scattered to the workers."""
    from dask.distributed import as_completed

    total = source.count()
    chunks: list[range | None] = (
        [None]
        if total is None
        else [range(i, min(i + BIN_CHUNK, total)) for i in range(0, total, BIN_CHUNK)]
    )
    futures = [client.submit(bin_scans, shared, chunk, tiling, pure=False) for chunk in chunks]
    bins: list[ScanBins] = []
    observer.binning(0, total)
    for future in as_completed(futures):
        bins += future.result()
        future.release()
        observer.binning(len(bins), total)
    return sorted(bins, key=lambda scan_bins: scan_bins.index)


def scans_per_tile(bins: list[ScanBins]) -> dict[TileKey, tuple[list[int], int]]:
    """Per tile crossed: the scans that cross it, in order, and their rays in it."""
    tiles: dict[TileKey, tuple[list[int], int]] = {}
    for scan_bins in bins:
        for key, rays in scan_bins.rays.items():
            indices, total = tiles.get(key, ([], 0))
            indices.append(scan_bins.index)
            tiles[key] = (indices, total + rays)
    return tiles


def tile_blocks(rays: dict[TileKey, int], block: int) -> list[tuple[list[TileKey], int]]:
    """The tasks: tiles grouped into blocks of `block` tiles a side, with each block's rays
    (its cost), largest first, so the longest tasks start first and none is left to the end."""
    grouped: dict[TileKey, tuple[list[TileKey], int]] = {}
    for key in sorted(rays):
        block_key = tuple(k // block for k in key)
        keys, total = grouped.get(block_key, ([], 0))
        grouped[block_key] = ([*keys, key], total + rays[key])
    return sorted(grouped.values(), key=lambda item: -item[1])


def learned_tasks(
    client: Any, shared: Any, tasks: list[tuple[list[TileJob], int]], tiling: Tiling
) -> Iterator[TaskResult]:
    """Submit each task's jobs (with its cost as priority) and yield each task's result as it
    comes, its futures released."""
    from dask.distributed import as_completed

    futures = [
        client.submit(learn_tiles, shared, jobs, tiling, priority=cost, pure=False)
        for jobs, cost in tasks
    ]
    for future in as_completed(futures):
        task = future.result()
        future.release()
        yield task


class NoObserver:
    """A BuildObserver told nothing."""

    def binning(self, done: int, total: int | None) -> None:
        pass

    def learning(self, done: int, total: int, result: TileResult | None) -> None:
        pass


@contextmanager
def dask_client(client: Any, workers: int | None) -> Iterator[Any]:
    """The client to run on: `client`, one connected to the address `client` ('tcp://host:
    8786'), or one of a LocalCluster of `workers` single-threaded processes (None: this
    machine's cores), closed on leaving. ImportError without dask.distributed."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error

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
    if _importing_main_in_child():
        raise InputError(
            f"a tiled build started while a worker process imported the script. {MAIN_GUARD_HINT}"
        )
    try:
        cluster = LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # any free port: clusters side by side never clash
            silence_logs=logging.ERROR,
        )
    except RuntimeError as error:
        if not _main_script_unguarded():
            raise
        raise InputError(f"Dask's workers failed to start ({error}). {MAIN_GUARD_HINT}") from error
    with cluster, Client(cluster) as local:
        yield local


def _main_script_unguarded() -> bool:
    """The program runs a script whose text has no `if __name__ == "__main__":` guard."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    try:
        text = Path(path).read_text(errors="replace") if path else "__main__"
    except OSError:
        return False
    return "__main__" not in text


def _importing_main_in_child() -> bool:
    """True in a spawned process that is still importing the parent's main script: starting
    a cluster there would start processes while Python bootstraps this one, which it refuses
    (multiprocessing.spawn checks the same flag)."""
    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))
