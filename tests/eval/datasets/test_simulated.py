"""Simulated scans of the synthetic scenes."""

import numpy as np

from ehm.eval.datasets import street, warehouse
from ehm.eval.datasets.simulated import CityDrive, city_drive, corridor_2d, warehouse_drive


def test_warehouse_scans_start_in_free_space_and_end_on_surfaces():
    data = warehouse(rings=8, azimuths=90, noise_std=0.0)
    assert len(data.scans) == 6
    for scan in data.scans:
        assert not data.scene.occupied(scan.origin[None])[0]
        hits = scan.points_world[scan.hit_mask]
        assert len(hits) > 0.9 * len(scan)
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)


def test_street_scans_see_ground_far_away_thin_posts_and_sky():
    data = street(azimuths=512, noise_std=0.0)
    assert len(data.scans) == 6
    np.testing.assert_allclose([s.origin[0] for s in data.scans], [-25, -15, -5, 5, 15, 25])
    posts = (data.scene.box_max - data.scene.box_min)[:, 0] < 0.11
    assert posts.sum() == 2 * 10 + 4  # lamp posts every 12 m on both sidewalks, sign posts
    for scan in data.scans:
        assert not data.scene.occupied(scan.origin[None])[0]
        hits = scan.points_world[scan.hit_mask]
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)
        assert 0.02 < np.mean(~scan.hit_mask) < 0.3  # rays into the sky return nothing
        ranges = np.linalg.norm(hits - scan.origin, axis=1)
        assert np.any((hits[:, 2] < 1e-6) & (ranges > 25.0))  # ground at grazing angles
    on_posts = np.zeros(0, dtype=bool)
    for scan in data.scans:
        hits = scan.points_world[scan.hit_mask]
        inside = (hits[:, None] >= data.scene.box_min[posts] - 1e-6) & (
            hits[:, None] <= data.scene.box_max[posts] + 1e-6
        )
        on_posts = np.concatenate([on_posts, np.all(inside, axis=2).any(axis=1)])
    assert on_posts.sum() > 100


def test_corridor_scans_drive_its_length_and_end_on_its_walls():
    data = corridor_2d(n_scans=40, length=20.0, noise_std=0.0)
    origins = np.array([scan.origin for scan in data.scans])
    assert len(data.scans) == 40 and data.scene.dim == 2
    assert origins[0, 0] == 0.5 and origins[-1, 0] == 19.5 and np.all(np.diff(origins[:, 0]) > 0)
    assert not data.scene.occupied(origins).any()
    for scan in data.scans:
        hits = scan.points_world[scan.hit_mask]
        # Ray-cast against the solids in range only, the hits lie on the whole scene's surfaces.
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)
        assert np.all(np.linalg.norm(hits - scan.origin, axis=1) <= 8.0)
    # Doors open on the rooms: some rays end beyond the corridor's walls at |y| = 1.1.
    hits = np.concatenate([s.points_world[s.hit_mask] for s in data.scans])
    assert np.any(np.abs(hits[:, 1]) > 4.0)


def test_warehouse_drive_loops_round_the_shelving():
    data = warehouse_drive(n_scans=40, rings=4, azimuths=64, noise_std=0.0)
    origins = np.array([scan.origin for scan in data.scans])
    assert len(data.scans) == 40 and np.all(origins[:, 2] == 1.5)
    on_loop = np.isclose(np.abs(origins[:, 0]), 17.0) | np.isin(origins[:, 1], [-10.3, 9.5])
    assert on_loop.all() and len(np.unique(origins[:20].round(6), axis=0)) == 20
    np.testing.assert_allclose(origins[20:], origins[:20], atol=1e-9)  # the second lap
    np.testing.assert_allclose(origins[0], [-17.0, -10.3, 1.5])
    assert not data.scene.occupied(origins).any()
    for scan in data.scans:
        hits = scan.points_world[scan.hit_mask]
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)
        assert np.all(np.linalg.norm(scan.points_world - scan.origin, axis=1) <= 30.0 + 1e-9)


def test_city_drive_runs_down_a_long_street():
    data = city_drive(length=300.0, n_scans=12, rings=4, azimuths=128, noise_std=0.0)
    origins = np.array([scan.origin for scan in data.scans])
    np.testing.assert_allclose(origins[[0, -1], 0], [1.0, 299.0])
    assert np.all(origins[:, 1:] == [-2.0, 1.8]) and not data.scene.occupied(origins).any()
    for scan in data.scans:
        hits = scan.points_world[scan.hit_mask]
        # Cast against the solids in range only, the hits lie on the whole scene's surfaces.
        np.testing.assert_allclose(data.scene.surface_distance(hits), 0.0, atol=1e-6)
        assert 0.3 < scan.hit_mask.mean() < 1.0  # ground and facades; sky, and past the ends
    again = city_drive(length=300.0, n_scans=12, rings=4, azimuths=128, noise_std=0.0)
    np.testing.assert_array_equal(again.scans[5].points_world, data.scans[5].points_world)
    heights = data.scene.box_max[:, 2]
    assert heights.max() > 20.0 and np.sum(heights > 7.0) > 10  # buildings along the street


def test_a_city_drive_makes_any_scan_alone_as_in_order():
    import pickle

    drive = CityDrive(length=200.0, n_scans=8, rings=4, azimuths=64)
    in_order = list(drive)
    sent = pickle.dumps(drive)  # as a cluster's workers get it: settings, not the scene
    assert len(sent) < 1000
    alone = pickle.loads(sent)
    [(index, scan)] = list(alone.read([5]))
    assert index == 5 and drive.count() == len(in_order) == 8
    np.testing.assert_array_equal(scan.points_world, in_order[5].points_world)
    np.testing.assert_array_equal(scan.hit_mask, in_order[5].hit_mask)
