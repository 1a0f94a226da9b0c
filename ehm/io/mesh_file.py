"""Triangle meshes as binary PLY files, the format mesh viewers (MeshLab, CloudCompare,
Blender, Open3D) all open."""

from __future__ import annotations

from os import PathLike

import numpy as np


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
