"""Point clouds as text: `x y z` per line, metres (extra columns ignored), optionally bzip2."""

from __future__ import annotations

import bz2
from os import PathLike
from pathlib import Path

import numpy as np


def read_xyz(path: str | PathLike[str]) -> np.ndarray:
    """Whitespace-separated `x y z` per line (extra columns ignored); .bz2 is decompressed."""
    path = Path(path)
    opener = bz2.open if path.suffix == ".bz2" else open
    with opener(path, "rt") as stream:
        points = np.loadtxt(stream, usecols=(0, 1, 2), ndmin=2, comments="#")
    return points.astype(np.float64)
