"""Fixtures of the file-format tests: a point cloud and an LZF encoder."""

import numpy as np
import pytest


@pytest.fixture
def cloud(rng):
    """(50, 3) float64 points that float32 holds exactly."""
    return rng.uniform(-5, 5, (50, 3)).astype(np.float32).astype(np.float64)


@pytest.fixture
def lzf_compress():
    """A greedy LZF encoder (brute-force matching) for test data."""
    return _lzf_compress


def _lzf_compress(data: bytes) -> bytes:
    """Greedy LZF encoder (brute-force matching) for test data."""
    out, literal, i = bytearray(), bytearray(), 0

    def flush():
        while literal:
            chunk = literal[:32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
            del literal[:32]

    while i < len(data):
        best_len, best_off = 0, 0
        for start in range(max(0, i - 8191), i):
            length = 0
            while (
                i + length < len(data) and length < 264 and data[start + length] == data[i + length]
            ):
                length += 1
            if length > best_len:
                best_len, best_off = length, i - start - 1
        if best_len >= 3:
            flush()
            length = best_len - 2
            if length < 7:
                out.append((length << 5) | (best_off >> 8))
            else:
                out.append((7 << 5) | (best_off >> 8))
                out.append(length - 7)
            out.append(best_off & 0xFF)
            i += best_len
        else:
            literal.append(data[i])
            i += 1
    flush()
    return bytes(out)
