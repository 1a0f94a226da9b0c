"""Open addressing for tables of int64 keys, shared by the compiled kernels that look up cells
of space: a table is an (size,) int64 array of keys, size a power of 2, EMPTY_KEY where a slot
is free; values live in arrays of the same size, indexed by slot. Distinct keys, sorted, come
from NumPy's sort (`sorted_distinct`), which `group_by_key` ranks keys against."""

from __future__ import annotations

import numba
import numpy as np

EMPTY_KEY = np.int64(-1)
_HASH_MULTIPLIER = np.uint64(11400714819323198485)  # 2^64 / golden ratio


@numba.njit(cache=True, nogil=True)
def table_size(n_keys: int) -> int:  # pragma: no cover - compiled
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
    s = _first_slot(np.uint64(key), mask)
    while table_keys[s] != key and table_keys[s] != EMPTY_KEY:
        s = (s + 1) & mask
    return s


@numba.njit(cache=True, inline="always")
def _first_slot(value, mask):  # pragma: no cover - compiled
    """The slot, among mask + 1, where probing for uint64 `value` starts."""
    mixed = value * _HASH_MULTIPLIER
    return np.int64(mixed ^ (mixed >> np.uint64(29))) & mask


@numba.njit(cache=True, inline="always")
def hash_bits(key, bits):  # pragma: no cover - compiled
    """The top `bits` bits (1 to 63) of the multiplicative hash of `key` (>= 0): a slot among
    2^bits for a small direct-mapped cache of keys, which neighbouring keys spread over."""
    return np.int64((np.uint64(key) * _HASH_MULTIPLIER) >> np.uint64(64 - bits))


def sorted_distinct(values: np.ndarray) -> np.ndarray:
    """Sorted distinct values of (n,) integers, as np.unique gives them, through NumPy's sort:
    np.unique alone (no inverse, no counts) takes a hash table, many times slower than a sort
    on int64 keys in NumPy 2."""
    ordered = np.sort(values)
    if len(ordered) == 0:
        return ordered
    return ordered[np.concatenate(([True], ordered[1:] != ordered[:-1]))]


@numba.njit(cache=True, nogil=True)
def row_table(keys):  # pragma: no cover - compiled
    """A table of distinct `keys` (n,) int64 >= 0 and the row of each: (table keys (size,)
    int64, EMPTY_KEY where a slot is free; the row in `keys` of the key in each slot (size,)
    int64), read by `row_of`."""
    table = np.full(table_size(len(keys)), EMPTY_KEY, dtype=np.int64)
    rows = np.zeros(len(table), dtype=np.int64)
    for r in range(len(keys)):
        s = hash_slot(table, keys[r])
        table[s] = keys[r]
        rows[s] = r
    return table, rows


@numba.njit(cache=True, inline="always")
def row_of(table, rows, key):  # pragma: no cover - compiled
    """The row of `key` (>= 0) in a `row_table` (table, rows), -1 where it is not there."""
    s = hash_slot(table, key)
    return rows[s] if table[s] != EMPTY_KEY else -1


def group_by_key(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of `keys` (n,) int64 >= 0 grouped by key: (distinct (u,) int64, sorted; starts
    (u + 1,) int64, where each key's rows begin in `order`, and its end; order (n,) int64, the
    rows, key by key and in their own order within a key), as a stable argsort of the keys
    gives them."""
    distinct = sorted_distinct(keys)
    return (distinct, *rows_by_rank(_ranks(distinct, keys), len(distinct)))


@numba.njit(cache=True, nogil=True)
def _ranks(distinct, keys):  # pragma: no cover - compiled
    """(n,) int64 the place of each of `keys` among the `distinct` keys (all of them there)."""
    table, rank = row_table(distinct)
    ranks = np.empty(len(keys), dtype=np.int64)
    for i in range(len(keys)):
        ranks[i] = row_of(table, rank, keys[i])
    return ranks


@numba.njit(cache=True, nogil=True)
def first_come_ranks(keys):  # pragma: no cover - compiled
    """The rank of each of `keys` (n,) int64 >= 0 among the distinct keys in the order they
    first come: ((n,) int64, how many distinct keys). One pass over a table, no sort."""
    table = np.full(table_size(len(keys)), EMPTY_KEY, dtype=np.int64)
    rank = np.empty(len(table), dtype=np.int64)
    row_rank = np.empty(len(keys), dtype=np.int64)
    n = 0
    for i in range(len(keys)):
        s = hash_slot(table, keys[i])
        if table[s] == EMPTY_KEY:
            table[s] = keys[i]
            rank[s] = n
            n += 1
        row_rank[i] = rank[s]
    return row_rank, n


@numba.njit(cache=True, nogil=True)
def rows_by_rank(row_rank, n_groups):  # pragma: no cover - compiled
    """Rows grouped by their rank (n,) int64 in 0 .. n_groups - 1, a counting sort: (starts
    (n_groups + 1,) int64, where each group's rows begin in `order`, and its end; order (n,)
    int64, the rows, group by group and in their own order within a group)."""
    starts = np.zeros(n_groups + 1, dtype=np.int64)
    for i in range(len(row_rank)):
        starts[row_rank[i] + 1] += 1
    for r in range(n_groups):
        starts[r + 1] += starts[r]
    filled = starts[:-1].copy()
    order = np.empty(len(row_rank), dtype=np.int64)
    for i in range(len(row_rank)):
        order[filled[row_rank[i]]] = i
        filled[row_rank[i]] += 1
    return starts, order
