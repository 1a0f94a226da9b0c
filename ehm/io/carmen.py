"""CARMEN logs of 2D laser scans: `FLASER` lines (the old format: n readings over a field of
view the line does not record) and `ROBOTLASER1` lines (each with its own start angle, field
of view, angular step, maximum range and laser pose).

Readings of 0 (Hokuyo's no-return) and at or beyond the maximum range (SICK's 81.83 m) are
no-returns: the beam saw nothing it could range, so it gives neither a hit nor free space
(such rays cross known obstacles far more often than ranged ones), and they are dropped.
"""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_text

# FLASER lines do not say their laser's range; SICK LMS lasers log no-returns at 81.83 m.
FLASER_MAX_RANGE = 81.0
# FLASER lines do not say their field of view either: SICK LMS lasers see half a turn.
FLASER_FOV = np.pi


def read_carmen(path: str | PathLike[str], fov: float | None = None) -> list[Scan]:
    """2D scans of a CARMEN log, one per FLASER or ROBOTLASER1 line, in world frame (the
    laser's pose in the log), each at the line's ipc_timestamp where it has one.

    FLASER `n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp ...`: beam i at
    theta - fov/2 + i fov/n, fov in radians (None: pi, a SICK's half turn).
    ROBOTLASER1 `type start_angle fov step max_range accuracy remission_mode n r_1..r_n m
    [remissions] laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv ... ipc_timestamp`:
    beam i at laser_theta + start_angle + i step.
    No-returns (0, or at the maximum range) are dropped. FileReadError naming the line for a
    malformed line (a pose that is not finite, a reading that is NaN or negative), or for a
    log without laser lines."""
    if fov is not None and not 0 < fov <= 2 * np.pi:
        raise InputError(f"a laser's field of view is in (0, 2 pi] radians, got {fov}")
    scans, n_lines = [], 0
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        words = line.split()
        if not words or words[0] not in ("FLASER", "ROBOTLASER1"):
            continue
        n_lines += 1
        try:
            if words[0] == "FLASER":
                beams = _flaser(words, FLASER_FOV if fov is None else fov)
            else:
                beams = _robotlaser(words)
        except (ValueError, IndexError) as error:
            layout = _LAYOUTS[words[0]]
            message = f"malformed {words[0]} line: expected '{words[0]} {layout}' ({error})"
            raise FileReadError(path, message, f"line {number}") from None
        scan = _scan(*beams)
        if scan is not None:
            scans.append(scan)
    if n_lines == 0:
        raise FileReadError(
            path, "no FLASER or ROBOTLASER1 lines: not a CARMEN log of 2D laser scans"
        )
    return scans


_LAYOUTS = {
    "FLASER": "n r_1..r_n x y theta ...",
    "ROBOTLASER1": "type start_angle fov step max_range accuracy remission_mode n r_1..r_n m "
    "[remissions] laser_x laser_y laser_theta ...",
}


def _flaser(words: list[str], fov: float):
    """(ranges, angles, pose x y theta, max range, time) of a FLASER line."""
    n = int(words[1])
    if not 0 < n <= len(words) - 5:
        raise ValueError(f"{n} readings announced, {max(len(words) - 5, 0)} given")
    ranges = _ranges(words[2 : 2 + n])
    pose = _pose(words[2 + n : 5 + n])
    angles = pose[2] - fov / 2 + np.arange(n) * fov / n
    return ranges, angles, pose, FLASER_MAX_RANGE, _number(words, 8 + n)


def _robotlaser(words: list[str]):
    """(ranges, angles, laser pose x y theta, max range, time) of a ROBOTLASER1 line."""
    if len(words) < 10:
        raise ValueError(f"{len(words)} words")
    start, fov, step, max_range = (float(w) for w in words[2:6])
    n = int(words[8])
    if not 0 < n <= len(words) - 10:
        raise ValueError(f"{n} readings announced, {max(len(words) - 10, 0)} given")
    if not (np.isfinite([start, fov, step, max_range]).all() and step > 0 and max_range > 0):
        raise ValueError(f"start angle {start}, step {step}, maximum range {max_range}")
    ranges = _ranges(words[9 : 9 + n])
    n_remissions = int(words[9 + n])
    if n_remissions < 0:
        raise ValueError(f"{n_remissions} remissions")
    laser = 10 + n + n_remissions
    pose = _pose(words[laser : laser + 3])
    with np.errstate(over="ignore", invalid="ignore"):
        angles = pose[2] + start + np.arange(n) * step
    if not np.all(np.isfinite(angles)):
        raise ValueError(f"start angle {start} and step {step} over {n} readings overflow")
    return ranges, angles, pose, max_range, _number(words, laser + 11)


def _ranges(words: list[str]) -> np.ndarray:
    ranges = np.array(words, dtype=np.float64)
    if np.any(np.isnan(ranges) | (ranges < 0)):
        raise ValueError("readings must be numbers >= 0")
    return ranges


def _pose(words: list[str]) -> np.ndarray:
    pose = np.array(words, dtype=np.float64)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"pose x y theta {pose.tolist()} is not 3 finite numbers")
    return pose


def _scan(
    ranges: np.ndarray, angles: np.ndarray, pose: np.ndarray, max_range: float, time
) -> Scan | None:
    """The scan of one laser line's ranged beams; None when no beam ranged anything."""
    ranged = (ranges > 0) & (ranges < max_range)
    if not ranged.any():
        return None
    x, y, _ = pose
    r, a = ranges[ranged], angles[ranged]
    with np.errstate(over="ignore", invalid="ignore"):  # too far to hold: dropped by Scan
        points = np.column_stack([x + r * np.cos(a), y + r * np.sin(a)])
    return Scan(points, np.array([x, y]), time=time)


def _number(words: list[str], index: int) -> float | None:
    """The number at `index` of a line (its ipc_timestamp), seconds; None for a line that ends
    before it or holds no number there."""
    try:
        value = float(words[index])
    except (IndexError, ValueError):
        return None
    return value if np.isfinite(value) else None
