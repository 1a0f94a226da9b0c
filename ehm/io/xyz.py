"""Point clouds as text: `x y z` per line, metres (extra columns ignored), optionally bzip2."""

from __future__ import annotations

import io
import warnings
from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.io.files import read_text


def read_xyz(path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 points, metres: whitespace-separated `x y z` per line (extra columns
    ignored, `#` starts a comment), also compressed (ehm.io.files.read_text). FileReadError naming
    the row for a line that is not three numbers, or for a file without points."""
    text = read_text(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # numpy's "empty input file"
            points = np.loadtxt(io.StringIO(text), usecols=(0, 1, 2), ndmin=2, comments="#")
    except ValueError as error:
        raise FileReadError(path, f"expected 'x y z' numbers on each line: {error}") from None
    if len(points) == 0:
        raise FileReadError(path, "no points (expected 'x y z' numbers on each line)")
    return points.astype(np.float64)
