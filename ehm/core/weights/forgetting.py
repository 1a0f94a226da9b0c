"""Clusters that forget the evidence taken back from the memory (ehm.core.observations.memory).

A weight learned from many samples has a large AdaGrad accumulator and a high posterior
precision: it moves little for new samples, which is what keeps a static surface steady. When
rays show that the occupied evidence behind an occupied cluster is gone (a cart that left), the
cluster forgets in the same measure: its weight where positive, its accumulator, the part of
its precision above the prior, and its sample count are scaled by the share of its evidence
that stands,

    f_m = sum_e phi_m(x_e) w_e(after) / sum_e phi_m(x_e) w_e(before),

over the occupied entries e near the retraction, each at its mean x_e and weighted by its
kernel value. A cluster whose evidence is all gone learns the next samples as a new one does.

A map with MapConfig.forget_after F also forgets what it has not seen for a while: evidence last
seen at time s (a cluster's, or a memory region's) stands whole until s + F and halves every
FADE_HALF_LIFE * F after, all weights alike, free and occupied, so the place drifts back to
unknown (0.5, with the prior's std).
"""

from __future__ import annotations

import numpy as np

from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures

# Half-life of evidence unseen for longer than MapConfig.forget_after, in units of it.
FADE_HALF_LIFE = 0.25


def standing_shares(
    features: SparseFeatures, before: np.ndarray, after: np.ndarray, n_clusters: int
) -> np.ndarray:
    """(M,) float64 the share f_m of each cluster's evidence that stands (see the module's
    docstring; 1 for clusters the entries do not reach): features of the entries, their weights
    before and after (n,) float64."""
    sample = np.repeat(np.arange(len(before)), np.diff(features.indptr))
    mass_before = np.bincount(features.rows, features.values * before[sample], n_clusters)
    mass_after = np.bincount(features.rows, features.values * after[sample], n_clusters)
    share = np.ones(n_clusters)
    reached = mass_before > 0
    share[reached] = np.minimum(mass_after[reached] / mass_before[reached], 1.0)
    return share


def forget(clusters: ClusterSet, share: np.ndarray, prior_precision: float) -> np.ndarray:
    """Scale the positive weight, the AdaGrad accumulator, the precision above
    `prior_precision` and the sample count of each occupied fine cluster by its standing
    `share` (M,); returns the (k,) int64 rows of the clusters that forgot anything."""
    rows = np.flatnonzero((share < 1.0) & clusters.occupied & ~clusters.coarse)
    positive = rows[clusters.weights[rows] > 0]
    clusters.weights[positive] *= share[positive]
    _scale_confidence(clusters, rows, share[rows], prior_precision)
    return rows


def fade_shares(seen: np.ndarray, before: float, now: float, forget_after: float) -> np.ndarray:
    """(n,) float64 the share of evidence last seen at `seen` (n,) seconds (NaN: never, kept
    whole) that stands at time `now` of what stood at `before`, both seconds (see the module's
    docstring)."""
    start = np.maximum(seen + forget_after, before)
    unseen = np.nan_to_num(np.maximum(now - start, 0.0))
    return 0.5 ** (unseen / (FADE_HALF_LIFE * forget_after))


def fade(clusters: ClusterSet, shares: np.ndarray, prior_precision: float) -> np.ndarray:
    """Scale the weight, the AdaGrad accumulator, the precision above `prior_precision` and
    the sample count of every cluster by its `shares` (M,); returns the (k,) int64 rows of the
    clusters that faded."""
    rows = np.flatnonzero(shares < 1.0)
    clusters.weights[rows] *= shares[rows]
    _scale_confidence(clusters, rows, shares[rows], prior_precision)
    return rows


def mark_seen(clusters: ClusterSet, features: SparseFeatures, new: np.ndarray, time: float) -> None:
    """Record `time` (seconds) as seen for every cluster the features of the `new` (n,) bool
    samples reach."""
    reached = np.repeat(new, np.diff(features.indptr))
    clusters.seen[features.rows[reached]] = time


def _scale_confidence(
    clusters: ClusterSet, rows: np.ndarray, share: np.ndarray, prior_precision: float
) -> None:
    """Scale how sure the clusters `rows` are of their weights by `share` (k,): the AdaGrad
    accumulator, the precision above the prior and the sample count."""
    clusters.grad_sq[rows] *= share
    clusters.precision[rows] = prior_precision + share * (
        clusters.precision[rows] - prior_precision
    )
    clusters.counts[rows] *= share
