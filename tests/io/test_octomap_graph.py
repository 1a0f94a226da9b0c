"""OctoMap scan graphs."""

import struct

import numpy as np
import pytest

from ehm.errors import FileReadError
from ehm.io.readers import read_scans


def test_octomap_graph(tmp_path, cloud):
    def node(points, translation, quaternion_wxyz, node_id):
        body = struct.pack("<I", len(points))
        for p in points:
            body += struct.pack("<i3d", 3, *p)
        body += struct.pack("<i3d", 3, *translation) + struct.pack("<i4d", 4, *quaternion_wxyz)
        return body + struct.pack("<I", node_id)

    half_turn_z = (0.0, 0.0, 0.0, 1.0)  # 180 degrees about z
    data = struct.pack("<I", 2) + node(cloud, (0, 0, 0), (1, 0, 0, 0), 0)
    data += node(cloud[:10], (1, 2, 3), half_turn_z, 1) + struct.pack("<I", 0)
    (tmp_path / "a.graph").write_bytes(data)
    scans = read_scans(tmp_path / "a.graph")
    np.testing.assert_allclose(scans[0].points_world, cloud)
    expected = np.column_stack([1 - cloud[:10, 0], 2 - cloud[:10, 1], 3 + cloud[:10, 2]])
    np.testing.assert_allclose(scans[1].points_world, expected, atol=1e-12)
    (tmp_path / "b.graph").write_bytes(data[:100])
    with pytest.raises(FileReadError, match=r"b\.graph, byte 8: truncated: 50 points announced"):
        read_scans(tmp_path / "b.graph")
