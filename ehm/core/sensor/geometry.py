"""Rigid transforms."""

from __future__ import annotations

import numpy as np

from ehm.errors import InputError


def quaternion_to_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    """(3, 3) rotation matrix of a quaternion (normalised first)."""
    q = np.array([w, x, y, z], dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # a norm that is not finite is refused
        norm = np.linalg.norm(q)
    if not 0 < norm < np.inf:
        raise InputError(f"quaternion {q.tolist()} (w, x, y, z) is no rotation")
    w, x, y, z = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def transform_points(T_world_sensor: np.ndarray, points_sensor: np.ndarray) -> np.ndarray:
    """(N, 3) points in world frame from (N, 3) points in sensor frame and a (3|4, 4) pose.
    Points that overflow become infinite (a Scan drops them)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return points_sensor @ T_world_sensor[:3, :3].T + T_world_sensor[:3, 3]
