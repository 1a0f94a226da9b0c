"""Spatial index over cluster centres: the nearest clusters of many points at once.

Clusters come in two scales: fine ones (surfaces, and the free space just in front of them,
a few centimetres across) and coarse ones (open free space along rays, about a metre across).
Fine clusters crowd around surfaces, so the k nearest centres of a point a few decimetres in
front of a wall are all fine ones whose kernels do not reach it. Each scale therefore has its
own kd-tree, and a point's neighbours are its nearest fine and its nearest coarse clusters.

Searches stop at the largest kernel reach of the scale (plus how far the points sharing a
search lie from its centre): clusters farther away add zero to every feature, so leaving them
out changes no result and prunes most of the tree.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

# cKDTree keeps a copy of the data, a permutation and about this many bytes per node.
_KDTREE_NODE_BYTES = 80
_KDTREE_LEAF_SIZE = 16


class ClusterIndex:
    """kd-trees over (M, d) cluster centres, metres, world frame.

    coarse: (M,) bool scale of each cluster. reach: (M,) metres, distance beyond which each
    cluster's kernel is zero (None: unbounded searches).
    """

    def __init__(
        self, centres: np.ndarray, coarse: np.ndarray, reach: np.ndarray | None = None
    ) -> None:
        self._rows = [np.flatnonzero(~coarse), np.flatnonzero(coarse)]
        self._trees = [
            cKDTree(centres[rows], leafsize=_KDTREE_LEAF_SIZE) if len(rows) else None
            for rows in self._rows
        ]
        self._reach = [
            np.inf if reach is None or len(rows) == 0 else float(reach[rows].max())
            for rows in self._rows
        ]

    def nearest_of_scale(
        self, points: np.ndarray, coarse: bool, k: int, spread: float = np.inf
    ) -> np.ndarray:
        """(n, k) int64 cluster rows of the k nearest centres of one scale, -1 past the last.

        spread: metres; the search serves points up to this far from each of `points`, and
        skips clusters whose kernels reach none of them (inf: no pruning).
        """
        n = len(points)
        found = np.full((n, k), -1, dtype=np.int64)
        rows, tree = self._rows[int(coarse)], self._trees[int(coarse)]
        if tree is None or n == 0 or k == 0:
            return found
        kk = min(k, len(rows))
        bound = (self._reach[int(coarse)] + spread) * (1.0 + 1e-9)
        _, idx = tree.query(points, k=kk, workers=-1, distance_upper_bound=bound)
        idx = np.asarray(idx).reshape(n, kk)
        missing = idx >= len(rows)
        found[:, :kk] = np.where(missing, -1, rows[np.where(missing, 0, idx)])
        return found

    def nearest(
        self, points: np.ndarray, k_fine: int, k_coarse: int, spread: float = np.inf
    ) -> np.ndarray:
        """(n, k_fine + k_coarse) int64: each point's nearest fine, then nearest coarse
        clusters whose kernels can reach within `spread` metres of it; -1 where there are
        fewer. The coarse columns are left out when the map has no coarse clusters."""
        if self._trees[1] is None:
            k_coarse = 0
        return np.hstack(
            [
                self.nearest_of_scale(points, False, k_fine, spread),
                self.nearest_of_scale(points, True, k_coarse, spread),
            ]
        )

    @property
    def nbytes(self) -> int:
        """Approximate memory of the trees, bytes."""
        total = 0
        for rows, tree in zip(self._rows, self._trees, strict=True):
            if tree is not None:
                n_nodes = 2 * max(1, len(rows) // _KDTREE_LEAF_SIZE)
                total += tree.data.nbytes + tree.indices.nbytes + rows.nbytes
                total += n_nodes * _KDTREE_NODE_BYTES
        return int(total)
