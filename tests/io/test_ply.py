"""PLY: point clouds in, meshes out."""

import numpy as np
import pytest

from ehm.io.ply import read_ply, write_ply_mesh


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


def test_ply_mesh_round_trip(tmp_path, rng):
    vertices = rng.uniform(-3, 3, (500, 3)).astype(np.float32).astype(np.float64)
    faces = np.array([rng.choice(500, 3, replace=False) for _ in range(900)])
    colors = rng.integers(0, 256, vertices.shape).astype(np.uint8)
    path = tmp_path / "ball.ply"
    write_ply_mesh(path, vertices, faces, colors)
    np.testing.assert_array_equal(read_ply(path), vertices)
    data = path.read_bytes()
    header, body = data.split(b"end_header\n", 1)
    assert b"format binary_little_endian 1.0" in header
    assert f"element face {len(faces)}".encode() in header
    vertex_bytes = len(vertices) * 15
    records = np.frombuffer(body[vertex_bytes:], dtype=[("n", "u1"), ("i", "<i4", (3,))])
    assert np.all(records["n"] == 3)
    np.testing.assert_array_equal(records["i"], faces)
    vertex_records = np.frombuffer(
        body[:vertex_bytes], dtype=[("p", "<f4", (3,)), ("c", "u1", (3,))]
    )
    np.testing.assert_array_equal(vertex_records["c"], colors)
    with pytest.raises(ValueError, match="outside"):
        write_ply_mesh(path, vertices, faces + len(vertices))
