"""Ouster captures: lidar packets in a pcap decoded with their metadata."""

import json

import numpy as np
import pytest
from ouster_captures import ouster_metadata, write_ouster

from ehm.errors import AssumptionWarning, FileReadError
from ehm.eval.datasets.real import data_dir
from ehm.io.readers import guess_format, read_scans


def _ranges(width=16, beams=3, frames=1):
    """(F, H, W) millimetres: beam b of column m at 1000 + 10 b + m mm, one no-return."""
    ranges = 1000 + 10 * np.arange(beams)[:, None] + np.arange(width)[None, :]
    ranges = np.repeat(ranges[None], frames, axis=0).astype(np.int64)
    ranges[:, 0, 1] = 0
    return ranges


@pytest.mark.parametrize("profile", ["RNG19_RFL8_SIG16_NIR16", "RNG15_RFL8_NIR8", "LEGACY"])
def test_points_follow_the_beam_geometry_in_the_sensor_frame(tmp_path, profile):
    width = 16
    metadata = ouster_metadata([0.0, 30.0, -30.0], width, profile, columns_per_packet=4)
    if profile == "LEGACY":
        metadata["data_format"]["columns_per_packet"] = 16
    ranges = _ranges(width) // 8 * 8  # RNG15 keeps ranges in steps of 8 mm
    capture = write_ouster(tmp_path / "os.pcap", metadata, ranges)
    with pytest.warns(AssumptionWarning, match=rf"os\.pcap: decoded with os\.json \({profile}"):
        (scan,) = read_scans(capture)
    assert len(scan) == 3 * width - 1  # the zero range is no return
    assert np.allclose(scan.origin, [0.0, 0.0, 0.03618])
    # Column m looks 360 m / W degrees clockwise from the LiDAR's +x, which is the sensor's -x.
    level_beam = scan.points_world[np.isclose(scan.points_world[:, 2], 0.03618)]
    columns = np.flatnonzero(ranges[0, 0] > 0)
    angles = 2 * np.pi * columns / width
    expected = (
        ranges[0, 0, columns, None] / 1000 * np.column_stack([-np.cos(angles), np.sin(angles)])
    )
    assert np.allclose(level_beam[:, :2], expected, atol=1e-9)
    up = scan.points_world[scan.points_world[:, 2] > 0.1]
    horizontal = np.hypot(up[:, 0], up[:, 1])
    assert np.allclose(np.degrees(np.arctan2(up[:, 2] - 0.03618, horizontal)), 30.0)


def test_frames_are_scans_timed_by_their_first_column_and_fragments_are_joined(tmp_path):
    metadata = ouster_metadata([0.0, 10.0], 16, "RNG19_RFL8_SIG16_NIR16", columns_per_packet=16)
    capture = write_ouster(tmp_path / "os.pcap", metadata, _ranges(16, 2, 3), fragment=True)
    with pytest.warns(AssumptionWarning) as notes:
        scans = read_scans(capture)
    assert [scan.time for scan in scans] == [1.0, 2.0, 3.0]
    assert [len(scan) for scan in scans] == [31, 31, 31]
    assert any("mapped from one sensor pose" in str(note.message) for note in notes)
    poses = tmp_path / "poses.txt"
    poses.write_text("".join(f"1 0 0 {x} 0 1 0 0 0 0 1 0\n" for x in (0, 1, 2)))
    moved = read_scans(capture, poses=poses)
    assert np.allclose([scan.origin[0] for scan in moved], [0, 1, 2])
    assert np.allclose(moved[2].points_world - [2, 0, 0], scans[2].points_world)
    poses.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(FileReadError, match=r"poses\.txt: 1 poses for 3 frames"):
        read_scans(capture, poses=poses)


def test_a_capture_cut_short_is_read_up_to_the_cut(tmp_path):
    metadata = ouster_metadata([0.0, 10.0], 16, "RNG19_RFL8_SIG16_NIR16", columns_per_packet=4)
    capture = write_ouster(tmp_path / "os.pcap", metadata, _ranges(16, 2, 2))
    capture.write_bytes(capture.read_bytes()[:-100])
    with pytest.warns(AssumptionWarning, match=r"os\.pcap ends inside a packet"):
        scans = read_scans(capture)
    assert [len(scan) for scan in scans] == [31, 23]  # the last packet's 4 columns lost


def test_captures_without_their_metadata_or_packets_are_refused(tmp_path):
    assert guess_format("drive.pcap") == "ouster"
    metadata = ouster_metadata([0.0], 8, "RNG19_RFL8_SIG16_NIR16")
    capture = write_ouster(tmp_path / "a.pcap", metadata, _ranges(8, 1))
    (tmp_path / "b.json").write_text("{}")
    capture.with_suffix(".json").rename(tmp_path / "elsewhere.json")
    with pytest.raises(
        FileReadError, match=r"neither an Ouster LiDAR, whose metadata JSON .*a\.json"
    ):
        read_scans(capture)
    metadata["data_format"]["udp_profile_lidar"] = "FUSA_RNG15_RFL8_NIR8_DUAL"
    capture.with_suffix(".json").write_text(json.dumps(metadata))
    with pytest.raises(FileReadError, match="profile 'FUSA_RNG15_RFL8_NIR8_DUAL' is not read"):
        read_scans(capture)
    metadata["data_format"]["udp_profile_lidar"] = "LEGACY"
    capture.with_suffix(".json").write_text(json.dumps(metadata))
    with pytest.raises(FileReadError, match=r"no lidar packets of .* \(LEGACY, 1 beams\)"):
        read_scans(capture)
    capture.write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(40))
    with pytest.raises(FileReadError, match="pcapng capture; save it as pcap first"):
        read_scans(capture)


def test_a_real_capture_matches_its_own_geometry():
    """ouster-sdk's OS-0-128 test capture: one frame, its ground 1.96 m under the sensor."""
    capture = data_dir() / "ouster_pcap" / "OS-0-128-U1_v2.3.0_1024x10.pcap"
    if not capture.exists():
        pytest.skip(f"{capture} not found (set EHM_DATA_DIR to the data folder)")
    with pytest.warns(AssumptionWarning):
        (scan,) = read_scans(capture)
    assert len(scan) == 97_299  # pixels with a return
    ranges = np.linalg.norm(scan.points_world - scan.origin, axis=1)
    assert 0.2 < ranges.min() < 0.3 and 128 < ranges.max() < 129
    # The ground: a level plane about 1.95 m under the sensor.
    points = scan.points_world
    near_ground = (points[:, 2] < -1.5) & (np.hypot(points[:, 0], points[:, 1]) < 15)
    x, y, z = points[near_ground].T
    (a, b, c), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), z, rcond=None)
    assert np.degrees(np.arctan(np.hypot(a, b))) < 1.0
    assert -2.0 < c < -1.85
