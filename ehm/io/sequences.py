"""Scan sequences with poses: KITTI .bin, OctoMap .graph, TUM depth PNGs, CARMEN 2D logs.

Each reader returns a list of ehm.Scan in world frame, the sensor origin of each scan being the
translation of its pose.
"""

from __future__ import annotations

import struct
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.geometry import quaternion_to_matrix, transform_points
from ehm.scan import Scan

Pathish = str | PathLike[str]


def read_kitti_poses(path: Pathish) -> list[np.ndarray]:
    """KITTI odometry poses: 12 numbers per line, a row-major 3x4 T_world_sensor."""
    values = np.loadtxt(path, ndmin=2)
    if values.shape[1] != 12:
        raise ValueError(f"{path}: expected 12 numbers per line, got {values.shape[1]}")
    return [np.vstack([row.reshape(3, 4), [0, 0, 0, 1]]) for row in values]


def read_kitti(bin_paths: list[Pathish], poses_path: Pathish) -> list[Scan]:
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


def read_octomap_graph(path: Pathish) -> list[Scan]:
    """OctoMap ScanGraph (.graph): per node a point cloud in sensor frame and a 6D pose."""
    data = Path(path).read_bytes()
    offset = 0

    def take(fmt: str) -> tuple:
        nonlocal offset
        size = struct.calcsize(fmt)
        if offset + size > len(data):
            raise ValueError(f"{path}: truncated OctoMap graph at byte {offset}")
        values = struct.unpack_from(fmt, data, offset)
        offset += size
        return values

    (n_nodes,) = take("<I")
    scans = []
    for _ in range(n_nodes):
        (n_points,) = take("<I")
        if offset + 28 * n_points > len(data):
            raise ValueError(f"{path}: truncated OctoMap graph at byte {offset}")
        # Each point: int32 (=3) then three float64.
        records = np.frombuffer(
            data, dtype=[("n", "<i4"), ("xyz", "<f8", 3)], count=n_points, offset=offset
        )
        offset += 28 * n_points
        _, tx, ty, tz = take("<i3d")
        _, qw, qx, qy, qz = take("<i4d")
        take("<I")  # node id
        T_world_sensor = np.eye(4)
        T_world_sensor[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
        T_world_sensor[:3, 3] = (tx, ty, tz)
        points_world = transform_points(T_world_sensor, records["xyz"].astype(np.float64))
        scans.append(Scan(points_world, np.array([tx, ty, tz])))
    return scans


def read_tum(
    folder: Pathish,
    fx: float = 520.9,
    fy: float = 521.0,
    cx: float = 325.1,
    cy: float = 249.7,
    depth_scale: float = 5000.0,
    pixel_stride: int = 2,
) -> list[Scan]:
    """TUM RGB-D depth frames listed in `folder`/poses.txt (`depth/<file> tx ty tz qx qy qz
    qw`, camera-to-world). Intrinsics default to Freiburg 2; depth in metres = value /
    depth_scale; 0 means no reading and is skipped. Every `pixel_stride`-th pixel is used."""
    from PIL import Image

    folder = Path(folder)
    scans = []
    for line in (folder / "poses.txt").read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        name, *numbers = line.split()
        tx, ty, tz, qx, qy, qz, qw = map(float, numbers)
        depth = np.asarray(Image.open(folder / name), dtype=np.float64)[
            ::pixel_stride, ::pixel_stride
        ]
        v, u = np.nonzero(depth)
        z = depth[v, u] / depth_scale
        u, v = u * pixel_stride, v * pixel_stride
        points_camera = np.column_stack([(u - cx) * z / fx, (v - cy) * z / fy, z])
        T_world_camera = np.eye(4)
        T_world_camera[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
        T_world_camera[:3, 3] = (tx, ty, tz)
        scans.append(Scan(transform_points(T_world_camera, points_camera), np.array([tx, ty, tz])))
    return scans


def read_carmen(path: Pathish, max_range: float = 81.0, fov: float = np.pi) -> list[Scan]:
    """2D scans of a CARMEN log: each `FLASER n r_1..r_n x y theta ...` line, beam i at angle
    theta - fov/2 + i fov/n; readings >= max_range (sensor dropouts) are dropped."""
    scans = []
    for number, line in enumerate(Path(path).read_text().splitlines(), start=1):
        words = line.split()
        if not words or words[0] != "FLASER":
            continue
        try:
            n = int(words[1])
            ranges = np.array(words[2 : 2 + n], dtype=np.float64)
            x, y, theta = map(float, words[2 + n : 5 + n])
        except (ValueError, IndexError) as error:
            raise ValueError(f"{path}:{number}: malformed FLASER line ({error})") from error
        angles = theta - fov / 2 + np.arange(n) * fov / n
        keep = ranges < max_range
        points = np.column_stack([x + ranges * np.cos(angles), y + ranges * np.sin(angles)])[keep]
        if len(points):
            scans.append(Scan(points, np.array([x, y])))
    return scans
