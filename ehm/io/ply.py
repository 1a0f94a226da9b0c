"""PLY files (ascii and binary): the vertices of a point cloud in, triangle meshes out as
binary PLY, the format mesh viewers (MeshLab, CloudCompare, Blender, Open3D) all open."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.errors import FileReadError, InputError
from ehm.io.fields import ascii_rows, xyz_columns
from ehm.io.files import read_input

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def read_ply(path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 vertices of a PLY file (ascii, binary_little_endian or binary_big_endian),
    in the file's frame. FileReadError naming the line or byte for a header or body that does
    not match."""
    data = read_input(path)
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise FileReadError(path, "not a PLY file (no 'ply' magic or no end_header)")
    body_start = data.find(b"\n", end) + 1 or len(data)
    lines = data[:end].decode("ascii", "replace").splitlines()
    fmt, fields, n_vertices = _vertex_layout(lines, path)
    if n_vertices <= 0:
        raise FileReadError(path, f"no vertices (element vertex {n_vertices})")
    names = [name for name, _ in fields]
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise FileReadError(path, f"no {', '.join(missing)} vertex property")
    body = data[body_start:]
    if fmt == "ascii":
        text = ascii_rows(body, n_vertices, len(fields), path, len(lines) + 2)
        return np.column_stack([text[:, names.index(c)] for c in "xyz"])
    order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
    if order is None:
        raise FileReadError(
            path,
            f"unknown format {fmt!r}: expected ascii, binary_little_endian or binary_big_endian",
        )
    dtype = np.dtype([(name, order + code) for name, code in fields])
    if len(body) < dtype.itemsize * n_vertices:
        message = (
            f"truncated: {n_vertices} vertices of {dtype.itemsize} bytes announced, "
            f"{len(body)} bytes found"
        )
        raise FileReadError(path, message, f"byte {body_start}")
    return xyz_columns(np.frombuffer(body, dtype=dtype, count=n_vertices), path)


def _vertex_layout(lines: list[str], path: str | PathLike[str]) -> tuple[str, list, int]:
    """The format, the vertex properties (name, numpy code) and the vertex count of a header."""
    fmt, fields, n_vertices, in_vertex = "", [], 0, False
    for number, line in enumerate(lines, start=1):
        words = line.split()
        where = f"line {number}"
        if words[:1] == ["format"] and len(words) >= 2:
            fmt = words[1]
        elif words[:1] == ["element"]:
            in_vertex = words[1:2] == ["vertex"]
            if in_vertex:
                try:
                    n_vertices = int(words[2])
                except (IndexError, ValueError):
                    raise FileReadError(path, f"bad vertex count {line!r}", where) from None
            elif not fields:
                raise FileReadError(path, "elements before 'vertex' are not supported", where)
        elif words[:1] == ["property"] and in_vertex:
            if words[1:2] == ["list"]:
                raise FileReadError(path, "list properties on vertices are not supported", where)
            if len(words) != 3 or words[1] not in _PLY_TYPES:
                raise FileReadError(
                    path,
                    f"expected 'property TYPE NAME' with TYPE one of "
                    f"{', '.join(sorted(_PLY_TYPES))}, got {line!r}",
                    where,
                )
            if words[2] in (name for name, _ in fields):
                raise FileReadError(path, f"vertex property {words[2]!r} given twice", where)
            fields.append((words[2], _PLY_TYPES[words[1]]))
    return fmt, fields, n_vertices


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
        raise InputError(f"vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"faces must have shape (F, 3), got {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(f"faces refer to vertices outside 0..{len(vertices) - 1}")
    vertex_fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        if np.shape(colors) != vertices.shape:
            raise InputError(f"colors must have shape {vertices.shape}, got {np.shape(colors)}")
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
