"""Spatial index over cluster centres: the nearest clusters of many points at once.

Clusters come in two scales: fine ones (surfaces, and the free space just in front of them,
a few centimetres across) and coarse ones (open free space along rays, about a metre across).
Fine clusters crowd around surfaces, so the k nearest centres of a point a few decimetres in
front of a wall are all fine ones whose kernels do not reach it. Each scale therefore has its
own kd-tree, and a point's neighbours are its nearest fine and its nearest coarse clusters.

Searches stop at the largest kernel reach of the scale (plus how far the points sharing a
search lie from its centre): clusters farther away add zero to every feature, so leaving them
out changes no result and prunes most of the tree. Points with no centre of the scale that
close are not searched at all (ehm.core.search.centre_counts).

Two settings change the search: anisotropic search ranks a point's clusters by the radius
their kernel gives it instead of by the distance to their centres (candidates from the
Euclidean search, re-ranked), and anchor layers replace the kd-trees by a top-down search
through clusters of clusters (ehm.core.search.anchors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import PointGroups
from ehm.core.model.kernels import projected_radii
from ehm.core.search.anchors import AnchorLayers, AnchorTree
from ehm.core.search.centre_counts import CentreCounts

# cKDTree keeps a copy of the data, a permutation and about this many bytes per node.
_KDTREE_NODE_BYTES = 80
_KDTREE_LEAF_SIZE = 16
# The trees split at the middle of a node's box (sliding midpoint) and keep the nodes' boxes
# as split, not shrunk to their points: made faster than with median splits, searched as fast,
# the neighbours the same.
_KDTREE_OPTIONS = {"leafsize": _KDTREE_LEAF_SIZE, "balanced_tree": False, "compact_nodes": False}


# Searches for fewer points than this run on one thread: starting the others costs more.
PARALLEL_SEARCH_POINTS = 4096
# Points whose centres near are counted first, and the share of them with some above which
# every point is searched (ehm.core.search.centre_counts).
SAMPLED_POINTS = 256
NEAR_SHARE = 0.9


@dataclass(frozen=True)
class KernelRanking:
    """Anisotropic search: `factor` times k nearest centres are re-ranked by the radius each
    cluster's kernel gives the point (see `kernel_radii`). means (M, d) metres, transforms
    (M, d, d) 1/m, planar (M,) bool: the clusters' kernels."""

    means: np.ndarray
    transforms: np.ndarray
    planar: np.ndarray
    factor: int

    def best(self, points: np.ndarray, candidates: np.ndarray, k: int) -> np.ndarray:
        """(n, k) int64: the k of each row of `candidates` with the smallest kernel radius at
        the row's point, smallest first; -1 past the last."""
        radii = kernel_radii(points, candidates, self.means, self.transforms, self.planar)
        order = np.argsort(radii, axis=1, kind="stable")[:, :k]
        best = np.take_along_axis(candidates, order, axis=1)
        return np.where(np.isfinite(np.take_along_axis(radii, order, axis=1)), best, -1)


@numba.njit(cache=True, parallel=True)
def kernel_radii(points, candidates, means, transforms, planar):  # pragma: no cover - compiled
    """(n, c) radius |T_m (x - mu_m)| (max_a |.| for planar kernels) of each point at its
    candidate clusters; inf where the candidate is -1. The kernel is 0 from radius 1 on."""
    n, c = candidates.shape
    radii = np.full((n, c), np.inf)
    for i in numba.prange(n):
        for j in range(c):
            m = candidates[i, j]
            if m >= 0:
                r2, r_max = projected_radii(points, i, m, means, transforms)
                radii[i, j] = r_max if planar[m] else np.sqrt(r2)
    return radii


def kernel_radii_reference(
    points: np.ndarray,
    candidates: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
) -> np.ndarray:
    """Plain NumPy twin of `kernel_radii`."""
    safe = np.maximum(candidates, 0)
    projected = np.einsum("nkab,nkb->nka", transforms[safe], points[:, None, :] - means[safe])
    radii = np.where(planar[safe], np.abs(projected).max(axis=2), np.linalg.norm(projected, axis=2))
    return np.where(candidates >= 0, radii, np.inf)


@numba.njit(cache=True, parallel=True)
def tree_rows_into(found, tree_index, rows):  # pragma: no cover - compiled
    """Write into found (n, k) int64 the cluster rows of a kd-tree's answer tree_index
    (n, kk) int64, positions in `rows` (len(rows) where there was none), -1 for none and past
    column kk."""
    n, k = found.shape
    kk = min(k, tree_index.shape[1])
    for i in numba.prange(n):
        for j in range(kk):
            position = tree_index[i, j]
            found[i, j] = rows[position] if position < rows.shape[0] else -1
        for j in range(kk, k):
            found[i, j] = -1


def tree_rows_reference(tree_index: np.ndarray, rows: np.ndarray, k: int) -> np.ndarray:
    """Plain NumPy twin of `tree_rows_into`: the (n, k) rows it writes."""
    missing = tree_index >= len(rows)
    found = np.full((len(tree_index), k), -1, dtype=np.int64)
    kk = min(k, tree_index.shape[1])
    found[:, :kk] = np.where(missing, -1, rows[np.where(missing, 0, tree_index)])[:, :kk]
    return found


class ClusterIndex:
    """Search structures over (M, d) cluster centres, metres, world frame: per scale a kd-tree
    or, with anchor layers, an AnchorTree.

    coarse: (M,) bool scale of each cluster. reach: (M,) metres, distance beyond which each
    cluster's kernel is zero (None: unbounded searches). ranking: re-rank candidates by kernel
    radius (None: by distance between centres). anchors: search top-down through these anchor
    layers (None or no layers: kd-trees).
    """

    def __init__(
        self,
        centres: np.ndarray,
        coarse: np.ndarray,
        reach: np.ndarray | None = None,
        ranking: KernelRanking | None = None,
        anchors: AnchorLayers | None = None,
    ) -> None:
        self._rows = [np.flatnonzero(~coarse), np.flatnonzero(coarse)]
        self._ranking = ranking
        if anchors is not None and anchors.n_layers > 0:
            self._trees = [
                AnchorTree.build(anchors, centres, coarse, bool(scale)) if len(rows) else None
                for scale, rows in enumerate(self._rows)
            ]
        else:
            self._trees = [
                cKDTree(centres[rows], **_KDTREE_OPTIONS) if len(rows) else None
                for rows in self._rows
            ]
        self._reach = [
            np.inf if reach is None or len(rows) == 0 else float(reach[rows].max())
            for rows in self._rows
        ]
        # Per scale, its centres counted in cells as wide as its reach: made at the first search
        # whose sample shows many points far from every centre (learning's seldom does).
        self._counts: list[CentreCounts | None] = [None, None]

    @classmethod
    def of(
        cls,
        clusters: ClusterSet,
        anchors: AnchorLayers | None = None,
        config: MapConfig | None = None,
    ) -> ClusterIndex:
        """The search over `clusters` that `config` (default: MapConfig()) asks for: kd-trees
        bounded by the kernels' reach or, when `anchor_layers` > 1, the `anchors` (every
        cluster placed); candidates re-ranked by kernel radius when `anisotropic_search`."""
        config = config if config is not None else MapConfig()
        ranking = None
        if config.anisotropic_search:
            ranking = KernelRanking(
                clusters.means,
                clusters.transforms,
                clusters.planar_kernel,
                config.anisotropic_candidates,
            )
        layers = anchors if config.anchor_layers > 1 else None
        return cls(clusters.means, clusters.coarse, clusters.reach(), ranking, layers)

    def nearest_of_scale(
        self, points: np.ndarray, coarse: bool, k: int, spread: float = np.inf
    ) -> np.ndarray:
        """(n, k) int64 cluster rows of the k nearest clusters of one scale, -1 past the last.

        spread: metres; the search serves points up to this far from each of `points`, and
        skips clusters whose kernels reach none of them (inf: no pruning).
        """
        found = np.empty((len(points), k), dtype=np.int64)
        self._nearest_into(found, points, coarse, spread)
        return found

    def _nearest_into(
        self, found: np.ndarray, points: np.ndarray, coarse: bool, spread: float
    ) -> None:
        """Write nearest_of_scale's (n, k) rows into `found` (a view of that shape)."""
        n, k = found.shape
        if self._trees[int(coarse)] is None or n == 0 or k == 0:
            found[:] = -1
            return
        bound = (self._reach[int(coarse)] + spread) * (1.0 + 1e-9)
        searched = self._near_centres(points, coarse, bound)
        if searched is not None:  # the other points have no cluster of the scale that close
            found[:] = -1
            part = np.empty((len(searched), k), dtype=np.int64)
            self._search_into(part, points[searched], coarse, bound)
            found[searched] = part
            return
        self._search_into(found, points, coarse, bound)

    def _near_centres(self, points: np.ndarray, coarse: bool, bound: float) -> np.ndarray | None:
        """(s,) int64 rows of `points` (n, d) that may have a centre of the scale within
        `bound` metres, or None: all of them."""
        scale = int(coarse)
        if not 0.0 < self._reach[scale] < np.inf or not np.isfinite(bound):
            return None
        # Where nearly every point has centres near (points around hits, training samples),
        # reading the table for each costs more than the searches it spares: a sample tells.
        stride = len(points) // SAMPLED_POINTS
        if stride < 2:  # too few points for the table to pay
            return None
        sample = np.empty((len(points[::stride]), 1), dtype=np.int64)
        self._search_into(sample, points[::stride], coarse, bound)
        if np.mean(sample[:, 0] >= 0) > NEAR_SHARE:
            return None
        if self._counts[scale] is None:
            self._counts[scale] = CentreCounts.of(self._centres(scale), self._reach[scale])
        near = self._counts[scale].any_within(points, bound)
        return None if near.all() else np.flatnonzero(near)

    def _centres(self, scale: int) -> np.ndarray:
        """(m, d) the centres of the clusters of one scale, as its search holds them."""
        tree = self._trees[scale]
        if isinstance(tree, AnchorTree):
            return tree.centres[: len(tree.cluster_rows)]
        return tree.data

    def _search_into(
        self, found: np.ndarray, points: np.ndarray, coarse: bool, bound: float
    ) -> None:
        """The search of _nearest_into, over every one of `points`."""
        n, k = found.shape
        if n == 0:
            return
        rows, tree = self._rows[int(coarse)], self._trees[int(coarse)]
        wanted = k * (self._ranking.factor if self._ranking is not None else 1)
        if isinstance(tree, AnchorTree):
            candidates = tree.nearest(points, wanted, bound)
        else:
            kk = min(wanted, len(rows))
            workers = numba.get_num_threads() if n >= PARALLEL_SEARCH_POINTS else 1
            _, idx = tree.query(points, k=kk, workers=workers, distance_upper_bound=bound)
            idx = np.asarray(idx).reshape(n, kk)
            if self._ranking is None:  # the tree's rows straight into `found`
                tree_rows_into(found, idx, rows)
                return
            candidates = np.empty((n, kk), dtype=np.int64)
            tree_rows_into(candidates, idx, rows)
        if self._ranking is not None:
            candidates = self._ranking.best(points, candidates, k)
        kk = min(k, candidates.shape[1])
        found[:, :kk] = candidates[:, :kk]
        found[:, kk:] = -1

    def group_neighbours(
        self, points: np.ndarray, groups: PointGroups, k_fine: int, k_coarse: int
    ) -> np.ndarray:
        """(G, k_fine + k_coarse) int64: for each group of `points` (n, d), metres, the nearest
        fine and nearest coarse clusters of its centre whose kernels can reach any of its
        points; -1 where there are fewer (see nearest)."""
        return self.nearest(groups.centres, k_fine, k_coarse, groups.spread(points))

    def nearest(
        self, points: np.ndarray, k_fine: int, k_coarse: int, spread: float = np.inf
    ) -> np.ndarray:
        """(n, k_fine + k_coarse) int64: each point's nearest fine, then nearest coarse
        clusters whose kernels can reach within `spread` metres of it; -1 where there are
        fewer. The coarse columns are left out when the map has no coarse clusters."""
        if self._trees[1] is None:
            k_coarse = 0
        found = np.empty((len(points), k_fine + k_coarse), dtype=np.int64)
        self._nearest_into(found[:, :k_fine], points, False, spread)
        self._nearest_into(found[:, k_fine:], points, True, spread)
        return found

    @property
    def nbytes(self) -> int:
        """Approximate memory of the search structures, bytes."""
        total = sum(rows.nbytes for rows in self._rows)
        total += sum(counts.sums.nbytes for counts in self._counts if counts is not None)
        for tree in self._trees:
            if isinstance(tree, AnchorTree):
                total += tree.nbytes
            elif tree is not None:
                total += tree.data.nbytes + tree.indices.nbytes + tree.size * _KDTREE_NODE_BYTES
        return int(total)
