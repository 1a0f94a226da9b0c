"""Ray casting: the walk through candidate cells against sampling, the march against dense
sampling, and HilbertMap.raycast against the exact scene."""

import numpy as np
import pytest

import ehm
from ehm.core.queries.raycast import (
    CandidateCells,
    first_crossings,
    first_crossings_reference,
    next_run_reference,
)


def unit_rows(rng, n, d):
    rows = rng.normal(size=(n, d))
    return rows / np.linalg.norm(rows, axis=1)[:, None]


@pytest.mark.parametrize("d", [2, 3])
def test_the_cell_walk_agrees_with_sampling(rng, d):
    means = rng.uniform(-3.0, 3.0, (60, d))
    weights = rng.normal(size=60)
    cells = CandidateCells.of_kernels(means, np.full(60, 0.4), weights, 0.0, 0.0, 0.5)
    assert cells is not None and len(cells.keys) > 0
    origins = rng.uniform(-4.0, 4.0, (300, d))
    directions = unit_rows(rng, 300, d)
    directions[:20, 0] = 0.0  # rays parallel to a cell face
    directions[:20] /= np.linalg.norm(directions[:20], axis=1)[:, None]
    start, stop = np.zeros(300), np.full(300, 10.0)
    entry, leave = cells.next_run(origins, directions, start, stop)
    expected = next_run_reference(cells, origins, directions, start, stop, 1e-3)
    assert np.isfinite(entry).sum() > 100
    np.testing.assert_array_equal(np.isfinite(entry), np.isfinite(expected[0]))
    both = np.isfinite(entry)
    np.testing.assert_allclose(entry[both], expected[0][both], atol=2e-3)
    np.testing.assert_allclose(leave[both], expected[1][both], atol=2e-3)
    # From the end of a run on, the walk finds the next run or none.
    later, _ = cells.next_run(origins[both], directions[both], leave[both], stop[both])
    assert np.all(~np.isfinite(later) | (later >= leave[both]))


def test_cells_are_where_positive_kernels_reach():
    means = np.array([[0.2, 0.2], [5.2, 0.2]])
    cells = CandidateCells.of_kernels(means, np.full(2, 0.1), np.array([1.0, -1.0]), 0.0, 0.0, 1.0)
    assert len(cells.keys) == 1  # only the positive kernel's cell
    assert CandidateCells.of_kernels(means, np.full(2, 0.1), np.ones(2), 0.5, 0.0, 1.0) is None
    # Two weights of 0.3 reach one cell: above a threshold of 0.5 together, not alone.
    pair = CandidateCells.of_kernels(means[[0, 0]], np.full(2, 0.1), np.full(2, 0.3), 0.0, 0.5, 1.0)
    assert len(pair.keys) == 1
    alone = CandidateCells.of_kernels(means[:1], np.full(1, 0.1), np.full(1, 0.3), 0.0, 0.5, 1.0)
    assert len(alone.keys) == 0


def test_marching_finds_what_dense_sampling_finds(room):
    hilbert_map = ehm.HilbertMap().fit(room.scans[:1])
    rng = np.random.default_rng(5)
    scan = room.scans[0]
    rays = rng.choice(len(scan), 400, replace=False)
    origins = np.broadcast_to(scan.origin, (400, 3)).copy()
    offsets = scan.points_world[rays] - scan.origin
    directions = offsets / np.linalg.norm(offsets, axis=1)[:, None]
    max_range = np.full(400, 12.0)

    def log_odds(points):
        return hilbert_map.decision_function(points)

    found = first_crossings(log_odds, origins, directions, max_range, 0.0, 0.06, 0.012)
    dense = first_crossings_reference(log_odds, origins, directions, max_range, 0.0, 0.005)
    both = np.isfinite(found) & np.isfinite(dense)
    assert both.mean() > 0.95
    # 0.970 when written: a step of 6 cm steps over the narrowest bumps of the log-odds.
    assert np.mean(np.abs(found[both] - dense[both]) < 0.02) > 0.96


def test_raycast_hits_the_room_where_the_scene_is(room):
    hilbert_map = ehm.HilbertMap().fit(room.scans)
    scan = room.scans[0]
    rng = np.random.default_rng(6)
    rays = rng.choice(np.flatnonzero(scan.hit_mask), 3000, replace=False)
    offsets = scan.points_world[rays] - scan.origin
    directions = offsets / np.linalg.norm(offsets, axis=1)[:, None]
    exact = room.scene.raycast(scan.origin, directions)
    distance = hilbert_map.raycast(scan.origin, directions, 20.0)
    assert np.isfinite(distance).mean() > 0.97
    error = np.abs(distance - exact)[np.isfinite(distance)]
    assert np.median(error) < 0.04 and np.mean(error < 0.15) > 0.9
    # Segments stopping short of the hits are free; those through them are not.
    before = scan.origin + directions * (exact[:, None] - 0.3)
    beyond = scan.origin + directions * (exact[:, None] + 0.3)
    assert hilbert_map.segment_free(scan.origin, before).mean() > 0.9
    assert hilbert_map.segment_free(scan.origin, beyond).mean() < 0.05
    assert hilbert_map.segment_free(scan.origin, scan.origin)[0]
    np.testing.assert_array_equal(hilbert_map.raycast(scan.origin, directions[:5], 0.0), np.inf)


def test_ray_mistakes_are_named(room_map):
    with pytest.raises(ehm.InputError, match=r"ray directions must have shape \(n, 3\)"):
        room_map.raycast(np.zeros(3), np.ones((4, 2)), 5.0)
    with pytest.raises(ehm.InputError, match="directions finite and not zero"):
        room_map.raycast(np.zeros(3), np.zeros((1, 3)), 5.0)
    with pytest.raises(ehm.InputError, match="max_range must be finite metres >= 0"):
        room_map.raycast(np.zeros(3), np.ones((1, 3)), np.inf)
    with pytest.raises(ehm.InputError, match="level must be a probability between 0 and 1"):
        room_map.raycast(np.zeros(3), np.ones((1, 3)), 5.0, level=1.0)
    with pytest.raises(ehm.InputError, match=r"ray origins must have shape \(3,\) or \(4, 3\)"):
        room_map.raycast(np.zeros((2, 3)), np.ones((4, 3)), 5.0)
    with pytest.raises(ehm.InputError, match="segment ends must be"):
        room_map.segment_free(np.zeros((2, 3)), np.ones((3, 3)))


@pytest.mark.parametrize("d", [2, 3])
def test_grid_marching_agrees_with_scipy_interpolation(rng, d):
    from ehm.core.queries.raycast import grid_crossings, grid_crossings_reference

    scores = rng.normal(-2.0, 1.0, (12,) * d)
    scores[tuple(rng.integers(0, 12, (d, 40)))] = 3.0  # a few occupied voxels
    grid_origin = np.full(d, -0.6)
    origins = rng.uniform(-0.5, 0.5, (200, d))
    directions = unit_rows(rng, 200, d)
    max_range = np.full(200, 1.2)
    arguments = (origins, directions, max_range, scores, grid_origin, 0.1, 0.0, 0.02)
    found = grid_crossings(*arguments)
    expected = grid_crossings_reference(*arguments)
    assert np.isfinite(found).sum() > 20
    np.testing.assert_array_equal(np.isfinite(found), np.isfinite(expected))
    np.testing.assert_allclose(
        found[np.isfinite(found)], expected[np.isfinite(expected)], atol=1e-9
    )


def test_guesses_are_refined_or_refused():
    from ehm.core.queries.raycast import refine_guesses

    def log_odds(points):  # occupied from x = 1 to x = 1.2
        return np.where((points[:, 0] > 1.0) & (points[:, 0] < 1.2), 1.0, -1.0)

    origins, directions = np.zeros((3, 2)), np.tile([1.0, 0.0], (3, 1))
    low, high = np.array([0.8, 1.1, 1.3]), np.array([1.3, 1.5, 1.6])
    found = refine_guesses(log_odds, origins, directions, low, high, 0.0, 0.1, 0.001)
    assert abs(found[0] - 1.0) < 0.001
    assert np.isnan(found[1])  # already inside at low: the crossing is before the window
    assert np.isnan(found[2])  # nothing in the window


def test_guesses_look_further_where_the_window_holds_no_crossing():
    from ehm.core.queries.raycast import refine_guesses

    def log_odds(points):  # occupied from x = 1.5 to x = 1.7
        return np.where((points[:, 0] > 1.5) & (points[:, 0] < 1.7), 1.0, -1.0)

    origins, directions = np.zeros((3, 2)), np.tile([1.0, 0.0], (3, 1))
    low, high = np.array([0.8, 1.6, 0.8]), np.array([1.3, 1.9, 1.3])
    further = np.array([1.8, 2.5, 1.4])
    found = refine_guesses(log_odds, origins, directions, low, high, 0.0, 0.1, 0.001, further)
    assert abs(found[0] - 1.5) < 0.001  # found beyond the window, before `further`
    assert np.isnan(found[1])  # inside at low: not looked for further on
    assert np.isnan(found[2])  # `further` falls short of it


def test_rays_see_what_the_map_learns_after_their_first_cast():
    """The grid rays march first follows the map as it learns: a wall learned later stops the
    same ray sooner."""
    angles = np.linspace(-0.6, 0.6, 400)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])

    def wall_scan(x):  # a wall across the rays at distance x along the axis
        return directions * (x / directions[:, :1])

    hilbert_map = ehm.HilbertMap(batch_rays=0).integrate(wall_scan(4.0), np.zeros(2))
    first = hilbert_map.raycast(np.zeros(2), np.array([[1.0, 0.0]]), 10.0)[0]
    assert abs(first - 4.0) < 0.1
    hilbert_map.integrate(wall_scan(2.0), np.zeros(2))
    second = hilbert_map.raycast(np.zeros(2), np.array([[1.0, 0.0]]), 10.0)[0]
    assert abs(second - 2.0) < 0.1


def test_the_ray_grid_follows_updates_as_a_fresh_one_would(rng):
    """After the map learns, rays march a grid brought up to date where clusters changed (the
    stage 'grids'), and find what rays of the same map with a grid made anew find; a map that
    grows beyond its grid has it made again."""
    angles = np.linspace(-1.2, 1.2, 600)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    hilbert_map = ehm.HilbertMap(batch_rays=0)
    hilbert_map.integrate(directions * 4.0, np.zeros(2))
    origins = rng.uniform(-0.5, 0.5, (300, 2))
    rays = unit_rows(rng, 300, 2)
    hilbert_map.raycast(origins, rays, 10.0)  # makes the grid
    for radius, origin in ((3.0, [0.5, 0.0]), (9.0, [0.0, 0.0])):  # inside it, then beyond
        hilbert_map.integrate(directions * radius + origin, np.array(origin))
        assert "grids" in hilbert_map.timings_
        kept = hilbert_map.raycast(origins, rays, 10.0)
        fresh = ehm.HilbertMap.from_state(hilbert_map.state()).raycast(origins, rays, 10.0)
        assert np.isfinite(kept).sum() > 100
        # The grids' voxels differ (the followed one keeps the bounds it was made with) and
        # their values by rounding; the crossings agree to raycast's tolerance, a tenth of
        # the cluster radius (the midpoints of neighbouring parts of a crossing step lie that
        # far apart, to rounding).
        np.testing.assert_array_equal(np.isfinite(kept), np.isfinite(fresh))
        finite = np.isfinite(kept)
        tolerance = hilbert_map.config.cluster_radius / 10
        np.testing.assert_allclose(kept[finite], fresh[finite], rtol=0, atol=tolerance + 1e-9)


def test_rays_stop_where_the_known_space_ends():
    """stop_at_unknown against a known region x < 2: rays along +x stop at its edge, within
    the tolerance; one starting outside reads 0; one already stopped nearer keeps its stop."""
    from ehm.core.queries.raycast import stop_at_unknown

    def known(points):
        return points[:, 0] < 2.0

    origins = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    directions = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [-1.0, 0.0]])
    distance = np.array([np.inf, np.inf, 1.0, np.inf])
    found = stop_at_unknown(known, origins, directions, distance, np.full(4, 10.0), 0.1, 0.01)
    assert abs(found[0] - 2.0) <= 0.01
    assert found[1] == 0.0 and found[2] == 1.0 and found[3] == np.inf


def test_never_seen_space_is_not_free_unless_asked():
    """One 2D scan of a wall 3 m ahead: space behind the sensor no ray reached is unknown, so a
    ray into it stops where the evidence ends and a segment through it is not free; with
    unknown='free' both pass, as the map's occupancy there reads 0.5."""
    angles = np.radians(np.linspace(-15.0, 15.0, 121))
    wall = np.column_stack([np.full_like(angles, 3.0), 3.0 * np.tan(angles)])
    hilbert_map = ehm.HilbertMap().integrate(wall, np.zeros(2)).flush()
    assert hilbert_map.known(np.array([[1.5, 0.0], [-4.0, 0.0], [np.nan, 0.0]])).tolist() == [
        True,
        False,
        False,
    ]
    assert hilbert_map.occupancy(np.array([[-4.0, 0.0]]))[0] == pytest.approx(0.5)
    ahead, behind = np.array([[1.0, 0.0]]), np.array([[-1.0, 0.0]])
    assert hilbert_map.raycast(np.zeros(2), ahead, 10.0)[0] == pytest.approx(3.0, abs=0.15)
    stop = hilbert_map.raycast(np.zeros(2), behind, 10.0)[0]
    assert 0.0 <= stop < 1.0
    assert hilbert_map.raycast(np.zeros(2), behind, 10.0, unknown="free")[0] == np.inf
    assert not hilbert_map.segment_free(np.zeros(2), np.array([-5.0, 0.0]))[0]
    assert hilbert_map.segment_free(np.zeros(2), np.array([-5.0, 0.0]), unknown="free")[0]
    assert hilbert_map.segment_free(np.zeros(2), np.array([2.0, 0.0]))[0]
    with pytest.raises(ehm.InputError, match="unknown must be 'occupied' or 'free'"):
        hilbert_map.raycast(np.zeros(2), ahead, 10.0, unknown="maybe")


def test_runs_of_known_cells_halve_the_queries_and_keep_the_stops(room_map, rng):
    """Rays from inside the room in every direction, out to 12 m (well past its walls into
    never-seen space): passing over cells known all through gives the stops of a march that
    asks every step, with fewer points asked."""
    from ehm.core.queries.raycast import stop_at_unknown

    radius = room_map.config.cluster_radius
    runs = room_map._planner.known_cells(room_map._local_snapshot)
    asked = []

    def known(points):
        asked.append(len(points))
        return room_map._known_at(points, "batch")

    origins = rng.uniform([-2.0, -1.5, 0.5], [2.0, 1.5, 2.0], (400, 3))
    directions = unit_rows(rng, 400, 3)
    rays = (origins, directions, np.full(400, np.inf), np.full(400, 12.0), radius / 2, radius / 10)
    marched = stop_at_unknown(known, *rays)
    every_step = sum(asked)
    asked.clear()
    skipped = stop_at_unknown(known, *rays, known_runs=runs)
    assert np.isfinite(marched).all() and np.all(marched < 12.0)
    assert sum(asked) < 0.55 * every_step  # about half, in this small room
    # Both sample each ray half a radius apart, from other starts past the known runs: a gap
    # in the evidence narrower than that step is met by one and not the other. Against a
    # march eight times finer, neither is the nearer.
    assert np.mean(np.abs(skipped - marched) <= radius / 10 + 1e-9) > 0.95
    fine = stop_at_unknown(known, *rays[:4], radius / 16, radius / 10)
    assert np.mean(np.abs(skipped - fine)) <= 1.2 * np.mean(np.abs(marched - fine)) + 1e-3
