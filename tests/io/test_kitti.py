"""KITTI Velodyne scans with poses."""

import numpy as np
import pytest

from ehm.io.readers import read_scans


def test_kitti_bin_with_poses(tmp_path, cloud):
    raw = np.column_stack([cloud, np.ones(len(cloud))]).astype("<f4")
    raw.tofile(tmp_path / "000000.bin")
    raw.tofile(tmp_path / "000001.bin")
    (tmp_path / "poses.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n0 -1 0 10 1 0 0 20 0 0 1 30\n")
    scans = read_scans(
        [tmp_path / "000000.bin", tmp_path / "000001.bin"], poses=tmp_path / "poses.txt"
    )
    np.testing.assert_allclose(scans[0].points_world, cloud, rtol=1e-6)
    rotated = np.column_stack([-cloud[:, 1] + 10, cloud[:, 0] + 20, cloud[:, 2] + 30])
    np.testing.assert_allclose(scans[1].points_world, rotated, rtol=1e-6)
    np.testing.assert_array_equal(scans[1].origin, [10, 20, 30])
    with pytest.raises(ValueError, match="need a poses file"):
        read_scans(tmp_path / "000000.bin")
