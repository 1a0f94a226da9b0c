"""CARMEN logs of 2D laser scans: one `FLASER n r_1..r_n x y theta ...` line per scan."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.scan import Scan


def read_carmen(
    path: str | PathLike[str], max_range: float = 81.0, fov: float = np.pi
) -> list[Scan]:
    """2D scans of a CARMEN log: each `FLASER n r_1..r_n x y theta ...` line, beam i at angle
    theta - fov/2 + i fov/n; readings >= max_range (sensor dropouts) are dropped."""
    scans = []
    for number, line in enumerate(Path(path).read_text().splitlines(), start=1):
        words = line.split()
        if not words or words[0] != "FLASER":
            continue
        try:
            n = int(words[1])
            ranges = np.array(words[2 : 2 + n], dtype=np.float64)
            x, y, theta = map(float, words[2 + n : 5 + n])
        except (ValueError, IndexError) as error:
            raise ValueError(f"{path}:{number}: malformed FLASER line ({error})") from error
        angles = theta - fov / 2 + np.arange(n) * fov / n
        keep = ranges < max_range
        points = np.column_stack([x + ranges * np.cos(angles), y + ranges * np.sin(angles)])[keep]
        if len(points):
            scans.append(Scan(points, np.array([x, y])))
    return scans
