"""UDP payloads from a libpcap capture (`tcpdump -w`, Wireshark's "pcap"): Ethernet (with VLAN
tags) or Linux cooked frames carrying IPv4, fragmented datagrams put back together.

for datagram in udp_payloads("drive.pcap"): datagram.time, datagram.port, datagram.payload
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import NamedTuple

from ehm.errors import FileReadError, assumed

_MAGIC = {
    b"\xd4\xc3\xb2\xa1": "<",  # microsecond time stamps, little-endian
    b"\xa1\xb2\xc3\xd4": ">",
    b"\x4d\x3c\xb2\xa1": "<",  # nanosecond time stamps
    b"\xa1\xb2\x3c\x4d": ">",
}
_NANOSECONDS = (b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")
_PCAPNG = b"\x0a\x0d\x0d\x0a"
# Link layers: how many bytes precede the EtherType field, and the field's length.
_LINK_HEADERS = {1: 12, 113: 14}  # Ethernet, Linux cooked capture (SLL)
_IPV4, _VLAN, _UDP = 0x0800, 0x8100, 17
# Larger than any frame a link carries (an IPv4 datagram is at most 64 KiB).
_LARGEST_FRAME = 2**18


class Datagram(NamedTuple):
    """A UDP datagram of a capture: when it was captured (seconds, the capturing host's
    clock), its destination port and its payload."""

    time: float
    port: int
    payload: bytes


def udp_payloads(path: str | PathLike[str]) -> Iterator[Datagram]:
    """Each UDP datagram in the capture at `path`, in capture order; IPv4 fragments are
    joined, other traffic is skipped, a packet cut by the capture's end is noted and left
    out. FileReadError for a file that is not a libpcap capture (pcapng is named, with the
    command that converts it)."""
    path = Path(path)
    with path.open("rb") as file:
        header = file.read(24)
        if header[:4] == _PCAPNG:
            raise FileReadError(
                path, "is a pcapng capture; save it as pcap first (editcap -F pcap IN OUT)"
            )
        order = _MAGIC.get(header[:4])
        if order is None or len(header) < 24:
            raise FileReadError(path, "is not a libpcap capture (no pcap file header)")
        link = struct.unpack(order + "I", header[20:24])[0] & 0xFFFF
        fraction = 1e-9 if header[:4] in _NANOSECONDS else 1e-6
        if link not in _LINK_HEADERS:
            raise FileReadError(path, f"captures link type {link}; Ethernet (1) is read")
        fragments: dict[tuple[bytes, int], _Fragments] = {}
        while record := file.read(16):
            size = struct.unpack(order + "I", record[8:12])[0] if len(record) == 16 else 0
            if size > _LARGEST_FRAME:
                raise FileReadError(path, f"holds a packet of {size} bytes: a damaged capture")
            frame = file.read(size)
            if len(record) < 16 or len(frame) < size:
                assumed(f"{path.name} ends inside a packet (a capture cut short): read up to it")
                return
            datagram = _ipv4_udp(frame, _LINK_HEADERS[link], fragments)
            if datagram is not None:
                seconds, part = struct.unpack(order + "II", record[:8])
                yield Datagram(seconds + part * fraction, *datagram)


def _ipv4_udp(
    frame: bytes, type_offset: int, fragments: dict[tuple[bytes, int], _Fragments]
) -> tuple[int, bytes] | None:
    """(port, payload) of a frame holding a whole UDP datagram, or its last missing fragment;
    None for anything else. `fragments` keeps the parts of datagrams not yet complete."""
    ether_type = int.from_bytes(frame[type_offset : type_offset + 2], "big")
    start = type_offset + 2
    while ether_type == _VLAN:
        ether_type = int.from_bytes(frame[start + 2 : start + 4], "big")
        start += 4
    if ether_type != _IPV4 or len(frame) < start + 20:
        return None
    ip = frame[start:]
    header_length = (ip[0] & 0x0F) * 4
    total_length = int.from_bytes(ip[2:4], "big")
    if ip[9] != _UDP:
        return None
    flags_offset = int.from_bytes(ip[6:8], "big")
    more, offset = flags_offset & 0x2000, (flags_offset & 0x1FFF) * 8
    body = ip[header_length:total_length]
    if more or offset:
        key = (ip[12:20], int.from_bytes(ip[4:6], "big"))  # addresses and identification
        datagram = fragments.setdefault(key, _Fragments())
        datagram.parts[offset] = body
        if not more:
            datagram.length = offset + len(body)
        body = datagram.joined()
        if body is None:
            return None
        del fragments[key]
    if len(body) < 8:
        return None
    port, length = int.from_bytes(body[2:4], "big"), int.from_bytes(body[4:6], "big")
    return port, body[8:length]


@dataclass
class _Fragments:
    """The fragments of one IPv4 datagram seen so far: bodies by byte offset, and the
    datagram's length once its last fragment has come."""

    parts: dict[int, bytes] = field(default_factory=dict)
    length: int | None = None

    def joined(self) -> bytes | None:
        """The whole datagram, or None while a part is missing."""
        if self.length is None:
            return None
        body = b"".join(self.parts[start] for start in sorted(self.parts))
        return body if len(body) == self.length else None
