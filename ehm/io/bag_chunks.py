"""ROS 1 bags read record by record from their start, their index left aside.

A ROS 1 bag (format 2.0) is a run of records, each a header of `name=value` fields (its `op`
names its kind) and its data. Messages live in chunks (op 5, stored plainly or compressed with
bz2 or lz4), each holding the connection records (op 7: topic, type and message definition)
and the message records (op 2) it needs; index records (ops 4 and 6, and the connection
records at the end) only tell readers where chunks and messages are. Some bags of public data
sets carry index records whose length fields are wrong, and the bag library refuses them
though every chunk is intact: `ChunkReader` reads such bags from their chunks alone, in file
order, with the interface of the library's AnyReader that ehm.io.bags uses. The file is mapped,
not read into memory, and only one chunk is decompressed at a time; opening walks every chunk
once for the connections, as no index can be trusted to list them.
"""

from __future__ import annotations

import bz2
import mmap
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from ehm.errors import FileReadError

MAGIC = b"#ROSBAG V2.0\n"
OP_MESSAGE, OP_CHUNK, OP_CONNECTION = 2, 5, 7
# A record: its op, its header's fields and its data.
Record = tuple[int, dict[bytes, bytes], bytes]


@dataclass(frozen=True)
class ChunkConnection:
    """A connection found in a chunk: its id in the bag, topic, message type (ROS 2 style,
    'pkg/msg/Name') and message definition."""

    id: int
    topic: str
    msgtype: str
    msgdef: str


class ChunkReader:
    """The connections and messages of the ROS 1 bag at `path`, found chunk by chunk (see the
    module): open(), then `connections`, messages(connections) and deserialize(raw, msgtype),
    then close(). FileReadError naming the bag for a file that is not one."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.connections: list[ChunkConnection] = []
        self._data: mmap.mmap | bytes = b""
        self._typestore = None

    def open(self) -> None:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        try:
            with open(self.path, "rb") as stream:
                self._data = mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError) as error:  # ValueError: an empty file
            raise FileReadError(self.path, f"cannot be mapped ({error})") from None
        try:
            self.connections = self._find_connections()
        except BaseException:
            self.close()
            raise
        types: dict = {}
        for connection in self.connections:
            types.update(get_types_from_msg(connection.msgdef, connection.msgtype))
        self._typestore = get_typestore(Stores.EMPTY)
        self._typestore.register(types)

    def _find_connections(self) -> list[ChunkConnection]:
        """The connection records of every chunk, one per connection id, in file order."""
        if self._data[: len(MAGIC)] != MAGIC:
            raise FileReadError(self.path, "not a ROS 1 bag of format 2.0")
        found: dict[int, ChunkConnection] = {}
        for op, fields, data in self._chunk_records():
            if op == OP_CONNECTION:
                connection = _connection(fields, data)
                found.setdefault(connection.id, connection)
        return list(found.values())

    def close(self) -> None:
        if isinstance(self._data, mmap.mmap):
            self._data.close()
        self._data = b""

    def messages(
        self, connections: list[ChunkConnection]
    ) -> Iterator[tuple[ChunkConnection, int, bytes]]:
        """(connection, time in nanoseconds, raw message) of each message on `connections`,
        in file order."""
        wanted = {c.id: c for c in connections}
        for op, fields, data in self._chunk_records():
            if op != OP_MESSAGE:
                continue
            connection = wanted.get(struct.unpack("<I", fields[b"conn"])[0])
            if connection is not None:
                seconds, nanoseconds = struct.unpack("<II", fields[b"time"])
                yield connection, seconds * 1_000_000_000 + nanoseconds, data

    def deserialize(self, raw: bytes, msgtype: str) -> object:
        return self._typestore.deserialize_ros1(raw, msgtype)

    def _chunk_records(self) -> Iterator[Record]:
        """(op, header fields, data) of every record inside every chunk, in file order."""
        for op, fields, data in _records(self._data, len(MAGIC), self.path):
            if op != OP_CHUNK:
                continue
            compression = fields.get(b"compression", b"none")
            if compression == b"none":
                content = data
            elif compression == b"bz2":
                content = bz2.decompress(data)
            elif compression == b"lz4":
                import lz4.frame

                content = lz4.frame.decompress(data)
            else:
                raise FileReadError(self.path, f"a chunk compressed with {compression.decode()}")
            yield from _records(content, 0, self.path)


def _records(
    data: bytes, start: int, path: Path
) -> Iterator[tuple[int, dict[bytes, bytes], bytes]]:
    """(op, header fields, data) of the records of `data` from byte `start` on; a record cut
    short ends the walk with a FileReadError naming its byte."""
    position = start
    while position < len(data):
        try:
            (header_length,) = struct.unpack_from("<I", data, position)
            header = data[position + 4 : position + 4 + header_length]
            (data_length,) = struct.unpack_from("<I", data, position + 4 + header_length)
        except struct.error:
            raise FileReadError(path, "a record cut short", f"byte {position}") from None
        body_start = position + 8 + header_length
        if len(header) < header_length or body_start + data_length > len(data):
            raise FileReadError(path, "a record cut short", f"byte {position}")
        fields = _fields(header)
        op = fields.get(b"op", b"\0")[0]
        yield op, fields, data[body_start : body_start + data_length]
        position = body_start + data_length


def _fields(header: bytes) -> dict[bytes, bytes]:
    """The `name=value` fields of a record header."""
    fields, position = {}, 0
    while position + 4 <= len(header):
        (length,) = struct.unpack_from("<I", header, position)
        name, _, value = header[position + 4 : position + 4 + length].partition(b"=")
        fields[name] = value
        position += 4 + length
    return fields


def _connection(fields: dict[bytes, bytes], data: bytes) -> ChunkConnection:
    """The connection of a connection record: its id and topic from the header, its type and
    message definition from the connection header in its data."""
    described = _fields(data)
    msgtype = described.get(b"type", b"").decode()
    package, _, name = msgtype.partition("/")
    return ChunkConnection(
        struct.unpack("<I", fields[b"conn"])[0],
        fields[b"topic"].decode(),
        f"{package}/msg/{name}" if "/msg/" not in msgtype else msgtype,
        described.get(b"message_definition", b"").decode(),
    )
