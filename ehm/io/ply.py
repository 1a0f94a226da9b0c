"""PLY files (ascii and binary): the vertices of a point cloud in, triangle meshes out as
binary PLY, the format mesh viewers (MeshLab, CloudCompare, Blender, Open3D) all open."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from ehm.io.fields import xyz_columns

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def read_ply(path: str | PathLike[str]) -> np.ndarray:
    """Vertices of a PLY file: ascii, binary_little_endian or binary_big_endian."""
    path = Path(path)
    data = path.read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file")
    lines = data[:end].decode("ascii").splitlines()
    body = data[end + len(b"end_header\n") :]
    fmt, fields, n_vertices, in_vertex = None, [], 0, False
    for line in lines:
        words = line.split()
        if words[:1] == ["format"]:
            fmt = words[1]
        elif words[:1] == ["element"]:
            in_vertex = words[1] == "vertex"
            if in_vertex:
                n_vertices = int(words[2])
            elif not fields:
                raise ValueError(f"{path}: elements before 'vertex' are not supported")
        elif words[:1] == ["property"] and in_vertex:
            if words[1] == "list":
                raise ValueError(f"{path}: list properties on vertices are not supported")
            fields.append((words[2], _PLY_TYPES[words[1]]))
    if fmt == "ascii":
        text = np.loadtxt(body.decode("ascii").splitlines()[:n_vertices], ndmin=2)
        names = [f[0] for f in fields]
        return np.column_stack([text[:, names.index(c)] for c in "xyz"])
    order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt or "")
    if order is None:
        raise ValueError(f"{path}: unknown PLY format {fmt!r}")
    dtype = np.dtype([(name, order + code) for name, code in fields])
    if len(body) < dtype.itemsize * n_vertices:
        raise ValueError(f"{path}: truncated ({n_vertices} vertices announced)")
    return xyz_columns(np.frombuffer(body, dtype=dtype, count=n_vertices), path)


def write_ply_mesh(
    path: str | PathLike[str],
    vertices: np.ndarray,
    faces: np.ndarray,
    colors: np.ndarray | None = None,
) -> None:
    """Write a binary little-endian PLY. vertices: (V, 3) metres (stored as float32); faces:
    (F, 3) vertex rows; colors: (V, 3) uint8 RGB per vertex, or None."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must have shape (F, 3), got {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError(f"faces refer to vertices outside 0..{len(vertices) - 1}")
    vertex_fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        if np.shape(colors) != vertices.shape:
            raise ValueError(f"colors must have shape {vertices.shape}, got {np.shape(colors)}")
        vertex_fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertex_records = np.empty(len(vertices), dtype=vertex_fields)
    for axis, name in enumerate("xyz"):
        vertex_records[name] = vertices[:, axis]
    if colors is not None:
        for channel, name in enumerate(("red", "green", "blue")):
            vertex_records[name] = np.asarray(colors)[:, channel]
    face_records = np.empty(len(faces), dtype=[("n", "u1"), ("vertex_indices", "<i4", (3,))])
    face_records["n"] = 3
    face_records["vertex_indices"] = faces
    types = {"<f4": "float", "u1": "uchar"}
    header = [
        "ply",
        "format binary_little_endian 1.0",
        "comment written by ehm",
        f"element vertex {len(vertices)}",
        *(f"property {types[code]} {name}" for name, code in vertex_fields),
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    with open(path, "wb") as stream:
        stream.write(("\n".join(header) + "\n").encode("ascii"))
        stream.write(vertex_records.tobytes())
        stream.write(face_records.tobytes())
