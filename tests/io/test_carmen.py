"""CARMEN 2D laser logs."""

import gzip

import numpy as np

from ehm.io.readers import read_scans


def test_carmen_log(tmp_path):
    ranges = " ".join(["1.0", "81.83", "2.0", "1.5"])
    log = f"ODOM 0 0 0\nFLASER 4 {ranges} 1.0 2.0 0.0 0 0 0 1234.5 host 0.1\n"
    (tmp_path / "a.log").write_text(log)
    (scan,) = read_scans(tmp_path / "a.log")
    assert scan.time == 1234.5  # the line's ipc_timestamp
    assert len(scan) == 3  # the 81.83 m dropout is gone
    np.testing.assert_allclose(scan.origin, [1, 2])
    np.testing.assert_allclose(scan.points_world[0], [1.0, 1.0], atol=1e-12)  # -90 degrees
    np.testing.assert_allclose(scan.points_world[1], [3.0, 2.0], atol=1e-12)  # 0 degrees


def test_gzipped_carmen_log_reads_as_the_log(tmp_path):
    # Public CARMEN logs are distributed as x.log.gz.
    text = "".join(f"FLASER 3 1.0 2.0 3.0 {i} 0.5 0.1 0 0 0 host {i}\n" for i in range(4))
    (tmp_path / "a.log").write_text(text)
    (tmp_path / "a.log.gz").write_bytes(gzip.compress(text.encode()))
    plain, packed = read_scans(tmp_path / "a.log"), read_scans(tmp_path / "a.log.gz")
    assert len(packed) == len(plain) == 4
    for a, b in zip(plain, packed, strict=True):
        np.testing.assert_array_equal(a.points_world, b.points_world)
        np.testing.assert_array_equal(a.origin, b.origin)


def test_a_flaser_line_without_its_timestamps_has_no_time(tmp_path):
    (tmp_path / "a.log").write_text("FLASER 2 1.0 2.0 0.0 0.0 0.0\n")
    (scan,) = read_scans(tmp_path / "a.log")
    assert scan.time is None and len(scan) == 2
