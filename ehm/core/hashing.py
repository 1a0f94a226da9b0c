"""Open addressing for tables of int64 keys, shared by the compiled kernels that look up cells
of space: a table is an (size,) int64 array of keys, size a power of 2, EMPTY_KEY where a slot
is free; values live in arrays of the same size, indexed by slot."""

from __future__ import annotations

import numba
import numpy as np

EMPTY_KEY = np.int64(-1)
_HASH_MULTIPLIER = np.uint64(11400714819323198485)  # 2^64 / golden ratio


def table_size(n_keys: int) -> int:
    """Slots for a table that holds n_keys keys at most half full: a power of 2, at least 64."""
    size = 64
    while size < 2 * n_keys:
        size *= 2
    return size


@numba.njit(cache=True, inline="always")
def hash_slot(table_keys, key):  # pragma: no cover - compiled
    """Slot of `key` (>= 0) in the table, or of the empty slot where it would go (linear
    probing)."""
    mask = np.int64(len(table_keys) - 1)
    mixed = np.uint64(key) * _HASH_MULTIPLIER
    s = np.int64(mixed ^ (mixed >> np.uint64(29))) & mask
    while table_keys[s] != key and table_keys[s] != EMPTY_KEY:
        s = (s + 1) & mask
    return s


@numba.njit(cache=True)
def unique_keys(keys):  # pragma: no cover - compiled
    """Sorted distinct values of `keys` (n,) int64 >= 0: np.unique, with the duplicates
    dropped in one pass over a table before the sort, so only distinct keys are sorted."""
    size = 64
    while size < 2 * len(keys):
        size *= 2
    table = np.full(size, EMPTY_KEY, dtype=np.int64)
    distinct = np.empty(len(keys), dtype=np.int64)
    n = 0
    for key in keys:
        s = hash_slot(table, key)
        if table[s] == EMPTY_KEY:
            table[s] = key
            distinct[n] = key
            n += 1
    return np.sort(distinct[:n])


@numba.njit(cache=True, inline="always")
def key_part(key, parts):  # pragma: no cover - compiled
    """Which of `parts` parts of the keys `key` belongs to: about as many keys in each,
    wherever they lie."""
    mixed = np.uint64(key) * _HASH_MULTIPLIER
    return np.int64(mixed >> np.uint64(40)) % parts
