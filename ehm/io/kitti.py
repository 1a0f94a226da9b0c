"""KITTI odometry Velodyne scans: `velodyne/NNNNNN.bin` (float32 x y z intensity in the
Velodyne frame), placed by the sequence's poses (line i: frame i's row-major 3x4
T_world_camera0) and calib.txt's `Tr` (T_camera0_velodyne), each at its time in times.txt
(line i: frame i's, seconds) where the sequence has one."""

from __future__ import annotations

from collections.abc import Iterator
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.sensor.geometry import transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_input, read_text
from ehm.io.poses import read_kitti_calibration, read_poses

# `calib` value for poses that already place the Velodyne (say, from a LiDAR odometry).
IDENTITY = "identity"


def read_kitti(
    bin_paths: list[str | PathLike[str]],
    poses_path: str | PathLike[str],
    calib: str | PathLike[str] | None = None,
) -> list[Scan]:
    """KITTI Velodyne scans in world frame, in frame order. The frame number is the file's
    name (000123.bin is frame 123, placed by line 123 of the poses file), so any subset of a
    sequence finds its own poses. T_world_velodyne = T_world_camera0 @ Tr, with Tr from
    `calib`: a calib.txt path; by default the calib.txt of the scans' sequence folder (beside
    `velodyne/`); or "identity" when the poses already place the Velodyne."""
    return list(kitti_scans(bin_paths, poses_path, calib))


def kitti_files(
    items: list[str | PathLike[str]], poses: str | PathLike[str] | None
) -> tuple[list[Path], Path]:
    """The .bin scans of `items` (files, or sequence folders holding velodyne/) and the poses
    file: `poses`, or for one sequence folder NN the odometry layout's poses/NN.txt beside
    sequences/ (dataset/sequences/NN and dataset/poses/NN.txt)."""
    scans: list[Path] = []
    for item in map(Path, items):
        if item.is_dir():
            found = sorted((item / "velodyne").glob("*.bin"))
            if not found:
                raise FileReadError(item, "a KITTI sequence folder without velodyne/*.bin")
            scans += found
        else:
            scans.append(item)
    if poses is not None:
        return scans, Path(poses)
    folders = [Path(item) for item in items if Path(item).is_dir()]
    if len(folders) == 1:
        beside = folders[0].resolve().parent.parent / "poses" / f"{folders[0].name}.txt"
        if beside.exists():
            return scans, beside
    raise InputError("KITTI scans need the sequence's poses file (--poses)")


def kitti_scans(
    bin_paths: list[str | PathLike[str]],
    poses_path: str | PathLike[str],
    calib: str | PathLike[str] | None = None,
) -> Iterator[Scan]:
    """The scans of `read_kitti`, each read when it is asked for; the frame numbers, poses
    and calibration are checked first, here."""
    frames = kitti_frames(bin_paths, poses_path, calib)
    return (read_kitti_scan(*frame) for frame in frames)


def kitti_frames(
    bin_paths: list[str | PathLike[str]],
    poses_path: str | PathLike[str],
    calib: str | PathLike[str] | None = None,
) -> list[tuple[Path, np.ndarray, float | None]]:
    """Each scan's file, (4, 4) T_world_velodyne and time (seconds; None without the
    sequence's times.txt beside `velodyne/`), in frame order, checked (frame numbers, poses
    and calibration; see read_kitti); no scan is read."""
    frames = sorted((_frame_number(path), Path(path)) for path in bin_paths)
    poses = read_poses(poses_path)
    T_camera_velodyne = _calibration(frames[0][1], calib)
    for frame, path in frames:
        if frame >= len(poses):
            raise FileReadError(
                poses_path, f"{len(poses)} poses: none for frame {frame} ({path.name})"
            )
    times = _times(frames[0][1])
    return [
        (path, poses[frame] @ T_camera_velodyne, times[frame] if frame < len(times) else None)
        for frame, path in frames
    ]


def read_kitti_scan(path: Path, T_world_velodyne: np.ndarray, time: float | None = None) -> Scan:
    """One Velodyne scan in world frame, placed by its (4, 4) T_world_velodyne, taken at
    `time` seconds (None: unknown)."""
    raw = read_input(path)
    if len(raw) % 16:
        raise FileReadError(
            path, f"{len(raw)} bytes is not a whole number of points (16 bytes: x y z i)"
        )
    with np.errstate(invalid="ignore"):  # bytes that are not numbers become NaN, dropped
        points_velodyne = np.frombuffer(raw, "<f4").reshape(-1, 4)[:, :3].astype(np.float64)
    points_world = transform_points(T_world_velodyne, points_velodyne)
    try:
        return Scan(points_world, T_world_velodyne[:3, 3].copy(), time=time)
    except InputError as error:
        raise FileReadError(path, str(error)) from None


def _frame_number(path: str | PathLike[str]) -> int:
    stem = Path(path).stem
    if not stem.isdigit():
        raise FileReadError(
            path, "the name is not a frame number (KITTI scans are named 000000.bin, ...)"
        )
    return int(stem)


def _calibration(first_scan: Path, calib: str | PathLike[str] | None) -> np.ndarray:
    """T_camera0_velodyne from `calib` (see read_kitti)."""
    if calib is not None and str(calib) == IDENTITY:
        return np.eye(4)
    if calib is not None:
        return read_kitti_calibration(calib)
    beside = first_scan.resolve().parent.parent / "calib.txt"
    if not beside.exists():
        raise InputError(
            f"KITTI poses place the left camera, and {beside} is missing: give its calib.txt "
            f"(--calib PATH) or, for poses that already place the Velodyne, --calib {IDENTITY}"
        )
    return read_kitti_calibration(beside)


def _times(first_scan: Path) -> list[float]:
    """The frame times of the scans' sequence, seconds: its times.txt beside `velodyne/`, one
    number per line (none without the file); FileReadError naming a line that is not one."""
    path = first_scan.resolve().parent.parent / "times.txt"
    if not path.exists():
        return []
    times = []
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        try:
            times.append(float(line))
        except ValueError:
            raise FileReadError(
                path, f"not a time in seconds: {line!r}", f"line {number}"
            ) from None
    return times
