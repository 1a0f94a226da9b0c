"""Thinning a batch of training samples where rays crowd, each kept sample standing for those
left out of its cell.

A scan draws free samples at an even spacing along every ray, so where rays converge, near the
sensor, they pile up: within a metre of a LiDAR's centre there are as many free samples as rays,
and a depth camera's frame puts 300,000 free samples into a few cubic metres. They all say the
same thing. OctoMap updates each voxel a scan crosses once; here each cell keeps at most
`per_cell` samples of each kind, drawn uniformly, and a kept sample's weight grows by the share
of its cell's samples that were left out, so the loss, and the balance of free against
occupied, stays what it was in expectation while clustering, features and gradient steps see
fewer samples.

Cells are half as wide as the clusters of their kind (`cluster_radius` around hits,
`free_cluster_radius` along rays), so every cluster still gathers several cells of samples.
The three kinds (occupied, free around hits, free along rays) are thinned apart.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.config import MapConfig
from ehm.core.cells import packed_cell_keys, rank_in_runs
from ehm.core.hashing import EMPTY_KEY, hash_slot, table_size
from ehm.core.samples import TrainingSamples

# Side of a thinning cell as a share of the cluster radius of its kind.
CELL_FACTOR = 0.5


def thinning_keys(samples: TrainingSamples, config: MapConfig) -> np.ndarray:
    """(n,) int64 key of each sample's thinning cell: its kind in the lowest two bits."""
    side = CELL_FACTOR * np.where(
        samples.at_surface, config.cluster_radius, config.free_cluster_radius
    )
    kind = 2 * samples.occupied.astype(np.int64) + samples.at_surface
    remedy = "set samples_per_cell=0 to map without thinning"
    return packed_cell_keys(samples.points, side, kind, 2, remedy)


def thin_samples(
    samples: TrainingSamples, config: MapConfig, rng: np.random.Generator
) -> TrainingSamples:
    """At most config.samples_per_cell of `samples` per cell and kind, uniformly drawn, each
    weighted by (samples in its cell) / (kept in its cell) times its own weight; all of them
    when samples_per_cell is 0. Kept samples stay in their order."""
    per_cell = config.samples_per_cell
    if per_cell == 0 or len(samples) == 0:
        return samples
    keys = thinning_keys(samples, config)
    order = rng.permutation(len(samples))
    keep, share = thinning_kernel(keys, order, per_cell, table_size(len(samples)))
    kept = samples.subset(keep)
    return TrainingSamples(kept.points, kept.occupied, kept.at_surface, kept.weight * share[keep])


@numba.njit(cache=True)
def thinning_kernel(keys, order, per_cell, size):  # pragma: no cover - compiled
    """(keep (n,) bool, share (n,) float64): the first `per_cell` samples of each key in
    `order` are kept, and each sample's share is its key's count over the kept count. size:
    slots of the hash of keys (a power of 2, above the number of distinct keys)."""
    n = len(keys)
    table = np.full(size, EMPTY_KEY, dtype=np.int64)
    seen = np.zeros(size, dtype=np.int64)
    slot_of = np.empty(n, dtype=np.int64)
    keep = np.zeros(n, dtype=np.bool_)
    for i in order:
        s = hash_slot(table, keys[i])
        table[s] = keys[i]
        slot_of[i] = s
        keep[i] = seen[s] < per_cell
        seen[s] += 1
    share = np.empty(n)
    for i in range(n):
        count = seen[slot_of[i]]
        share[i] = count / min(count, per_cell)
    return keep, share


def thinning_reference(
    keys: np.ndarray, order: np.ndarray, per_cell: int
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `thinning_kernel`, by sorting keys."""
    by_key = order[np.argsort(keys[order], kind="stable")]  # each key's samples in `order`
    keep = np.zeros(len(keys), dtype=bool)
    keep[by_key[rank_in_runs(keys[by_key]) < per_cell]] = True
    _, key_of_sample, count = np.unique(keys, return_inverse=True, return_counts=True)
    share = count / np.minimum(count, per_cell)
    return keep, share[key_of_sample]
