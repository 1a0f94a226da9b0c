"""PCD point clouds."""

import gzip
import struct

import numpy as np

from ehm.io.pcd import read_pcd
from ehm.io.readers import read_scans


def _pcd_header(kind, n):
    return (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 1 2 3 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
    ).encode()


def test_pcd_ascii_binary_and_compressed(tmp_path, cloud, lzf_compress):
    n = len(cloud)
    (tmp_path / "a.pcd").write_bytes(
        _pcd_header("ascii", n) + "".join(f"{x} {y} {z}\n" for x, y, z in cloud).encode()
    )
    (tmp_path / "b.pcd").write_bytes(_pcd_header("binary", n) + cloud.astype("<f4").tobytes())
    field_major = cloud.T.astype("<f4").tobytes()
    packed = lzf_compress(field_major)
    (tmp_path / "c.pcd").write_bytes(
        _pcd_header("binary_compressed", n)
        + struct.pack("<II", len(packed), len(field_major))
        + packed
    )
    (tmp_path / "b.pcd.gz").write_bytes(gzip.compress((tmp_path / "b.pcd").read_bytes()))
    for name in ("a.pcd", "b.pcd", "c.pcd", "b.pcd.gz"):
        points, viewpoint = read_pcd(tmp_path / name)
        np.testing.assert_allclose(points, cloud, rtol=1e-6)
        np.testing.assert_array_equal(viewpoint, [1, 2, 3])
    scans = read_scans(tmp_path / "c.pcd")
    np.testing.assert_array_equal(scans[0].origin, [1, 2, 3])
