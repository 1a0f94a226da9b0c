"""Point clouds as text: `x y z` per line, metres (a few more columns, intensity, colour or
normals, ignored), optionally compressed."""

from __future__ import annotations

import io
import warnings
from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.io.files import read_text

# x y z and what point files add after them (intensity, colour, normals, a label); a line of
# more columns is some other table, a laser log or a matrix, not a point.
MAX_COLUMNS = 12


def read_xyz(path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 points, metres: whitespace-separated `x y z` per line (extra columns
    ignored, `#` starts a comment), also compressed (ehm.io.files.read_text). FileReadError naming
    the row for a line that is not three numbers or has more than MAX_COLUMNS, or for a file
    without points."""
    text = read_text(path)
    _check_columns(path, text)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # numpy's "empty input file"
            points = np.loadtxt(io.StringIO(text), usecols=(0, 1, 2), ndmin=2, comments="#")
    except ValueError as error:
        raise FileReadError(path, f"expected 'x y z' numbers on each line: {error}") from None
    if len(points) == 0:
        raise FileReadError(path, "no points (expected 'x y z' numbers on each line)")
    return points.astype(np.float64)


def _check_columns(path: str | PathLike[str], text: str) -> None:
    """FileReadError naming the first point line with more than MAX_COLUMNS columns."""
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split("#")[0].split()
        if words:
            if len(words) > MAX_COLUMNS:
                raise FileReadError(
                    path,
                    f"{len(words)} columns, and a point is 'x y z' and at most "
                    f"{MAX_COLUMNS - 3} more (intensity, colour, normals): not a point file; "
                    "give its format (--format)",
                    f"line {number}",
                )
            return
