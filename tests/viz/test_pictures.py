"""PNG pictures of meshes and grids."""

import matplotlib
import numpy as np
import pytest
from PIL import Image

import ehm
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.viz.pictures import grid_picture, mesh_picture, occupancy_slices
from ehm.viz.render import Camera


def test_pictures_are_written_off_screen(tmp_path, two_squares):
    vertices, faces = two_squares
    mesh_picture(vertices, faces, tmp_path / "mesh.png", Camera(width=300, height=200))
    assert Image.open(tmp_path / "mesh.png").size[0] > 300
    with pytest.raises(ValueError, match="nothing to draw"):
        mesh_picture(vertices, faces, tmp_path / "none.png", cut_above=-1.0)
    grid = OccupancyGrid(np.zeros(2), 0.1, (30, 20))
    grid.scores[10:20, 5:8] = 3.0
    grid_picture(grid, tmp_path / "grid.png")
    assert Image.open(tmp_path / "grid.png").size[0] > 300


def test_std_slices_show_unobserved_space_at_the_top_of_the_scale(tmp_path, plan):
    hilbert_map = ehm.HilbertMap().fit(plan.scans)
    low, high = np.array([-12.0, -12.0]), np.array([12.0, 12.0])  # well beyond the plan
    occupancy_slices(hilbert_map, low, high, tmp_path / "std.png", resolution=0.1, std=True)
    pixels = np.asarray(Image.open(tmp_path / "std.png").convert("RGB")).reshape(-1, 3)
    # Never-observed space has the prior's std, the top of the colour scale (magma's last
    # colour); observed space is darker.
    top = np.round(255 * np.array(matplotlib.colormaps["magma"](1.0)[:3]))
    bottom = np.round(255 * np.array(matplotlib.colormaps["magma"](0.1)[:3]))
    assert np.mean(np.all(np.abs(pixels - top) <= 2, axis=1)) > 0.2
    assert np.mean(np.all(np.abs(pixels - bottom) <= 30, axis=1)) > 0.005
