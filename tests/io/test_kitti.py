"""KITTI Velodyne scans placed by their sequence's poses and calib.txt's Tr."""

import numpy as np
import pytest

from ehm.errors import FileReadError, InputError
from ehm.io.readers import read_scans

# Frame 0 at the world origin; frame 1 turned a quarter about z and moved to (10, 20, 30);
# frame 2 moved to (0, 0, 5).
POSES = "1 0 0 0 0 1 0 0 0 0 1 0\n0 -1 0 10 1 0 0 20 0 0 1 30\n1 0 0 0 0 1 0 0 0 0 1 5\n"
# Velodyne to camera: x forward, y left, z up -> x right, y down, z forward.
TR = "Tr: 0 -1 0 0 0 0 -1 0 1 0 0 0.5\n"
T_CAMERA_VELODYNE = np.array([[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0.5], [0, 0, 0, 1]])


@pytest.fixture
def sequence(tmp_path, cloud):
    """A KITTI sequence folder: velodyne/00000{0,1,2}.bin, calib.txt and poses.txt."""
    (tmp_path / "velodyne").mkdir()
    raw = np.column_stack([cloud, np.ones(len(cloud))]).astype("<f4")
    for frame in range(3):
        raw.tofile(tmp_path / "velodyne" / f"00000{frame}.bin")
    (tmp_path / "calib.txt").write_text("P0: " + " ".join(["0"] * 12) + "\n" + TR)
    (tmp_path / "poses.txt").write_text(POSES)
    return tmp_path


def expected_points(cloud, pose_line):
    T_world_camera = np.vstack([np.array(pose_line.split(), float).reshape(3, 4), [0, 0, 0, 1]])
    T = np.linalg.inv(T_CAMERA_VELODYNE) @ T_world_camera @ T_CAMERA_VELODYNE
    return cloud @ T[:3, :3].T + T[:3, 3], T[:3, 3]


def test_maps_are_in_the_first_lidar_frame_with_z_up(sequence, cloud):
    """A camera that drives 5 m along its optical axis (KITTI's z forward) moves its LiDAR 5 m
    along the world's x, level: the ground stays under the sensor."""
    (sequence / "poses.txt").write_text(
        "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 5\n1 0 0 0 0 1 0 0 0 0 1 0\n"
    )
    first, second, _ = read_scans(sequence, poses=sequence / "poses.txt")
    np.testing.assert_allclose(first.origin, [0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(second.origin, [5.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(first.points_world, cloud, atol=1e-6)


def test_scans_without_poses_are_placed_at_an_origin(sequence, cloud):
    (scan,) = read_scans(sequence / "velodyne" / "000001.bin", origin=[1.0, 2.0, 3.0])
    np.testing.assert_allclose(scan.origin, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(scan.points_world, cloud + np.array([1.0, 2.0, 3.0]), atol=1e-6)
    with pytest.raises(InputError, match="--origin X,Y,Z to map them in the LiDAR's own frame"):
        read_scans(sequence / "velodyne" / "000001.bin")


def test_calibration_places_the_velodyne(sequence, cloud):
    bins = sorted((sequence / "velodyne").glob("*.bin"))
    scans = read_scans(bins, poses=sequence / "poses.txt")
    for scan, line in zip(scans, POSES.splitlines(), strict=True):
        points, origin = expected_points(cloud, line)
        np.testing.assert_allclose(scan.points_world, points, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(scan.origin, origin)
    explicit = read_scans(bins, poses=sequence / "poses.txt", calib=sequence / "calib.txt")
    np.testing.assert_array_equal(explicit[1].points_world, scans[1].points_world)


def test_a_subset_takes_its_own_frames_poses(sequence, cloud):
    """Frames 2 and 1 given out of order and without frame 0 still find lines 2 and 1."""
    velodyne = sequence / "velodyne"
    scans = read_scans(
        [velodyne / "000002.bin", velodyne / "000001.bin"], poses=sequence / "poses.txt"
    )
    for scan, line in zip(scans, POSES.splitlines()[1:], strict=True):
        np.testing.assert_allclose(scan.points_world, expected_points(cloud, line)[0], rtol=1e-6)


def test_poses_of_the_velodyne_need_no_calibration(sequence, cloud):
    scans = read_scans(
        [sequence / "velodyne" / "000001.bin"], poses=sequence / "poses.txt", calib="identity"
    )
    rotated = np.column_stack([-cloud[:, 1] + 10, cloud[:, 0] + 20, cloud[:, 2] + 30])
    np.testing.assert_allclose(scans[0].points_world, rotated, rtol=1e-6)
    np.testing.assert_array_equal(scans[0].origin, [10, 20, 30])


def test_kitti_mistakes_are_named(sequence):
    bins = sorted((sequence / "velodyne").glob("*.bin"))
    poses = sequence / "poses.txt"
    with pytest.raises(InputError, match="need the sequence's poses file"):
        read_scans(bins)
    with pytest.raises(InputError, match="give an origin or poses, not both"):
        read_scans(bins, poses=poses, origin=[0, 0, 0])
    (sequence / "calib.txt").unlink()
    with pytest.raises(InputError, match=r"calib\.txt is missing: give its calib\.txt"):
        read_scans(bins, poses=poses)
    (sequence / "calib.txt").write_text("P0: 1 2 3\n")
    with pytest.raises(FileReadError, match=r"calib\.txt: no 'Tr:' line"):
        read_scans(bins, poses=poses)
    (sequence / "velodyne" / "000007.bin").write_bytes(bytes(32))
    with pytest.raises(FileReadError, match=r"poses\.txt: 3 poses: none for frame 7"):
        read_scans([sequence / "velodyne" / "000007.bin"], poses=poses, calib="identity")
    (sequence / "velodyne" / "scan.bin").write_bytes(bytes(32))
    with pytest.raises(FileReadError, match=r"scan\.bin: the name is not a frame number"):
        read_scans([sequence / "velodyne" / "scan.bin"], poses=poses, calib="identity")
    (sequence / "velodyne" / "000001.bin").write_bytes(bytes(20))
    with pytest.raises(FileReadError, match=r"000001\.bin: 20 bytes is not a whole number"):
        read_scans(bins, poses=poses, calib="identity")
    poses.write_text("1 0 0 0 0 2 0 0 0 0 1 0\n")
    with pytest.raises(FileReadError, match=r"poses.txt, line 1: not a pose: its 3x3 part"):
        read_scans(bins[:1], poses=poses, calib="identity")


def test_a_sequence_folder_finds_its_scans_and_poses(tmp_path, cloud):
    """The odometry layout: dataset/sequences/07/{velodyne,calib.txt} and dataset/poses/07.txt."""
    sequence = tmp_path / "dataset" / "sequences" / "07"
    (sequence / "velodyne").mkdir(parents=True)
    raw = np.column_stack([cloud, np.ones(len(cloud))]).astype("<f4")
    for frame in range(3):
        raw.tofile(sequence / "velodyne" / f"00000{frame}.bin")
    (sequence / "calib.txt").write_text(TR)
    (tmp_path / "dataset" / "poses").mkdir()
    (tmp_path / "dataset" / "poses" / "07.txt").write_text(POSES)
    scans = read_scans(sequence)
    assert len(scans) == 3
    np.testing.assert_allclose(
        scans[2].points_world, expected_points(cloud, POSES.splitlines()[2])[0], rtol=1e-6
    )
    with pytest.raises(InputError, match=r"07\.txt: an origin would put every scan at one"):
        read_scans(sequence, origin=[0.0, 0.0, 0.0])
    (tmp_path / "dataset" / "poses" / "07.txt").unlink()
    with pytest.raises(InputError, match=r"need the sequence's poses file \(--poses\), or"):
        read_scans(sequence)


def test_each_frame_takes_its_time_from_the_sequences_times_file(sequence):
    bins = sorted((sequence / "velodyne").glob("*.bin"))
    assert {scan.time for scan in read_scans(bins, poses=sequence / "poses.txt")} == {None}
    (sequence / "times.txt").write_text("0.000000e+00\n1.036022e-01\n2.072043e-01\n")
    scans = read_scans(bins[1:], poses=sequence / "poses.txt")
    assert [scan.time for scan in scans] == [1.036022e-01, 2.072043e-01]
    (sequence / "times.txt").write_text("0.0\nsoon\n")
    with pytest.raises(FileReadError, match=r"times\.txt, line 2: not a time in seconds: 'soon'"):
        read_scans(bins, poses=sequence / "poses.txt")
