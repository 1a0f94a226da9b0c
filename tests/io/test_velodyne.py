"""Velodyne captures decoded by velodyne-decoder: a real HDL-32E rotation (tests/io/data)."""

from pathlib import Path

import numpy as np
import pytest

from ehm.errors import AssumptionWarning, FileReadError
from ehm.io.readers import guess_format, read_scans

pytest.importorskip("velodyne_decoder")
CAPTURE = Path(__file__).parent / "data" / "hdl32e.pcap"


def test_a_real_rotation_matches_its_own_geometry():
    assert guess_format(CAPTURE) == "velodyne"
    with pytest.warns(AssumptionWarning, match="Velodyne packets, the model and its calib"):
        scans = read_scans(CAPTURE)
    first = scans[0]  # the capture's one whole rotation; then the start of the next
    assert len(scans) == 2 and 18_000 < len(first) < 18_300
    assert first.time == pytest.approx(1415644617.485, abs=1e-3)
    ranges = np.linalg.norm(first.points_world - first.origin, axis=1)
    assert ranges.min() > 2.0 and ranges.max() < 111.0
    # 32 beams from -30.67 to +10.67 degrees, the model the packets name.
    elevation = np.degrees(np.arcsin((first.points_world[:, 2]) / ranges))
    assert -31.0 < elevation.min() < -30.0 and 10.0 < elevation.max() < 11.0
    # The ground: a level plane about 0.96 m under the sensor.
    points = first.points_world
    near = (np.hypot(points[:, 0], points[:, 1]) < 20) & (np.abs(points[:, 2] + 0.96) < 0.3)
    x, y, z = points[near].T
    (a, b, c), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), z, rcond=None)
    assert near.sum() > 1000 and np.degrees(np.arctan(np.hypot(a, b))) < 1.0
    assert c == pytest.approx(-0.96, abs=0.05)


def test_captures_of_no_known_sensor_are_refused_naming_both(tmp_path):
    from ouster_captures import write_capture

    capture = tmp_path / "other.pcap"
    write_capture(capture, [bytes(100)] * 3, port=9000)
    with pytest.raises(FileReadError, match=r"neither an Ouster LiDAR, whose metadata JSON .*"
                       r"\(other\.json\), nor a Velodyne"):  # fmt: skip
        read_scans(capture)
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(CAPTURE.read_bytes()[:50_000])
    assert guess_format(cut) == "velodyne"
    with pytest.warns(AssumptionWarning):
        assert len(read_scans(cut)) == 1  # the decoder reads up to the cut
