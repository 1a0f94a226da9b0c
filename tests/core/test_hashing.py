"""Open-addressing tables of int64 keys."""

import numpy as np

from ehm.core.hashing import unique_keys


def test_unique_keys_is_np_unique(rng):
    keys = rng.integers(0, 50, 1000).astype(np.int64) * 1_000_003
    np.testing.assert_array_equal(unique_keys(keys), np.unique(keys))
    assert len(unique_keys(np.zeros(0, dtype=np.int64))) == 0
