"""A progress bar for tiled builds: scans binned, then tiles learned, with their rates."""

from __future__ import annotations

import time
from typing import Any

from ehm.pipeline import rate_progress
from ehm.tiles.build import TileResult


class TileProgressBar:
    """Rich progress bars of a build (a BuildObserver): scans binned, then tiles learned,
    each with its rate and the time elapsed."""

    def __init__(self, console: Any = None) -> None:
        self._progress = rate_progress(console)
        self._tasks: dict[str, Any] = {}
        self._started: dict[str, float] = {}

    def binning(self, done: int, total: int | None) -> None:
        self._advance("binning scans", "scans", done, total)

    def learning(self, done: int, total: int, result: TileResult | None) -> None:
        self._advance("learning tiles", "tiles", done, total)

    def __enter__(self) -> TileProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.stop()

    def _advance(self, stage: str, unit: str, done: int, total: int | None) -> None:
        if stage not in self._tasks:
            self._progress.start()
            self._started[stage] = time.perf_counter()
            self._tasks[stage] = self._progress.add_task(stage, total=total, rate="")
        rate = done / max(time.perf_counter() - self._started[stage], 1e-9)
        self._progress.update(
            self._tasks[stage], completed=done, total=total, rate=f"{rate:.1f} {unit}/s"
        )
