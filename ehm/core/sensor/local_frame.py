"""A map's own frame: where it keeps its clusters and memory, so that georeferenced data (UTM,
State Plane: millions of metres from the world origin) keeps the precision of data near it."""

from __future__ import annotations

import numpy as np

from ehm.config import MapConfig
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


def in_frame(
    scans: list[Scan], config: MapConfig, local_origin: np.ndarray
) -> tuple[list[Scan], MapConfig]:
    """`scans` (world frame) and `config`'s learn_box in the frame whose origin is
    `local_origin` ((d,) metres, world frame); both as given where that is the world origin."""
    if not local_origin.any():
        return scans, config
    if config.learn_box:
        box = np.asarray(config.learn_box).reshape(2, -1) - local_origin
        config = config.replace(learn_box=tuple(box.ravel()))
    shifted = [
        Scan(scan.points_world - local_origin, scan.origin - local_origin, scan.hit_mask, scan.time)
        for scan in scans
    ]
    return shifted, config
