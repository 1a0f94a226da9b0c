"""RGB-D frames in the Redwood layout that Open3D's examples use: `depth/*.png` (16-bit,
millimetres by Open3D's convention; 0 is no reading), a trajectory in Redwood's `.log` format
(per frame a line `i i i+1`, then the 4x4 camera-to-world matrix of frame i, optical frame),
and the camera as Open3D writes a PinholeCameraIntrinsic (a JSON file with `intrinsic_matrix`,
the 3x3 matrix column by column)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.errors import FileReadError, InputError, assumed
from ehm.io.depth import INTRINSICS_HINT, DepthCamera, DepthFrame, check_depth_options
from ehm.io.files import read_text
from ehm.io.poses import matrix_pose

# Open3D's depth_scale default: its RGB-D images hold millimetres.
REDWOOD_DEPTH_SCALE = 1000.0
# The trajectory read when a folder holds several logs, the first found first.
TRAJECTORY_NAMES = ("trajectory.log", "odometry.log")


def is_redwood(folder: Path) -> bool:
    """Whether `folder` holds a Redwood RGB-D sequence (depth/ and a .log trajectory)."""
    return (folder / "depth").is_dir() and next(folder.glob("*.log"), None) is not None


def redwood_frames(
    folder: str | PathLike[str],
    intrinsics: Sequence[float] | None = None,
    depth_scale: float | None = None,
) -> tuple[DepthCamera, list[DepthFrame]]:
    """The camera and the posed depth frames of a Redwood folder, in frame order (frame i is
    the i-th image of depth/ by name); no image is read. `intrinsics` (fx, fy, cx, cy,
    pixels) and `depth_scale` (raw units a metre) replace the folder's own. InputError when
    there is no camera file and no intrinsics; FileReadError naming what cannot be read."""
    folder = Path(folder)
    camera = _camera(folder, intrinsics, depth_scale)
    images = sorted((folder / "depth").glob("*.png"))
    trajectory = _trajectory_path(folder)
    poses = _read_log(trajectory)
    frames = []
    for index, T_world_camera in poses:
        if index >= len(images):
            raise FileReadError(
                trajectory, f"a pose for frame {index}, and depth/ holds {len(images)} images"
            )
        frames.append(DepthFrame(images[index], T_world_camera, None))
    return camera, frames


def _trajectory_path(folder: Path) -> Path:
    logs = sorted(folder.glob("*.log"))
    chosen = next((folder / n for n in TRAJECTORY_NAMES if (folder / n).is_file()), None)
    if chosen is None and len(logs) > 1:
        raise InputError(
            f"{folder}: {len(logs)} trajectories ({', '.join(p.name for p in logs)}): keep one"
        )
    chosen = chosen or logs[0]
    if len(logs) > 1:
        assumed(f"{folder.name}: poses from {chosen.name} of {len(logs)} trajectories")
    return chosen


def _read_log(path: Path) -> list[tuple[int, np.ndarray]]:
    """(frame index, (4, 4) T_world_camera) of each block of a Redwood .log file."""
    lines = [
        (number, line.split())
        for number, line in enumerate(read_text(path).splitlines(), start=1)
        if line.strip()
    ]
    if not lines or len(lines) % 5:
        raise FileReadError(
            path, f"{len(lines)} lines: a Redwood trajectory has 5 a frame ('i i i+1', 4 rows)"
        )
    poses = []
    for block in range(0, len(lines), 5):
        number, header = lines[block]
        rows = [words for _, words in lines[block + 1 : block + 5]]
        try:
            index = int(header[0])
            if index < 0 or any(len(row) != 4 for row in rows):
                raise ValueError("expected 'i i i+1' and four rows of four numbers")
            values = np.array(rows, dtype=np.float64).ravel()
            if not np.all(np.isfinite(values)):
                raise ValueError("numbers that are not finite")
            poses.append((index, matrix_pose(values)))
        except (ValueError, IndexError) as error:  # InputError too
            raise FileReadError(path, f"not a frame's pose ({error})", f"line {number}") from None
    return poses


def _camera(
    folder: Path, intrinsics: Sequence[float] | None, depth_scale: float | None
) -> DepthCamera:
    if intrinsics is None:
        intrinsics = _camera_file_intrinsics(folder)
    camera = DepthCamera(*intrinsics, REDWOOD_DEPTH_SCALE).with_options(None, depth_scale)
    if depth_scale is None:
        assumed(
            f"{folder.name}: Redwood depth images read as millimetres, Open3D's convention "
            f"({camera.describe()}); --depth-scale says otherwise"
        )
    return camera


def _camera_file_intrinsics(folder: Path) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy), pixels, of the Open3D camera file beside the frames (a JSON file with
    `intrinsic_matrix`, in the folder or a camera*.json above it); InputError without one."""
    files = sorted(folder.glob("*.json")) + sorted(folder.parent.glob("camera*.json"))
    found = next((p for p in files if "intrinsic_matrix" in read_text(p)), None)
    if found is None:
        raise InputError(
            f"{folder}: no camera file (Open3D's PinholeCameraIntrinsic JSON) beside the frames: "
            f"{INTRINSICS_HINT}"
        )
    try:
        K = np.array(json.loads(read_text(found))["intrinsic_matrix"], dtype=np.float64)
        if K.size != 9:
            raise ValueError(f"{K.size} numbers, a 3x3 matrix has 9")
        fx, fy, cx, cy = K.ravel()[[0, 4, 6, 7]]  # column by column
        check_depth_options((fx, fy, cx, cy), None)
    except (ValueError, KeyError, TypeError) as error:  # InputError too
        raise FileReadError(found, f"not a camera's intrinsic_matrix ({error})") from None
    return fx, fy, cx, cy
