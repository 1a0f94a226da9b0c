"""Colours by height."""

import numpy as np

from ehm.viz.colors import height_colors, height_range, vertex_colors


def test_heights_map_onto_the_colour_map_and_clip_at_its_ends():
    colors = height_colors(np.array([-1.0, 0.0, 1.0, 2.0, 3.0]), (0.0, 2.0))
    np.testing.assert_array_equal(colors[0], colors[1])  # clipped below
    np.testing.assert_array_equal(colors[3], colors[4])  # clipped above
    assert not np.allclose(colors[1], colors[2]) and not np.allclose(colors[2], colors[3])
    assert np.all((colors >= 0) & (colors <= 1)) and colors.shape == (5, 3)


def test_vertex_colors_span_the_vertices_own_heights():
    vertices = np.array([[0, 0, 5.0], [1, 0, 6.0], [0, 1, 7.0]])
    colors = vertex_colors(vertices)
    assert colors.dtype == np.uint8 and colors.shape == (3, 3)
    expected = np.round(255 * height_colors(vertices[:, 2], (5.0, 7.0))).astype(np.uint8)
    np.testing.assert_array_equal(colors, expected)
    assert vertex_colors(np.zeros((0, 3))).shape == (0, 3)
    assert height_range(vertices, np.array([[0, 1, 1]])) == (5.0, 6.0)
