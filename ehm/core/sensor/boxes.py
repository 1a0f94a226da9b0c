"""Axis-aligned boxes and the part of each ray inside one (the slab method)."""

from __future__ import annotations

import numpy as np


def ray_box_intervals(
    origin: np.ndarray, directions: np.ndarray, lengths: np.ndarray, box: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where rays run inside a box: (n,) start and end distances along each ray, metres from
    `origin`, within [0, lengths]; start > end where a ray misses the box.

    origin: (d,) metres, world frame, or (n, d): each ray's own; directions: (n, d) unit
    vectors; lengths: (n,) metres;
    box: (2, d) metres, [low corner, high corner]. A ray that only touches a face counts as
    inside over that point.
    """
    n = len(directions)
    start, end = np.zeros(n), np.asarray(lengths, dtype=np.float64).copy()
    for axis in range(directions.shape[1]):
        step = directions[:, axis]
        low, high = box[0, axis] - origin[..., axis], box[1, axis] - origin[..., axis]
        moving = step != 0.0
        with np.errstate(divide="ignore", invalid="ignore"):  # rays parallel: see below
            t_low, t_high = low / step, high / step
        near = np.where(moving, np.minimum(t_low, t_high), -np.inf)
        far = np.where(moving, np.maximum(t_low, t_high), np.inf)
        # A ray parallel to this axis' faces runs between them or nowhere in the box.
        far = np.where(moving | ((low <= 0.0) & (high >= 0.0)), far, -np.inf)
        np.maximum(start, near, out=start)
        np.minimum(end, far, out=end)
    return start, end


def points_in_box(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(n,) bool: which of (n, d) points, metres, lie in `box` ((2, d), faces included)."""
    return np.all((points >= box[0]) & (points <= box[1]), axis=1)
