"""Poses files (KITTI and TUM layouts) and point clouds placed by one pose per file."""

import numpy as np
import pytest

from ehm.errors import FileReadError, InputError
from ehm.io.poses import read_poses
from ehm.io.readers import read_scans

QUARTER_TURN_Z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def test_both_layouts_give_the_same_poses(tmp_path):
    half = np.sqrt(0.5)
    (tmp_path / "kitti.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n0 -1 0 10 1 0 0 20 0 0 1 30\n")
    (tmp_path / "tum.txt").write_text(
        f"# timestamp tx ty tz qx qy qz qw\n0.0 0 0 0 0 0 0 1\n\n0.1 10 20 30 0 0 {half} {half}\n"
    )
    for name in ("kitti.txt", "tum.txt"):
        first, second = read_poses(tmp_path / name)
        np.testing.assert_array_equal(first, np.eye(4))
        np.testing.assert_allclose(second[:3, :3], QUARTER_TURN_Z, atol=1e-15)
        np.testing.assert_array_equal(second[:3, 3], [10, 20, 30])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no poses"),
        ("1 2 3\n", r"line 1: expected 12 \(KITTI\) or 8 \(TUM\) numbers per line, got 3"),
        ("0 0 0 0 0 0 0 1\n0 0 0 0 0 0 1\n", "line 2: expected 8 numbers per line, got 7"),
        ("0 0 0 0 0 0 0 1\n0 0 0 nan 0 0 0 1\n", "line 2: not a pose: numbers that are not fin"),
        ("0 0 0 0 x 0 0 1\n", "line 1: not a pose: could not convert"),
        ("0 0 0 0 0 0 0 0\n", r"line 1: not a pose: quaternion .* is no rotation"),
        ("2 0 0 0 0 1 0 0 0 0 1 0\n", r"line 1: not a pose: its 3x3 part is not a rotation"),
        ("-1 0 0 0 0 1 0 0 0 0 1 0\n", "line 1: not a pose: its 3x3 part is not a rotation"),
    ],
)
def test_bad_poses_files_are_named(tmp_path, text, message):
    (tmp_path / "poses.txt").write_text(text)
    with pytest.raises(FileReadError, match=message):
        read_poses(tmp_path / "poses.txt")


def test_each_point_cloud_file_takes_its_pose(tmp_path, input_files, cloud):
    """Files in their sensor's frame, one pose each, in the order given; a PCD's VIEWPOINT is
    its sensor's place in its own frame, so the pose carries it into the world too."""
    paths = [input_files[name][0] for name in ("a.pcd", "b.pcd", "c.pcd")]
    (tmp_path / "poses.txt").write_text(
        "1 0 0 5 0 1 0 0 0 0 1 0\n0 -1 0 10 1 0 0 20 0 0 1 30\n1 0 0 0 0 1 0 0 0 0 1 0\n"
    )
    scans = read_scans(paths, poses=tmp_path / "poses.txt")
    viewpoint = np.array([1.0, 2.0, 3.0])  # the PCDs' VIEWPOINT
    np.testing.assert_allclose(scans[0].points_world, cloud + np.array([5, 0, 0]), rtol=1e-7)
    np.testing.assert_array_equal(scans[0].origin, viewpoint + np.array([5, 0, 0]))
    turned = cloud @ QUARTER_TURN_Z.T + [10, 20, 30]
    np.testing.assert_allclose(scans[1].points_world, turned, rtol=1e-6)
    np.testing.assert_allclose(scans[1].origin, QUARTER_TURN_Z @ viewpoint + [10, 20, 30])
    np.testing.assert_allclose(scans[2].points_world, cloud, rtol=1e-7)
    xyz, _ = input_files["a.xyz"]
    (tmp_path / "one.txt").write_text("0 -1 0 10 1 0 0 20 0 0 1 30\n")
    (scan,) = read_scans(xyz, poses=tmp_path / "one.txt")
    np.testing.assert_allclose(scan.points_world, turned, rtol=1e-6)
    np.testing.assert_array_equal(scan.origin, [10, 20, 30])
    (tmp_path / "two.txt").write_text("1 0 0 5 0 1 0 0 0 0 1 0\n" * 2)
    with pytest.raises(FileReadError, match=r"two\.txt: 2 poses for 3 files"):
        read_scans(paths, poses=tmp_path / "two.txt")


def test_inputs_of_mixed_formats_are_refused(input_files):
    paths = [input_files[name][0] for name in ("a.xyz", "b.ply")]
    with pytest.raises(InputError, match=r"b\.ply is ply, a\.xyz is xyz: give files of one"):
        read_scans(paths)
