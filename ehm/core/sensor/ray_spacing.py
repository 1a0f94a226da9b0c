"""How far apart a scan's rays are, as an angle: the square root of the solid angle its rays
cover over their number in 3D (the geometric mean of the gaps between rings and between the
rays along a ring of a spinning LiDAR), the angle they cover over their number in 2D.

The covered angle is counted in cells of SPACING_CELL_DEGREES on the sphere (equal-area:
azimuth and the sine of elevation) or the circle, so a field of view with gaps, a LiDAR's
blind cone or a depth camera's frustum, counts what its rays reach only.
"""

from __future__ import annotations

import numpy as np

SPACING_CELL_DEGREES = 4.0
"""Side of the cells that count the angle a scan's rays cover: wider than the rings of sparse
LiDARs (2 degrees apart on 16 beams), so cells between rings are not left out."""


def angular_spacing(directions: np.ndarray, scan_of: np.ndarray) -> np.ndarray:
    """(n,) float64 radians: the spacing of the rays of each ray's scan. directions: (n, d)
    unit vectors, d 2 or 3; scan_of: (n,) int64, the scan of each ray, 0 to the number of
    scans - 1."""
    n, dim = directions.shape
    if n == 0:
        return np.zeros(0)
    cell = np.radians(SPACING_CELL_DEGREES)
    azimuths = int(np.ceil(2.0 * np.pi / cell))
    turn = np.arctan2(directions[:, 1], directions[:, 0]) + np.pi
    column = np.minimum((turn / (2.0 * np.pi) * azimuths).astype(np.int64), azimuths - 1)
    # Rows of cells by the sine of elevation, -1 to 1, in steps of a cell; one row in 2D.
    heights = 1 if dim == 2 else int(np.ceil(2.0 / cell))
    row = np.zeros(n, dtype=np.int64)
    if dim == 3:
        sine = np.clip(directions[:, 2], -1.0, 1.0)
        row = np.minimum(((sine + 1.0) / 2.0 * heights).astype(np.int64), heights - 1)
    cells, n_cells = row * azimuths + column, heights * azimuths
    cell_angle = 2.0 * np.pi / azimuths * (1.0 if dim == 2 else 2.0 / heights)
    # Counted, not sorted: a batch's rays meet a few thousand cells of each of its scans.
    n_scans = int(scan_of.max()) + 1
    met = np.bincount(scan_of * n_cells + cells, minlength=n_scans * n_cells)
    covered_angle = np.count_nonzero(met.reshape(n_scans, n_cells), axis=1) * cell_angle
    rays = np.maximum(np.bincount(scan_of, minlength=n_scans), 1)
    spacing = covered_angle / rays if dim == 2 else np.sqrt(covered_angle / rays)
    return spacing[scan_of]
