"""Point coordinates out of the records of point-cloud files, and counting their rows."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.errors import FileReadError


def xyz_columns(records: np.ndarray, path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 of the x, y and z fields of structured `records`; FileReadError naming
    `path` when a field is missing."""
    missing = [f for f in "xyz" if f not in (records.dtype.names or ())]
    if missing:
        raise FileReadError(path, f"no {', '.join(missing)} field")
    with np.errstate(invalid="ignore"):  # values that are not numbers become NaN, then dropped
        return np.column_stack([records[f].astype(np.float64) for f in "xyz"])


def ascii_rows(
    body: bytes, n_rows: int, n_columns: int, path: str | PathLike[str], first_line: int
) -> np.ndarray:
    """(n_rows, n_columns) float64 of the first `n_rows` lines of whitespace-separated numbers in
    `body`, whose first line is line `first_line` of the file; FileReadError naming the line
    when there are fewer rows than announced, or a row is not `n_columns` numbers."""
    lines = body.decode("ascii", "replace").splitlines()[:n_rows]
    if len(lines) < n_rows:
        raise FileReadError(path, f"truncated: {n_rows} points announced, {len(lines)} found")
    try:
        rows = np.loadtxt(lines, ndmin=2, comments=None)
        if rows.shape == (n_rows, n_columns):
            return rows
    except ValueError:
        pass
    for number, line in enumerate(lines):
        problem = _row_problem(line.split(), n_columns)
        if problem:
            message = f"expected {n_columns} numbers per point, got {line[:60]!r} ({problem})"
            raise FileReadError(path, message, f"line {first_line + number}")
    raise FileReadError(path, f"expected {n_rows} rows of {n_columns} numbers")


def _row_problem(words: list[str], n_columns: int) -> str | None:
    """What is wrong with one row of numbers, or None."""
    if len(words) != n_columns:
        return f"{len(words)} numbers"
    try:
        np.array(words, dtype=np.float64)
    except ValueError as error:
        return str(error)
    return None
