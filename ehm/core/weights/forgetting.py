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
"""

from __future__ import annotations

import numpy as np

from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import SparseFeatures


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
    f = share[rows]
    clusters.grad_sq[rows] *= f
    clusters.precision[rows] = prior_precision + f * (clusters.precision[rows] - prior_precision)
    clusters.counts[rows] *= f
    positive = clusters.weights[rows] > 0
    clusters.weights[rows[positive]] *= f[positive]
    return rows
