"""TUM RGB-D depth frames: a folder with poses.txt (`depth/<file> tx ty tz qx qy qz qw`,
camera-to-world) and 16-bit depth PNGs."""

from __future__ import annotations

import io
from collections.abc import Iterator
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix, transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_bytes, read_text


def read_tum(folder: str | PathLike[str], **camera: float) -> list[Scan]:
    """Every frame of `tum_scans` (same arguments), read now."""
    return list(tum_scans(folder, **camera))


def tum_scans(
    folder: str | PathLike[str],
    fx: float = 520.9,
    fy: float = 521.0,
    cx: float = 325.1,
    cy: float = 249.7,
    depth_scale: float = 5000.0,
    pixel_stride: int = 2,
) -> Iterator[Scan]:
    """TUM RGB-D depth frames listed in `folder`/poses.txt (`depth/<file> tx ty tz qx qy qz
    qw`, camera-to-world), each read when it is asked for. Intrinsics default to Freiburg 2;
    depth in metres = value / depth_scale; 0 means no reading and is skipped. Every
    `pixel_stride`-th pixel is used. A frame's time is its file's name, as TUM names depth
    images (depth/1311877813.991479.png: seconds), where the name is a number."""
    folder = Path(folder)
    poses_path = folder / "poses.txt"
    for number, line in enumerate(read_text(poses_path).splitlines(), start=1):
        if not line.strip() or line.startswith("#"):
            continue
        name, *numbers = line.split()
        try:
            if len(numbers) != 7:
                raise InputError(f"{len(numbers)} numbers")
            tx, ty, tz, qx, qy, qz, qw = map(float, numbers)
            T_world_camera = np.eye(4)
            T_world_camera[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
            T_world_camera[:3, 3] = (tx, ty, tz)
        except ValueError as error:  # InputError too
            message = f"expected 'depth/FILE tx ty tz qx qy qz qw' ({error})"
            raise FileReadError(poses_path, message, f"line {number}") from None
        depth = _depth_image(folder / name)[::pixel_stride, ::pixel_stride]
        v, u = np.nonzero(depth)
        z = depth[v, u] / depth_scale
        u, v = u * pixel_stride, v * pixel_stride
        points_camera = np.column_stack([(u - cx) * z / fx, (v - cy) * z / fy, z])
        points_world = transform_points(T_world_camera, points_camera)
        try:
            scan = Scan(points_world, T_world_camera[:3, 3].copy(), time=_stamp(name))
        except InputError as error:
            raise FileReadError(folder / name, str(error)) from None
        yield scan


def _depth_image(path: Path) -> np.ndarray:
    """(H, W) float64 raw depth values of a 16-bit PNG; FileReadError naming it otherwise."""
    from PIL import Image

    data = read_bytes(path)
    try:
        with Image.open(io.BytesIO(data)) as image:
            depth = np.asarray(image)
    except Exception as error:
        # Pillow's decoders fail in many ways (UnidentifiedImageError, OSError, SyntaxError,
        # ValueError, ...) on bytes that are not an image.
        raise FileReadError(path, f"not a depth image ({error!r})") from None
    if depth.ndim != 2 or depth.dtype.kind not in "ui":
        raise FileReadError(
            path, f"expected a one-channel 16-bit depth image, got {depth.dtype} {depth.shape}"
        )
    return depth.astype(np.float64)


def _stamp(name: str) -> float | None:
    """The time a TUM depth image's name gives (depth/1311877813.991479.png), seconds; None for
    a name that is not a number."""
    try:
        time = float(Path(name).stem)
    except ValueError:
        return None
    return time if np.isfinite(time) else None
