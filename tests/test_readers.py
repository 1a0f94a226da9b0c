import bz2
import struct

import numpy as np
import pytest
from conftest import load_or_skip

from ehm.datasets import real
from ehm.io.lzf import lzf_decompress, lzf_decompress_reference
from ehm.io.pointcloud import read_pcd, read_ply, read_xyz
from ehm.io.readers import guess_format, read_scans
from ehm.io.sequences import read_tum


@pytest.fixture
def cloud(rng):
    return rng.uniform(-5, 5, (50, 3)).astype(np.float32).astype(np.float64)


def _lzf_compress(data: bytes) -> bytes:
    """Greedy LZF encoder (brute-force matching) for test data."""
    out, literal, i = bytearray(), bytearray(), 0

    def flush():
        while literal:
            chunk = literal[:32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
            del literal[:32]

    while i < len(data):
        best_len, best_off = 0, 0
        for start in range(max(0, i - 8191), i):
            length = 0
            while (
                i + length < len(data) and length < 264 and data[start + length] == data[i + length]
            ):
                length += 1
            if length > best_len:
                best_len, best_off = length, i - start - 1
        if best_len >= 3:
            flush()
            length = best_len - 2
            if length < 7:
                out.append((length << 5) | (best_off >> 8))
            else:
                out.append((7 << 5) | (best_off >> 8))
                out.append(length - 7)
            out.append(best_off & 0xFF)
            i += best_len
        else:
            literal.append(data[i])
            i += 1
    flush()
    return bytes(out)


def test_lzf_compiled_matches_reference_and_round_trips(rng):
    data = bytes(rng.integers(0, 4, 3000).astype(np.uint8)) + b"abc" * 200
    packed = _lzf_compress(data)
    assert len(packed) < len(data)
    assert lzf_decompress(packed, len(data)) == data
    assert lzf_decompress_reference(packed, len(data)) == data
    with pytest.raises(ValueError, match="corrupt LZF"):
        lzf_decompress(packed[:-5], len(data))


def test_xyz_text_and_bz2(tmp_path, cloud):
    text = "\n".join(" ".join(f"{v:.9g}" for v in p) for p in cloud)
    (tmp_path / "a.xyz").write_text(text)
    (tmp_path / "a.dat.bz2").write_bytes(bz2.compress(text.encode()))
    np.testing.assert_allclose(read_xyz(tmp_path / "a.xyz"), cloud, rtol=1e-7)
    np.testing.assert_allclose(read_xyz(tmp_path / "a.dat.bz2"), cloud, rtol=1e-7)


def test_ply_ascii_and_binary(tmp_path, cloud):
    header = "ply\nformat {}\nelement vertex {}\nproperty float x\nproperty float y\n"
    header += "property float z\nproperty uchar intensity\nend_header\n"
    ascii_body = "".join(f"{x} {y} {z} 7\n" for x, y, z in cloud)
    (tmp_path / "a.ply").write_text(header.format("ascii 1.0", len(cloud)) + ascii_body)
    records = np.zeros(len(cloud), dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("i", "u1")])
    for axis, name in enumerate("xyz"):
        records[name] = cloud[:, axis]
    binary = header.format("binary_big_endian 1.0", len(cloud)).encode() + records.tobytes()
    (tmp_path / "b.ply").write_bytes(binary)
    np.testing.assert_allclose(read_ply(tmp_path / "a.ply"), cloud, rtol=1e-6)
    np.testing.assert_array_equal(read_ply(tmp_path / "b.ply"), cloud)
    (tmp_path / "c.ply").write_bytes(binary[:-10])
    with pytest.raises(ValueError, match="truncated"):
        read_ply(tmp_path / "c.ply")


def _pcd_header(kind, n):
    return (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 1 2 3 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
    ).encode()


def test_pcd_ascii_binary_and_compressed(tmp_path, cloud):
    n = len(cloud)
    (tmp_path / "a.pcd").write_bytes(
        _pcd_header("ascii", n) + "".join(f"{x} {y} {z}\n" for x, y, z in cloud).encode()
    )
    (tmp_path / "b.pcd").write_bytes(_pcd_header("binary", n) + cloud.astype("<f4").tobytes())
    field_major = cloud.T.astype("<f4").tobytes()
    packed = _lzf_compress(field_major)
    (tmp_path / "c.pcd").write_bytes(
        _pcd_header("binary_compressed", n)
        + struct.pack("<II", len(packed), len(field_major))
        + packed
    )
    for name in ("a.pcd", "b.pcd", "c.pcd"):
        points, viewpoint = read_pcd(tmp_path / name)
        np.testing.assert_allclose(points, cloud, rtol=1e-6)
        np.testing.assert_array_equal(viewpoint, [1, 2, 3])
    scans = read_scans(tmp_path / "c.pcd")
    np.testing.assert_array_equal(scans[0].origin, [1, 2, 3])


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


def test_octomap_graph(tmp_path, cloud):
    def node(points, translation, quaternion_wxyz, node_id):
        body = struct.pack("<I", len(points))
        for p in points:
            body += struct.pack("<i3d", 3, *p)
        body += struct.pack("<i3d", 3, *translation) + struct.pack("<i4d", 4, *quaternion_wxyz)
        return body + struct.pack("<I", node_id)

    half_turn_z = (0.0, 0.0, 0.0, 1.0)  # 180 degrees about z
    data = struct.pack("<I", 2) + node(cloud, (0, 0, 0), (1, 0, 0, 0), 0)
    data += node(cloud[:10], (1, 2, 3), half_turn_z, 1) + struct.pack("<I", 0)
    (tmp_path / "a.graph").write_bytes(data)
    scans = read_scans(tmp_path / "a.graph")
    np.testing.assert_allclose(scans[0].points_world, cloud)
    expected = np.column_stack([1 - cloud[:10, 0], 2 - cloud[:10, 1], 3 + cloud[:10, 2]])
    np.testing.assert_allclose(scans[1].points_world, expected, atol=1e-12)
    (tmp_path / "b.graph").write_bytes(data[:100])
    with pytest.raises(ValueError, match="truncated OctoMap graph"):
        read_scans(tmp_path / "b.graph")


def test_tum_depth_frames(tmp_path):
    from PIL import Image

    depth = np.zeros((6, 8), dtype=np.uint16)
    depth[2, 4] = 10000  # 2 m at pixel (u=4, v=2)
    (tmp_path / "depth").mkdir()
    Image.fromarray(depth).save(tmp_path / "depth" / "0.png")
    (tmp_path / "poses.txt").write_text("# header\ndepth/0.png 1 2 3 0 0 0 1\n")
    assert len(read_scans(tmp_path)) == 1  # a folder with poses.txt reads as TUM
    scans = read_tum(tmp_path, fx=2.0, fy=2.0, cx=4.0, cy=1.0, pixel_stride=1)
    assert len(scans) == 1 and len(scans[0]) == 1
    np.testing.assert_allclose(scans[0].points_world, [[1.0, 2.0 + 1.0, 3.0 + 2.0]])


def test_carmen_log(tmp_path):
    ranges = " ".join(["1.0", "81.83", "2.0", "1.5"])
    (tmp_path / "a.log").write_text(f"ODOM 0 0 0\nFLASER 4 {ranges} 1.0 2.0 0.0 0 0 0 0 host 0\n")
    (scan,) = read_scans(tmp_path / "a.log")
    assert len(scan) == 3  # the 81.83 m dropout is gone
    np.testing.assert_allclose(scan.origin, [1, 2])
    np.testing.assert_allclose(scan.points_world[0], [1.0, 1.0], atol=1e-12)  # -90 degrees
    np.testing.assert_allclose(scan.points_world[1], [3.0, 2.0], atol=1e-12)  # 0 degrees


def test_format_guess_and_errors(tmp_path):
    assert guess_format("a.PCD") == "pcd"
    assert guess_format("scan.dat.bz2") == "xyz"
    with pytest.raises(ValueError, match=r"unknown extension '\.abc'"):
        guess_format("a.abc")
    with pytest.raises(ValueError, match="no such file"):
        read_scans(tmp_path / "missing.ply")


def test_real_octomap_scan():
    (scan,) = load_or_skip(real.octomap_scan)
    assert len(scan) == 88206
    np.testing.assert_allclose(scan.origin, [0.035, 0.0, 0.513])


def test_real_pcl_room():
    scans = load_or_skip(real.pcl_room)
    assert len(scans) == 2
    for scan in scans:
        ranges = np.linalg.norm(scan.points_world - scan.origin, axis=1)
        assert 80_000 < len(scan) <= 112_624 and ranges.min() >= 0.3


def test_real_tum_sequence():
    scans = load_or_skip(real.tum_fr2_pioneer_slam2)
    assert len(scans) == 10
    assert all(10_000 < len(s) <= 640 * 480 // 4 for s in scans)


def test_real_intel_lab():
    scans = load_or_skip(real.intel_lab)
    assert len(scans) == 910 and all(s.dim == 2 for s in scans)
    ranges = np.concatenate([np.linalg.norm(s.points_world - s.origin, axis=1) for s in scans])
    assert ranges.max() < 81.0
