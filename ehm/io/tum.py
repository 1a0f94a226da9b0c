"""TUM RGB-D depth frames, in either layout of a sequence folder:

- TUM's own download (rgbd_dataset_freiburg2_pioneer_slam2/): `depth.txt` (`time file` per
  line) and `groundtruth.txt` (`time tx ty tz qx qy qz qw`), each depth image given the
  ground-truth pose nearest in time within 20 ms, one to one, as TUM's associate.py does;
- a `poses.txt` of `depth/<file> tx ty tz qx qy qz qw` lines, the poses already associated.

Poses are camera-to-world (optical frame); depth is 16-bit PNG in fifths of a millimetre. The
camera is Freiburg 1, 2 or 3, named by the sequence folder (freiburg2 or fr2 in its name);
a folder that names none needs its camera given (--intrinsics).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix
from ehm.errors import FileReadError, InputError, assumed
from ehm.io.depth import INTRINSICS_HINT, DepthCamera, DepthFrame
from ehm.io.files import read_text

# TUM's depth unit, a metre in raw image values, and its calibration of each Kinect (the
# depth images are registered to the colour camera).
TUM_DEPTH_SCALE = 5000.0
FREIBURG_CAMERAS = {
    1: DepthCamera(517.3, 516.5, 318.6, 255.3, TUM_DEPTH_SCALE),
    2: DepthCamera(520.9, 521.0, 325.1, 249.7, TUM_DEPTH_SCALE),
    3: DepthCamera(535.4, 539.2, 320.1, 247.6, TUM_DEPTH_SCALE),
}
# TUM's associate.py pairs time stamps no further apart than this, seconds.
MAX_TIME_DIFFERENCE = 0.02
_FREIBURG_NAME = re.compile(r"(?:^|[^a-z])(?:freiburg|fr)([123])(?![0-9])", re.IGNORECASE)


def is_tum(folder: Path) -> bool:
    """Whether `folder` is a TUM sequence in either layout."""
    official = (folder / "depth.txt").is_file() and (folder / "groundtruth.txt").is_file()
    return official or (folder / "poses.txt").is_file()


def tum_frames(
    folder: str | PathLike[str],
    intrinsics: Sequence[float] | None = None,
    depth_scale: float | None = None,
) -> tuple[DepthCamera, list[DepthFrame]]:
    """The camera and the posed depth frames of a TUM sequence folder, in time order; no image
    is read. `intrinsics` (fx, fy, cx, cy, pixels) and `depth_scale` (raw units a metre)
    replace the sequence's own. InputError when the folder names no Freiburg camera and no
    intrinsics are given; FileReadError naming the line of a file that cannot be read."""
    folder = Path(folder)
    camera = _camera(folder, intrinsics, depth_scale)
    if (folder / "poses.txt").is_file():
        return camera, _listed_frames(folder)
    return camera, _associated_frames(folder)


def _camera(
    folder: Path, intrinsics: Sequence[float] | None, depth_scale: float | None
) -> DepthCamera:
    match = _FREIBURG_NAME.search(folder.resolve().name)
    if match is None and intrinsics is None:
        raise InputError(
            f"{folder}: TUM sequences name their camera (freiburg1, 2 or 3, as in "
            f"rgbd_dataset_freiburg2_pioneer_slam2) and this folder's name names none: "
            f"{INTRINSICS_HINT}"
        )
    if match is None:
        camera = DepthCamera(*intrinsics, TUM_DEPTH_SCALE).with_options(None, depth_scale)
    else:
        camera = FREIBURG_CAMERAS[int(match.group(1))].with_options(intrinsics, depth_scale)
    assumptions = []
    if intrinsics is None:
        assumptions.append(f"Freiburg {match.group(1)}'s camera (the folder's name)")
    if depth_scale is None:
        assumptions.append("TUM's depth unit")
    if assumptions:
        assumed(
            f"{folder.name}: TUM depth frames read with {' and '.join(assumptions)}: "
            f"{camera.describe()}; --intrinsics and --depth-scale say otherwise"
        )
    return camera


def _listed_frames(folder: Path) -> list[DepthFrame]:
    """The frames of poses.txt (`depth/<file> tx ty tz qx qy qz qw`)."""
    path, frames = folder / "poses.txt", []
    for number, words in _lines(path):
        name, *numbers = words
        if len(numbers) != 7:
            message = f"expected 'depth/FILE tx ty tz qx qy qz qw', got {len(words)} words"
            raise FileReadError(path, message, f"line {number}")
        frames.append(DepthFrame(folder / name, _pose(path, number, numbers), _stamp(name)))
    if not frames:
        raise FileReadError(path, "no frames")
    return frames


def _associated_frames(folder: Path) -> list[DepthFrame]:
    """The frames of depth.txt, each with the pose of groundtruth.txt nearest in time within
    MAX_TIME_DIFFERENCE, one to one (TUM's associate.py: closest pairs first)."""
    depth_path, truth_path = folder / "depth.txt", folder / "groundtruth.txt"
    images = []
    for number, words in _lines(depth_path):
        if len(words) != 2:
            raise FileReadError(depth_path, "expected 'time depth/FILE'", f"line {number}")
        images.append((_time(depth_path, number, words[0]), words[1]))
    truth = [
        (_time(truth_path, number, words[0]), number, words[1:])
        for number, words in _lines(truth_path)
    ]
    if not images or not truth:
        raise FileReadError(depth_path if not images else truth_path, "no frames")
    truth_times = np.array([time for time, _, _ in truth])
    order = np.argsort(truth_times)
    by_time = truth_times[order]
    pairs = []
    for i, (time, _) in enumerate(images):
        low = np.searchsorted(by_time, time - MAX_TIME_DIFFERENCE, "left")
        high = np.searchsorted(by_time, time + MAX_TIME_DIFFERENCE, "right")
        pairs += [(abs(truth_times[j] - time), i, j) for j in order[low:high]]
    pairs.sort()
    matched: dict[int, int] = {}
    used: set[int] = set()
    for difference, i, j in pairs:
        if difference < MAX_TIME_DIFFERENCE and i not in matched and j not in used:
            matched[i] = j
            used.add(j)
    if not matched:
        raise FileReadError(
            truth_path,
            f"no pose within {1000 * MAX_TIME_DIFFERENCE:.0f} ms of any frame of depth.txt",
        )
    if len(matched) < len(images):
        assumed(
            f"{folder.name}: {len(images) - len(matched)} of {len(images)} depth frames have no "
            f"ground-truth pose within {1000 * MAX_TIME_DIFFERENCE:.0f} ms and are left out"
        )
    frames = []
    for i in sorted(matched):
        time, name = images[i]
        _, number, numbers = truth[matched[i]]
        if len(numbers) != 7:
            raise FileReadError(
                truth_path, "expected 'time tx ty tz qx qy qz qw'", f"line {number}"
            )
        frames.append(DepthFrame(folder / name, _pose(truth_path, number, numbers), time))
    return frames


def _lines(path: Path) -> list[tuple[int, list[str]]]:
    """(line number, words) of each line of a TUM text file that is not blank or a comment."""
    return [
        (number, line.split())
        for number, line in enumerate(read_text(path).splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]


def _pose(path: Path, number: int, numbers: list[str]) -> np.ndarray:
    """(4, 4) T_world_camera of `tx ty tz qx qy qz qw`; FileReadError naming the line."""
    try:
        tx, ty, tz, qx, qy, qz, qw = map(float, numbers)
        if not np.all(np.isfinite([tx, ty, tz])):
            raise InputError(f"position {tx} {ty} {tz} is not finite")
        T_world_camera = np.eye(4)
        T_world_camera[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
        T_world_camera[:3, 3] = (tx, ty, tz)
    except ValueError as error:  # InputError too
        message = f"expected 'tx ty tz qx qy qz qw' ({error})"
        raise FileReadError(path, message, f"line {number}") from None
    return T_world_camera


def _time(path: Path, number: int, word: str) -> float:
    try:
        time = float(word)
    except ValueError:
        time = float("nan")
    if not np.isfinite(time):
        raise FileReadError(path, f"not a time in seconds: {word!r}", f"line {number}")
    return time


def _stamp(name: str) -> float | None:
    """The time a TUM depth image's name gives (depth/1311877813.991479.png), seconds; None for
    a name that is not a number."""
    try:
        time = float(Path(name).stem)
    except ValueError:
        return None
    return time if np.isfinite(time) else None
