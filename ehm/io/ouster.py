"""Ouster LiDAR captures: a `.pcap` of the sensor's UDP lidar packets with its metadata JSON
(the file `ouster-cli` or the sensor's web page saves, beside the capture as NAME.json or the
folder's only .json), decoded into one scan per frame, in the sensor frame.

Profiles read: LEGACY, RNG19_RFL8_SIG16_NIR16, RNG19_RFL8_SIG16_NIR16_DUAL (both returns) and
RNG15_RFL8_NIR8. A pixel's point follows Ouster's sensor manual (beam altitude and azimuth
angles, the encoder angle of its column, the beam origin's offset from the LiDAR axis), then
the metadata's lidar_to_sensor_transform (millimetres); a range of 0 is no return.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, assumed
from ehm.io.pcap import udp_payloads


@dataclass(frozen=True)
class _Profile:
    """Where a UDP lidar profile keeps a column's parts, in bytes."""

    packet_header: int
    column_header: int
    pixel: int
    column_footer: int
    packet_footer: int
    returns: int  # ranges a pixel holds: 2 for the dual-return profiles


_PROFILES = {
    "LEGACY": _Profile(0, 16, 12, 4, 0, 1),
    "RNG19_RFL8_SIG16_NIR16": _Profile(32, 12, 12, 0, 32, 1),
    "RNG19_RFL8_SIG16_NIR16_DUAL": _Profile(32, 12, 16, 0, 32, 2),
    "RNG15_RFL8_NIR8": _Profile(32, 12, 4, 0, 32, 1),
}
_LIDAR_PACKET = 1  # packet_type of lidar data in the non-legacy header
# What Ouster's SDK takes for metadata of early firmware, which does not record them.
_DEFAULT_LIDAR_TO_SENSOR = [-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1]
_DEFAULT_BEAM_OFFSET_MM = 12.163
_OS1_DEFAULTS = ("lidar_to_sensor_transform", "lidar_origin_to_beam_origin_mm")


@dataclass(frozen=True)
class OusterSensor:
    """What turns an Ouster sensor's lidar packets into points: its metadata.

    altitude, azimuth: (H,) float64, radians, each beam's angles; beam_offset: metres, the
    beam origin's distance from the LiDAR axis; T_sensor_lidar: (4, 4), metres;
    width: columns a frame (its measurement ids run over 0..width-1); pixels: beams a
    column; columns_per_packet; profile: one of _PROFILES' names; port: the lidar UDP port
    (0: any).
    """

    altitude: np.ndarray
    azimuth: np.ndarray
    beam_offset: float
    T_sensor_lidar: np.ndarray
    width: int
    pixels: int
    columns_per_packet: int
    profile: str
    port: int

    @property
    def packet_size(self) -> int:
        """Bytes in one lidar packet's UDP payload."""
        p = _PROFILES[self.profile]
        column = p.column_header + self.pixels * p.pixel + p.column_footer
        return p.packet_header + self.columns_per_packet * column + p.packet_footer


def metadata_path(capture: str | PathLike[str]) -> Path:
    """The metadata JSON of a capture: NAME.json beside NAME.pcap, else the folder's only
    .json file. FileReadError naming where it was looked for when there is none."""
    capture = Path(capture)
    beside = capture.with_suffix(".json")
    if beside.is_file():
        return beside
    found = sorted(capture.parent.glob("*.json"))
    if len(found) == 1:
        return found[0]
    raise FileReadError(
        capture,
        f"needs its sensor's metadata JSON to decode: put it beside the capture as {beside.name} "
        "(`ouster-cli source SENSOR save NAME.pcap` writes both)",
    )


class OusterCapture:
    """The frames of an Ouster capture (a .pcap) as scans: its metadata is found and read when
    it is made (FileReadError naming what is missing or wrong), its packets when iterated."""

    def __init__(self, capture: str | PathLike[str]) -> None:
        self.path = Path(capture)
        metadata = metadata_path(self.path)
        self.sensor = read_ouster_metadata(metadata)
        assumed(
            f"{self.path.name}: decoded with {metadata.name} ({self.sensor.profile}, "
            f"{self.sensor.pixels} x {self.sensor.width}); frames are in the sensor's own frame"
        )

    def __iter__(self) -> Iterator[Scan]:
        return ouster_scans(self.path, self.sensor)


def read_ouster_metadata(path: str | PathLike[str]) -> OusterSensor:
    """An Ouster metadata JSON, in the flat layout of firmware 2.x or the sectioned one of
    newer SDKs. FileReadError naming a missing key or a profile not read."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise FileReadError(path, f"is not readable JSON: {error}") from None
    if not isinstance(document, dict):
        raise FileReadError(path, "is not an Ouster metadata object")
    values = _flattened(document)
    missing = [name for name in _OS1_DEFAULTS if name not in values]
    if missing:
        assumed(
            f"{path.name} has no {' or '.join(missing)} (firmware before 1.13): took Ouster's "
            "defaults for the OS1 (the LiDAR 36.18 mm above the sensor's base, turned 180 "
            "degrees; beams 12.163 mm from its axis)"
        )

    def value(name: str, default: Any = None) -> Any:
        if name not in values:
            if default is None:
                raise FileReadError(path, f"has no {name!r}: is it an Ouster sensor's metadata?")
            return default
        return values[name]

    profile = value("udp_profile_lidar", "LEGACY")
    if profile not in _PROFILES:
        raise FileReadError(
            path, f"lidar profile {profile!r} is not read; read are {', '.join(_PROFILES)}"
        )
    try:
        altitude = np.radians(np.asarray(value("beam_altitude_angles"), dtype=np.float64))
        azimuth = np.radians(np.asarray(value("beam_azimuth_angles"), dtype=np.float64))
        pixels = int(value("pixels_per_column", len(altitude)))
        T_sensor_lidar = np.asarray(
            value("lidar_to_sensor_transform", _DEFAULT_LIDAR_TO_SENSOR), dtype=np.float64
        )
        width = int(value("columns_per_frame", 0) or str(value("lidar_mode")).split("x")[0])
        columns_per_packet = int(value("columns_per_packet", 16))
        beam_offset = float(value("lidar_origin_to_beam_origin_mm", _DEFAULT_BEAM_OFFSET_MM))
        beam_offset /= 1000.0
        port = int(value("udp_port_lidar", 0) or 0)
    except (TypeError, ValueError) as error:
        message = f"holds a value that is not a number where one is: {error}"
        raise FileReadError(path, message) from None
    if altitude.shape != (pixels,) or azimuth.shape != (pixels,):
        raise FileReadError(path, f"beam angles for {len(altitude)} beams, columns of {pixels}")
    if T_sensor_lidar.size != 16:
        raise FileReadError(path, "lidar_to_sensor_transform is not 16 numbers")
    if min(width, pixels, columns_per_packet) < 1 or width % columns_per_packet:
        raise FileReadError(
            path, f"{width} columns a frame, {columns_per_packet} a packet: not a sensor's"
        )
    T_sensor_lidar = T_sensor_lidar.reshape(4, 4)
    T_sensor_lidar[:3, 3] /= 1000.0  # millimetres
    if not (np.all(np.isfinite(T_sensor_lidar)) and np.all(np.isfinite(altitude + azimuth))):
        raise FileReadError(path, "holds beam angles or a transform that are not finite")
    return OusterSensor(
        altitude=altitude,
        azimuth=azimuth,
        beam_offset=beam_offset,
        T_sensor_lidar=T_sensor_lidar,
        width=width,
        pixels=pixels,
        columns_per_packet=columns_per_packet,
        profile=profile,
        port=port,
    )


def _flattened(document: dict[str, Any]) -> dict[str, Any]:
    """The metadata's values by name, its sections (beam_intrinsics, lidar_data_format, ...)
    opened into one level; a name at the top level wins."""
    values: dict[str, Any] = {}
    for section in document.values():
        if isinstance(section, dict):
            values.update(section)
    values.update({k: v for k, v in document.items() if not isinstance(v, dict)})
    return values


def ouster_scans(capture: str | PathLike[str], sensor: OusterSensor) -> Iterator[Scan]:
    """One scan per frame of an Ouster capture taken by `sensor` (its metadata), points and
    origin in the sensor frame (metres), timed by its first column (seconds, the sensor's
    clock); frames cut by the capture's start or end are kept with the columns they have.
    FileReadError when no packet fits the metadata."""
    capture = Path(capture)
    frame_id, columns = None, []
    found = 0
    for _, port, payload in udp_payloads(capture):
        if (sensor.port and port != sensor.port) or len(payload) != sensor.packet_size:
            continue
        packet_frame, packet_columns = _decode(payload, sensor)
        if packet_frame is None:
            continue
        found += 1
        if frame_id is not None and packet_frame != frame_id and columns:
            yield _frame_scan(columns, sensor)
            columns = []
        frame_id = packet_frame
        columns.append(packet_columns)
    if columns:
        yield _frame_scan(columns, sensor)
    if not found:
        raise FileReadError(
            capture,
            f"holds no lidar packets of {sensor.packet_size} bytes"
            + (f" on port {sensor.port}" if sensor.port else "")
            + f" ({sensor.profile}, {sensor.pixels} beams): is the metadata this capture's?",
        )


def _decode(payload: bytes, sensor: OusterSensor) -> tuple[int | None, tuple[np.ndarray, ...]]:
    """A lidar packet's frame id (None: not a lidar packet) and its valid columns: time stamps
    (C,) ns, measurement ids (C,), ranges (C, H, returns) in millimetres."""
    p = _PROFILES[sensor.profile]
    n, h = sensor.columns_per_packet, sensor.pixels
    body = np.frombuffer(payload, np.uint8, offset=p.packet_header)
    body = body[: len(body) - p.packet_footer] if p.packet_footer else body
    blocks = body.reshape(n, -1)
    header = blocks[:, : p.column_header]
    time = header[:, :8].copy().view("<u8").ravel()
    measurement = header[:, 8:10].copy().view("<u2").ravel()
    pixels = blocks[:, p.column_header : p.column_header + h * p.pixel].reshape(n, h, p.pixel)
    if sensor.profile == "LEGACY":
        frame = int(header[0, 10:12].copy().view("<u2")[0])
        status = blocks[:, -4:].copy().view("<u4").ravel()
        valid = status == 0xFFFFFFFF
        ranges = (pixels[:, :, :4].copy().view("<u4")[..., 0] & 0xFFFFF)[..., None]
    else:
        if int.from_bytes(payload[:2], "little") != _LIDAR_PACKET:
            return None, ()
        frame = int.from_bytes(payload[2:4], "little")
        valid = (header[:, 10:12].copy().view("<u2").ravel() & 1) == 1
        words = pixels[:, :, : 8 if p.returns == 2 else 4].copy().view("<u4")
        if sensor.profile == "RNG15_RFL8_NIR8":
            ranges = ((words & 0x7FFF) * 8)[..., :1]
        else:
            ranges = words & 0x7FFFF
    return frame, (time[valid], measurement[valid], ranges[valid].astype(np.float64))


def _frame_scan(packets: list[tuple[np.ndarray, ...]], sensor: OusterSensor) -> Scan:
    """The scan of one frame's decoded packets."""
    times = np.concatenate([packet[0] for packet in packets])
    measurement = np.concatenate([packet[1] for packet in packets])
    ranges = np.concatenate([packet[2] for packet in packets]) / 1000.0  # (C, H, R), metres
    points = lidar_points(ranges, measurement, sensor)
    T = sensor.T_sensor_lidar
    points = points @ T[:3, :3].T + T[:3, 3]
    time = float(times.min()) * 1e-9 if times.size else None
    return Scan(points, T[:3, 3].copy(), time=time)


def lidar_points(ranges: np.ndarray, measurement: np.ndarray, sensor: OusterSensor) -> np.ndarray:
    """(N, 3) float64, metres, LiDAR frame: the points of returns (`ranges` (C, H, R) metres,
    0 for none) of columns with `measurement` ids (C,), by Ouster's beam geometry."""
    encoder = 2.0 * np.pi * (1.0 - measurement / sensor.width)  # (C,)
    column, beam, echo = np.nonzero(ranges > 0)
    r = ranges[column, beam, echo]
    theta = encoder[column]
    phi = sensor.altitude[beam]
    along = r - sensor.beam_offset
    heading = theta - sensor.azimuth[beam]
    return np.column_stack(
        [
            along * np.cos(heading) * np.cos(phi) + sensor.beam_offset * np.cos(theta),
            along * np.sin(heading) * np.cos(phi) + sensor.beam_offset * np.sin(theta),
            along * np.sin(phi),
        ]
    )
