"""Point coordinates out of the structured records of binary point-cloud files."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def xyz_columns(records: np.ndarray, path: Path) -> np.ndarray:
    """(N, 3) float64 of the x, y and z fields of `records`; ValueError naming `path` when a
    field is missing."""
    missing = [f for f in "xyz" if f not in (records.dtype.names or ())]
    if missing:
        raise ValueError(f"{path}: no {', '.join(missing)} field")
    return np.column_stack([records[f].astype(np.float64) for f in "xyz"])
