"""A map's grid in blocks: the same voxels and surfaces as one grid, never the whole array."""

import numpy as np
import pytest

from ehm.errors import InputError
from ehm.grid.blocks import block_layout, block_mesh, grid_blocks
from ehm.grid.bounds import aligned_bounds
from ehm.grid.mesh import joined_meshes


def _surface_area(vertices, faces):
    corners = vertices[faces]
    return (
        np.linalg.norm(
            np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
        ).sum()
        / 2
    )


def _open_edges(faces):
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts == 1).sum())


@pytest.mark.parametrize("bounds", [None, [[-1.93, -2.41, 0.07], [2.52, 1.11, 2.3]]])
def test_blocks_hold_the_voxels_of_one_grid_each_once(room_map, bounds):
    snapshot, resolution = room_map.snapshot(), 0.05
    box = aligned_bounds(room_map.extent(), resolution) if bounds is None else np.array(bounds)
    whole = room_map.grid(box, resolution)
    blocks = list(grid_blocks(snapshot, resolution, None if bounds is None else box))
    assert len(blocks) > 8 and all(block.shape == (32, 32, 32) for block in blocks[:1])
    covered = np.zeros(whole.shape, dtype=int)
    for block in blocks:
        first = np.round((block.origin - whole.origin) / resolution).astype(int)
        assert np.allclose(first * resolution + whole.origin, block.origin)
        low = np.maximum(first, 0)
        high = np.minimum(first + block.shape, whole.shape)
        inside = tuple(slice(a, b) for a, b in zip(low, high, strict=True))
        part = tuple(slice(a, b) for a, b in zip(low - first, high - first, strict=True))
        np.testing.assert_allclose(block.scores[part], whole.scores[inside], atol=1e-9)
        covered[inside] += 1
        outside = np.ones(block.shape, dtype=bool)
        outside[part] = False
        assert not np.any(block.scores[outside])  # a block past the whole grid holds nothing
    assert covered.max() == 1
    assert np.all(covered[whole.scores != 0.0] == 1)  # every known voxel is in a block


def test_blocks_without_bounds_lie_on_multiples_of_the_resolution(room_map):
    layout = block_layout(room_map.snapshot(), 0.15)
    origins = layout.keys * layout.size * 0.15 + layout.anchor
    assert np.allclose(layout.anchor, 0.0)
    assert np.allclose(origins / 0.15, np.round(origins / 0.15))


def test_a_mesh_made_block_by_block_is_the_mesh_of_one_grid(room_map):
    bounds = np.array([[-2.2, -2.4, -0.1], [2.3, 2.2, 2.7]])
    whole_vertices, whole_faces = room_map.grid(bounds, 0.05).mesh()
    vertices, faces = block_mesh(room_map.snapshot(), 0.05, bounds)
    assert np.all(vertices >= bounds[0]) and np.all(vertices <= bounds[1])
    whole_area = _surface_area(whole_vertices, whole_faces)
    assert _surface_area(vertices, faces) == pytest.approx(whole_area, rel=1e-4)
    # Closed across the seams: the only edges of one face are where the bounds cut the surface
    # (a few more where slivers thinner than a ten-thousandth of a voxel were merged away).
    assert _open_edges(faces) == pytest.approx(_open_edges(whole_faces), rel=0.01)
    # Vertices that coincide (crossings at a voxel centre reading exactly the level) are one.
    assert len(vertices) == pytest.approx(len(whole_vertices), rel=0.01)


def test_joined_meshes_share_the_vertices_on_their_seam():
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    left = (square[[0, 1, 2]], np.array([[0, 1, 2]]))
    right = (square[[0, 2, 3]] + 1e-9, np.array([[0, 1, 2]]))
    vertices, faces = joined_meshes([left, right], resolution=0.1)
    assert len(vertices) == 4
    np.testing.assert_allclose(vertices[faces], square[[[0, 1, 2], [0, 2, 3]]], atol=1e-8)


def test_layouts_far_finer_than_the_map_are_refused_before_they_are_made(room_map):
    with pytest.raises(InputError, match=r"listing the blocks .* at 0\.001 m takes .* GiB"):
        block_layout(room_map.snapshot(), 0.001)
