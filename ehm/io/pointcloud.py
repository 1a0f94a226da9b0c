"""Single point-cloud files: `x y z` text (optionally .bz2), PLY and PCD. Points are (N, 3)
float64, metres, in the file's frame."""

from __future__ import annotations

import bz2
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.io.lzf import lzf_decompress

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def read_xyz(path: str | PathLike[str]) -> np.ndarray:
    """Whitespace-separated `x y z` per line (extra columns ignored); .bz2 is decompressed."""
    path = Path(path)
    opener = bz2.open if path.suffix == ".bz2" else open
    with opener(path, "rt") as stream:
        points = np.loadtxt(stream, usecols=(0, 1, 2), ndmin=2, comments="#")
    return points.astype(np.float64)


def _xyz_columns(records: np.ndarray, path: Path) -> np.ndarray:
    missing = [f for f in "xyz" if f not in (records.dtype.names or ())]
    if missing:
        raise ValueError(f"{path}: no {', '.join(missing)} field")
    return np.column_stack([records[f].astype(np.float64) for f in "xyz"])


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
    return _xyz_columns(np.frombuffer(body, dtype=dtype, count=n_vertices), path)


def read_pcd(path: str | PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Points of a PCD v0.7 file (ascii, binary or binary_compressed) and its VIEWPOINT
    translation (3,), the sensor origin in the file's frame."""
    path = Path(path)
    data = path.read_bytes()
    header, offset = {}, 0
    while "DATA" not in header:
        newline = data.find(b"\n", offset)
        if newline < 0:
            raise ValueError(f"{path}: not a PCD file (no DATA line)")
        line = data[offset:newline].decode("ascii", "replace").strip()
        offset = newline + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key] = values
    try:
        names, sizes = header["FIELDS"], [int(s) for s in header["SIZE"]]
        types = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        n_points = int(header["POINTS"][0])
    except (KeyError, ValueError) as error:
        raise ValueError(f"{path}: incomplete PCD header ({error})") from error
    viewpoint = np.array([float(v) for v in header.get("VIEWPOINT", ["0"] * 7)[:3]])
    codes = [{"F": "f", "I": "i", "U": "u"}[t] + str(s) for t, s in zip(types, sizes, strict=True)]
    dtype = np.dtype(
        [(n, "<" + c, (k,) if k > 1 else ()) for n, c, k in zip(names, codes, counts, strict=True)]
    )
    kind, body = header["DATA"][0], data[offset:]
    if kind == "ascii":
        text = np.loadtxt(body.decode("ascii").splitlines()[:n_points], ndmin=2)
        columns = np.cumsum([0, *counts])
        return np.column_stack([text[:, columns[names.index(c)]] for c in "xyz"]), viewpoint
    if kind == "binary":
        if len(body) < dtype.itemsize * n_points:
            raise ValueError(f"{path}: truncated ({n_points} points announced)")
        return _xyz_columns(np.frombuffer(body, dtype=dtype, count=n_points), path), viewpoint
    if kind == "binary_compressed":
        compressed, size = np.frombuffer(body[:8], dtype="<u4")
        raw = lzf_decompress(body[8 : 8 + int(compressed)], int(size))
        # Field-major layout: all points' x, then all y, ...
        records = np.empty(n_points, dtype=dtype)
        start = 0
        for name in names:
            field = dtype.fields[name][0]
            stop = start + field.itemsize * n_points
            records[name] = np.frombuffer(raw[start:stop], dtype=field.base).reshape(
                records[name].shape
            )
            start = stop
        return _xyz_columns(records, path), viewpoint
    raise ValueError(f"{path}: unknown PCD DATA kind {kind!r}")
