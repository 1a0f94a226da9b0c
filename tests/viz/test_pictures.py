"""PNG pictures of meshes and grids."""

import numpy as np
import pytest
from PIL import Image

from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.viz.pictures import grid_picture, mesh_picture
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
