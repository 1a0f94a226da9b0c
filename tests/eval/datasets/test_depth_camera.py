"""The virtual room seen by a depth camera: dense frames, noise-free or noisy."""

import numpy as np

from ehm.eval.datasets import load_dataset
from ehm.eval.datasets.depth_camera import (
    DENSE_ROOM_POSES,
    camera_directions,
    dense_room,
    rotation_world_camera,
)


def test_a_cameras_pixels_span_its_field_of_view_row_by_row():
    rays = camera_directions(4, 3, 90.0)
    assert rays.shape == (12, 3)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    # Focal length 2 pixels: the first pixel centre is 1.5 pixels left of and 1 above the axis.
    np.testing.assert_allclose(rays[0], np.array([-1.5, -1.0, 2.0]) / np.sqrt(7.25))
    assert np.all(rays[:4, 1] < 0) and np.all(np.diff(rays[:4, 0]) > 0)


def test_the_camera_looks_along_yaw_and_below_the_horizon_by_pitch():
    rotation = rotation_world_camera(90.0, 30.0)
    np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(rotation), 1.0)
    forward, down = rotation @ [0.0, 0.0, 1.0], rotation @ [0.0, 1.0, 0.0]
    np.testing.assert_allclose(forward, [0.0, np.cos(np.pi / 6), -0.5], atol=1e-12)
    assert down[2] < 0  # the image's rows run downwards


def test_noise_free_frames_end_on_the_rooms_surfaces():
    data = dense_room(width=48, height=36)
    assert data.name == "dense_room" and len(data.scans) == len(DENSE_ROOM_POSES)
    for scan in data.scans:
        assert scan.hit_mask.all() and 0.9 * 48 * 36 < len(scan) <= 48 * 36
        offsets = scan.points_world - scan.origin
        directions = offsets / np.linalg.norm(offsets, axis=1)[:, None]
        beyond = data.scene.occupied(scan.points_world + 1e-4 * directions)
        before = data.scene.occupied(scan.points_world - 1e-4 * directions)
        assert beyond.mean() > 0.99 and not before.any()


def test_noisy_frames_scatter_about_the_noise_free_ones():
    clean, noisy = dense_room(width=48, height=36), dense_room(noise_std=0.01, width=48, height=36)
    assert noisy.name == "dense_room_noisy"
    offsets = [
        np.linalg.norm(n.points_world - c.points_world, axis=1)
        for n, c in zip(noisy.scans, clean.scans, strict=True)
    ]
    assert 0.007 < np.sqrt(np.mean(np.concatenate(offsets) ** 2)) < 0.013
    assert len(load_dataset("dense_room_noisy")) == len(DENSE_ROOM_POSES)
