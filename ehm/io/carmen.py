"""CARMEN logs of 2D laser scans: one `FLASER n r_1..r_n x y theta ...` line per scan."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError
from ehm.io.files import read_text


def read_carmen(
    path: str | PathLike[str], max_range: float = 81.0, fov: float = np.pi
) -> list[Scan]:
    """2D scans of a CARMEN log: each `FLASER n r_1..r_n x y theta ...` line, beam i at angle
    theta - fov/2 + i fov/n; readings >= max_range (sensor dropouts) are dropped. Each scan's
    time is the line's ipc_timestamp (after x y theta and the odometry pose), where it has one.
    FileReadError naming the line for a malformed FLASER line (a pose that is not finite, a
    reading that is NaN or negative), or for a log without one."""
    scans, n_lines = [], 0
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        words = line.split()
        if not words or words[0] != "FLASER":
            continue
        n_lines += 1
        try:
            n = int(words[1])
            if not 0 < n <= len(words) - 5:
                raise ValueError(f"{n} readings announced, {max(len(words) - 5, 0)} given")
            ranges = np.array(words[2 : 2 + n], dtype=np.float64)
            x, y, theta = pose = np.array(words[2 + n : 5 + n], dtype=np.float64)
            if not np.all(np.isfinite(pose)):
                raise ValueError(f"pose x y theta {pose.tolist()} is not finite")
            if np.any(np.isnan(ranges) | (ranges < 0)):
                raise ValueError("readings must be numbers >= 0")
            keep = ranges < max_range
            ranges, angles = ranges[keep], (theta - fov / 2 + np.arange(n) * fov / n)[keep]
            points = np.column_stack([x + ranges * np.cos(angles), y + ranges * np.sin(angles)])
            if keep.any():
                scans.append(Scan(points, np.array([x, y]), time=_ipc_time(words, n)))
        except (ValueError, IndexError) as error:  # InputError too: a bad origin
            message = f"malformed FLASER line: expected 'FLASER n r_1..r_n x y theta' ({error})"
            raise FileReadError(path, message, f"line {number}") from None
    if n_lines == 0:
        raise FileReadError(path, "no FLASER lines: not a CARMEN log of 2D laser scans")
    return scans


def _ipc_time(words: list[str], n: int) -> float | None:
    """The ipc_timestamp of a FLASER line of n readings (`... x y theta odom_x odom_y odom_theta
    ipc_timestamp ...`), seconds; None for a line that ends before it or holds no number."""
    try:
        time = float(words[8 + n])
    except (IndexError, ValueError):
        return None
    return time if np.isfinite(time) else None
