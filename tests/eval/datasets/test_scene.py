"""Analytic scenes: exact occupancy and distances."""

import numpy as np

from ehm.eval.datasets.scene import Scene


def test_surface_distance_by_hand():
    scene = Scene(
        np.array([[0.0, 0.0, 0.0]]),
        np.array([[2.0, 1.0, 1.0]]),
        np.array([[5.0, 0.0, 0.0]]),
        np.array([1.0]),
    )
    points = np.array(
        [
            [1.0, 0.5, 0.5],  # box centre: 0.5 below the faces at y and z
            [1.0, 0.5, 1.3],  # 0.3 above the box's top
            [3.0, 2.0, 1.0],  # off the box's edge x = 2, y = 1 at z = 1
            [5.0, 0.0, 0.2],  # inside the ball, 0.8 from its surface
            [5.0, 3.0, 0.0],  # 2.0 outside the ball
        ]
    )
    np.testing.assert_allclose(
        scene.surface_distance(points), [0.5, 0.3, np.sqrt(2.0), 0.8, 2.0], atol=1e-12
    )
    assert np.all(scene.surface_distance(points) >= 0.0)
