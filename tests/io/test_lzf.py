"""LZF decompression (PCD binary_compressed)."""

import numpy as np
import pytest

from ehm.io.lzf import lzf_decompress, lzf_decompress_reference


def test_lzf_compiled_matches_reference_and_round_trips(rng, lzf_compress):
    data = bytes(rng.integers(0, 4, 3000).astype(np.uint8)) + b"abc" * 200
    packed = lzf_compress(data)
    assert len(packed) < len(data)
    assert lzf_decompress(packed, len(data)) == data
    assert lzf_decompress_reference(packed, len(data)) == data
    with pytest.raises(ValueError, match="corrupt LZF"):
        lzf_decompress(packed[:-5], len(data))
