"""PCD point clouds (PCL's format, v0.7): ascii, binary and binary_compressed (LZF). Points
are (N, 3) float64, metres, in the file's frame; VIEWPOINT gives the sensor origin."""

from __future__ import annotations

import math
from os import PathLike

import numpy as np

from ehm.errors import EhmError, FileReadError
from ehm.io.fields import ascii_rows, xyz_columns
from ehm.io.files import read_input
from ehm.io.lzf import lzf_decompress

_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}
# The most values one field holds per point (PCL's largest descriptors hold a few hundred).
_MAX_COUNT = 4096
# LZF turns 3 bytes into at most 264: no valid stream expands more.
_LZF_MAX_RATIO = 88


def read_pcd(path: str | PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Points of a PCD v0.7 file (ascii, binary or binary_compressed), (N, 3) float64 in the
    file's frame, and its VIEWPOINT translation (3,), the sensor origin in that frame.
    FileReadError naming the line or byte for a header or body that does not match."""
    data = read_input(path)
    header, offset, n_lines = {}, 0, 0
    while "DATA" not in header:
        newline = data.find(b"\n", offset)
        if newline < 0:
            raise FileReadError(path, "not a PCD file (no DATA line)")
        line = data[offset:newline].decode("ascii", "replace").strip()
        offset, n_lines = newline + 1, n_lines + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key.upper()] = values
    dtype, names, counts, n_points = _record_layout(header, path)
    viewpoint = _viewpoint(header, path)
    kind, body = header["DATA"][0].lower() if header["DATA"] else "", data[offset:]
    if kind == "ascii":
        columns = np.cumsum([0, *counts])
        text = ascii_rows(body, n_points, int(columns[-1]), path, n_lines + 1)
        return np.column_stack([text[:, columns[names.index(c)]] for c in "xyz"]), viewpoint
    if kind == "binary":
        if len(body) < dtype.itemsize * n_points:
            message = (
                f"truncated: {n_points} points of {dtype.itemsize} bytes announced, "
                f"{len(body)} bytes found"
            )
            raise FileReadError(path, message, f"byte {offset}")
        return xyz_columns(np.frombuffer(body, dtype=dtype, count=n_points), path), viewpoint
    if kind == "binary_compressed":
        records = _decompressed(body, dtype, names, n_points, path, offset)
        return xyz_columns(records, path), viewpoint
    raise FileReadError(
        path, f"unknown DATA kind {kind!r}: expected ascii, binary or binary_compressed"
    )


def _record_layout(header: dict, path: str | PathLike[str]) -> tuple:
    """The point record's dtype, field names, counts and the number of points, checked."""
    try:
        names, types = header["FIELDS"], [t.upper() for t in header["TYPE"]]
        sizes = [int(s) for s in header["SIZE"]]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        n_points = int(header["POINTS"][0]) if "POINTS" in header else _width_height(header)
    except (KeyError, ValueError, IndexError) as error:
        raise FileReadError(path, f"incomplete PCD header ({error!r})") from None
    if not len(names) == len(types) == len(sizes) == len(counts):
        raise FileReadError(
            path,
            f"FIELDS, SIZE, TYPE and COUNT differ in length "
            f"({len(names)}, {len(sizes)}, {len(types)}, {len(counts)})",
        )
    for name, kind, size, count in zip(names, types, sizes, counts, strict=True):
        if size not in _SIZES.get(kind, ()):
            raise FileReadError(
                path,
                f"field {name!r} has TYPE {kind} SIZE {size}: expected F 4/8, I 1/2/4/8 "
                "or U 1/2/4/8",
            )
        if not 1 <= count <= _MAX_COUNT:
            raise FileReadError(
                path, f"field {name!r} has COUNT {count}, expected 1 to {_MAX_COUNT}"
            )
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise FileReadError(path, f"no {', '.join(missing)} field")
    if any(names.count(c) > 1 for c in "xyz"):
        raise FileReadError(path, f"FIELDS name x, y or z twice: {names}")
    # PCL names padding fields "_", as often as it pads.
    names = [n if names.count(n) == 1 else f"{n}{i}" for i, n in enumerate(names)]
    if n_points <= 0:
        raise FileReadError(path, f"no points (POINTS {n_points})")
    codes = [kind.lower() + str(size) for kind, size in zip(types, sizes, strict=True)]
    dtype = np.dtype(
        [(n, "<" + c, (k,) if k > 1 else ()) for n, c, k in zip(names, codes, counts, strict=True)]
    )
    return dtype, names, counts, n_points


def _width_height(header: dict) -> int:
    return int(header["WIDTH"][0]) * int(header["HEIGHT"][0])


def _viewpoint(header: dict, path: str | PathLike[str]) -> np.ndarray:
    """The VIEWPOINT translation (3,), metres; (0, 0, 0) without one."""
    words = header.get("VIEWPOINT", ["0"] * 7)
    try:
        values = [float(v) for v in words]
    except ValueError:
        values = []
    if len(values) != 7 or not all(math.isfinite(v) for v in values):
        raise FileReadError(
            path, f"VIEWPOINT needs 7 finite numbers (tx ty tz qw qx qy qz), got {words}"
        )
    return np.array(values[:3])


def _decompressed(
    body: bytes,
    dtype: np.dtype,
    names: list[str],
    n_points: int,
    path: str | PathLike[str],
    offset: int,
) -> np.ndarray:
    """The point records of binary_compressed data: two uint32 sizes, then LZF data of the
    fields one after another (all points' x, then all y, ...)."""
    if len(body) < 8:
        raise FileReadError(path, "truncated: no compressed sizes", f"byte {offset}")
    compressed, size = (int(v) for v in np.frombuffer(body[:8], dtype="<u4"))
    if compressed > len(body) - 8:
        raise FileReadError(
            path,
            f"truncated: {compressed} compressed bytes announced, {len(body) - 8} found",
            f"byte {offset}",
        )
    if size != dtype.itemsize * n_points or size > _LZF_MAX_RATIO * compressed + 64:
        raise FileReadError(
            path,
            f"compressed data of {size} bytes announced, expected {n_points} points of "
            f"{dtype.itemsize} bytes",
            f"byte {offset}",
        )
    try:
        raw = lzf_decompress(body[8 : 8 + compressed], size)
    except EhmError as error:
        raise FileReadError(path, str(error), f"byte {offset + 8}") from None
    records = np.empty(n_points, dtype=dtype)
    start = 0
    for name in names:
        field = dtype.fields[name][0]
        stop = start + field.itemsize * n_points
        records[name] = np.frombuffer(raw[start:stop], dtype=field.base).reshape(
            records[name].shape
        )
        start = stop
    return records
