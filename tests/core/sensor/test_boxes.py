"""The part of each ray inside a box."""

import numpy as np

from ehm.core.sensor.boxes import points_in_box, ray_box_intervals


def test_ray_box_intervals_agree_with_points_marched_along_each_ray(rng):
    box = np.array([[-1.0, 0.0, 0.5], [2.0, 1.5, 2.0]])
    origin = np.array([0.3, -1.0, 1.0])
    directions = rng.normal(size=(300, 3))
    directions[:20, 0] = 0.0  # rays parallel to a pair of faces
    directions[20:30, :2] = 0.0
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    lengths = rng.uniform(0.5, 6.0, 300)
    start, end = ray_box_intervals(origin, directions, lengths, box)
    steps = np.linspace(0.0, 1.0, 4001)
    for ray in range(300):
        along = steps * lengths[ray]
        inside = points_in_box(origin + along[:, None] * directions[ray], box)
        if not inside.any():
            assert start[ray] > end[ray] - 2e-3 * lengths[ray]
            continue
        step = lengths[ray] / 4000
        assert abs(start[ray] - along[inside].min()) <= step + 1e-12
        assert abs(end[ray] - along[inside].max()) <= step + 1e-12


def test_rays_from_inside_start_at_zero_and_end_at_the_wall_or_their_length():
    box = np.array([[0.0, 0.0], [1.0, 1.0]])
    directions = np.array([[1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    start, end = ray_box_intervals(np.array([0.5, 0.5]), directions, np.array([2.0, 2.0, 0.2]), box)
    np.testing.assert_allclose(start, 0.0)
    np.testing.assert_allclose(end, [0.5, 0.5, 0.2])


def test_rays_of_many_origins_each_meet_the_box_as_from_their_own(rng):
    """Rays each with an origin of its own (a batch of scans, some inside the box, some
    outside, some on a face's plane) get the interval each would get alone."""
    box = np.array([[-1.0, 0.0, 0.5], [2.0, 1.5, 2.0]])
    origins = rng.uniform(-3.0, 4.0, (200, 3))
    origins[:10, 0] = -1.0  # on the plane of a face
    directions = rng.normal(size=(200, 3))
    directions[10:20, 1] = 0.0
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    lengths = rng.uniform(0.5, 6.0, 200)
    start, end = ray_box_intervals(origins, directions, lengths, box)
    for ray in range(200):
        alone = ray_box_intervals(
            origins[ray], directions[ray : ray + 1], lengths[ray : ray + 1], box
        )
        assert (start[ray], end[ray]) == (alone[0][0], alone[1][0])
    assert 0 < np.sum(start <= end) < 200
