"""Walking a ray through a grid of cubic cells, one cell after the next in the order the ray
enters them (Amanatides and Woo 1987), for the compiled kernels that march rays."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def walk_setup(origin, direction, side, cell, step, next_t, delta):  # pragma: no cover - compiled
    """Prepare a walk of the ray origin + t direction ((d,) metres, unit) from `cell` (d,)
    int64, cells of `side` metres: fills step (d,) int64, the cell step along each axis,
    next_t (d,), the distance at which the ray leaves the cell across each axis, and delta
    (d,), the distance between two such crossings (inf along axes the ray does not move on)."""
    for a in range(len(cell)):
        if direction[a] > 0.0:
            step[a] = 1
            next_t[a] = ((cell[a] + 1) * side - origin[a]) / direction[a]
            delta[a] = side / direction[a]
        elif direction[a] < 0.0:
            step[a] = -1
            next_t[a] = (cell[a] * side - origin[a]) / direction[a]
            delta[a] = -side / direction[a]
        else:
            step[a] = 0
            next_t[a] = np.inf
            delta[a] = np.inf


@numba.njit(cache=True, inline="always")
def walk_step(cell, step, next_t, delta):  # pragma: no cover - compiled
    """Move `cell` to the next cell the ray enters; returns the distance at which it enters."""
    axis = 0
    for a in range(1, len(cell)):
        if next_t[a] < next_t[axis]:
            axis = a
    t = next_t[axis]
    next_t[axis] += delta[axis]
    cell[axis] += step[axis]
    return t
