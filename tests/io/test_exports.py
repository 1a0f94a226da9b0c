"""Exports read back by the tools they are for: OctoMap trees through octomap-python,
map_server images, point clouds through the project's readers."""

import numpy as np
import pytest
from PIL import Image

import ehm
from ehm.grid.bounds import aligned_bounds
from ehm.grid.navigation import FREE, OCCUPIED, UNKNOWN, NavigationGrid, navigation_grid
from ehm.io.exports import (
    OCTOMAP_BYTES_PER_VOXEL,
    occupied_voxels,
    write_map_server,
    write_octomap,
    write_point_cloud,
)
from ehm.io.pcd import read_pcd
from ehm.io.ply import read_ply

octomap = pytest.importorskip("octomap")


@pytest.fixture(scope="module")
def room_grid(room_map):
    bounds = aligned_bounds(np.array([[-2.0, -2.0, 0.0], [2.0, 2.0, 2.6]]), 0.1)
    return room_map.grid(bounds, 0.1)


def tree_occupancy(tree, centres):
    """Each centre's occupancy in the tree, NaN where the tree has no node."""
    found = np.full(len(centres), np.nan)
    for i, centre in enumerate(centres):
        try:
            found[i] = tree.search(centre).getOccupancy()
        except octomap.NullPointerException:
            continue
    return found


def voxel_centres(grid):
    index = np.indices(grid.shape).reshape(3, -1).T
    return grid.origin + (index + 0.5) * grid.resolution


def test_ot_files_keep_each_known_voxel_probability(room_grid, tmp_path):
    known = write_octomap(room_grid, tmp_path / "room.ot")
    tree = octomap.OcTree.read(str(tmp_path / "room.ot").encode())
    centres = voxel_centres(room_grid)
    read = tree_occupancy(tree, centres)
    is_known = (room_grid.scores != 0).ravel()
    assert known == is_known.sum() > 10_000 and is_known.mean() < 1
    assert np.all(np.isnan(read[~is_known]))  # no kernel reaches: unknown in the tree
    probability = room_grid.probability.ravel()[is_known]
    np.testing.assert_allclose(read[is_known], np.clip(probability, 1e-6, 1 - 1e-6), atol=1e-3)


def test_trees_of_blocks_hold_what_the_tree_of_one_grid_holds(room_map, room_grid, tmp_path):
    blocks = list(room_map.grid_blocks(room_grid.bounds, 0.1))
    assert len(blocks) > 1
    known = write_octomap(blocks, tmp_path / "blocks.ot")
    assert known == write_octomap(room_grid, tmp_path / "room.ot")
    tree = octomap.OcTree.read(str(tmp_path / "blocks.ot").encode())
    centres = voxel_centres(room_grid)
    expected = octomap.OcTree.read(str(tmp_path / "room.ot").encode())
    np.testing.assert_allclose(
        tree_occupancy(tree, centres[::7]), tree_occupancy(expected, centres[::7]), atol=1e-9
    )
    limit = (known - 1) * OCTOMAP_BYTES_PER_VOXEL
    with pytest.raises(ehm.InputError, match=r"passes \d+ known voxels of 0\.1 m"):
        write_octomap(room_map.grid_blocks(room_grid.bounds, 0.1), tmp_path / "x.ot", limit)


def test_bt_files_hold_the_occupied_voxels_and_no_others(room_grid, tmp_path):
    write_octomap(room_grid, tmp_path / "room.bt")
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(tmp_path / "room.bt").encode())
    centres = voxel_centres(room_grid)
    read = tree_occupancy(tree, centres)
    is_known = (room_grid.scores != 0).ravel()
    occupied = is_known & (room_grid.probability.ravel() > 0.5)
    assert occupied.sum() > 1000
    np.testing.assert_array_equal(read[is_known] > 0.5, occupied[is_known])
    assert np.all(np.isnan(read[~is_known]))
    volume = sum(leaf.getSize() ** 3 for leaf in tree.begin_leafs() if tree.isNodeOccupied(leaf))
    assert volume == pytest.approx(occupied.sum() * 0.1**3)


def test_map_server_maps_read_back_as_nav2_reads_them(plan, tmp_path):
    plan_map = ehm.HilbertMap().fit(plan.scans)
    grid = navigation_grid(plan_map, aligned_bounds(plan_map.extent(), 0.1), 0.1)
    yaml_path = write_map_server(grid, tmp_path / "plan.pgm")
    settings = dict(line.split(": ", 1) for line in yaml_path.read_text().splitlines())
    assert settings["image"] == "plan.pgm" and float(settings["resolution"]) == 0.1
    assert settings["mode"] == "trinary"
    origin = [float(v) for v in settings["origin"].strip("[]").split(",")]
    np.testing.assert_allclose(origin, [*grid.origin, 0.0])
    image = np.asarray(Image.open(tmp_path / "plan.pgm"))
    assert image.shape == (grid.shape[1], grid.shape[0])
    occupancy = (255 - image.astype(float)) / 255  # map_server's reading, negate 0
    read = np.where(
        occupancy > float(settings["occupied_thresh"]),
        OCCUPIED,
        np.where(occupancy < float(settings["free_thresh"]), FREE, UNKNOWN),
    )
    # Row r from the top is y index ny - 1 - r; column c is x index c.
    np.testing.assert_array_equal(read, grid.states.T[::-1])
    assert {OCCUPIED, FREE, UNKNOWN} <= set(np.unique(read).tolist())
    with pytest.raises(ehm.InputError, match="written from a navigation grid"):
        write_map_server(plan_map.grid(resolution=0.1), tmp_path / "x.pgm")
    solid = NavigationGrid(np.zeros(3), 0.1, np.zeros((2, 2, 2), dtype=np.int8))
    with pytest.raises(ehm.InputError, match="map_server maps are 2D"):
        write_map_server(solid, tmp_path / "x.pgm")


def test_occupied_voxels_as_point_clouds(room_grid, tmp_path):
    points = occupied_voxels(room_grid)
    assert len(points) == np.count_nonzero((room_grid.probability > 0.5) & (room_grid.scores != 0))
    write_point_cloud(points, tmp_path / "occupied.ply")
    write_point_cloud(points, tmp_path / "occupied.pcd")
    np.testing.assert_allclose(read_ply(tmp_path / "occupied.ply"), points, atol=1e-6)
    np.testing.assert_allclose(read_pcd(tmp_path / "occupied.pcd")[0], points, atol=1e-6)


def test_octomap_needs_aligned_3d_grids(room_map, tmp_path):
    shifted = room_map.grid(np.array([[0.03, 0.0, 0.0], [1.0, 1.0, 1.0]]), 0.1)
    with pytest.raises(ehm.InputError, match="not on OctoMap's voxel boundaries"):
        write_octomap(shifted, tmp_path / "x.bt")
    with pytest.raises(ehm.OutputError, match=r"OctoMap files end in \.ot or \.bt"):
        write_octomap(shifted, tmp_path / "x.oct")
