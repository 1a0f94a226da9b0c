"""A ball known exactly, on a grid of voxels: the log-odds the tests of surfels and distance
fields read."""

import numpy as np

RESOLUTION = 0.1
ORIGIN = np.array([-1.0, -1.0, -1.0])
SHAPE = (20, 20, 20)


def centres(shape=SHAPE, origin=ORIGIN, resolution=RESOLUTION):
    """(X, Y, Z, 3) voxel centres, metres."""
    axes = [origin[a] + (np.arange(n) + 0.5) * resolution for a, n in enumerate(shape)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


def ball_log_odds(points, centre=(0.0, 0.0, 0.0), radius=0.45, slope=20.0):
    """Log-odds rising linearly into a ball: the level 0 is its sphere."""
    return slope * (radius - np.linalg.norm(points - centre, axis=-1))
