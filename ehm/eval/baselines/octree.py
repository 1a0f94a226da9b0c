"""OctoMap (Hornung et al. 2013) through the `octomap-python` bindings, as a Mapper.

Each scan's hits are inserted with insertPointCloud from the scan's origin; rays without
return are left out. A 2D scan is mapped in the plane z = 0 of a 3D tree. A query reads the
occupancy of the point's voxel, 0.5 where the voxel is unknown.
"""

from __future__ import annotations

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.io.octomap_bindings import octomap_module


def _in_3d(points: np.ndarray) -> np.ndarray:
    """(n, 3) float64: 3D points as they are, 2D points in the plane z = 0."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[-1] == 3:
        return np.ascontiguousarray(points)
    return np.concatenate([points, np.zeros((*points.shape[:-1], 1))], axis=-1)


class OctoMapMapper:
    """OctoMap at `resolution` metres, its default sensor model and clamping."""

    def __init__(self, resolution: float) -> None:
        self._octomap = octomap_module()
        self.resolution = resolution
        self.tree = None

    @property
    def description(self) -> str:
        return f"OctoMap (Hornung et al. 2013), {self.resolution} m voxels, hits inserted per scan"

    def build(self, scans: list[Scan]) -> None:
        self.tree = self._octomap.OcTree(self.resolution)
        for scan in scans:
            self.insert(scan)

    def insert(self, scan: Scan) -> None:
        """Insert one more scan's hits into the tree (build first)."""
        self.tree.insertPointCloud(_in_3d(scan.points_world[scan.hit_mask]), _in_3d(scan.origin))

    def occupancy(self, points: np.ndarray) -> np.ndarray:
        if self.tree is None:
            raise RuntimeError("build the map before querying it")
        probability = np.full(len(points), 0.5)
        for i, point in enumerate(_in_3d(points)):
            try:
                known = self.tree.search(point).getOccupancy()
            except self._octomap.NullPointerException:
                continue
            probability[i] = known
        return probability

    def labels(self, points: np.ndarray) -> np.ndarray:
        """(n,) float64 occupancy of each point's voxel as OctoMap labels it (getLabels,
        vectorised): 1 occupied, 0 free, 0.5 unknown. points: (n, d), metres."""
        if self.tree is None:
            raise RuntimeError("build the map before querying it")
        labels = self.tree.getLabels(_in_3d(points))
        return np.where(labels == 1, 1.0, np.where(labels == 0, 0.0, 0.5))

    def memory_bytes(self) -> int:
        return 0 if self.tree is None else int(self.tree.memoryUsage())
