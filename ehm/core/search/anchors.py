"""Anchor layers (Sec. 3.4, Fig. 6): clusters of clusters, searched top-down.

Layer 0 is the map's clusters; the members of layer l (l >= 1) are grouped into the anchors
of layer l, by quick-means over their centres with inner radius
`anchor_radius_factor`^l times the clusters' radius. An anchor's centre is the mean of its
members' centres. Clusters of the two scales (fine and coarse) have anchors of their own.

As scans arrive, each new member joins the anchor of its scale with the nearest centre when
that lies within the layer's inner radius; the members left over seed new anchors by
quick-means, which join the layer above the same way. Clusters merged away leave their
anchors; an anchor left without members is skipped by searches.

A search goes down from the top layer: the k nearest anchors, then the k nearest of their
members, and so on to the k nearest clusters among the members of the chosen anchors of
layer 1. It returns the same clusters as a flat search unless one of a point's k nearest
clusters belongs to an anchor whose centre is not among the k nearest of its layer: points
near the border of large anchors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.spatial import cKDTree

from ehm.core.primitives.quickmeans import quick_means


@dataclass
class AnchorLayers:
    """parents[l]: (n_l,) int64, the anchor of layer l + 1 of each member of layer l (layer 0:
    the clusters). coarse[l]: (n_{l+1},) bool, the scale of each anchor of layer l + 1."""

    parents: list[np.ndarray] = field(default_factory=list)
    coarse: list[np.ndarray] = field(default_factory=list)

    @property
    def n_layers(self) -> int:
        """Anchor layers above the clusters."""
        return len(self.parents)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.parents + self.coarse)

    def drop_clusters(self, source: np.ndarray) -> None:
        """Follow a removal of clusters: `source` (M_after,) gives the old row of each.
        Clusters that had no anchor yet keep none."""
        if self.parents:
            old = self.parents[0]
            padded = np.concatenate([old, np.full(max(0, source.max() + 1 - len(old)), -1)])
            self.parents[0] = padded[source]

    def extend(
        self,
        centres: np.ndarray,
        coarse: np.ndarray,
        radii: tuple[float, float],
        growth: float,
        n_layers: int,
    ) -> None:
        """Place the clusters that have no anchor yet (new rows, and rows whose parent is -1),
        layer by layer. centres: (M, d) metres; coarse: (M,) bool; radii: the clusters' inner
        radius, metres, (fine, coarse): the anchors of layer l use growth^l times it."""
        members, member_coarse = centres, coarse
        for layer in range(n_layers):
            if layer == len(self.parents):
                self.parents.append(np.zeros(0, dtype=np.int64))
                self.coarse.append(np.zeros(0, dtype=bool))
            placed = self.parents[layer]
            parents = np.concatenate([placed, np.full(len(members) - len(placed), -1)])
            old = parents >= 0
            anchor_centres = member_means(members[old], parents[old], len(self.coarse[layer]))
            for scale in (False, True):
                radius = radii[int(scale)] * growth ** (layer + 1)
                asking = np.flatnonzero(~old & (member_coarse == scale))
                anchors = np.flatnonzero(self.coarse[layer] == scale)
                anchors = anchors[np.isfinite(anchor_centres[anchors, 0])]
                joins = np.zeros(len(asking), dtype=bool)
                if len(asking) and len(anchors):
                    distance, nearest = cKDTree(anchor_centres[anchors]).query(members[asking])
                    joins = distance < radius
                    parents[asking[joins]] = anchors[nearest[joins]]
                seeds = asking[~joins]
                if len(seeds) == 0:
                    continue
                grouping = quick_means(
                    members[seeds], radius, radius, 1, np.random.default_rng(len(members))
                )
                parents[seeds] = len(self.coarse[layer]) + grouping.owner
                self.coarse[layer] = np.concatenate(
                    [self.coarse[layer], np.full(len(grouping.seeds), scale)]
                )
            self.parents[layer] = parents
            members = member_means(members, parents, len(self.coarse[layer]))
            member_coarse = self.coarse[layer]

    def centres(self, cluster_centres: np.ndarray) -> list[np.ndarray]:
        """(n_l, d) metres: the centre of every anchor of each layer (inf when empty)."""
        found, members = [], cluster_centres
        for layer, parents in enumerate(self.parents):
            members = member_means(members, parents, len(self.coarse[layer]))
            found.append(members)
        return found


def member_means(members: np.ndarray, parents: np.ndarray, n_anchors: int) -> np.ndarray:
    """(n_anchors, d) mean of the members of each anchor; inf for anchors without members."""
    usable = np.isfinite(members[:, 0])  # members that are empty anchors themselves
    parents, members = parents[usable], members[usable]
    sizes = np.bincount(parents, minlength=n_anchors).astype(np.float64)
    sums = np.stack(
        [np.bincount(parents, members[:, a], n_anchors) for a in range(members.shape[1])], axis=1
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / sizes[:, None]
    means[sizes == 0] = np.inf
    return means


@dataclass(frozen=True)
class AnchorTree:
    """The layers of one scale flattened into nodes for the compiled search. Nodes 0..C-1 are
    that scale's clusters, in the order of `cluster_rows`; anchors follow, layer by layer.

    centres: (N, d) metres. child_start: (N + 1,) int64 and children: node ids, the members of
    each node (none for clusters). top: node ids of the top layer. n_layers: anchor layers."""

    cluster_rows: np.ndarray
    centres: np.ndarray
    child_start: np.ndarray
    children: np.ndarray
    top: np.ndarray
    n_layers: int

    @classmethod
    def build(
        cls, layers: AnchorLayers, cluster_centres: np.ndarray, coarse: np.ndarray, scale: bool
    ) -> AnchorTree:
        """The tree of the clusters of one scale (coarse == scale)."""
        anchor_centres = layers.centres(cluster_centres)
        member_nodes = np.full(len(cluster_centres), -1, dtype=np.int64)
        cluster_rows = np.flatnonzero(coarse == scale)
        member_nodes[cluster_rows] = np.arange(len(cluster_rows))
        centres, n_nodes = [cluster_centres[cluster_rows]], len(cluster_rows)
        child_lists = [np.zeros(0, dtype=np.int64)] * len(cluster_rows)
        for layer, parents in enumerate(layers.parents):
            anchors = np.flatnonzero(layers.coarse[layer] == scale)
            anchor_nodes = np.full(len(layers.coarse[layer]), -1, dtype=np.int64)
            anchor_nodes[anchors] = n_nodes + np.arange(len(anchors))
            mine = member_nodes >= 0
            order = np.argsort(parents[mine], kind="stable")
            members_sorted = member_nodes[mine][order]
            bounds = np.searchsorted(parents[mine][order], np.arange(len(anchor_nodes) + 1))
            child_lists += [members_sorted[bounds[a] : bounds[a + 1]] for a in anchors]
            centres.append(anchor_centres[layer][anchors])
            n_nodes += len(anchors)
            member_nodes = anchor_nodes
        sizes = np.array([len(c) for c in child_lists], dtype=np.int64)
        top = member_nodes[member_nodes >= 0]
        top = top[np.isfinite(np.concatenate(centres)[top, 0])]
        return cls(
            cluster_rows,
            np.ascontiguousarray(np.concatenate(centres)),
            np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
            np.concatenate([*child_lists, np.zeros(0, dtype=np.int64)]).astype(np.int64),
            top.astype(np.int64),
            layers.n_layers,
        )

    @property
    def nbytes(self) -> int:
        return sum(
            a.nbytes
            for a in (self.cluster_rows, self.centres, self.child_start, self.children, self.top)
        )

    def nearest(self, points: np.ndarray, k: int, bound: float) -> np.ndarray:
        """(n, k) int64 cluster rows found top-down, nearest first, only those within `bound`
        metres of each point; -1 past the last."""
        nodes = search_top_down(
            points,
            k,
            bound * bound,
            self.centres,
            self.child_start,
            self.children,
            self.top,
            self.n_layers,
        )
        return np.where(nodes >= 0, self.cluster_rows[np.maximum(nodes, 0)], -1)


@numba.njit(cache=True)
def _squared_distances(point, centres, nodes):  # pragma: no cover - compiled
    found = np.empty(len(nodes))
    for i in range(len(nodes)):
        total = 0.0
        for a in range(len(point)):
            step = centres[nodes[i], a] - point[a]
            total += step * step
        found[i] = total
    return found


@numba.njit(cache=True)
def _search_one(point, k, bound2, centres, child_start, children, top, n_layers, found):
    # pragma: no cover - compiled
    current = top
    for _ in range(n_layers):
        distances = _squared_distances(point, centres, current)
        chosen = current[np.argsort(distances, kind="mergesort")[: min(k, len(current))]]
        total = 0
        for node in chosen:
            total += child_start[node + 1] - child_start[node]
        below = np.empty(total, dtype=np.int64)
        filled = 0
        for node in chosen:
            for c in range(child_start[node], child_start[node + 1]):
                below[filled] = children[c]
                filled += 1
        current = below
    distances = _squared_distances(point, centres, current)
    order = np.argsort(distances, kind="mergesort")
    for j in range(min(k, len(current))):
        if distances[order[j]] <= bound2:
            found[j] = current[order[j]]


@numba.njit(cache=True, parallel=True)
def search_top_down(
    points, k, bound2, centres, child_start, children, top, n_layers
):  # pragma: no cover - compiled
    """Node ids (n, k) of the k nearest clusters found by keeping the k nearest nodes of each
    layer and descending into their members; -1 past the last or beyond sqrt(bound2)."""
    found = np.full((points.shape[0], k), -1, dtype=np.int64)
    for q in numba.prange(points.shape[0]):
        _search_one(points[q], k, bound2, centres, child_start, children, top, n_layers, found[q])
    return found


def search_top_down_reference(
    points: np.ndarray,
    k: int,
    bound2: float,
    centres: np.ndarray,
    child_start: np.ndarray,
    children: np.ndarray,
    top: np.ndarray,
    n_layers: int,
) -> np.ndarray:
    """Plain NumPy twin of `search_top_down`."""
    found = np.full((len(points), k), -1, dtype=np.int64)
    for q, point in enumerate(points):
        current = top
        for _ in range(n_layers):
            distances = np.sum((centres[current] - point) ** 2, axis=1)
            chosen = current[np.argsort(distances, kind="stable")[:k]]
            current = np.concatenate(
                [children[child_start[c] : child_start[c + 1]] for c in chosen]
                + [np.zeros(0, dtype=np.int64)]
            )
        distances = np.sum((centres[current] - point) ** 2, axis=1)
        order = np.argsort(distances, kind="stable")[:k]
        order = order[distances[order] <= bound2]
        found[q, : len(order)] = current[order]
    return found
