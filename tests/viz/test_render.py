"""The off-screen mesh rasterizer."""

import numpy as np
import pytest

from ehm.viz.render import Camera, rasterize, rasterize_reference, render_mesh


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


def test_render_from_above_shows_nearest_surface_coloured_by_height(two_squares):
    vertices, faces = two_squares
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
