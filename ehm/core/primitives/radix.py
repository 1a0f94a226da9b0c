"""Stable orders, and ranks, of non-negative integer keys by least-significant-digit radix
sort: a pass over the rows per RADIX_BITS bits of the largest key at most, no comparisons, so
that grouping rows by keys that are dense small integers (table slots, cell numbers) costs time
linear in the rows."""

from __future__ import annotations

import numba
import numpy as np

# The most bits of a key one pass sorts by: 4,096 counters fit in the first level of cache.
RADIX_BITS = 12


@numba.njit(cache=True, nogil=True)
def radix_order(keys):  # pragma: no cover - compiled
    """(n,) int64 rows of `keys` (n,) int64 >= 0 in increasing key order, rows of equal keys
    in their own order: np.argsort(keys, kind='stable')."""
    n = len(keys)
    order = np.arange(n)
    if n == 0:
        return order
    top = keys.max()
    bits = 0
    while (top >> bits) > 0:
        bits += 1
    # As few passes as RADIX_BITS allows, their digits of equal width.
    passes = -(-bits // RADIX_BITS)
    width = -(-bits // passes) if passes else 0
    digit_mask = np.int64((1 << width) - 1)
    sorted_keys = keys.copy()
    next_order = np.empty(n, dtype=np.int64)
    next_keys = np.empty(n, dtype=np.int64)
    for p in range(passes):
        shift = p * width
        begin = np.zeros((1 << width) + 1, dtype=np.int64)
        for j in range(n):
            begin[((sorted_keys[j] >> shift) & digit_mask) + 1] += 1
        for d in range(1 << width):
            begin[d + 1] += begin[d]
        for j in range(n):
            d = (sorted_keys[j] >> shift) & digit_mask
            next_order[begin[d]] = order[j]
            next_keys[begin[d]] = sorted_keys[j]
            begin[d] += 1
        order, next_order = next_order, order
        sorted_keys, next_keys = next_keys, sorted_keys
    return order


@numba.njit(cache=True, nogil=True)
def radix_ranks(keys):  # pragma: no cover - compiled
    """(n,) int64 rank of each of `keys` (n,) int64 >= 0 among the distinct keys, in
    increasing order: np.unique(keys, return_inverse=True)[1], by radix_order (about twice as
    fast as a sort and a table of the distinct keys, ehm.core.primitives.hashing)."""
    order = radix_order(keys)
    ranks = np.empty(len(keys), dtype=np.int64)
    rank = -1
    for j in range(len(order)):
        if j == 0 or keys[order[j]] != keys[order[j - 1]]:
            rank += 1
        ranks[order[j]] = rank
    return ranks
