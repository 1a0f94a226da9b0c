"""Ouster captures written for tests: lidar packets of a given profile in a libpcap file,
with the metadata JSON beside it."""

import json
import struct
from pathlib import Path

import numpy as np

# Ethernet + IPv4 + UDP headers before each payload; the largest IPv4 payload a frame takes.
_MTU_PAYLOAD = 1480


def ouster_metadata(
    altitudes_deg, width: int, profile: str, columns_per_packet: int = 4, beam_offset_mm=0.0
) -> dict:
    """Metadata in the flat layout of firmware 2.x: beams at `altitudes_deg`, azimuth 0,
    the LiDAR frame turned 180 degrees about z and raised 36.18 mm, as Ouster's are."""
    beams = len(altitudes_deg)
    return {
        "beam_altitude_angles": list(map(float, altitudes_deg)),
        "beam_azimuth_angles": [0.0] * beams,
        "lidar_origin_to_beam_origin_mm": beam_offset_mm,
        "lidar_to_sensor_transform": [-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1],
        "lidar_mode": f"{width}x10",
        "data_format": {
            "columns_per_frame": width,
            "columns_per_packet": columns_per_packet,
            "pixels_per_column": beams,
            "udp_profile_lidar": profile,
        },
        "udp_port_lidar": 7502,
    }


def lidar_packets(metadata: dict, frames_mm: np.ndarray, first_frame: int = 7) -> list[bytes]:
    """UDP payloads of frames of ranges (F, H, W) millimetres, 0 for no return."""
    data = metadata["data_format"]
    profile, per_packet = data["udp_profile_lidar"], data["columns_per_packet"]
    packets = []
    for f, ranges in enumerate(frames_mm):
        frame_id = first_frame + f
        for start in range(0, ranges.shape[1], per_packet):
            columns = []
            for m in range(start, start + per_packet):
                stamp = 1_000_000_000 * (f + 1) + 100_000 * m
                column = ranges[:, m].astype(np.uint32)
                if profile == "LEGACY":
                    pixels = np.zeros((len(column), 3), "<u4")
                    pixels[:, 0] = column
                    header = struct.pack("<QHHI", stamp, m, frame_id, 0)
                    columns.append(header + pixels.tobytes() + b"\xff" * 4)
                    continue
                if profile == "RNG15_RFL8_NIR8":
                    pixels = (column // 8).astype("<u4")
                else:
                    pixels = np.zeros((len(column), 3), "<u4")
                    pixels[:, 0] = column
                columns.append(struct.pack("<QHH", stamp, m, 1) + pixels.tobytes())
            body = b"".join(columns)
            if profile != "LEGACY":
                body = struct.pack("<HH", 1, frame_id) + bytes(28) + body + bytes(32)
            packets.append(body)
    return packets


def write_capture(path: Path, payloads: list[bytes], port: int = 7502, fragment=False) -> None:
    """A libpcap file of UDP datagrams to `port`, each cut into IPv4 fragments if asked (sent
    last fragment first, as a capture may hold them)."""
    records = []
    for number, payload in enumerate(payloads):
        udp = struct.pack(">HHHH", port, port, 8 + len(payload), 0) + payload
        pieces = [udp]
        if fragment:
            pieces = [udp[i : i + _MTU_PAYLOAD] for i in range(0, len(udp), _MTU_PAYLOAD)]
        frames = []
        for i, piece in enumerate(pieces):
            more = 0x2000 if i < len(pieces) - 1 else 0
            flags = more | (i * _MTU_PAYLOAD // 8)
            ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(piece), number, flags, 64, 17, 0,
                             bytes([10, 5, 5, 86]), bytes([10, 5, 5, 1]))  # fmt: skip
            frames.append(bytes(12) + b"\x08\x00" + ip + piece)
        records += frames[::-1] if fragment else frames
    with open(path, "wb") as file:
        file.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))
        for frame in records:
            file.write(struct.pack("<IIII", 0, 0, len(frame), len(frame)) + frame)


def write_ouster(path: Path, metadata: dict, frames_mm: np.ndarray, fragment=False) -> Path:
    """An Ouster capture at `path` (.pcap) with its metadata as the .json beside it."""
    write_capture(path, lidar_packets(metadata, frames_mm), fragment=fragment)
    path.with_suffix(".json").write_text(json.dumps(metadata))
    return path
