"""Query points from files: .npy arrays or comma-separated text, (n, d) metres, world frame."""

from __future__ import annotations

import io
import warnings
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.errors import FileReadError
from ehm.io.files import read_bytes, read_text


def read_points(path: str | PathLike[str], dim: int) -> np.ndarray:
    """(n, dim) float64 points of a .npy file or of comma-separated text (one point per line,
    `#` starts a comment). FileReadError naming the row for text that is not `dim` numbers,
    or for an array of another shape."""
    path = Path(path)
    if path.suffix.lower() == ".npy":
        data = read_bytes(path)
        try:
            points = np.load(io.BytesIO(data), allow_pickle=False)
        except Exception as error:
            # NumPy's header parser fails in many ways (SyntaxError, TokenError, ValueError,
            # EOFError, ...) on bytes that are not an array file.
            raise FileReadError(path, f"not a NumPy array file ({error!r})") from None
    else:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # numpy's "empty input file"
                text = io.StringIO(read_text(path))
                points = np.loadtxt(text, delimiter=",", ndmin=2, comments="#")
        except ValueError as error:
            raise FileReadError(
                path, f"expected {dim} comma-separated numbers per line, no header ({error})"
            ) from None
    if points.ndim != 2 or points.shape[1] != dim or points.dtype.kind not in "fiu":
        raise FileReadError(
            path, f"expected points of shape (n, {dim}), got {points.dtype} {points.shape}"
        )
    return points.astype(np.float64)
