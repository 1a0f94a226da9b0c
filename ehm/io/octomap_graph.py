"""OctoMap scan graphs (.graph): per node a point cloud in the sensor frame and a 6D pose."""

from __future__ import annotations

import struct
from os import PathLike

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix, transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.files import read_input


def read_octomap_graph(path: str | PathLike[str]) -> list[Scan]:
    """OctoMap ScanGraph (.graph): per node a point cloud in sensor frame and a 6D pose."""
    data = read_input(path)
    offset = 0

    def take(fmt: str) -> tuple:
        nonlocal offset
        size = struct.calcsize(fmt)
        if offset + size > len(data):
            raise FileReadError(path, f"truncated: {fmt} expected", f"byte {offset}")
        values = struct.unpack_from(fmt, data, offset)
        offset += size
        return values

    (n_nodes,) = take("<I")
    scans = []
    for _ in range(n_nodes):
        (n_points,) = take("<I")
        if offset + 28 * n_points > len(data):
            message = f"truncated: {n_points} points announced, {len(data) - offset} bytes left"
            raise FileReadError(path, message, f"byte {offset}")
        # Each point: int32 (=3) then three float64.
        records = np.frombuffer(
            data, dtype=[("n", "<i4"), ("xyz", "<f8", 3)], count=n_points, offset=offset
        )
        offset += 28 * n_points
        _, tx, ty, tz = take("<i3d")
        _, qw, qx, qy, qz = take("<i4d")
        take("<I")  # node id
        try:
            T_world_sensor = np.eye(4)
            T_world_sensor[:3, :3] = quaternion_to_matrix(qw, qx, qy, qz)
            T_world_sensor[:3, 3] = (tx, ty, tz)
            points_world = transform_points(T_world_sensor, records["xyz"].astype(np.float64))
            scans.append(Scan(points_world, T_world_sensor[:3, 3].copy()))
        except InputError as error:
            raise FileReadError(path, f"node {len(scans)}: {error}", f"byte {offset}") from None
    return scans
