"""Occupancy grids (Sec. 3.5): values, geometry and incremental updates."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ehm
from ehm.core.model.features import decision_values


@pytest.fixture(scope="module")
def planar_room_map(room):
    return ehm.HilbertMap(planar_kernel=True).fit(room.scans)


def sector_scans(scan: ehm.Scan, parts: int) -> list[ehm.Scan]:
    """The scan split into `parts` azimuth sectors, as if the sensor swept round in steps."""
    offsets = scan.points_world - scan.origin
    sector = np.floor((np.arctan2(offsets[:, 1], offsets[:, 0]) + np.pi) / (2 * np.pi) * parts)
    return [scan.subset(sector == s) for s in range(parts)]


@pytest.mark.parametrize("fixture", ["room_map", "planar_room_map"])
def test_grid_is_the_sum_over_every_kernel_at_voxel_centres(fixture, request):
    """Eq. 17 exactly: at each voxel centre, the weighted sum of all kernels reaching it."""
    hilbert_map = request.getfixturevalue(fixture)
    grid = hilbert_map.grid(resolution=0.1)
    centres = grid.centers()
    picked = np.random.default_rng(0).choice(len(centres), 20_000, replace=False)
    clusters = hilbert_map.clusters_
    assert clusters.planar_kernel.any() == (fixture == "planar_room_map")
    reach = clusters.reach()
    lists = cKDTree(clusters.means).query_ball_point(centres[picked], reach.max())
    every = np.full((len(picked), max(map(len, lists))), -1)
    for row, found in enumerate(lists):
        every[row, : len(found)] = found
    expected, squares = decision_values(
        centres[picked],
        np.arange(len(picked)),
        every,
        clusters.means,
        clusters.transforms,
        clusters.planar_kernel,
        clusters.weights,
        0.0,
        1.0 / clusters.precision,
        True,
    )
    np.testing.assert_allclose(grid.scores.ravel()[picked], expected, rtol=0, atol=1e-9)
    with_std = hilbert_map.grid(resolution=0.1, std=True)
    np.testing.assert_array_equal(with_std.scores, grid.scores)
    sums = with_std.variance_sums.reshape(2, -1)[:, picked].T
    np.testing.assert_allclose(sums, squares, rtol=1e-12, atol=1e-12)


def test_with_nearest_features_grids_match_point_queries_within_tolerance(room):
    """With 'nearest' features point queries use the nearest 8 fine and 4 coarse kernels, the
    grid every kernel that reaches a voxel: they agree to 0.015 on average, and within 0.08
    at 95 % of voxels."""
    nearest_map = ehm.HilbertMap(features="nearest").fit(room.scans)
    grid = nearest_map.grid(resolution=0.1)
    difference = np.abs(nearest_map.occupancy(grid.centers()) - grid.probability.ravel())
    assert difference.mean() < 0.015
    assert np.quantile(difference, 0.95) < 0.08


@pytest.mark.parametrize("scene", ["room", "plan"])
def test_by_default_points_and_grids_are_one_model(scene, room, plan):
    """With every kernel not zero at a point as its features (the default), a point query at a
    voxel centre is the grid's value there, in both query modes, std included."""
    scans = room.scans if scene == "room" else plan.scans
    hilbert_map = ehm.HilbertMap()
    for scan in scans:
        hilbert_map.integrate_scan(scan)
    grid = hilbert_map.grid(resolution=0.1 if scene == "room" else 0.05, std=True)
    centres = grid.centers()
    for mode in ("batch", "exact"):
        probability, std = hilbert_map.occupancy(centres, mode, return_std=True)
        np.testing.assert_allclose(probability, grid.probability.ravel(), rtol=0, atol=1e-9)
        np.testing.assert_allclose(std, grid.std.ravel(), rtol=0, atol=1e-9)
    assert np.ptp(grid.probability) > 0.9


def test_grid_geometry_and_centres_order(room_map):
    bounds = np.array([[-1.0, -2.0, 0.0], [1.0, 0.5, 1.25]])
    grid = room_map.grid(bounds, resolution=0.25)
    assert grid.shape == (8, 10, 5) and grid.probability.shape == grid.shape
    np.testing.assert_allclose(grid.bounds, bounds)
    centres = grid.centers()
    assert centres.shape == (400, 3)
    index = np.unravel_index(137, grid.shape)
    np.testing.assert_allclose(centres[137], bounds[0] + (np.array(index) + 0.5) * 0.25)


def test_default_bounds_hold_every_kernel(room_map):
    grid = room_map.grid(resolution=0.2)
    means = room_map.clusters_.means
    reach = room_map.clusters_.reach()
    assert np.all(grid.bounds[0] <= means.min(axis=0))
    assert np.all(grid.bounds[1] >= means.max(axis=0))
    assert np.all(grid.bounds[0] >= means.min(axis=0) - reach.max() - 0.2)


def test_followed_grids_stay_equal_to_rebuilt_ones(room):
    hilbert_map = ehm.HilbertMap(calibrate=True)  # the scale moves with every update
    scans = sector_scans(room.scans[0], 4)
    hilbert_map.integrate_scan(scans[0])
    bounds = np.array([[-4.5, -3.5, -0.5], [4.5, 3.5, 3.5]])
    fine = hilbert_map.grid(bounds, resolution=0.1, follow=True)
    coarse = hilbert_map.grid(bounds, resolution=0.25, follow=True, std=True)
    kinds = []
    for scan in scans[1:]:
        hilbert_map.integrate_scan(scan)
        assert "grids" in hilbert_map.timings_
        kinds.append(fine.update(hilbert_map.snapshot()).kind)  # already current: nothing to do
        for followed in (fine, coarse):
            rebuilt = hilbert_map.grid(bounds, followed.resolution, std=followed.has_std)
            np.testing.assert_allclose(followed.scores, rebuilt.scores, rtol=0, atol=1e-9)
            calibrated = hilbert_map.model_.scale * followed.scores
            np.testing.assert_array_equal(followed.probability, 1 / (1 + np.exp(-calibrated)))
        np.testing.assert_allclose(coarse.std, rebuilt.std, rtol=0, atol=1e-9)
    assert kinds == ["incremental"] * 3


def test_incremental_update_touches_only_changed_clusters(room):
    hilbert_map = ehm.HilbertMap()
    first, second = sector_scans(room.scans[0], 2)
    hilbert_map.integrate_scan(first)
    grid = hilbert_map.grid(resolution=0.2)
    weights = hilbert_map.clusters_.weights.copy()
    hilbert_map.integrate_scan(second)
    changed = np.count_nonzero(hilbert_map.clusters_.weights[: len(weights)] != weights)
    new = hilbert_map.n_clusters - len(weights)
    update = grid.update(hilbert_map.snapshot())
    assert update.kind == "incremental"
    assert update.local_grids <= 2 * changed + new < 2 * hilbert_map.n_clusters


def test_refitted_map_rebuilds_its_grids(plan):
    hilbert_map = ehm.HilbertMap().fit(plan.scans[:2])
    grid = hilbert_map.grid(resolution=0.1, follow=True)
    hilbert_map.fit(plan.scans)
    rebuilt = hilbert_map.grid(grid.bounds, 0.1)
    np.testing.assert_allclose(grid.scores, rebuilt.scores, rtol=0, atol=1e-9)
    assert grid.update(ehm.HilbertMap().fit(plan.scans[:1]).snapshot()).kind == "rebuild"


def test_2d_grid_matches_point_queries(plan):
    hilbert_map = ehm.HilbertMap().fit(plan.scans)
    grid = hilbert_map.grid(resolution=0.05)
    assert grid.dim == 2 and grid.centers().shape == (grid.probability.size, 2)
    difference = np.abs(hilbert_map.occupancy(grid.centers()) - grid.probability.ravel())
    assert difference.mean() < 0.015 and np.quantile(difference, 0.95) < 0.08
    truth = plan.scene.occupied(grid.centers())
    seen = np.abs(grid.probability.ravel() - 0.5) > 0.1
    assert np.mean((grid.probability.ravel()[seen] > 0.5) == truth[seen]) > 0.9


def test_grid_of_an_empty_map_is_refused():
    with pytest.raises(ehm.EmptyMapError, match="map is empty"):
        ehm.HilbertMap().grid()
