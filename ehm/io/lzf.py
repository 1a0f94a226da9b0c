"""LZF decompression, as used by PCD's binary_compressed data."""

from __future__ import annotations

import numba
import numpy as np

from ehm.errors import InputError


@numba.njit(cache=True)
def _lzf_kernel(source, out):  # pragma: no cover - compiled
    ip, op = 0, 0
    n_in, n_out = len(source), len(out)
    while ip < n_in:
        ctrl = np.int64(source[ip])
        ip += 1
        if ctrl < 32:
            length = ctrl + 1
            if ip + length > n_in or op + length > n_out:
                return -1
            out[op : op + length] = source[ip : ip + length]
            ip += length
            op += length
            continue
        length = ctrl >> 5
        ref = op - ((ctrl & 0x1F) << 8) - 1
        if length == 7:
            if ip >= n_in:
                return -1
            length += np.int64(source[ip])
            ip += 1
        if ip >= n_in:
            return -1
        ref -= np.int64(source[ip])
        ip += 1
        length += 2
        if ref < 0 or op + length > n_out:
            return -1
        for _ in range(length):
            out[op] = out[ref]
            op += 1
            ref += 1
    return op


def lzf_decompress(data: bytes, size: int) -> bytes:
    """Decompress LZF `data` into exactly `size` bytes; InputError when it is malformed."""
    out = np.empty(size, dtype=np.uint8)
    written = _lzf_kernel(np.frombuffer(data, dtype=np.uint8), out)
    if written != size:
        raise InputError(f"corrupt LZF data: decoded {written} bytes, expected {size}")
    return out.tobytes()


def lzf_decompress_reference(data: bytes, size: int) -> bytes:
    """Plain Python twin of `lzf_decompress`."""
    out = bytearray()
    ip = 0
    while ip < len(data):
        ctrl = data[ip]
        ip += 1
        if ctrl < 32:
            out += data[ip : ip + ctrl + 1]
            ip += ctrl + 1
            continue
        length = ctrl >> 5
        ref = len(out) - ((ctrl & 0x1F) << 8) - 1
        if length == 7:
            length += data[ip]
            ip += 1
        ref -= data[ip]
        ip += 1
        for _ in range(length + 2):
            out.append(out[ref])
            ref += 1
    if len(out) != size:
        raise InputError(f"corrupt LZF data: decoded {len(out)} bytes, expected {size}")
    return bytes(out)
