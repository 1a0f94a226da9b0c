"""Dense data: the virtual room seen by a depth camera, frame after frame, noise-free or with
range noise; its exact occupancy is the room's (ehm.eval.datasets.simulated.virtual_room_scene).

A frame is a pinhole camera's pixels, each a ray from the camera's centre to the first surface
it meets; pixels whose surface lies beyond the camera's range give nothing (as a depth
camera's invalid pixels do) and are left out. At 240 x 180 pixels over 58 degrees, a frame
samples a wall 3 m away every 1.3 cm: finer than the 5 cm the maps are made at.
"""

from __future__ import annotations

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.eval.datasets.simulated import SimulatedDataset, virtual_room_scene

# Where the camera stands and looks in each frame: x, y, z (metres, world frame), yaw (degrees
# from +x towards +y) and pitch (degrees below the horizon), a walk round the room that sees
# every wall and the furniture from two sides.
DENSE_ROOM_POSES = np.array(
    [
        [-2.8, -1.2, 1.3, 30.0, 15.0],
        [-1.5, 0.5, 1.3, 90.0, 20.0],
        [0.0, 1.8, 1.3, 0.0, 20.0],
        [2.0, 1.0, 1.3, -60.0, 25.0],
        [3.0, -0.5, 1.3, -150.0, 20.0],
        [1.5, -2.0, 1.3, 160.0, 15.0],
        [-0.5, -1.0, 1.3, -100.0, 25.0],
        [-2.5, 1.5, 1.3, -45.0, 20.0],
    ]
)


def camera_directions(width: int, height: int, horizontal_fov_deg: float) -> np.ndarray:
    """(height * width, 3) unit directions of a pinhole camera's pixel centres, in its optical
    frame (x right, y down, z forward), row by row."""
    focal = 0.5 * width / np.tan(np.deg2rad(horizontal_fov_deg) / 2.0)
    u = np.arange(width) + 0.5 - 0.5 * width
    v = np.arange(height) + 0.5 - 0.5 * height
    uu, vv = np.meshgrid(u / focal, v / focal)
    rays = np.column_stack([uu.ravel(), vv.ravel(), np.ones(uu.size)])
    return rays / np.linalg.norm(rays, axis=1)[:, None]


def rotation_world_camera(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """(3, 3) rotation from a camera's optical frame to the world frame (z up), for a camera
    turned `yaw_deg` from +x towards +y and tilted `pitch_deg` below the horizon."""
    yaw, pitch = np.deg2rad(yaw_deg), np.deg2rad(pitch_deg)
    forward = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), -np.sin(pitch)])
    right = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    down = np.cross(forward, right)
    return np.column_stack([right, down, forward])


def dense_room(
    seed: int = 0,
    noise_std: float = 0.0,
    width: int = 240,
    height: int = 180,
    max_range: float = 8.0,
) -> SimulatedDataset:
    """Eight depth frames of width x height pixels (58 degrees across) walking round the
    virtual room (DENSE_ROOM_POSES), ranges with Gaussian noise of `noise_std` metres (none
    by default); pixels that see nothing within `max_range` metres are left out. Named
    'dense_room', or 'dense_room_noisy' when noise_std > 0."""
    scene = virtual_room_scene()
    rng = np.random.default_rng(seed)
    pixels = camera_directions(width, height, 58.0)
    scans = []
    for x, y, z, yaw, pitch in DENSE_ROOM_POSES:
        origin = np.array([x, y, z])
        directions = pixels @ rotation_world_camera(yaw, pitch).T
        ranges = scene.raycast(origin, directions)
        seen = ranges <= max_range
        ranges = ranges[seen] + rng.normal(0.0, noise_std, int(seen.sum()))
        scans.append(Scan(origin + directions[seen] * ranges[:, None], origin))
    return SimulatedDataset("dense_room_noisy" if noise_std > 0 else "dense_room", scans, scene)
