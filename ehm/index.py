"""Spatial index over cluster centres: the k nearest clusters of many points at once."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

# cKDTree keeps a copy of the data, a permutation and about this many bytes per node.
_KDTREE_NODE_BYTES = 80
_KDTREE_LEAF_SIZE = 16


class ClusterIndex:
    """kd-tree over (M, d) cluster centres, metres, world frame."""

    def __init__(self, centres: np.ndarray) -> None:
        self.size = len(centres)
        self.tree = cKDTree(centres, leafsize=_KDTREE_LEAF_SIZE) if self.size else None

    def nearest(self, points: np.ndarray, k: int) -> np.ndarray:
        """(n, k) int64 indices of the nearest centres of each point, -1 past the M-th."""
        n = len(points)
        found = np.full((n, k), -1, dtype=np.int64)
        if self.tree is None or n == 0:
            return found
        kk = min(k, self.size)
        _, idx = self.tree.query(points, k=kk, workers=-1)
        found[:, :kk] = np.asarray(idx).reshape(n, kk)
        return found

    @property
    def nbytes(self) -> int:
        """Approximate memory of the tree, bytes."""
        if self.tree is None:
            return 0
        n_nodes = 2 * max(1, self.size // _KDTREE_LEAF_SIZE)
        return int(self.tree.data.nbytes + self.tree.indices.nbytes + n_nodes * _KDTREE_NODE_BYTES)
