import numpy as np
import pytest
from PIL import Image

from ehm.grid import OccupancyGrid
from ehm.io.mesh_file import write_ply_mesh
from ehm.io.pointcloud import read_ply
from ehm.plots import grid_picture, mesh_picture
from ehm.render import Camera, rasterize, rasterize_reference, render_mesh


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


def test_ply_round_trip(tmp_path):
    vertices, faces = ball_grid(np.array([0.7, 1.05, 1.7]), 0.3).mesh()
    colors = np.random.default_rng(0).integers(0, 256, vertices.shape).astype(np.uint8)
    path = tmp_path / "ball.ply"
    write_ply_mesh(path, vertices, faces, colors)
    np.testing.assert_array_equal(read_ply(path), vertices.astype(np.float32))
    data = path.read_bytes()
    header, body = data.split(b"end_header\n", 1)
    assert b"format binary_little_endian 1.0" in header
    assert f"element face {len(faces)}".encode() in header
    vertex_bytes = len(vertices) * 15
    records = np.frombuffer(body[vertex_bytes:], dtype=[("n", "u1"), ("i", "<i4", (3,))])
    assert np.all(records["n"] == 3)
    np.testing.assert_array_equal(records["i"], faces)
    vertex_records = np.frombuffer(
        body[:vertex_bytes], dtype=[("p", "<f4", (3,)), ("c", "u1", (3,))]
    )
    np.testing.assert_array_equal(vertex_records["c"], colors)
    with pytest.raises(ValueError, match="outside"):
        write_ply_mesh(path, vertices, faces + len(vertices))


def test_compiled_rasterizer_matches_reference(rng):
    screen = np.column_stack(
        [rng.uniform(-20, 140, 300), rng.uniform(-20, 100, 300), rng.normal(size=300)]
    )
    faces = rng.integers(0, 300, (400, 3))
    faces[:5, 2] = faces[:5, 1]  # degenerate faces draw nothing
    colors = rng.uniform(0, 1, (400, 3))
    images = [np.ones((90, 120, 3)), np.ones((90, 120, 3))]
    depths = [np.full((90, 120), -np.inf), np.full((90, 120), -np.inf)]
    rasterize(screen, faces, colors, images[0], depths[0])
    rasterize_reference(screen, faces, colors, images[1], depths[1])
    assert np.isfinite(depths[0]).mean() > 0.5
    np.testing.assert_array_equal(depths[0], depths[1])
    np.testing.assert_array_equal(images[0], images[1])


def two_squares() -> tuple[np.ndarray, np.ndarray]:
    """A 2 x 2 m floor at z = 0 and a 1 x 1 m plate above its middle at z = 1."""
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    floor = np.column_stack([2 * square, np.zeros(4)])
    plate = np.column_stack([square + 0.5, np.ones(4)])
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    return np.vstack([floor, plate]), faces


def test_render_from_above_shows_nearest_surface_coloured_by_height():
    vertices, faces = two_squares()
    image, covered = render_mesh(
        vertices, faces, Camera(azimuth=0.0, elevation=89.0, width=200, height=200)
    )
    assert covered.mean() > 0.8 and np.all(image[~covered] == 255)
    centre, corner = image[100, 100].astype(int), image[20, 20].astype(int)
    assert not np.array_equal(centre, corner)  # the plate hides the floor in the middle
    # turbo: red-brown at the top of the height range, dark blue at the bottom
    assert centre[0] > centre[2] and corner[2] > corner[0]


def test_camera_is_validated():
    with pytest.raises(ValueError, match="elevation"):
        Camera(elevation=90.0)


def test_pictures_are_written_off_screen(tmp_path):
    vertices, faces = two_squares()
    mesh_picture(vertices, faces, tmp_path / "mesh.png", Camera(width=300, height=200))
    assert Image.open(tmp_path / "mesh.png").size[0] > 300
    with pytest.raises(ValueError, match="nothing to draw"):
        mesh_picture(vertices, faces, tmp_path / "none.png", cut_above=-1.0)
    grid = OccupancyGrid(np.zeros(2), 0.1, (30, 20))
    grid.scores[10:20, 5:8] = 3.0
    grid_picture(grid, tmp_path / "grid.png")
    assert Image.open(tmp_path / "grid.png").size[0] > 300
