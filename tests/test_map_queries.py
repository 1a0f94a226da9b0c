"""The queries both kinds of map answer alike from their log-odds, and what they refuse."""

import numpy as np
import pytest

import ehm
from ehm.core.primitives.logistic import sigmoid
from ehm.map_queries import checked_box
from ehm.tiles.tiled_map import TiledMap


@pytest.fixture(scope="module")
def maps(room):
    tiled = TiledMap(4.0, 1.0)
    for scan in room.scans:
        tiled.integrate_scan(scan)
    return ehm.HilbertMap().fit(room.scans), tiled


def test_probabilities_log_odds_and_std_agree_in_both_maps(maps, rng):
    points = rng.uniform([-4.0, -3.0, 0.0], [4.0, 3.0, 3.0], (2000, 3))
    points[7] = np.nan
    for hilbert_map in maps:
        p, std = hilbert_map.occupancy(points, return_std=True)
        log_odds, variance = hilbert_map.decision_function(points, return_variance=True)
        proba, proba_std = hilbert_map.predict_proba(points, return_std=True)
        np.testing.assert_array_equal(p, sigmoid(log_odds))
        np.testing.assert_array_equal(proba[:, 1], p)
        np.testing.assert_array_equal(proba[:, 0], 1.0 - p)
        np.testing.assert_array_equal(proba_std, std)
        assert np.isnan(p[7]) and np.isnan(std[7]) and np.isnan(variance[7])
        assert np.all(std[np.isfinite(std)] > 0.0)


def test_segments_are_free_where_rays_cross_nothing(maps, room):
    origin = room.scans[0].origin
    ends = origin + np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [30.0, 0.0, 0.0]])
    for hilbert_map in maps:
        free = hilbert_map.segment_free(np.tile(origin, (3, 1)), ends)
        assert free.tolist() == [True, True, False]  # the last leaves the room


def test_bad_queries_are_named(maps):
    for hilbert_map in maps:
        with pytest.raises(ehm.InputError, match=r"query points must have shape \(n, 3\)"):
            hilbert_map.occupancy(np.zeros((4, 2)))
        with pytest.raises(ehm.InputError, match="query mode must be 'batch' or 'exact'"):
            hilbert_map.occupancy(np.zeros((4, 3)), mode="fast")
        with pytest.raises(ehm.InputError, match=r"unknown_box must have shape \(2, 3\)"):
            hilbert_map.distance(np.zeros((1, 3)), unknown_box=np.zeros((2, 2)))
    for empty in (ehm.HilbertMap(), TiledMap()):
        with pytest.raises(ehm.EmptyMapError, match="before you measure distances in it"):
            empty.distance(np.zeros((1, 3)))


def test_boxes_are_low_corner_then_high_corner():
    assert checked_box("box", None, 3) is None
    np.testing.assert_array_equal(checked_box("box", [[0, 0], [1, 2]], 2), [[0, 0], [1, 2]])
    with pytest.raises(ehm.InputError, match=r"obstacle_box must be \[low corner, high corner\]"):
        checked_box("obstacle_box", [[0.0, 3.0], [1.0, 2.0]], 2)
    with pytest.raises(ehm.InputError, match="with low <= high and no NaN"):
        checked_box("box", [[0.0, np.nan], [1.0, 2.0]], 2)


def test_a_tiled_map_of_a_resolution_takes_that_resolution_s_settings():
    tiled = TiledMap(resolution=0.2, max_range=80.0)
    assert tiled.config == ehm.MapConfig.for_resolution(0.2, max_range=80.0)
