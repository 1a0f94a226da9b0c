"""KITTI odometry Velodyne scans (.bin, float32 x y z intensity in the sensor frame) placed
by a poses file of row-major 3x4 T_world_sensor, one line per scan."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.core.geometry import transform_points
from ehm.core.scan import Scan


def read_kitti_poses(path: str | PathLike[str]) -> list[np.ndarray]:
    """KITTI odometry poses: 12 numbers per line, a row-major 3x4 T_world_sensor."""
    values = np.loadtxt(path, ndmin=2)
    if values.shape[1] != 12:
        raise ValueError(f"{path}: expected 12 numbers per line, got {values.shape[1]}")
    return [np.vstack([row.reshape(3, 4), [0, 0, 0, 1]]) for row in values]


def read_kitti(bin_paths: list[str | PathLike[str]], poses_path: str | PathLike[str]) -> list[Scan]:
    """KITTI Velodyne scans (float32 x y z intensity, sensor frame) placed by their poses."""
    poses = read_kitti_poses(poses_path)
    if len(poses) < len(bin_paths):
        raise ValueError(f"{poses_path}: {len(poses)} poses for {len(bin_paths)} scans")
    scans = []
    for path, T_world_sensor in zip(sorted(map(str, bin_paths)), poses, strict=False):
        raw = np.fromfile(path, dtype="<f4")
        if raw.size % 4:
            raise ValueError(f"{path}: size is not a multiple of 16 bytes (x y z intensity)")
        points_sensor = raw.reshape(-1, 4)[:, :3].astype(np.float64)
        points_world = transform_points(T_world_sensor, points_sensor)
        scans.append(Scan(points_world, T_world_sensor[:3, 3].copy()))
    return scans
