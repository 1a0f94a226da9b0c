"""Pose files: one T_world_sensor per line, in KITTI's layout (12 numbers, a row-major 3x4
matrix) or TUM's (`timestamp tx ty tz qx qy qz qw`); and KITTI's calib.txt."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_text

# How far a pose's rotation may be from orthonormal, as text files round it.
_ROTATION_TOLERANCE = 1e-3


def read_poses(path: str | PathLike[str]) -> list[np.ndarray]:
    """(4, 4) T_world_sensor of each line of a poses file, KITTI or TUM layout (all lines
    alike; blank lines and `#` comments skipped). FileReadError naming the line for a line of
    another length, a number that is not finite, or a rotation that is not one."""
    poses, layout = [], None
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        words = line.split("#")[0].split()
        if not words:
            continue
        where = f"line {number}"
        if layout is None:
            layout = {12: "KITTI", 8: "TUM"}.get(len(words))
        expected = {"KITTI": 12, "TUM": 8, None: 0}[layout]
        if len(words) != expected:
            raise FileReadError(
                path,
                f"expected {expected or '12 (KITTI) or 8 (TUM)'} numbers per line, got "
                f"{len(words)}",
                where,
            )
        try:
            values = np.array(words, dtype=np.float64)
            if not np.all(np.isfinite(values)):
                raise InputError("numbers that are not finite")
            poses.append(matrix_pose(values) if layout == "KITTI" else _tum_pose(values))
        except ValueError as error:  # InputError too
            raise FileReadError(path, f"not a pose: {error}", where) from None
    if not poses:
        raise FileReadError(path, "no poses")
    return poses


def read_kitti_calibration(path: str | PathLike[str]) -> np.ndarray:
    """(4, 4) T_camera_velodyne, the `Tr` line of a KITTI odometry calib.txt."""
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        key, _, rest = line.partition(":")
        if key.strip() == "Tr":
            try:
                values = np.array(rest.split(), dtype=np.float64)
                if values.shape != (12,) or not np.all(np.isfinite(values)):
                    raise InputError(f"expected 12 finite numbers, got {len(values)}")
                return matrix_pose(values)
            except ValueError as error:  # InputError too
                raise FileReadError(path, f"bad Tr: {error}", f"line {number}") from None
    raise FileReadError(path, "no 'Tr:' line (the Velodyne-to-camera transform)")


def matrix_pose(values: np.ndarray) -> np.ndarray:
    """(4, 4) pose of a row-major 3x4 matrix (12 numbers, KITTI) or 4x4 matrix (16 numbers,
    7-Scenes, Redwood); InputError when its 3x3 part is not a rotation or a 4x4's last row is
    not 0 0 0 1."""
    if values.shape == (16,):
        if not np.allclose(values[12:], [0.0, 0.0, 0.0, 1.0], atol=_ROTATION_TOLERANCE):
            raise InputError(f"the last row of a 4x4 pose is {values[12:].tolist()}, not 0 0 0 1")
        values = values[:12]
    pose = np.vstack([values.reshape(3, 4), [0.0, 0.0, 0.0, 1.0]])
    rotation = pose[:3, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: an infinite error
        error = np.abs(rotation.T @ rotation - np.eye(3)).max()
    if error > _ROTATION_TOLERANCE or np.linalg.det(rotation) < 0:
        raise InputError(f"its 3x3 part is not a rotation (R^T R differs from I by {error:.3g})")
    return pose


def _tum_pose(values: np.ndarray) -> np.ndarray:
    _, tx, ty, tz, qx, qy, qz, qw = values
    pose = np.eye(4)
    pose[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
    pose[:3, 3] = (tx, ty, tz)
    return pose


def read_matrix(path: str | PathLike[str], shape: tuple[int, int]) -> np.ndarray:
    """The matrix of `shape` a text file holds, its numbers in rows (7-Scenes' frame poses,
    tsdf-fusion's camera-intrinsics.txt); FileReadError for any other count or a number that
    is not finite."""
    words = read_text(path).split()
    try:
        values = np.array(words, dtype=np.float64)
    except ValueError as error:
        raise FileReadError(path, f"not a {shape[0]}x{shape[1]} matrix ({error})") from None
    if values.size != shape[0] * shape[1] or not np.all(np.isfinite(values)):
        raise FileReadError(
            path, f"expected {shape[0]}x{shape[1]} finite numbers, got {values.size} numbers"
        )
    return values.reshape(shape)
