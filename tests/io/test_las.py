"""LAS and LAZ point clouds written by laspy, read back."""

import numpy as np
import pytest

from ehm.errors import FileReadError
from ehm.io.readers import read_scans

laspy = pytest.importorskip("laspy")


@pytest.mark.parametrize("name", ["cloud.las", "cloud.laz"])
def test_las_and_laz_read_back_to_their_scale(tmp_path, cloud, name):
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([100.0, 200.0, 0.0])
    las = laspy.LasData(header)
    shifted = cloud + np.array([100.0, 200.0, 0.0])
    las.x, las.y, las.z = shifted.T
    las.write(tmp_path / name)
    (scan,) = read_scans(tmp_path / name, origin=[100.0, 200.0, 1.5])
    np.testing.assert_allclose(scan.points_world, shifted, atol=0.0005 + 1e-9)
    np.testing.assert_array_equal(scan.origin, [100.0, 200.0, 1.5])


def test_broken_las_files_are_named(tmp_path):
    (tmp_path / "junk.las").write_bytes(b"LASF" + bytes(300))
    with pytest.raises(FileReadError, match=r"junk\.las: not a readable LAS/LAZ file"):
        read_scans(tmp_path / "junk.las")


@pytest.mark.parametrize(
    ("offset", "value", "message"),
    [
        (100, 10**6, "variable-length records do not fit the header"),
        (107, 10**9, "byte 227: truncated: 1000000000 points of 34 bytes announced"),
        (96, 10**8, "point data at byte 100000000 outside the file"),
    ],
)
def test_las_headers_the_file_cannot_hold_are_named(tmp_path, cloud, offset, value, message):
    """Sizes in the header are checked before laspy reads (bit flips there made it loop)."""
    header = laspy.LasHeader(point_format=3, version="1.2")
    las = laspy.LasData(header)
    las.x, las.y, las.z = cloud.T
    las.write(tmp_path / "good.las")
    data = bytearray((tmp_path / "good.las").read_bytes())
    data[offset : offset + 4] = value.to_bytes(4, "little")
    (tmp_path / "bad.las").write_bytes(bytes(data))
    with pytest.raises(FileReadError, match=message):
        read_scans(tmp_path / "bad.las")
