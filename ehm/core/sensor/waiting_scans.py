"""Scans a map was given and has not learned yet: they wait until they hold a batch of rays
(MapConfig.batch_rays) and are then learned as one."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


class WaitingScans:
    """The scans waiting, in the order given, until they hold `batch_rays` rays, and the
    origin of every scan given, waiting or learned (the sensor path)."""

    def __init__(
        self,
        batch_rays: int,
        scans: Iterable[Scan] = (),
        origins: Iterable[np.ndarray] = (),
    ) -> None:
        self.batch_rays = batch_rays
        self.scans = list(scans)
        self.origins = list(origins)
        self._rays = sum(len(scan) for scan in self.scans)

    def __len__(self) -> int:
        return len(self.scans)

    @property
    def dim(self) -> int | None:
        return self.scans[0].dim if self.scans else None

    def add(self, scan: Scan) -> bool:
        """Keep `scan` waiting; True when the waiting scans now hold a batch."""
        self.scans.append(scan)
        self.origins.append(scan.origin)
        self._rays += len(scan)
        return self._rays >= self.batch_rays

    def take(self) -> list[Scan]:
        """The waiting scans, none waiting after."""
        scans, self.scans, self._rays = self.scans, [], 0
        return scans

    def sensor_path(self, dim: int) -> np.ndarray:
        """(n, dim) float64, metres, world frame: the origin of every scan given, in order."""
        return np.stack(self.origins) if self.origins else np.zeros((0, dim))

    @property
    def nbytes(self) -> int:
        """Bytes of the waiting scans and the sensor path."""
        scans = sum(scan.points_world.nbytes + scan.hit_mask.nbytes for scan in self.scans)
        return scans + sum(origin.nbytes for origin in self.origins)


def check_scan(
    scan: object, what: str, dim: int | None, holder: str, forget_after: float | None
) -> Scan:
    """`scan`; InputError naming `what` for what is not a Scan, a scan of other than `dim`
    axes (those of `holder`; None: any), and a scan without time stamp given to a map that
    forgets what it has not seen for `forget_after` seconds."""
    if not isinstance(scan, Scan):
        raise InputError(f"{what}: expected ehm.Scan, got {type(scan).__name__}")
    if dim is not None and scan.dim != dim:
        raise InputError(f"{what} points are {scan.dim}D, {holder} is {dim}D")
    if forget_after is not None and scan.time is None:
        raise InputError(
            f"{what} has no time stamp, and the map forgets what it has not seen for "
            f"{forget_after} s (MapConfig.forget_after): give each scan its time "
            "(integrate(..., time=seconds))"
        )
    return scan
