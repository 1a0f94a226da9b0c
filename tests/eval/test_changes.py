"""A changing scene and what measures a map against it: the scene at each scan, the voxels
of surfaces, of rays' free parts and of hits, and maps that forget what left."""

import numpy as np
import pytest

from ehm import HilbertMap, MapConfig, Scan
from ehm.eval.change_scores import (
    ChangeProbe,
    contains,
    hit_voxels,
    passed_voxels,
    shell_voxels,
    voxel_centres,
)
from ehm.eval.datasets.changing import (
    DEPTH_PIXELS,
    DEPTH_RANGE,
    changing_room,
    cut_at,
    sensor_path,
)
from ehm.eval.datasets.scene import Scene


def test_the_scene_at_each_scan_holds_the_movers_there():
    room = changing_room(n_scans=6, rings=8, azimuths=32, departs_at=2, arrives_at=4, walk=(1, 3))
    cart = room.mover("departs").boxes[0].mean(axis=0)
    crate = room.mover("arrives").boxes[5].mean(axis=0)
    person = [room.mover("walks").boxes[i].mean(axis=0) for i in (1, 2)]
    inside = [room.scene_at(i).occupied(np.array([cart, crate, *person])) for i in range(6)]
    np.testing.assert_array_equal(
        inside,
        [
            [True, False, False, False],
            [True, False, True, False],
            [False, False, False, True],
            [False, False, False, False],
            [False, True, False, False],
            [False, True, False, False],
        ],
    )
    np.testing.assert_array_equal(room.times, np.arange(6.0))
    assert len(room.scans) == 6 and all(len(s) == 256 for s in room.scans)


def test_a_cart_of_any_size_leaves_and_comes_back_where_it_stood():
    room = changing_room(n_scans=8, rings=8, azimuths=64, cart=(0.3, 0.3, 0.3), departs_at=2,
                         returns_at=5, arrives_at=6, walk=(1, 3))  # fmt: skip
    np.testing.assert_allclose(
        room.mover("departs").boxes[0], [[0.85, -1.1, 0.0], [1.15, -0.8, 0.3]]
    )
    back = room.mover("returns")
    np.testing.assert_array_equal(room.mover("departs").boxes[1], back.boxes[5])
    middle = back.boxes[5].mean(axis=0)[None]
    there = [bool(room.scene_at(i).occupied(middle)[0]) for i in range(8)]
    assert there == [True, True, False, False, False, True, True, True]
    assert room.has("returns") and not changing_room(n_scans=3, rings=4, azimuths=8).has("returns")
    with pytest.raises(ValueError, match="returns after it departs"):
        changing_room(n_scans=8, rings=4, azimuths=8, departs_at=4, returns_at=3)


def test_ghosts_are_counted_until_the_cart_comes_back_and_then_it_is_found():
    """A map that reads everything occupied: every ghost read (1) only between the cart's
    departure and its return, and the cart back read (1) from the scan that sees it again."""
    room = changing_room(n_scans=10, rings=32, azimuths=256, departs_at=3, returns_at=7,
                         arrives_at=8, walk=(1, 5))  # fmt: skip
    probe = ChangeProbe(room, 0.05, np.random.default_rng(0))
    for i in range(10):
        probe.measure(i, lambda points: np.ones(len(points)))
    assert probe.ghosts_until == 7
    assert max(probe.ghost_tally.read) <= 4 and probe.ghost_tally.share(1) == 1.0
    assert probe.return_tally.read[1] > 20 and probe.return_tally.share(1) == 1.0


def test_a_sparse_lidar_on_a_loop_goes_once_round_clear_of_every_solid():
    room = changing_room(n_scans=12, rings=16, azimuths=64, elevations=(-15.0, 15.0),
                         height=1.0, path="loop")  # fmt: skip
    origins = np.array([scan.origin for scan in room.scans])
    np.testing.assert_allclose(origins, sensor_path("loop", 12, 1.0))
    np.testing.assert_allclose(origins[:, 2], 1.0)
    # Once round the room's centre, a twelfth of a turn a scan.
    turns = np.unwrap(np.arctan2(origins[:, 1] / 0.5, origins[:, 0] / 2.6))
    np.testing.assert_allclose(np.diff(turns), 2 * np.pi / 12)
    for i in range(12):
        assert not room.scene_at(i).occupied(origins).any()
    # Rings 2 degrees apart from -15 to +15.
    directions = (room.scans[0].points_world - origins[0])[: 64 * 16]
    elevations = np.degrees(np.arcsin(directions[:, 2] / np.linalg.norm(directions, axis=1)))
    np.testing.assert_allclose(np.unique(elevations.round(6)), np.linspace(-15, 15, 16))
    with pytest.raises(ValueError, match="path must be"):
        sensor_path("spiral", 3, 1.0)
    with pytest.raises(ValueError, match="laps must be"):
        sensor_path("loop", 3, 1.0, laps=0)


def test_a_2d_laser_sees_the_room_its_plane_cuts():
    room = changing_room(n_scans=4, sensor="laser", azimuths=90, height=0.3, path="loop")
    assert room.static.dim == 2 and all(scan.dim == 2 for scan in room.scans)
    np.testing.assert_allclose([s.origin for s in room.scans], sensor_path("loop", 4, 0.3)[:, :2])
    # A table leg is cut at 0.3 m, its top (0.72-0.77 m) is not; the cart is.
    leg, top = np.array([[-0.97, -2.87]]), np.array([[-0.2, -2.5]])
    assert room.static.occupied(leg)[0] and not room.static.occupied(top)[0]
    np.testing.assert_allclose(room.mover("departs").boxes[0], [[0.6, -1.4], [1.4, -0.8]])
    # Every hit lies on a solid's face.
    for i, scan in enumerate(room.scans):
        hits = scan.points_world[scan.hit_mask]
        assert np.abs(room.scene_at(i).surface_distance(hits)).max() < 0.06


def test_a_plane_cuts_discs_from_balls():
    scene = Scene(np.zeros((0, 3)), np.zeros((0, 3)), np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 0.2]]),
                  np.array([0.5, 0.1]))  # fmt: skip
    disc = cut_at(scene, 1.3)
    np.testing.assert_allclose(disc.ball_centres, [[0.0, 0.0]])
    np.testing.assert_allclose(disc.ball_radii, [0.4])


def test_a_depth_camera_looks_ahead_along_the_loop():
    room = changing_room(n_scans=8, sensor="depth", noise_std=0.0, path="loop", laps=2)
    origins = np.array([scan.origin for scan in room.scans])
    np.testing.assert_allclose(origins, sensor_path("loop", 8, 1.2, laps=2))
    np.testing.assert_allclose(origins[:4], origins[4:], atol=1e-12)  # twice round
    for i, scan in enumerate(room.scans):
        rays = scan.points_world - scan.origin
        ranges = np.linalg.norm(rays, axis=1)
        assert ranges.max() <= DEPTH_RANGE and len(scan) <= DEPTH_PIXELS[0] * DEPTH_PIXELS[1]
        # Noise-free: every pixel ends on a face; the view's middle looks along the path.
        assert np.abs(room.scene_at(i).surface_distance(scan.points_world)).max() < 1e-6
        turn = np.pi * i / 2  # a quarter of the ellipse a frame
        ahead = np.array([-2.6 * np.sin(turn), 0.5 * np.cos(turn)])
        middle = np.mean(rays / ranges[:, None], axis=0)[:2]
        assert middle @ ahead / np.linalg.norm(middle) / np.linalg.norm(ahead) > 0.95
    with pytest.raises(ValueError, match="sensor must be"):
        changing_room(n_scans=2, sensor="sonar")


def test_shell_voxels_lie_inside_within_one_voxel_of_the_surface():
    box = np.array([[0.0, 0.0, 0.0], [0.2, 0.2, 0.2]])
    keys = shell_voxels(box, 0.05)
    # A 4 x 4 x 4 block of voxels, every one within 0.05 m of a face but the 2 x 2 x 2 core.
    assert len(keys) == 64 - 8
    assert not contains(np.array([[1, 1, 1]]), keys)[0]


def test_passed_and_hit_voxels_follow_the_rays():
    scan = Scan(np.array([[1.0, 0.025, 0.025], [0.3, 0.125, 0.025]]), np.array([0.0, 0.025, 0.025]),
                np.array([True, False]))  # fmt: skip
    box = np.array([[0.0, 0.0, 0.0], [2.0, 0.2, 0.2]])
    passed = passed_voxels(scan, box, 0.05)
    # The hit ray frees voxels 0 to 18 along x (up to one voxel before its hit), the ray
    # without return all it crosses.
    assert contains(np.array([[k, 0, 0] for k in range(19)]), passed).all()
    assert not contains(np.array([[20, 0, 0]]), passed)[0]
    assert contains(np.array([[5, 2, 0]]), passed)[0]
    np.testing.assert_array_equal(hit_voxels(scan, box, 0.05), [[20, 0, 0]])
    np.testing.assert_allclose(voxel_centres(np.array([[20, 0, 0]]), 0.05), [[1.025, 0.025, 0.025]])


@pytest.fixture(scope="module")
def followed():
    """A small changing room learned by a map that keeps all evidence and one that takes back
    what rays pass through: (measures at the end, ghost tally, arrival tally) of each."""
    room = changing_room(n_scans=8, rings=40, azimuths=400, departs_at=3, arrives_at=4,
                         walk=(1, 5))  # fmt: skip
    results = {}
    for share in (0.0, 0.5):
        probe = ChangeProbe(room, 0.05, np.random.default_rng(0))
        hilbert_map = HilbertMap(MapConfig(pass_retraction=share))
        for i, scan in enumerate(room.scans):
            hilbert_map.integrate_scan(scan)
            last = probe.measure(i, hilbert_map.occupancy)
        results[share] = (last, probe.ghost_tally, probe.arrival_tally)
    return results


def test_a_map_that_takes_back_passed_evidence_forgets_what_left(followed):
    keeps, forgets = followed[0.0], followed[0.5]
    # The cart's surface, three and four scans after rays began to pass through it: 134 and
    # 121 of 191 voxels read occupied where all evidence is kept, 5 and 2 where it is taken
    # back.
    assert keeps[1].share(3) > 0.6 and keeps[1].share(4) > 0.6
    assert forgets[1].share(3) < 0.1 and forgets[1].share(4) < 0.1
    # The person's trail: 4.1 % against 30.9 %.
    assert forgets[0]["trail"] < 0.1 and keeps[0]["trail"] > 0.2


def test_what_stayed_and_what_arrived_are_kept(followed):
    keeps, forgets = followed[0.0], followed[0.5]
    assert forgets[0]["near F1"] == pytest.approx(keeps[0]["near F1"], abs=0.01)
    # The crate two scans after it was first seen: 102 of 120 voxels against 107 (the free
    # samples in front of the floor it stands on lie up to a margin above it).
    assert forgets[2].share(2) > 0.8 and keeps[2].share(2) > 0.8
