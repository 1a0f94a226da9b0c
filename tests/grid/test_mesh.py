"""Marching-cubes meshes of grids."""

import numpy as np
import pytest

from ehm.grid.occupancy_grid import OccupancyGrid


def ball_grid(centre, radius: float, resolution: float = 0.05) -> OccupancyGrid:
    """A grid whose log-odds fall linearly with the distance from a ball's surface."""
    grid = OccupancyGrid(np.array([-0.3, 0.2, 1.0]), resolution, (40, 36, 30))
    distance = np.linalg.norm(grid.centers() - centre, axis=1)
    grid.scores[...] = (4.0 * (radius - distance)).reshape(grid.shape)
    return grid


def test_mesh_of_a_ball_lies_on_its_surface_in_world_coordinates():
    centre = np.array([0.7, 1.05, 1.7])
    vertices, faces = ball_grid(centre, 0.45).mesh(level=0.5)
    distance = np.linalg.norm(vertices - centre, axis=1)
    assert len(faces) > 1000 and faces.dtype == np.int64 and faces.max() < len(vertices)
    np.testing.assert_allclose(distance, 0.45, atol=0.01)
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    outward = np.einsum("fa,fa->f", normals, corners.mean(axis=1) - centre)
    assert np.mean(outward > 0) > 0.99  # normals point from occupied to free space
    # A lower level moves the surface outward: p = 0.25 where 4 (r - d) = log(1/3).
    vertices, _ = ball_grid(centre, 0.45).mesh(level=0.25)
    expected = 0.45 - np.log(1 / 3) / 4
    np.testing.assert_allclose(np.linalg.norm(vertices - centre, axis=1), expected, atol=0.01)


def test_mesh_edge_cases():
    grid = OccupancyGrid(np.zeros(3), 0.1, (5, 5, 5))
    vertices, faces = grid.mesh()  # all unknown: no surface
    assert vertices.shape == (0, 3) and faces.shape == (0, 3)
    with pytest.raises(ValueError, match="between 0 and 1"):
        grid.mesh(level=1.0)
    with pytest.raises(ValueError, match="needs a 3D grid"):
        OccupancyGrid(np.zeros(2), 0.1, (5, 5)).mesh()
