"""Open-addressing tables of int64 keys."""

import numpy as np

from ehm.core.hashing import key_part, unique_keys


def test_unique_keys_is_np_unique(rng):
    keys = rng.integers(0, 50, 1000).astype(np.int64) * 1_000_003
    np.testing.assert_array_equal(unique_keys(keys), np.unique(keys))
    assert len(unique_keys(np.zeros(0, dtype=np.int64))) == 0


def test_key_parts_agree_with_numpy_and_share_keys_evenly(rng):
    keys = rng.integers(0, 2**62, 30_000).astype(np.int64)
    parts = np.array([key_part(key, 3) for key in keys])
    mixed = keys.astype(np.uint64) * np.uint64(11400714819323198485)
    np.testing.assert_array_equal(parts, (mixed >> np.uint64(40)).astype(np.int64) % 3)
    np.testing.assert_allclose(np.bincount(parts, minlength=3) / len(keys), 1 / 3, atol=0.02)
