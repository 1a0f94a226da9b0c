"""Marching-cubes meshes of grids: on the surface, closed, wound toward free space."""

import numpy as np
import pytest

from ehm.grid.mesh import marching_cubes
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


def directed_edges(faces: np.ndarray) -> np.ndarray:
    return np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])


def assert_closed_and_wound_alike(faces: np.ndarray) -> None:
    """Every edge joins two faces, which run along it in opposite directions."""
    edges = directed_edges(faces)
    _, directed_uses = np.unique(edges, axis=0, return_counts=True)
    _, uses = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    assert np.all(uses == 2) and np.all(directed_uses == 1)


def test_a_ball_is_a_closed_surface_of_its_area_and_volume():
    centre, radius = np.array([0.7, 1.05, 1.7]), 0.45
    vertices, faces = ball_grid(centre, radius).mesh()
    assert_closed_and_wound_alike(faces)
    corners = vertices[faces]
    crossed = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(crossed, axis=1).sum()
    volume = np.einsum("fa,fa->", corners[:, 0] - centre, crossed) / 6.0  # divergence theorem
    np.testing.assert_allclose(area, 4 * np.pi * radius**2, rtol=0.03)
    np.testing.assert_allclose(volume, 4 / 3 * np.pi * radius**3, rtol=0.01)


def test_occupied_voxels_in_unknown_space_close_over_the_level():
    # Unknown space reads exactly 0.5, the level: crossings meet at those voxels' centres.
    rng = np.random.default_rng(3)
    probability = np.full((12, 11, 10), 0.5)
    probability[2:10, 2:9, 2:8] = np.where(rng.random((8, 7, 6)) < 0.6, 0.9, 0.5)
    probability[5, 5, 5] = 0.2  # a free voxel inside
    vertices, faces = marching_cubes(probability, np.zeros(3), 0.1)
    assert len(faces) > 100
    used = np.unique(faces)
    assert len(used) == len(vertices)  # every vertex belongs to a face
    edges = np.sort(directed_edges(faces), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert np.all(uses % 2 == 0)  # closed: a surface may touch itself where voxels meet at corners


def test_every_cube_case_makes_a_closed_surface():
    # One cube of the 256 cases inside free space: the surface around its occupied corners.
    for case in range(256):
        probability = np.full((4, 4, 4), 0.1)
        bits = [(case >> c) & 1 for c in range(8)]
        for c, bit in enumerate(bits):
            probability[1 + (c & 1), 1 + (c >> 1 & 1), 1 + (c >> 2 & 1)] = 0.9 if bit else 0.1
        _, faces = marching_cubes(probability, np.zeros(3), 1.0)
        if case:
            assert_closed_and_wound_alike(faces)
