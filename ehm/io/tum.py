"""TUM RGB-D depth frames: a folder with poses.txt (`depth/<file> tx ty tz qx qy qz qw`,
camera-to-world) and 16-bit depth PNGs."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.geometry import quaternion_to_matrix, transform_points
from ehm.core.scan import Scan


def read_tum(
    folder: str | PathLike[str],
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
