"""HilbertMap.distance: against the exact scene where the map saw the nearest surface, kept
up to date as the map learns, unknown space taken for an obstacle when asked, and bad input."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ehm
from ehm.errors import EmptyMapError, InputError

ANGLES = np.linspace(-1.2, 1.2, 600)
DIRECTIONS = np.column_stack([np.cos(ANGLES), np.sin(ANGLES)])


def wall_map(x: float = 4.0) -> ehm.HilbertMap:
    """A 2D map of one scan of rays ending on a circle of radius x around the origin."""
    return ehm.HilbertMap(batch_rays=0).integrate(DIRECTIONS * x, np.zeros(2))


def seen_surface_distances(scene, scans, points, resolution):
    """Exact signed distances of `points` to the scene, and which points' nearest surface the
    scans saw (the nearest hit lies within two resolutions of that distance)."""
    exact = scene.surface_distance(points)
    signed = np.where(scene.occupied(points), -exact, exact)
    hits = np.vstack([scan.points_world[scan.hit_mask] for scan in scans])
    nearest_hit, _ = cKDTree(hits).query(points)
    return signed, np.abs(nearest_hit - exact) < 2 * resolution


def test_distances_in_the_room_match_the_scene_where_it_was_seen(room, room_map, rng):
    points = rng.uniform([-3.8, -2.8, 0.2], [3.8, 2.8, 2.8], (20000, 3))
    distance, gradient = room_map.distance(points, return_gradient=True)
    signed, seen = seen_surface_distances(room.scene, room.scans, points, 0.05)
    judged = seen & (signed < 1.5)
    error = np.abs(distance - signed)[judged]
    assert judged.sum() > 15000
    # Within the map's own errors: its 0.5 level lies off the scene's surfaces here and there
    # (blobs in open space, a band in front of walls), which the tail holds.
    assert np.median(error) < 0.05
    assert np.percentile(error, 90) < 0.15
    # Gradients are unit vectors that point away from the nearest obstacle: a step along one
    # adds its length to the distance.
    moving = judged & (np.abs(distance) > 0.2) & (np.abs(distance) < 1.0)
    np.testing.assert_allclose(np.linalg.norm(gradient[moving], axis=1), 1.0, atol=1e-9)
    stepped = room_map.distance(points[moving] + 0.02 * gradient[moving])
    assert np.median(stepped - distance[moving]) == pytest.approx(0.02, abs=0.003)


def at_level(hilbert_map, points):
    """(n,) bool: the map's occupancy reaches 0.5 at `points`, each read alone (mode 'exact');
    unknown space (0.5 exactly, no kernel reaches it) does not."""
    occupancy = hilbert_map.occupancy(points, mode="exact")
    return (occupancy >= 0.5) & (np.abs(occupancy - 0.5) > 1e-9)


def nearest_level_distances(hilbert_map, raster, points, reach):
    """Signed distances from `points` to the nearest point of `raster` on the other side of
    the map's 0.5 level (`at_level`), clipped to `reach`."""
    on_raster, at_points = at_level(hilbert_map, raster), at_level(hilbert_map, points)
    to_obstacle = cKDTree(raster[on_raster]).query(points)[0]
    to_free = cKDTree(raster[~on_raster]).query(points)[0]
    return np.clip(np.where(at_points, -to_free, to_obstacle), -reach, reach)


def raster_of(low, high, step):
    axes = [np.arange(a, b, step) + step / 2 for a, b in zip(low, high, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(low))


def test_distances_agree_with_dense_sampling_of_the_map(rng):
    """Distances to where the map's occupancy reaches 0.5, against the nearest such point of a
    1 cm raster of point queries, after a nearer wall was learned over a farther one."""
    hilbert_map = wall_map(4.0)
    origin = np.zeros((1, 2))
    # Unknown space free, as the raster reads it (it lies just behind the origin).
    first, gradient = hilbert_map.distance(origin, return_gradient=True, unknown="free")
    # Distances are told up to distance_reach (2 m): the wall 4 m away is beyond it.
    assert first[0] == hilbert_map.config.distance_reach
    np.testing.assert_array_equal(gradient, 0.0)
    hilbert_map.integrate(DIRECTIONS * 1.5, np.zeros(2))
    points = np.vstack([origin, rng.uniform([-0.5, -3.0], [4.5, 3.0], (5000, 2))])
    raster = raster_of([-1.0, -6.0], [6.5, 6.0], 0.01)
    expected = nearest_level_distances(hilbert_map, raster, points, 2.0)
    distance, gradient = hilbert_map.distance(points, return_gradient=True, unknown="free")
    error = np.abs(distance - expected)
    assert np.median(error) < 0.03
    assert np.percentile(error, 95) < 0.1
    assert error[0] < 0.05  # within a voxel of the level (0.032 when written)
    assert gradient.shape == (5001, 2)
    # At the origin: away from a point at the level no more than two voxels (10 cm) farther
    # than the nearest. The level is an arc with bumps (1.42 m away at 35 degrees, 1.49 at
    # 62), and the field's surfels, which come from the grid's voxels, lie up to a voxel off
    # it: the nearest may be any bump within a voxel of the nearest's distance.
    obstacles = raster[at_level(hilbert_map, raster)]
    reach = np.linalg.norm(obstacles, axis=1)
    near = reach < reach.min() + 0.1
    assert np.min(obstacles[near] / reach[near, None] @ gradient[0]) < -0.98


def test_distances_in_3d_agree_with_dense_sampling_of_the_map(room_map, rng):
    low, high = np.array([1.5, -0.5, 0.2]), np.array([3.5, 1.5, 1.6])  # the table, a wall
    points = rng.uniform(low + 0.3, high - 0.3, (3000, 3))
    expected = nearest_level_distances(room_map, raster_of(low, high, 0.02), points, 0.3)
    # Unknown space free, as nearest_level_distances reads it.
    error = np.abs(room_map.distance(points, unknown="free") - expected)
    near = np.abs(expected) < 0.3
    assert near.sum() > 700
    assert np.median(error[near]) < 0.03
    # The tail: surfels found from the grid's voxel centres, which sum every kernel, where
    # point queries sum the nearest ones; a surface they do not share within a voxel is left
    # out (ehm.core.queries.surfels.on_level).
    assert np.percentile(error[near], 95) < 0.15


def test_the_field_follows_updates_as_a_fresh_one_would(rng):
    """After the map learns, distances come from a field brought up to date around the
    clusters that changed, and agree with those of the same map with a field made anew, also
    when the map grows beyond the grid the field was made on."""
    hilbert_map = wall_map(4.0)
    points = rng.uniform(-1.0, 5.0, (2000, 2))
    hilbert_map.distance(points)  # makes the field
    for radius, origin in ((3.0, [0.5, 0.0]), (9.0, [0.0, 0.0])):  # inside its grid, beyond
        hilbert_map.integrate(DIRECTIONS * radius + origin, np.array(origin))
        assert "grids" in hilbert_map.timings_
        kept = hilbert_map.distance(points)
        fresh = ehm.HilbertMap.from_state(hilbert_map.state()).distance(points)
        near = np.abs(fresh) < hilbert_map.config.distance_reach
        assert near.sum() > 500
        # The grids' voxels differ (the followed one keeps the bounds it was made with) and
        # so do their surfels a little; on one grid, a followed field equals one made anew
        # (tests/core/test_distance.py).
        error = np.abs(kept - fresh)
        assert np.median(error) < 0.02
        assert np.percentile(error, 90) < 0.75 * hilbert_map.config.cluster_radius


def test_surfels_read_the_log_odds_around_them_from_one_search_each(room, room_map, rng):
    """What puts surfels on the level reads points along each surfel's normal from one search
    of nearest clusters around it: at the surfel itself, what a point query reads; within the
    spread, nearly so (a group search, as batch queries make); with every kernel at a point
    ('support'), exactly what point queries read."""
    hits = room.scans[0].points_world[room.scans[0].hit_mask]
    places = hits[rng.integers(0, len(hits), 2000)] + rng.normal(0.0, 0.05, (2000, 3))
    spread = room_map.config.cluster_radius
    rows = np.repeat(np.arange(len(places)), 5)
    offsets = rng.normal(size=(len(rows), 3))
    offsets *= (rng.uniform(0.0, spread, len(rows)) / np.linalg.norm(offsets, axis=1))[:, None]
    points = places[rows] + offsets
    read = room_map._near_log_odds(places, spread)
    at_places = read(places, np.arange(len(places)))
    np.testing.assert_array_equal(at_places, room_map._point_log_odds(places))
    around, exact = read(points, rows), room_map._point_log_odds(points)
    assert np.median(np.abs(around - exact)) < 0.01
    assert np.mean(np.sign(around) == np.sign(exact)) > 0.95
    supported = ehm.HilbertMap(features="support").integrate_scan(room.scans[0])
    np.testing.assert_array_equal(
        supported._near_log_odds(places, spread)(points, rows), supported._point_log_odds(points)
    )


def test_unknown_space_is_an_obstacle_unless_asked_free():
    hilbert_map = wall_map(4.0)
    behind_the_wall = np.array([[7.0, 0.0]])
    beside_the_origin = np.array([[0.0, -0.5]])  # rays swept +-69 degrees: behind is unknown
    reach = hilbert_map.config.distance_reach
    assert hilbert_map.distance(behind_the_wall, unknown="free")[0] == reach
    assert hilbert_map.distance(behind_the_wall)[0] == -reach
    free = hilbert_map.distance(beside_the_origin, unknown="free")[0]
    bounded = hilbert_map.distance(beside_the_origin)[0]
    assert free == reach
    assert 0.0 < bounded < 0.5
    # Unknown space an obstacle only in a box ahead of the sensor (x > 1 m): behind it, and
    # beside the origin, space is free; a box holding everything changes nothing.
    ahead = np.array([[1.0, -20.0], [20.0, 20.0]])
    boxed = hilbert_map.distance(
        np.vstack([behind_the_wall, beside_the_origin]), unknown="occupied", unknown_box=ahead
    )
    assert boxed[0] == -reach and boxed[1] == reach
    everything = np.array([[-50.0, -50.0], [50.0, 50.0]])
    points = np.array([[7.0, 0.0], [0.0, -0.5], [2.0, 1.0]])
    np.testing.assert_array_equal(
        hilbert_map.distance(points, unknown="occupied", unknown_box=everything),
        hilbert_map.distance(points, unknown="occupied"),
    )
    with pytest.raises(InputError, match="unknown must be 'occupied' or 'free', got 'yes'"):
        hilbert_map.distance(points, unknown="yes")
    with pytest.raises(InputError, match=r"unknown_box must have shape \(2, 2\)"):
        hilbert_map.distance(points, unknown="occupied", unknown_box=np.zeros((2, 3)))
    for bad in ([[1.0, 0.0], [0.0, 1.0]], [[np.nan, 0.0], [1.0, 1.0]]):
        with pytest.raises(InputError, match="low <= high and no NaN"):
            hilbert_map.distance(points, unknown="occupied", unknown_box=np.array(bad))


def test_a_map_counts_only_obstacles_inside_the_obstacle_box():
    """The wall, a circle of 4 m, cut by a box that ends at x = 3.8 m: from (3, 0) the wall
    ahead no longer counts, only its part beside, as far as the box reaches."""
    hilbert_map = wall_map(4.0)
    points = np.array([[3.0, 0.0], [0.0, -0.5], [2.0, 1.0]])
    cut = np.array([[-20.0, -20.0], [3.8, 20.0]])
    whole = hilbert_map.distance(points)
    boxed = hilbert_map.distance(points, obstacle_box=cut)
    assert whole[0] == pytest.approx(1.0, abs=0.1)
    # The nearest wall point left: (3.8, 1.25) on the circle, 1.48 m away.
    assert boxed[0] == pytest.approx(np.hypot(0.8, np.sqrt(16.0 - 3.8**2)), abs=0.1)
    everything = np.array([[-50.0, -50.0], [50.0, 50.0]])
    for unknown in ("free", "occupied"):
        np.testing.assert_array_equal(
            hilbert_map.distance(points, unknown=unknown),
            hilbert_map.distance(points, unknown=unknown, obstacle_box=everything),
        )
    with pytest.raises(InputError, match=r"obstacle_box must have shape \(2, 2\)"):
        hilbert_map.distance(points, obstacle_box=np.zeros((2, 3)))
    with pytest.raises(InputError, match=r"obstacle_box must be .* low <= high and no NaN"):
        hilbert_map.distance(points, obstacle_box=np.array([[1.0, 0.0], [0.0, 1.0]]))


def test_distance_rows_and_mistakes():
    hilbert_map = wall_map(2.0)
    distance, gradient = hilbert_map.distance(
        np.array([[np.nan, 0.0], [0.0, 0.0]]), level=0.7, return_gradient=True
    )
    assert np.isnan(distance[0]) and np.all(np.isnan(gradient[0]))
    assert 1.0 < distance[1] < 2.0
    with pytest.raises(InputError, match="level"):
        hilbert_map.distance(np.zeros((1, 2)), level=1.0)
    with pytest.raises(InputError):
        hilbert_map.distance(np.zeros((1, 3)))
    with pytest.raises(EmptyMapError):
        ehm.HilbertMap().distance(np.zeros((1, 3)))


def test_a_map_too_large_for_one_field_answers_from_a_grid_around_the_points(
    room_map, monkeypatch, rng
):
    """With the map's grid over the cap (as an outdoor sweep at a fine resolution is), the
    field is made on a grid reaching the fields' reach around the points asked: the distances
    of the whole map's field, within the field's own error; points spread too far are refused
    by name."""
    import ehm.grid.planner_support as planner_support

    points = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 1.5], (300, 3))
    whole = room_map.distance(points)
    fresh = ehm.HilbertMap.from_state(room_map.state())
    monkeypatch.setattr(planner_support, "RAY_GRID_MAX_BYTES", 4 * 2**20)
    near = fresh.distance(points)
    assert fresh._planner._grid is None and fresh._planner._near is not None
    error = np.abs(near - whole)
    assert np.median(error) < 0.03 and np.percentile(error, 95) < 0.15
    np.testing.assert_array_equal(fresh.distance(points[:10]), near[:10])  # the grid kept
    spread = np.array([[-4.0, -3.0, 0.0], [4.0, 3.0, 3.0]])
    with pytest.raises(InputError, match=r"and so are the points asked, \[8\.0, 6\.0, 3\.0\] m"):
        fresh.distance(spread)


def test_distance_grids_asked_slab_by_slab_are_the_grid_asked_at_once(room_map, monkeypatch):
    import ehm.io.distance_file as distance_file

    origin, shape = np.array([-2.0, -1.5, 0.2]), (40, 30, 12)
    at_once = distance_file.DistanceGrid.at_centres(room_map, origin, 0.1, shape)
    monkeypatch.setattr(distance_file, "SLAB_METRES", 0.35)  # slabs of 3 voxels, one of 1
    in_slabs = distance_file.DistanceGrid.at_centres(room_map, origin, 0.1, shape)
    np.testing.assert_array_equal(in_slabs.distance, at_once.distance)
    np.testing.assert_array_equal(in_slabs.gradient, at_once.gradient)
