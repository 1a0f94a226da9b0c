"""Orientation clustering (Sec. 3.2, Eq. 14-15): planar clusters that lie on one surface merge.

Two planar clusters of the same scale and label merge when the angle between their normals
(Eq. 15) is below `coplanar_angle` and their anisotropic distance (Eq. 14) is below
`coplanar_distance`. The angle, cheaper, is tested first; square roots of the covariances are
computed once per pass. Each pass pairs every cluster it looks at with its best partner (no
cluster merges twice in a pass), pools the statistics of each pair, and looks again at the
clusters that grew, until a pass merges nothing: a fixed point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ehm.config import MapConfig
from ehm.core.clustering.merging import anisotropic_distances, merge_pooled
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.kernels import cluster_normals, covariance_square_roots
from ehm.core.primitives.hashing import sorted_distinct

# Nearest planar centres of the same kind each cluster considers as partners.
CANDIDATES = 8


@dataclass(frozen=True)
class CoplanarMerge:
    """What orientation clustering did: merged, clusters absorbed into others; passes, passes
    run (the last merged nothing); source: (M_after,) int64, the row each cluster had
    before."""

    merged: int
    passes: int
    source: np.ndarray


def coplanar_pairs(
    clusters: ClusterSet,
    rows: np.ndarray,
    max_angle_deg: float,
    max_distance: float,
    min_std: float,
) -> np.ndarray:
    """(P, 2) int64 disjoint pairs [keeper, absorbed] of planar clusters to merge, among
    clusters `rows` and their nearest planar neighbours of the same scale and label; each
    cluster of `rows` is paired with the partner at the smallest anisotropic distance, and
    pairs are taken in order of distance while both ends are free. Sorted by keeper."""
    kind = 2 * clusters.coarse.astype(np.int64) + clusters.occupied
    first, second = [], []
    for value in np.unique(kind[rows]):
        planar_rows = np.flatnonzero(clusters.planar & (kind == value))
        asking = rows[clusters.planar[rows] & (kind[rows] == value)]
        if len(asking) == 0 or len(planar_rows) < 2:
            continue
        k = min(CANDIDATES + 1, len(planar_rows))
        _, found = cKDTree(clusters.means[planar_rows]).query(clusters.means[asking], k=k)
        first.append(np.repeat(asking, k))
        second.append(planar_rows[np.asarray(found).reshape(len(asking), k)].ravel())
    if not first:
        return np.zeros((0, 2), dtype=np.int64)
    first, second = np.concatenate(first), np.concatenate(second)
    usable = first != second
    first, second = first[usable], second[usable]
    # Normals of the clusters in play only: a pass stays local to the update.
    nearby = sorted_distinct(np.concatenate([first, second]))
    normals = cluster_normals(clusters.covariances[nearby])
    first_normals = normals[np.searchsorted(nearby, first)]
    second_normals = normals[np.searchsorted(nearby, second)]
    cosines = np.abs(np.einsum("nd,nd->n", first_normals, second_normals))
    aligned = cosines >= np.cos(np.radians(max_angle_deg))
    first, second = first[aligned], second[aligned]
    if len(first) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    involved = sorted_distinct(np.concatenate([first, second]))
    roots = covariance_square_roots(clusters.covariances[involved], min_std)
    slot_first, slot_second = np.searchsorted(involved, first), np.searchsorted(involved, second)
    means = clusters.means[involved]
    distances = anisotropic_distances(means, roots, slot_first, means, roots, slot_second)
    close = distances < max_distance
    first, second, distances = first[close], second[close], distances[close]
    taken = np.zeros(len(clusters), dtype=bool)
    pairs = []
    for p in np.argsort(distances, kind="stable"):
        a, b = first[p], second[p]
        if not (taken[a] or taken[b]):
            taken[a] = taken[b] = True
            pairs.append((min(a, b), max(a, b)))
    return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)


def merge_coplanar(clusters: ClusterSet, touched: np.ndarray, config: MapConfig) -> CoplanarMerge:
    """Run orientation clustering from clusters `touched` ((T,) int64 rows) to a fixed point,
    in place. A merged cluster pools both clusters' samples (exact mean and covariance); its
    weight, AdaGrad state and posterior precision are the sample-weighted means of the pair's."""
    source = np.arange(len(clusters))
    rows, merged, passes = np.asarray(touched, dtype=np.int64), 0, 0
    while True:
        passes += 1
        pairs = coplanar_pairs(
            clusters, rows, config.coplanar_angle, config.coplanar_distance, config.min_std
        )
        if len(pairs) == 0:
            break
        keep, absorb = pairs[:, 0], pairs[:, 1]
        share = clusters.counts[absorb] / (clusters.counts[keep] + clusters.counts[absorb])
        for name in ("weights", "grad_sq", "precision"):
            values = getattr(clusters, name)
            values[keep] += share * (values[absorb] - values[keep])
        merge_pooled(
            clusters,
            keep,
            clusters.means[absorb],
            clusters.covariances[absorb],
            clusters.counts[absorb],
        )
        clusters.refresh(keep, config)
        moved = clusters.remove(absorb)
        source = source[moved]
        # Where the kept clusters sit now (a removal moves rows from the end into holes).
        new_row = np.full(len(moved) + len(absorb), -1, dtype=np.int64)
        new_row[moved] = np.arange(len(moved))
        rows = new_row[keep]
        merged += len(pairs)
    return CoplanarMerge(merged, passes, source)
