"""A map's own frame: where it keeps its clusters and memory, so that georeferenced data (UTM,
State Plane: millions of metres from the world origin) keeps the precision of data near it."""

from __future__ import annotations

import numpy as np

from ehm.core.sensor.scan import Scan

# A map whose first scan's sensor stands farther than this from the world origin, metres,
# keeps its clusters relative to a point near that sensor (LOCAL_ORIGIN_STEP metres apart):
# cells keyed by integers from the origin reach 15 km at the finest resolutions.
LOCAL_ORIGIN_BEYOND = 10_000.0
LOCAL_ORIGIN_STEP = 1024.0


def local_origin_for(sensor: np.ndarray) -> np.ndarray:
    """(d,) metres, world frame: the origin of a map's own frame, for the sensor position of
    its first scan: the world origin, unless the sensor stands farther than
    LOCAL_ORIGIN_BEYOND from it, then the sensor's position rounded to LOCAL_ORIGIN_STEP, a
    power of two, so shifting by it is exact."""
    sensor = np.asarray(sensor, dtype=np.float64)
    if np.abs(sensor).max() <= LOCAL_ORIGIN_BEYOND:
        return np.zeros_like(sensor)
    return np.round(sensor / LOCAL_ORIGIN_STEP) * LOCAL_ORIGIN_STEP


def scans_from(scans: list[Scan], local_origin: np.ndarray) -> list[Scan]:
    """`scans` (world frame) in the frame whose origin is `local_origin` ((d,) metres, world
    frame); the same scans where that is the world origin."""
    if not local_origin.any():
        return scans
    return [
        Scan(scan.points_world - local_origin, scan.origin - local_origin, scan.hit_mask, scan.time)
        for scan in scans
    ]
