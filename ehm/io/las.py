"""LAS and LAZ point clouds (airborne and terrestrial LiDAR), read with `laspy` (and `lazrs`
for LAZ): (N, 3) float64 x, y, z in the file's coordinates, metres, with its scale and offset
applied."""

from __future__ import annotations

import io
import struct
from os import PathLike

import numpy as np

from ehm.errors import FileReadError
from ehm.io.files import read_input

INSTALL_HINT = "LAS and LAZ files need laspy (and lazrs for LAZ): pip install 'ehm[las]'"


def read_las(path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 points of a LAS or LAZ file; FileReadError naming it when laspy cannot
    read it or it holds no points."""
    try:
        import laspy
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    data = read_input(path)
    _check_header(data, path)
    try:
        cloud = laspy.read(io.BytesIO(data))
        points = np.column_stack([np.asarray(cloud.x), np.asarray(cloud.y), np.asarray(cloud.z)])
    except Exception as error:
        # laspy and its LAZ backends report bad files in many exception types.
        raise FileReadError(path, f"not a readable LAS/LAZ file ({error!r})") from None
    if len(points) == 0:
        raise FileReadError(path, "no points")
    return points.astype(np.float64)


def _check_header(data: bytes, path: str | PathLike[str]) -> None:
    """FileReadError for a public header block whose sizes the file cannot hold: a LAS reader
    trusting them would read past the end or loop over records that are not there."""
    if len(data) < 227 or data[:4] != b"LASF":
        raise FileReadError(path, "not a LAS/LAZ file (no LASF header)")
    header_size, point_offset, n_vlrs = struct.unpack_from("<HII", data, 94)
    point_format, record_length, n_points = struct.unpack_from("<BHI", data, 104)
    if data[25] >= 4 and len(data) >= 255:  # LAS 1.4 counts points in 64 bits
        (n_points,) = struct.unpack_from("<Q", data, 247)
    compressed = bool(point_format & 0xC0)
    room = len(data) - point_offset
    if not header_size <= point_offset <= len(data):
        raise FileReadError(path, f"point data at byte {point_offset} outside the file")
    if n_vlrs * 54 > point_offset - header_size:
        raise FileReadError(path, f"{n_vlrs} variable-length records do not fit the header")
    if not compressed and n_points * record_length > room:
        raise FileReadError(
            path,
            f"truncated: {n_points} points of {record_length} bytes announced",
            f"byte {point_offset}",
        )
    if compressed and n_points > 1000 * room:  # LAZ stores a point in well over a byte
        raise FileReadError(path, f"{n_points} points announced in {room} compressed bytes")
