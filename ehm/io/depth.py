"""Depth images and the pinhole cameras that turn them into scans: the part every RGB-D
layout (TUM, 7-Scenes, Redwood) shares.

    camera = DepthCamera(fx=585.0, fy=585.0, cx=320.0, cy=240.0, depth_scale=1000.0)
    scan = depth_scan("frame-000000.depth.png", T_world_camera, camera)
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ehm.core.sensor.geometry import transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_bytes

# Every depth layout reads a sub-sampled image: every second row and column (a quarter of the
# pixels) keeps a 640 x 480 frame near 77k rays, as dense as a 3D LiDAR sweep.
PIXEL_STRIDE = 2
INTRINSICS_HINT = "give the camera with --intrinsics FX,FY,CX,CY and --depth-scale UNITS_PER_METRE"


class DepthFrame(NamedTuple):
    """One depth image of a sequence, its (4, 4) camera-to-world pose T_world_camera (optical
    frame: x right, y down, z forward) and its time (seconds; None when unknown)."""

    image: Path
    T_world_camera: np.ndarray
    time: float | None


@dataclass(frozen=True)
class DepthCamera:
    """A pinhole depth camera: focal lengths and principal point in pixels, and how many raw
    image units make a metre (1000 for millimetres, 5000 for TUM's fifths of a millimetre).
    Raw values in `no_reading` (0 always; 65535 too for 7-Scenes) are pixels without depth."""

    fx: float
    fy: float
    cx: float
    cy: float
    depth_scale: float
    no_reading: tuple[int, ...] = (0,)

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy, self.depth_scale)
        if not all(np.isfinite(values)) or min(self.fx, self.fy, self.depth_scale) <= 0:
            raise InputError(
                f"camera fx {self.fx}, fy {self.fy}, cx {self.cx}, cy {self.cy}, depth scale "
                f"{self.depth_scale}: focal lengths and depth scale must be positive, all finite"
            )

    @property
    def intrinsics(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy), pixels."""
        return (self.fx, self.fy, self.cx, self.cy)

    def with_options(
        self, intrinsics: Sequence[float] | None, depth_scale: float | None
    ) -> DepthCamera:
        """This camera with the user's intrinsics (fx, fy, cx, cy) and depth scale, where
        given, in place of its own."""
        fx, fy, cx, cy = self.intrinsics if intrinsics is None else intrinsics
        scale = self.depth_scale if depth_scale is None else depth_scale
        return DepthCamera(fx, fy, cx, cy, scale, self.no_reading)

    def describe(self) -> str:
        return (
            f"fx {self.fx:g}, fy {self.fy:g}, cx {self.cx:g}, cy {self.cy:g}, "
            f"{self.depth_scale:g} units a metre"
        )

    def points(self, depth: np.ndarray, stride: int = PIXEL_STRIDE) -> np.ndarray:
        """(N, 3) float64 points, metres, camera frame (x right, y down, z forward), of every
        `stride`-th row and column of a (H, W) raw depth image that has a reading."""
        taken = depth[::stride, ::stride]
        valid = ~np.isin(taken, self.no_reading)
        v, u = np.nonzero(valid)
        z = taken[v, u].astype(np.float64) / self.depth_scale
        u, v = u * stride, v * stride
        return np.column_stack([(u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z])


def check_depth_options(intrinsics: Sequence[float] | None, depth_scale: float | None) -> None:
    """InputError for intrinsics that are not four finite numbers (focal lengths positive) or
    a depth scale that is not a positive number."""
    if intrinsics is not None:
        values = list(intrinsics)
        if len(values) != 4:
            raise InputError(f"intrinsics are 4 numbers fx, fy, cx, cy (pixels), got {len(values)}")
        DepthCamera(*values, depth_scale=1.0)
    if depth_scale is not None and not (np.isfinite(depth_scale) and depth_scale > 0):
        raise InputError(
            f"depth scale is the raw units of a metre (1000 for millimetres), got {depth_scale}"
        )


def read_depth_image(path: str | PathLike[str]) -> np.ndarray:
    """(H, W) raw depth values of a one-channel integer PNG; FileReadError naming it otherwise."""
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
    return depth


def depth_scan(
    path: str | PathLike[str],
    T_world_camera: np.ndarray,
    camera: DepthCamera,
    time: float | None = None,
) -> Scan:
    """The scan of one depth image: its pixels with a reading, placed in world frame by the
    (4, 4) camera-to-world pose T_world_camera, the sensor at the camera's centre."""
    points_world = transform_points(T_world_camera, camera.points(read_depth_image(path)))
    try:
        return Scan(points_world, T_world_camera[:3, 3].copy(), time=time)
    except InputError as error:
        raise FileReadError(path, str(error)) from None
