"""CARMEN 2D laser logs, and text inputs compressed as logs are distributed."""

import bz2
import gzip
import lzma

import numpy as np
import pytest

from ehm.errors import FileReadError, InputError
from ehm.io.readers import read_scans
from ehm.io.xyz import read_xyz


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


COMPRESSORS = {".gz": gzip.compress, ".bz2": bz2.compress, ".xz": lzma.compress}


@pytest.mark.parametrize("suffix", COMPRESSORS)
@pytest.mark.parametrize("named", [True, False])
def test_compressed_carmen_log_reads_as_the_log(tmp_path, suffix, named):
    # Public CARMEN logs are distributed as x.log.gz, and sometimes renamed x.log.
    text = "".join(f"FLASER 3 1.0 2.0 3.0 {i} 0.5 0.1 0 0 0 host {i}\n" for i in range(4))
    (tmp_path / "a.log").write_text(text)
    packed_path = tmp_path / ("b.log" + (suffix if named else ""))
    packed_path.write_bytes(COMPRESSORS[suffix](text.encode()))
    plain, packed = read_scans(tmp_path / "a.log"), read_scans(packed_path)
    assert len(packed) == len(plain) == 4
    for a, b in zip(plain, packed, strict=True):
        np.testing.assert_array_equal(a.points_world, b.points_world)
        np.testing.assert_array_equal(a.origin, b.origin)


@pytest.mark.parametrize("suffix", COMPRESSORS)
def test_compressed_text_points_and_poses_read_as_plain(tmp_path, suffix):
    points = "1 2 3\n4 5 6\n"
    poses = "1 0 0 0 0 1 0 0 0 0 1 0\n"
    (tmp_path / "a.xyz").write_bytes(COMPRESSORS[suffix](points.encode()))  # named as plain
    (tmp_path / f"b.xyz{suffix}").write_bytes(COMPRESSORS[suffix](points.encode()))
    (tmp_path / f"poses.txt{suffix}").write_bytes(COMPRESSORS[suffix](poses.encode()))
    for name in ("a.xyz", f"b.xyz{suffix}"):
        np.testing.assert_array_equal(read_xyz(tmp_path / name), [[1, 2, 3], [4, 5, 6]])
    (scan,) = read_scans(tmp_path / "a.xyz", poses=tmp_path / f"poses.txt{suffix}")
    np.testing.assert_array_equal(scan.points_world, [[1, 2, 3], [4, 5, 6]])


def test_a_cut_xz_stream_is_named(tmp_path):
    (tmp_path / "a.log.xz").write_bytes(lzma.compress(b"FLASER 2 1.0 2.0 0 0 0\n" * 50)[:-20])
    with pytest.raises(FileReadError, match=r"a\.log\.xz: .*xz stream"):
        read_scans(tmp_path / "a.log.xz")


def test_a_flaser_line_without_its_timestamps_has_no_time(tmp_path):
    (tmp_path / "a.log").write_text("FLASER 2 1.0 2.0 0.0 0.0 0.0\n")
    (scan,) = read_scans(tmp_path / "a.log")
    assert scan.time is None and len(scan) == 2


def test_zero_and_maximum_range_readings_are_no_returns_not_walls(tmp_path):
    """A Hokuyo logs 0 where a beam ranged nothing: read as hits, the robot's own path would
    be drawn as a wall. Zero and maximum-range readings give neither hits nor free space."""
    (tmp_path / "a.log").write_text("FLASER 4 0.0 2.0 0.0 81.83 1.0 2.0 0.0 0 0 0 7.0 host 0\n")
    (scan,) = read_scans(tmp_path / "a.log")
    assert len(scan) == 1 and scan.hit_mask.all()
    assert np.linalg.norm(scan.points_world - scan.origin, axis=1).min() == pytest.approx(2.0)


def test_flaser_lines_take_the_field_of_view_they_are_given(tmp_path):
    """A 240-degree URG logged as FLASER: beam i at theta - fov/2 + i fov/n."""
    (tmp_path / "a.log").write_text("FLASER 3 1.0 1.0 1.0 0.0 0.0 0.0\n")
    (scan,) = read_scans(tmp_path / "a.log", fov=np.radians(240))
    angles = np.degrees(np.arctan2(scan.points_world[:, 1], scan.points_world[:, 0]))
    np.testing.assert_allclose(angles, [-120.0, -40.0, 40.0], atol=1e-9)
    with pytest.raises(InputError, match=r"field of view is in \(0, 2 pi\] radians"):
        read_scans(tmp_path / "a.log", fov=7.0)


def test_robotlaser1_lines_carry_their_own_geometry_and_laser_pose(tmp_path):
    """The Freiburg clinic's lines: start -90 deg, 1 deg steps, 81.9 m maximum, the laser
    0.22 m ahead of the robot; readings of 81.91 m are no-returns."""
    ranges = ["2.0", "81.91", "3.0"]
    line = (
        f"ROBOTLASER1 0 -1.570796 3.141593 0.017453 81.9 0.01 0 3 {' '.join(ranges)} 0 "
        "1.22 0.0 1.570796 1.0 0.0 1.570796 0 0 0 0 0 55.5 host 55.6\n"
    )
    (tmp_path / "a.clf").write_text(line)
    (scan,) = read_scans(tmp_path / "a.clf")
    assert scan.time == 55.5
    np.testing.assert_allclose(scan.origin, [1.22, 0.0])
    # Heading +90 deg: the first beam (-90 deg from it) points along +x, the third 2 deg on.
    np.testing.assert_allclose(scan.points_world[0], [3.22, 0.0], atol=1e-5)
    third = np.radians(2.0)
    np.testing.assert_allclose(
        scan.points_world[1], [1.22 + 3 * np.cos(third), 3 * np.sin(third)], atol=1e-5
    )
    assert len(scan) == 2
    (tmp_path / "b.clf").write_text("ROBOTLASER1 0 -1.57 3.14 0.0 81.9 0.01 0 1 2.0 0 0 0 0\n")
    with pytest.raises(FileReadError, match=r"b\.clf, line 1: malformed ROBOTLASER1 line"):
        read_scans(tmp_path / "b.clf")
