"""Open-addressing tables of int64 keys."""

import numpy as np

from ehm.core.primitives.hashing import (
    first_come_ranks,
    group_by_key,
    hash_bits,
    row_of,
    row_table,
    rows_by_rank,
    sorted_distinct,
    table_size,
)


def test_sorted_distinct_is_np_unique(rng):
    keys = rng.integers(0, 50, 1000).astype(np.int64) * 1_000_003
    np.testing.assert_array_equal(sorted_distinct(keys), np.unique(keys))
    np.testing.assert_array_equal(sorted_distinct(np.array([7, -3, 7, 0, -3])), [-3, 0, 7])
    assert len(sorted_distinct(np.zeros(0, dtype=np.int64))) == 0


def test_rows_grouped_by_key_as_a_stable_argsort_groups_them(rng):
    keys = rng.integers(0, 300, 5000).astype(np.int64) * 7_919
    distinct, starts, order = group_by_key(keys)
    stable = np.argsort(keys, kind="stable")
    np.testing.assert_array_equal(order, stable)
    np.testing.assert_array_equal(distinct, np.unique(keys))
    np.testing.assert_array_equal(
        starts, np.append(np.searchsorted(keys[stable], distinct), len(keys))
    )
    empty = group_by_key(np.zeros(0, dtype=np.int64))
    assert [len(part) for part in empty] == [0, 1, 0]


def test_first_come_ranks_number_keys_in_the_order_they_first_come(rng):
    keys = rng.integers(0, 300, 5000).astype(np.int64) * 7_919
    _, first_rows = np.unique(keys, return_index=True)
    first_come = keys[np.sort(first_rows)]
    place = {key: r for r, key in enumerate(first_come)}
    ranks, count = first_come_ranks(keys)
    np.testing.assert_array_equal(ranks, [place[key] for key in keys])
    assert count == len(first_come)


def test_rows_by_rank_is_a_stable_argsort_of_the_ranks(rng):
    ranks = rng.integers(0, 40, 3000).astype(np.int64)
    starts, order = rows_by_rank(ranks, 45)
    np.testing.assert_array_equal(order, np.argsort(ranks, kind="stable"))
    np.testing.assert_array_equal(np.diff(starts), np.bincount(ranks, minlength=45))
    empty_starts, empty_order = rows_by_rank(np.zeros(0, dtype=np.int64), 0)
    assert list(empty_starts) == [0] and len(empty_order) == 0


def test_tables_stay_at_most_half_full():
    assert [table_size(n) for n in (0, 32, 33, 1000)] == [64, 64, 128, 2048]


def test_hash_bits_are_the_top_bits_of_the_golden_ratio_hash_and_spread_neighbours():
    """Keys of 4,096 neighbouring cells (consecutive along one axis, rows of 64 along another)
    fill most of 4,096 slots, and each slot is the top 12 bits of key times 2^64 / golden
    ratio."""
    keys = (np.arange(64)[:, None] << 20 | np.arange(64)[None, :]).ravel().astype(np.int64)
    got = np.array([hash_bits(key, 12) for key in keys])
    with np.errstate(over="ignore"):
        want = (keys.astype(np.uint64) * np.uint64(11400714819323198485)) >> np.uint64(52)
    np.testing.assert_array_equal(got, want.astype(np.int64))
    assert got.min() >= 0 and got.max() < 4096
    assert len(np.unique(got)) > 0.6 * len(keys)


def test_a_row_table_finds_the_row_of_every_key_and_none_of_the_others(rng):
    keys = rng.choice(10**9, 3000, replace=False).astype(np.int64)
    table, rows = row_table(keys)
    assert len(table) >= 2 * len(keys)
    found = [row_of(table, rows, key) for key in keys]
    np.testing.assert_array_equal(found, np.arange(len(keys)))
    others = np.setdiff1d(rng.integers(0, 10**9, 3000), keys)
    assert all(row_of(table, rows, key) == -1 for key in others)
