"""Navigation grids: each cell occupied, free or unknown, from a grid twice as fine."""

import numpy as np
import pytest

import ehm
from ehm.grid.bounds import aligned_bounds
from ehm.grid.navigation import (
    FREE,
    KNOWN_VARIANCE_SHARE,
    OCCUPIED,
    UNKNOWN,
    NavigationGrid,
    default_heights,
    navigation_grid,
    projected_navigation_grid,
)
from ehm.grid.occupancy_grid import OccupancyGrid


def test_cells_take_occupied_anywhere_free_where_known_else_unknown():
    # Four cells of 2 x 2 voxels: log-odds and log-odds variance (prior precision 2: prior 0.5).
    log_odds = np.full((4, 4), -3.0)
    log_odds[0, 3] = 0.1  # above 0.5 in one voxel of cell (0, 1)
    variance = np.full((4, 4), 0.1)
    variance[2:, 2:] = [[0.5, 0.5], [0.5, 0.5]]  # the prior's: nothing observed
    variance[2:, :2] = [[0.5, 0.5], [0.1, 0.5]]  # mean 0.4 = KNOWN_VARIANCE_SHARE of 0.5
    fine = OccupancyGrid.of_log_odds(np.array([1.0, 2.0]), 0.05, log_odds, variance, 2.0)
    grid = NavigationGrid.of_fine_grid(fine)
    assert KNOWN_VARIANCE_SHARE == 0.8
    np.testing.assert_array_equal(grid.states, [[FREE, OCCUPIED], [FREE, UNKNOWN]])
    assert grid.states.dtype == np.int8 and grid.resolution == 0.1
    np.testing.assert_array_equal(grid.origin, [1.0, 2.0])


def test_a_cell_no_kernel_reaches_is_unknown_however_certain():
    fine = OccupancyGrid.of_log_odds(np.zeros(2), 0.05, np.zeros((2, 2)), np.zeros((2, 2)))
    assert NavigationGrid.of_fine_grid(fine).states.tolist() == [[UNKNOWN]]


def test_fine_grids_without_std_or_of_odd_shape_are_refused():
    with pytest.raises(ValueError, match="with its std"):
        NavigationGrid.of_fine_grid(OccupancyGrid(np.zeros(2), 0.05, (4, 4)))
    odd = OccupancyGrid.of_log_odds(np.zeros(2), 0.05, np.ones((4, 3)), np.ones((4, 3)))
    with pytest.raises(ValueError, match=r"shape \(4, 3\) does not split"):
        NavigationGrid.of_fine_grid(odd)


@pytest.fixture(scope="module")
def plan_navigation(plan):
    plan_map = ehm.HilbertMap().fit(plan.scans)
    bounds = aligned_bounds(plan_map.extent(), 0.05)
    return plan_map, navigation_grid(plan_map, bounds, 0.05)


def cell_states(grid, points):
    cells = np.floor((points - grid.origin) / grid.resolution).astype(int)
    return grid.states[tuple(cells.T)]


def test_hit_cells_read_occupied_and_crossed_space_free(plan, plan_navigation):
    plan_map, grid = plan_navigation
    hits = np.concatenate([s.points_world[s.hit_mask] for s in plan.scans])
    in_grid = np.mean(cell_states(grid, hits) == OCCUPIED)
    assert in_grid > 0.93
    # The grid at the cells' centres, read by map_server's threshold, holds fewer.
    centres = plan_map.grid(aligned_bounds(plan_map.extent(), 0.05), 0.05)
    at_centres = centres.probability[tuple(np.floor((hits - centres.origin) / 0.05).astype(int).T)]
    assert np.mean(at_centres > 0.65) < in_grid - 0.2  # 0.68 against 0.99 when written
    # Points halfway along the rays that returned, 0.5 m or more from their hit.
    crossed = []
    for scan in plan.scans:
        ends = scan.points_world[scan.hit_mask]
        length = np.linalg.norm(ends - scan.origin, axis=1)
        crossed.append((scan.origin + ends[length > 1.0]) / 2)
    assert np.mean(cell_states(grid, np.concatenate(crossed)) == FREE) > 0.98  # 0.995
    # The grid is the map's: every cell that reads occupied holds p > 0.5 somewhere, as point
    # queries read it, but for two of 5,717 (0.495 and 0.499): grids and point queries gather
    # a point's kernels in two ways by default (MapConfig.features).
    occupied = np.argwhere(grid.states == OCCUPIED)
    centres = grid.origin + (occupied + 0.5) * grid.resolution
    corners = centres[:, None, :] + 0.0125 * np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]])
    highest = plan_map.occupancy(corners.reshape(-1, 2)).reshape(-1, 4).max(axis=1)
    assert np.mean(highest > 0.5) > 0.999 and highest.min() > 0.49


def test_space_far_from_every_ray_reads_unknown(plan, plan_navigation):
    plan_map, _ = plan_navigation
    far = np.array([[40.0, 40.0], [-40.0, 30.0]])
    extent = plan_map.extent()
    bounds = np.stack([np.minimum(extent[0], far.min(0)), np.maximum(extent[1], far.max(0))])
    grid = navigation_grid(plan_map, aligned_bounds(bounds, 0.5), 0.5)
    assert np.all(cell_states(grid, far) == UNKNOWN)


def test_tiled_maps_give_navigation_grids_too(plan):
    tiled = ehm.TiledMap(tile_size=4.0)
    for scan in plan.scans:
        tiled.integrate_scan(scan)
    grid = navigation_grid(tiled, resolution=0.05)
    hits = np.concatenate([s.points_world[s.hit_mask] for s in plan.scans])
    inside = np.all((hits > grid.origin) & (hits < grid.origin + 0.05 * np.array(grid.shape)), 1)
    assert np.mean(cell_states(grid, hits[inside]) == OCCUPIED) > 0.9


def test_an_empty_map_has_no_navigation_grid():
    with pytest.raises(ehm.EmptyMapError, match="the map is empty"):
        navigation_grid(ehm.HilbertMap())


def test_a_3d_map_gives_voxels_occupied_where_it_was_hit(room, room_map):
    bounds = aligned_bounds(np.array([[-2.0, -2.0, 0.0], [2.0, 2.0, 2.6]]), 0.05)
    grid = navigation_grid(room_map, bounds, 0.05)
    assert grid.dim == 3 and grid.resolution == 0.05
    hits = np.concatenate([s.points_world[s.hit_mask] for s in room.scans])
    inside = np.all((hits > bounds[0] + 1e-9) & (hits < bounds[1] - 1e-9), axis=1)
    # 0.886; p above 0.5 at the voxels' centres: 0.545.
    assert np.mean(cell_states(grid, hits[inside]) == OCCUPIED) > 0.85
    origin = room.scans[0].origin
    assert cell_states(grid, origin[None])[0] == FREE  # the sensor stood in free space


def test_a_3d_map_projects_its_height_band_as_octomap_server_does(room, room_map):
    with pytest.warns(ehm.AssumptionWarning, match=r"above the floor found at -?0\.[01]\d m"):
        z_min, z_max = default_heights(room_map, 0.1)
    assert z_min == pytest.approx(0.3, abs=0.15) and z_max - z_min == pytest.approx(1.7)
    xy = np.array([[-4.5, -3.5], [4.5, 3.5]])
    grid = projected_navigation_grid(room_map, (z_min, z_max), xy, 0.1)
    assert grid.dim == 2 and grid.resolution == 0.1
    # Built block by block, it is the band of one 3D navigation grid, reduced over height.
    band = navigation_grid(room_map, np.column_stack([xy, [z_min, z_max]]), 0.1).states
    occupied = (band == OCCUPIED).any(axis=2)
    free = (band == FREE).any(axis=2)
    expected = np.where(occupied, OCCUPIED, np.where(free, FREE, UNKNOWN))
    np.testing.assert_array_equal(grid.states, expected)
    hits = np.concatenate([s.points_world[s.hit_mask] for s in room.scans])
    walls = hits[(hits[:, 2] > z_min) & (hits[:, 2] < z_max) & (np.abs(hits[:, 0]) > 3.85)]
    assert np.mean(cell_states(grid, walls[:, :2]) == OCCUPIED) > 0.9
    origins = np.array([s.origin[:2] for s in room.scans])
    assert np.all(cell_states(grid, origins) == FREE)
    outside = np.array([[-4.4, 0.0], [4.4, 0.5], [0.0, 3.4]])  # behind the walls, never seen
    assert np.all(cell_states(grid, outside) == UNKNOWN)


def test_bands_that_cannot_be_projected_are_refused(room_map, plan_navigation):
    with pytest.raises(ehm.InputError, match="z_min < z_max"):
        projected_navigation_grid(room_map, (1.0, 0.5))
    with pytest.raises(ehm.InputError, match="a 2D map is already flat"):
        projected_navigation_grid(plan_navigation[0], (0.0, 1.0))
    with pytest.raises(ehm.InputError, match="no floor found under the first sensor pose"):
        default_heights(ehm.HilbertMap(), 0.1)
