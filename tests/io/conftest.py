"""Fixtures of the file-format tests: a point cloud, an LZF encoder, and a small valid file
of every input format."""

import bz2
import struct

import numpy as np
import pytest
from depth_folders import redwood_sequence, seven_scenes_frames
from las_files import write_las
from ouster_captures import ouster_metadata, write_ouster


@pytest.fixture
def cloud(rng):
    """(50, 3) float64 points that float32 holds exactly."""
    return rng.uniform(-5, 5, (50, 3)).astype(np.float32).astype(np.float64)


@pytest.fixture
def input_files(tmp_path, cloud):
    """One small valid input of each reader, by name: {name: (path, read_scans keywords)}.
    The KITTI scan sits in a sequence folder with calib.txt and poses.txt; the TUM frames in
    a folder named for its Freiburg 2 camera, with poses.txt and depth/."""
    n = len(cloud)
    xyz_text = "\n".join(" ".join(f"{v:.9g}" for v in p) for p in cloud) + "\n"
    files = {
        "a.xyz": xyz_text.encode(),
        "a.dat.bz2": bz2.compress(xyz_text.encode()),
        "a.ply": _ply_header("ascii 1.0", n).encode() + xyz_text.encode(),
        "b.ply": _ply_header("binary_little_endian 1.0", n).encode()
        + cloud.astype("<f4").tobytes(),
        "a.pcd": _pcd_header("ascii", n) + xyz_text.encode(),
        "b.pcd": _pcd_header("binary", n) + cloud.astype("<f4").tobytes(),
        "a.graph": struct.pack("<I", 1) + _graph_node(cloud) + struct.pack("<I", 0),
        "a.log": (
            b"FLASER 4 1.0 81.83 2.0 1.5 1.0 2.0 0.0 0 0 0 0 host 0\n"
            b"FLASER 3 1.0 2.0 1.5 1.0 2.5 0.1 0 0 0 0 host 1\n"
        ),
        "b.clf": (
            b"ROBOTLASER1 0 -1.570796 3.141593 0.017453 81.9 0.01 0 3 2.0 81.91 3.0 0 "
            b"1.22 0.0 1.570796 1.0 0.0 1.570796 0 0 0 0 0 55.5 host 55.6\n"
        ),
    }
    field_major = cloud.T.astype("<f4").tobytes()
    packed = _lzf_compress(field_major)
    files["c.pcd"] = (
        _pcd_header("binary_compressed", n)
        + struct.pack("<II", len(packed), len(field_major))
        + packed
    )
    found = {}
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
        found[name] = (tmp_path / name, {})
    sequence = tmp_path / "sequence"
    (sequence / "velodyne").mkdir(parents=True)
    np.column_stack([cloud, np.ones(n)]).astype("<f4").tofile(sequence / "velodyne" / "000000.bin")
    (sequence / "calib.txt").write_text("Tr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n")
    (sequence / "poses.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    found["000000.bin"] = (sequence / "velodyne" / "000000.bin", {"poses": sequence / "poses.txt"})
    found["tum"] = (_tum_folder(tmp_path / "tum_fr2"), {})
    found["a.las"] = (write_las(tmp_path / "a.las", cloud), {})
    metadata = ouster_metadata([-10.0, 0.0, 10.0], 16, "RNG19_RFL8_SIG16_NIR16", 8)
    ranges = 1000 + np.arange(2 * 3 * 16).reshape(2, 3, 16)  # two frames, millimetres
    found["os.pcap"] = (write_ouster(tmp_path / "os.pcap", metadata, ranges), {})
    found["7scenes"] = (seven_scenes_frames(tmp_path / "seq-01", [1500, 3000]), {})
    found["redwood"] = (redwood_sequence(tmp_path / "redwood"), {})
    return found


def _ply_header(fmt: str, n: int) -> str:
    properties = "".join(f"property float {c}\n" for c in "xyz")
    return f"ply\nformat {fmt}\nelement vertex {n}\n{properties}end_header\n"


def _pcd_header(kind: str, n: int) -> bytes:
    return (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 1 2 3 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
    ).encode()


def _graph_node(points: np.ndarray) -> bytes:
    body = struct.pack("<I", len(points))
    for p in points:
        body += struct.pack("<i3d", 3, *p)
    body += struct.pack("<i3d", 3, 0.5, 0.0, 0.0) + struct.pack("<i4d", 4, 1.0, 0.0, 0.0, 0.0)
    return body + struct.pack("<I", 0)


def _tum_folder(folder):
    from PIL import Image

    (folder / "depth").mkdir(parents=True)
    depth = np.zeros((6, 8), dtype=np.uint16)
    depth[2:5, 3:6] = 10000
    Image.fromarray(depth).save(folder / "depth" / "0.png")
    (folder / "poses.txt").write_text("depth/0.png 1 2 3 0 0 0 1\n")
    return folder


@pytest.fixture
def lzf_compress():
    """A greedy LZF encoder (brute-force matching) for test data."""
    return _lzf_compress


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
