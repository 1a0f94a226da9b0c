"""Where a tiled build reads scans: any object with `count()` and `read(indices)`, small
enough to send to every process of a cluster, which then reads the scans it needs itself.

    ScanFiles(paths, ...)   scan files of any format (ehm.io.readers)
    CityDrive(length=...)   the generated city street (ehm.eval.datasets.simulated)
    ScanList(scans)         scans in memory: sent whole to the processes that need them
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from typing import Protocol, runtime_checkable

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


@runtime_checkable
class ScanSource(Protocol):
    """Scans in order, each read by its index (0-based)."""

    def count(self) -> int | None:
        """How many scans there are, or None when only reading them all tells."""

    def read(self, indices: Iterable[int] | None = None) -> Iterator[tuple[int, Scan]]:
        """(index, scan) for each of `indices` (None: every scan), in ascending order."""


class ScanList:
    """Scans already in memory, as a ScanSource."""

    def __init__(self, scans: Sequence[Scan]) -> None:
        scans = list(scans)
        for i, scan in enumerate(scans):
            if not isinstance(scan, Scan):
                raise InputError(f"scan {i}: expected ehm.Scan, got {type(scan).__name__}")
        self.scans = scans

    def count(self) -> int:
        return len(self.scans)

    def read(self, indices: Iterable[int] | None = None) -> Iterator[tuple[int, Scan]]:
        chosen = range(len(self.scans)) if indices is None else sorted(set(indices))
        return ((i, self.scans[i]) for i in chosen)


def scan_source(scans: ScanSource | Iterable[Scan]) -> ScanSource:
    """`scans` as a ScanSource: itself if it is one, else a ScanList of its scans."""
    if isinstance(scans, ScanSource):
        return scans
    if isinstance(scans, Scan):
        raise InputError("expected scans (a list, a ScanFiles, a CityDrive...), got one Scan")
    try:
        return ScanList(scans)
    except TypeError:
        raise InputError(
            f"expected scans (a list, a ScanFiles, a CityDrive...), got {type(scans).__name__}"
        ) from None
