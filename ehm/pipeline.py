"""The one scan loop: read scans, learn each one (or all at once), add up the time of every
stage, and tell observers how it goes. The command line, the demo, the evaluation and the
benchmarks all map through it.

    run = MappingPipeline(read_scans("scans/"), HilbertMap()).run()
    run.hilbert_map.save("map.ehm")
    run.stage_seconds, run.scan_seconds, run.n_rays

Scans may come from any iterable, read lazily: the time spent waiting for the next scan is
the stage 'read'. Observers (a progress bar, a viewer) see each scan; the loop never asks
whether any are there.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from operator import length_hint
from typing import Protocol

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError
from ehm.hilbert_map import HilbertMap

log = logging.getLogger(__name__)


@dataclass
class MappingRun:
    """What a pipeline run did. hilbert_map: the map it learned. n_scans, n_rays: scans and
    rays learned; n_dropped: non-finite points the scans dropped. stage_seconds: wall-clock
    seconds per stage ('read', then the map's stages, Table 2), summed over every update.
    scan_seconds: wall-clock seconds of each integrate (incremental), or of the one fit.
    batch_scans: how many scans each batch the map learned held, in order (incremental; see
    MapConfig.batch_rays)."""

    hilbert_map: HilbertMap
    n_scans: int = 0
    n_rays: int = 0
    n_dropped: int = 0
    stage_seconds: dict[str, float] = field(default_factory=dict)
    scan_seconds: list[float] = field(default_factory=list)
    batch_scans: list[int] = field(default_factory=list)

    @property
    def seconds(self) -> float:
        """Wall-clock seconds of reading and learning."""
        return self.stage_seconds.get("read", 0.0) + sum(self.scan_seconds)

    def amortized_scan_seconds(self) -> np.ndarray:
        """(n_scans,) seconds per scan with each batch's time shared equally by its scans
        (incremental runs): what a scan costs, whether it waited or closed its batch."""
        seconds = np.asarray(self.scan_seconds)
        ends = np.cumsum(self.batch_scans)
        per_batch = np.add.reduceat(seconds, ends - np.asarray(self.batch_scans))
        return np.repeat(per_batch / np.asarray(self.batch_scans), self.batch_scans)

    def add_stages(self, seconds: dict[str, float]) -> None:
        """Add seconds per stage to the totals."""
        for stage, value in seconds.items():
            self.stage_seconds[stage] = self.stage_seconds.get(stage, 0.0) + value


class MappingObserver(Protocol):
    """Told what a pipeline does, as it does it."""

    def started(self, total: int | None) -> None:
        """Mapping begins; `total` scans will come (None: unknown)."""

    def scan_read(self, index: int, scan: Scan) -> None:
        """Scan `index` (0-based) was read."""

    def scan_learned(self, index: int, scan: Scan, hilbert_map: HilbertMap) -> None:
        """Scan `index` is in the map (incremental mode; it may wait for its batch of
        `config.batch_rays` rays, which the map learns before it answers anything; in
        single-batch mode all are learned at the end, and only `finished` follows)."""

    def finished(self, run: MappingRun) -> None:
        """Mapping is over: done, or stopped by an error."""


class NullObserver:
    """An observer that does nothing."""

    def started(self, total: int | None) -> None:
        pass

    def scan_read(self, index: int, scan: Scan) -> None:
        pass

    def scan_learned(self, index: int, scan: Scan, hilbert_map: HilbertMap) -> None:
        pass

    def finished(self, run: MappingRun) -> None:
        pass


class MappingPipeline:
    """Learn `scans` into `hilbert_map` (a new HilbertMap() when None): one integrate per
    scan, in order, or with `batch` all of them in one fit (single-batch mode, Table 5).
    `observers` see each scan, and are told `total` scans will come (None: as many as
    operator.length_hint(scans) tells, if it does)."""

    def __init__(
        self,
        scans: Iterable[Scan],
        hilbert_map: HilbertMap | None = None,
        batch: bool = False,
        observers: Sequence[MappingObserver] = (),
        total: int | None = None,
    ) -> None:
        if total is None:
            total = length_hint(scans, -1)
        self.total = None if total < 0 else total
        self.scans = scans
        self.hilbert_map = hilbert_map if hilbert_map is not None else HilbertMap()
        self.batch = batch
        self.observers = list(observers) or [NullObserver()]

    def run(self) -> MappingRun:
        """Map every scan; returns what was done."""
        run = MappingRun(self.hilbert_map)
        for observer in self.observers:
            observer.started(self.total)
        try:
            if self.batch:
                scans = list(self._read(run))
                start = time.perf_counter()
                self.hilbert_map.fit(scans)
                self._learned(run, start)
                log.info("learned %d scans in one batch in %.2f s", len(scans), run.seconds)
            else:
                in_batch = 0
                for index, scan in enumerate(self._read(run)):
                    start = time.perf_counter()
                    self.hilbert_map.integrate_scan(scan)
                    self._learned(run, start)
                    in_batch += 1
                    self._log_scan(index, scan, run.scan_seconds[-1])
                    for observer in self.observers:
                        observer.scan_learned(index, scan, self.hilbert_map)
                    if self.hilbert_map.n_waiting_scans == 0:  # learned, or an observer asked
                        run.batch_scans.append(in_batch)
                        in_batch = 0
                if self.hilbert_map.n_waiting_scans:
                    # The last scans' batch is learned now, and counted with the last scan.
                    start = time.perf_counter()
                    self.hilbert_map.flush()
                    run.scan_seconds[-1] += time.perf_counter() - start
                    run.add_stages(self.hilbert_map.timings_)
                    run.batch_scans.append(in_batch)
        finally:
            for observer in self.observers:
                observer.finished(run)
        log.info(
            "mapped %d scans, %d rays in %.1f s: %d clusters, %.2f MB", run.n_scans, run.n_rays,
            run.seconds, self.hilbert_map.n_clusters, self.hilbert_map.memory_bytes() / 1e6,
        )  # fmt: skip
        return run

    def _read(self, run: MappingRun) -> Iterator[Scan]:
        """The scans, counted and passed to observers, with the wait for each timed as 'read'."""
        scans = iter(self.scans)
        index = 0
        while True:
            start = time.perf_counter()
            scan = next(scans, None)
            run.add_stages({"read": time.perf_counter() - start})
            if scan is None:
                return
            if not isinstance(scan, Scan):
                raise InputError(f"scan {index}: expected ehm.Scan, got {type(scan).__name__}")
            run.n_scans += 1
            run.n_rays += len(scan)
            run.n_dropped += scan.n_dropped
            for observer in self.observers:
                observer.scan_read(index, scan)
            yield scan
            index += 1

    def _log_scan(self, index: int, scan: Scan, seconds: float) -> None:
        """Log the scan just integrated, without learning scans that wait for their batch."""
        if not log.isEnabledFor(logging.INFO):
            return
        clusters = self.hilbert_map.clusters_
        waits = self.hilbert_map.n_waiting_scans
        log.info(
            "scan %d: %d rays in %.3f s; %d clusters%s", index, len(scan), seconds,
            0 if clusters is None else len(clusters), f"; {waits} scans wait for their batch"
            if waits else "",
        )  # fmt: skip

    def _learned(self, run: MappingRun, start: float) -> None:
        """Record an update that began at perf_counter() `start`."""
        run.scan_seconds.append(time.perf_counter() - start)
        run.add_stages(self.hilbert_map.timings_)


def rate_progress(console=None):
    """A Rich Progress whose tasks show a description, a bar, done of total, a `rate` field,
    the time elapsed and, where the total is known, the time left (the progress bars of
    mapping and of tiled builds)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        "{task.fields[rate]}",
        TimeElapsedColumn(),
        "left",
        TimeRemainingColumn(),
        console=console,
    )


class ProgressBar(NullObserver):
    """A Rich progress bar over the scans: scans learned, how many a second are read and how
    many learned (each rate over the time spent on it alone), and the time elapsed."""

    def __init__(self, console=None, description: str = "mapping") -> None:
        self._progress = rate_progress(console)
        self._description = description
        self._task = None
        self._last = 0.0
        self._reading = self._learning = 0.0

    def started(self, total: int | None) -> None:
        self._last = time.perf_counter()
        self._task = self._progress.add_task(self._description, total=total, rate="")
        self._progress.start()

    def scan_read(self, index: int, scan: Scan) -> None:
        now = time.perf_counter()
        self._reading += now - self._last
        self._last = now

    def scan_learned(self, index: int, scan: Scan, hilbert_map: HilbertMap) -> None:
        now = time.perf_counter()
        self._learning += now - self._last
        self._last = now
        read = (index + 1) / max(self._reading, 1e-9)
        learned = (index + 1) / max(self._learning, 1e-9)
        rate = f"read {read:.1f}, learn {learned:.1f} scans/s"
        self._progress.update(self._task, completed=index + 1, rate=rate)

    def finished(self, run: MappingRun) -> None:
        self._progress.update(self._task, total=run.n_scans, completed=run.n_scans)
        self._progress.stop()
