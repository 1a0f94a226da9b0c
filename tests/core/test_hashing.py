"""Open-addressing tables of int64 keys."""

import numpy as np

from ehm.core.search.hashing import group_by_key, table_size, unique_keys


def test_unique_keys_is_np_unique(rng):
    keys = rng.integers(0, 50, 1000).astype(np.int64) * 1_000_003
    np.testing.assert_array_equal(unique_keys(keys), np.unique(keys))
    assert len(unique_keys(np.zeros(0, dtype=np.int64))) == 0


def test_rows_grouped_by_key_as_a_stable_argsort_groups_them(rng):
    keys = rng.integers(0, 300, 5000).astype(np.int64) * 7_919
    distinct, starts, order = group_by_key(keys)
    stable = np.argsort(keys, kind="stable")
    np.testing.assert_array_equal(order, stable)
    np.testing.assert_array_equal(distinct, np.unique(keys))
    np.testing.assert_array_equal(starts, np.searchsorted(keys[stable], distinct))
    empty = group_by_key(np.zeros(0, dtype=np.int64))
    assert [len(part) for part in empty] == [0, 0, 0]


def test_tables_stay_at_most_half_full():
    assert [table_size(n) for n in (0, 32, 33, 1000)] == [64, 64, 128, 2048]
