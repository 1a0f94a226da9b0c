"""RGB-D frames in the 7-Scenes / tsdf-fusion layout: millimetres, 4x4 poses per frame."""

import numpy as np
import pytest
from depth_folders import seven_scenes_frames

from ehm.errors import AssumptionWarning, FileReadError
from ehm.io.readers import guess_format, read_scans


def test_frames_are_millimetres_through_the_folders_camera(tmp_path):
    folder = seven_scenes_frames(tmp_path / "data" / "rgbd-frames", [1500, 3000])
    (tmp_path / "data" / "camera-intrinsics.txt").write_text("2 0 0\n0 2 1\n0 0 1\n")
    assert guess_format(folder) == "7scenes"
    first, second = read_scans(folder)
    # z = 1.5 m: x = (4 - 0) * 1.5 / 2, y = (2 - 1) * 1.5 / 2; 65535 is no reading.
    np.testing.assert_allclose(first.points_world, [[3.0, 0.75, 1.5]])
    np.testing.assert_allclose(second.points_world, [[1.0 + 6.0, 1.5, 3.0]])
    np.testing.assert_allclose(second.origin, [1.0, 0.0, 0.0])


def test_without_a_camera_file_7_scenes_kinect_is_assumed_and_said(tmp_path):
    folder = seven_scenes_frames(tmp_path / "seq-01", [2000])
    with pytest.warns(AssumptionWarning, match="7-Scenes' Kinect is assumed .*fx 585"):
        (scan,) = read_scans(folder)
    np.testing.assert_allclose(scan.points_world, [[(4 - 320) * 2 / 585, (2 - 240) * 2 / 585, 2.0]])
    (scan,) = read_scans(folder, intrinsics=[2, 2, 0, 0], depth_scale=500)  # nothing assumed
    np.testing.assert_allclose(scan.points_world, [[8.0, 4.0, 4.0]])


def test_a_frame_without_its_pose_is_named(tmp_path):
    folder = seven_scenes_frames(tmp_path / "seq", [2000, 2000])
    (folder / "frame-000001.pose.txt").unlink()
    with pytest.raises(FileReadError, match=r"frame-000001\.depth\.png: no pose"):
        read_scans(folder, intrinsics=[2, 2, 0, 0])
    (folder / "frame-000001.pose.txt").write_text("1 0 0\n")
    with pytest.raises(FileReadError, match=r"frame-000001\.pose\.txt: expected 4x4"):
        read_scans(folder, intrinsics=[2, 2, 0, 0])


def test_a_camera_file_that_is_no_camera_is_named(tmp_path):
    folder = seven_scenes_frames(tmp_path / "seq", [2000])
    (folder / "camera-intrinsics.txt").write_text("0 0 320\n0 0 240\n0 0 1\n")
    with pytest.raises(FileReadError, match=r"camera-intrinsics\.txt: camera fx 0\.0"):
        read_scans(folder)
