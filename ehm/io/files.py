"""Reading input files whole, with errors that name the file: missing, a folder, unreadable,
not text, or a broken gzip, bzip2 or xz stream; and writing files whole, atomically."""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import os
import tempfile
import zlib
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.errors import FileReadError

# Name endings of compressed inputs: the reader is chosen by the ending before them.
COMPRESSED_SUFFIXES = (".gz", ".bz2", ".xz")
# How each kind of compressed stream begins: text inputs are recognised by it whatever their
# name (bzip2: its signature, a block size digit, then the magic of its first block).
GZIP_MAGIC = b"\x1f\x8b"
XZ_MAGIC = b"\xfd7zXZ\x00"
BZIP2_SIGNATURE, BZIP2_BLOCK_MAGIC = b"BZh", b"1AY&SY"


def read_bytes(path: str | PathLike[str]) -> bytes:
    """The bytes of the file at `path`; FileReadError when it is missing, a folder or cannot be
    read."""
    path = Path(path)
    if path.is_dir():
        raise FileReadError(path, "is a folder, expected a file")
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise FileReadError(path, "no such file") from None
    except OSError as error:
        raise FileReadError(path, f"cannot be read ({error.strerror or error})") from None
    return data


def uncompressed_suffix(path: str | PathLike[str]) -> str:
    """The lower-case extension that names the format of the file at `path`: the one before
    .gz, .bz2 or .xz for a compressed file ('' when there is none), else its own."""
    path = Path(path)
    if path.suffix.lower() in COMPRESSED_SUFFIXES:
        return Path(path.stem).suffix.lower()
    return path.suffix.lower()


def read_input(path: str | PathLike[str]) -> bytes:
    """The bytes of the input file at `path`, decompressed when its name ends in .gz, .bz2 or
    .xz (CARMEN logs and point files are often distributed so); FileReadError for a stream
    that is broken or cut short."""
    return _decompressed(path, read_bytes(path), Path(path).suffix.lower())


def read_text(path: str | PathLike[str]) -> str:
    """The text (UTF-8) of the input file at `path`, decompressed when its name ends in .gz,
    .bz2 or .xz or its bytes begin as such a stream does (a compressed log renamed .log);
    FileReadError naming the first byte that is not text."""
    data = read_bytes(path)
    suffix = Path(path).suffix.lower()
    compression = suffix if suffix in COMPRESSED_SUFFIXES else _compression_of(data)
    data = _decompressed(path, data, compression)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise FileReadError(path, "not a text file", f"byte {error.start}") from None


def _decompressed(path: str | PathLike[str], data: bytes, compression: str) -> bytes:
    """`data` decompressed as `compression` says ('.gz', '.bz2', '.xz'; anything else: as
    it is)."""
    if compression == ".bz2":
        return _bunzip(path, data)
    if compression == ".gz":
        return _gunzip(path, data)
    if compression == ".xz":
        return _unxz(path, data)
    return data


def _compression_of(data: bytes) -> str:
    """'.gz', '.bz2' or '.xz' when `data` begins as such a stream does, else ''."""
    if data.startswith(GZIP_MAGIC):
        return ".gz"
    if data.startswith(XZ_MAGIC):
        return ".xz"
    if data.startswith(BZIP2_SIGNATURE) and data[4:10] == BZIP2_BLOCK_MAGIC:
        return ".bz2"
    return ""


def _gunzip(path: str | PathLike[str], data: bytes) -> bytes:
    """The decompressed gzip members of `data`, one after another."""
    try:
        return gzip.decompress(data)
    except EOFError:
        raise FileReadError(path, "truncated gzip stream") from None
    except (OSError, zlib.error) as error:
        raise FileReadError(path, f"not a gzip stream ({error})") from None


def _bunzip(path: str | PathLike[str], data: bytes) -> bytes:
    """The decompressed bzip2 streams of `data`, one after another."""
    parts = []
    while data:
        stream = bz2.BZ2Decompressor()
        try:
            parts.append(stream.decompress(data))
        except OSError as error:
            raise FileReadError(path, f"not a bzip2 stream ({error})") from None
        if not stream.eof:
            raise FileReadError(path, "truncated bzip2 stream")
        data = stream.unused_data
    return b"".join(parts)


def _unxz(path: str | PathLike[str], data: bytes) -> bytes:
    """The decompressed xz streams of `data`, one after another."""
    try:
        return lzma.decompress(data, format=lzma.FORMAT_XZ)
    except EOFError:
        raise FileReadError(path, "truncated xz stream") from None
    except lzma.LZMAError as error:
        raise FileReadError(path, f"not an xz stream ({error})") from None


def read_archive(path: str | PathLike[str], kind: str, names: set[str]) -> dict[str, np.ndarray]:
    """The arrays of the .npz file at `path`, by name; FileReadError saying it is not `kind`
    (an 'ehm grid file') when it is no archive or lacks one of `names`."""
    data = read_bytes(path)
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except Exception as error:
        # NumPy's archive reader fails in many ways (zip, zlib, header parsing) on bytes that
        # are not an .npz file.
        raise FileReadError(path, f"not {kind} ({error!r})") from None
    missing = names - set(arrays)
    if missing:
        raise FileReadError(path, f"not {kind} (no {', '.join(sorted(missing))})")
    return arrays


def write_atomically(path: str | PathLike[str], data: bytes) -> None:
    """Write `data` to `path`: a temporary file in the same folder, synced, then a rename, so
    what was there survives a crash half-way and readers never see half a file. The file
    gets the mode a new file gets under the process's umask (mkstemp's own is 0600)."""
    target = Path(path)
    fd, temporary = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent or ".")
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _umask() -> int:
    """The process's umask (read by setting it, then setting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask
