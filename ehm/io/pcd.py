"""PCD point clouds (PCL's format, v0.7): ascii, binary and binary_compressed (LZF). Points
are (N, 3) float64, metres, in the file's frame; VIEWPOINT gives the sensor origin."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from ehm.io.fields import xyz_columns
from ehm.io.lzf import lzf_decompress


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
        return xyz_columns(np.frombuffer(body, dtype=dtype, count=n_points), path), viewpoint
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
        return xyz_columns(records, path), viewpoint
    raise ValueError(f"{path}: unknown PCD DATA kind {kind!r}")
