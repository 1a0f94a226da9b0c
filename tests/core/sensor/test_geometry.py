"""Rigid transforms."""

import numpy as np
import pytest

import ehm
from ehm.core.sensor.geometry import quaternion_to_matrix, transform_points


def test_quaternions_of_known_rotations():
    np.testing.assert_allclose(quaternion_to_matrix(1, 0, 0, 0), np.eye(3))
    half = np.sqrt(0.5)
    quarter_turn_z = quaternion_to_matrix(half, 0, 0, half)
    np.testing.assert_allclose(quarter_turn_z @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # Not normalised: the same rotation.
    np.testing.assert_allclose(quaternion_to_matrix(2 * half, 0, 0, 2 * half), quarter_turn_z)
    half_turn_x = quaternion_to_matrix(0, 1, 0, 0)
    np.testing.assert_allclose(half_turn_x, np.diag([1.0, -1.0, -1.0]), atol=1e-15)
    for w, x, y, z in [(0, 0, 0, 0), (np.nan, 0, 0, 1), (np.inf, 0, 0, 0)]:
        with pytest.raises(
            ehm.InputError, match=r"quaternion \[.*\] \(w, x, y, z\) is no rotation"
        ):
            quaternion_to_matrix(w, x, y, z)


def test_random_quaternions_give_rotations(rng):
    for q in rng.normal(size=(20, 4)):
        rotation = quaternion_to_matrix(*q)
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)


def test_transform_points_rotates_then_translates(rng):
    T_world_sensor = np.eye(4)
    T_world_sensor[:3, :3] = quaternion_to_matrix(np.sqrt(0.5), 0, 0, np.sqrt(0.5))
    T_world_sensor[:3, 3] = [1.0, 2.0, 3.0]
    points_sensor = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    expected = np.array([[1.0, 3.0, 3.0], [1.0, 2.0, 5.0]])
    np.testing.assert_allclose(transform_points(T_world_sensor, points_sensor), expected)
    # A 3 x 4 pose, as KITTI writes them, gives the same.
    np.testing.assert_allclose(transform_points(T_world_sensor[:3], points_sensor), expected)
