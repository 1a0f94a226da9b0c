"""Fixtures of the picture tests."""

import numpy as np
import pytest


@pytest.fixture
def two_squares() -> tuple[np.ndarray, np.ndarray]:
    """A 2 x 2 m floor at z = 0 and a 1 x 1 m plate above its middle at z = 1: vertices (8, 3)
    and faces (4, 3)."""
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    floor = np.column_stack([2 * square, np.zeros(4)])
    plate = np.column_stack([square + 0.5, np.ones(4)])
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    return np.vstack([floor, plate]), faces
