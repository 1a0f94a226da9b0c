"""Stable radix orders of non-negative int64 keys."""

import numpy as np
import pytest

from ehm.core.primitives.radix import radix_order, radix_ranks


@pytest.mark.parametrize("top", [1, 2, 4_096, 4_097, 2**23 + 5, 2**40, 2**62])
def test_radix_order_is_a_stable_argsort(rng, top):
    """Keys of one digit, of digits that just spill into another pass, and of many passes,
    with ties, come out as NumPy's stable argsort orders them."""
    keys = rng.integers(0, top, 5000).astype(np.int64)
    keys[::7] = keys[0]  # ties, whose rows must keep their order
    np.testing.assert_array_equal(radix_order(keys), np.argsort(keys, kind="stable"))


def test_radix_order_of_nothing_is_empty():
    assert len(radix_order(np.zeros(0, dtype=np.int64))) == 0


@pytest.mark.parametrize("top", [3, 2**20, 2**62])
def test_radix_ranks_are_the_ranks_np_unique_gives(rng, top):
    keys = rng.integers(0, top, 5000).astype(np.int64)
    _, ranks = np.unique(keys, return_inverse=True)
    np.testing.assert_array_equal(radix_ranks(keys), ranks)
    assert len(radix_ranks(np.zeros(0, dtype=np.int64))) == 0
