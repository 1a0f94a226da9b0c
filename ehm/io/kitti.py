"""KITTI odometry Velodyne scans: `velodyne/NNNNNN.bin` (float32 x y z intensity in the
Velodyne frame), placed by the sequence's poses (line i: frame i's row-major 3x4 pose of the
left camera, P_i = T_camera0_camera_i) and calib.txt's `Tr` (T_camera_velodyne), each at its
time in times.txt (line i: frame i's, seconds) where the sequence has one.

The map's world is the first LiDAR pose's frame, z up as robotics tools expect (KITTI's
poses are in the first camera's frame: y down, z forward): T_world_velodyne_i = Tr^-1 P_i Tr.
A scan without a poses file is placed in its LiDAR's own frame at a given origin."""

from __future__ import annotations

from collections.abc import Sequence
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


def kitti_files(items: list[str | PathLike[str]]) -> list[Path]:
    """The .bin scans of `items` (files, or sequence folders holding velodyne/)."""
    scans: list[Path] = []
    for item in map(Path, items):
        if item.is_dir():
            found = sorted((item / "velodyne").glob("*.bin"))
            if not found:
                raise FileReadError(item, "a KITTI sequence folder without velodyne/*.bin")
            scans += found
        else:
            scans.append(item)
    return scans


def sequence_poses(
    items: list[str | PathLike[str]], poses: str | PathLike[str] | None
) -> Path | None:
    """The poses file of KITTI scans: `poses`, or for one sequence folder NN the odometry
    layout's poses/NN.txt beside sequences/ (dataset/sequences/NN and dataset/poses/NN.txt);
    None when there is neither."""
    if poses is not None:
        return Path(poses)
    folders = [Path(item) for item in items if Path(item).is_dir()]
    if len(folders) == 1:
        beside = folders[0].resolve().parent.parent / "poses" / f"{folders[0].name}.txt"
        if beside.exists():
            return beside
    return None


def kitti_frames(
    bin_paths: list[str | PathLike[str]],
    poses_path: str | PathLike[str] | None,
    calib: str | PathLike[str] | None = None,
    origin: Sequence[float] | None = None,
) -> list[tuple[Path, np.ndarray, float | None]]:
    """Each scan's file, (4, 4) T_world_velodyne and time (seconds; None without the
    sequence's times.txt beside `velodyne/`), in frame order, checked (frame numbers, poses
    and calibration, see the module); no scan is read. Without a poses file, each scan is
    placed in its LiDAR's own frame with its centre at `origin` (metres)."""
    frames = sorted((_frame_number(path), Path(path)) for path in bin_paths)
    times = _times(frames[0][1])
    if poses_path is None:
        if origin is None:
            raise InputError(
                "KITTI scans need the sequence's poses file (--poses), or --origin X,Y,Z to map "
                "them in the LiDAR's own frame"
            )
        T_world_velodyne = np.eye(4)
        T_world_velodyne[:3, 3] = origin
        return [(path, T_world_velodyne, _time(times, frame)) for frame, path in frames]
    poses = read_poses(poses_path)
    T_camera_velodyne = _calibration(frames[0][1], calib)
    T_velodyne_camera = np.linalg.inv(T_camera_velodyne)
    for frame, path in frames:
        if frame >= len(poses):
            raise FileReadError(
                poses_path, f"{len(poses)} poses: none for frame {frame} ({path.name})"
            )
    return [
        (path, T_velodyne_camera @ poses[frame] @ T_camera_velodyne, _time(times, frame))
        for frame, path in frames
    ]


def _time(times: list[float], frame: int) -> float | None:
    return times[frame] if frame < len(times) else None


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
    """T_camera0_velodyne from `calib`: a calib.txt path; by default the calib.txt of the
    scans' sequence folder (beside `velodyne/`); or "identity" when the poses already place
    the Velodyne."""
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
