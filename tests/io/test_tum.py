"""TUM RGB-D depth frames, in the project's poses.txt layout and TUM's own download layout."""

import numpy as np
import pytest

from ehm.errors import AssumptionWarning, FileReadError, InputError
from ehm.io.readers import read_scans
from ehm.io.tum import FREIBURG_CAMERAS


def _depth_png(path, value=10000, shape=(6, 8), pixel=(2, 4)):
    from PIL import Image

    depth = np.zeros(shape, dtype=np.uint16)
    depth[pixel] = value
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(depth).save(path)


def test_poses_txt_frames_are_read_through_the_given_camera(tmp_path):
    _depth_png(tmp_path / "depth" / "1311877813.991479.png")  # 2 m at pixel (u=4, v=2)
    _depth_png(tmp_path / "depth" / "first.png")
    poses = "depth/1311877813.991479.png 1 2 3 0 0 0 1\ndepth/first.png 1 2 3 0 0 0 1\n"
    (tmp_path / "poses.txt").write_text("# header\n" + poses)
    scans = read_scans(tmp_path, intrinsics=[1.0, 1.0, 0.0, 0.0], depth_scale=5000)
    assert len(scans) == 2 and len(scans[0]) == 1
    # A frame's time is its name, where that is a number.
    assert scans[0].time == 1311877813.991479 and scans[1].time is None
    # Only every second pixel is read: (4, 2) is one of them.
    np.testing.assert_allclose(scans[0].points_world, [[1.0 + 8.0, 2.0 + 4.0, 3.0 + 2.0]])


def test_the_freiburg_camera_is_chosen_by_the_sequence_name_and_said(tmp_path):
    for number, camera in FREIBURG_CAMERAS.items():
        folder = tmp_path / f"rgbd_dataset_freiburg{number}_xyz"
        _depth_png(folder / "depth" / "0.png")
        (folder / "poses.txt").write_text("depth/0.png 0 0 0 0 0 0 1\n")
        with pytest.warns(AssumptionWarning, match=f"Freiburg {number}'s camera"):
            (scan,) = read_scans(folder)
        x, y, z = scan.points_world[0]
        assert z == 2.0
        expected = [(4 - camera.cx) * 2 / camera.fx, (2 - camera.cy) * 2 / camera.fy]
        np.testing.assert_allclose([x, y], expected)


def test_a_folder_that_names_no_camera_is_refused_naming_the_options(tmp_path):
    _depth_png(tmp_path / "frames" / "depth" / "0.png")
    (tmp_path / "frames" / "poses.txt").write_text("depth/0.png 0 0 0 0 0 0 1\n")
    with pytest.raises(InputError, match="--intrinsics FX,FY,CX,CY and --depth-scale"):
        read_scans(tmp_path / "frames")


def test_the_official_layout_associates_ground_truth_within_20_ms(tmp_path):
    """depth.txt and groundtruth.txt as TUM distributes them; a frame 30 ms from every pose is
    left out and said, the others take the nearest pose, one to one."""
    folder = tmp_path / "rgbd_dataset_freiburg1_desk"
    for name in ("100.000000", "100.033000", "100.500000"):
        _depth_png(folder / "depth" / f"{name}.png")
    (folder / "depth.txt").write_text(
        "# depth maps\n# file: 'x.bag'\n# timestamp filename\n"
        "100.000000 depth/100.000000.png\n100.033000 depth/100.033000.png\n"
        "100.500000 depth/100.500000.png\n"
    )
    (folder / "groundtruth.txt").write_text(
        "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
        "99.9950 1 0 0 0 0 0 1\n100.0400 2 0 0 0 0 0 1\n100.4700 3 0 0 0 0 0 1\n"
    )
    with pytest.warns(AssumptionWarning) as notes:
        scans = read_scans(folder)
    assert any(
        "1 of 3 depth frames have no ground-truth pose within 20 ms" in str(n.message)
        for n in notes
    )
    assert [scan.time for scan in scans] == [100.0, 100.033]
    assert [scan.origin[0] for scan in scans] == [1.0, 2.0]


def test_broken_tum_files_are_named_by_line(tmp_path):
    folder = tmp_path / "fr2"
    _depth_png(folder / "depth" / "0.png")
    (folder / "poses.txt").write_text("depth/0.png 0 0 0 0 0 1\n")
    with pytest.warns(AssumptionWarning), pytest.raises(FileReadError, match=r"poses\.txt, line 1"):
        read_scans(folder)
    (folder / "poses.txt").unlink()
    (folder / "depth.txt").write_text("soon depth/0.png\n")
    (folder / "groundtruth.txt").write_text("0 0 0 0 0 0 0 1\n")
    with (
        pytest.warns(AssumptionWarning),
        pytest.raises(FileReadError, match=r"depth\.txt, line 1: not a time in seconds: 'soon'"),
    ):
        read_scans(folder)
    (folder / "depth.txt").write_text("5.0 depth/0.png\n")
    with (
        pytest.warns(AssumptionWarning),
        pytest.raises(FileReadError, match="no pose within 20 ms of any frame"),
    ):
        read_scans(folder)
