"""Velodyne LiDAR captures: a `.pcap` of the sensor's 1206-byte UDP data packets, decoded by
velodyne-decoder (`pip install 'ehm[velodyne]'`), which tells the model from the packets and
carries every model's calibration: one scan per rotation, in the sensor frame (x forward, z
up), returns nearer than 0.1 m or without a return left out by the decoder.
"""

from __future__ import annotations

from collections.abc import Iterator
from os import PathLike
from pathlib import Path
from types import ModuleType

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError, assumed
from ehm.io.pcap import udp_payloads

VELODYNE_PACKET = 1206  # bytes of a data packet's UDP payload, every model
# The product ids in a data packet's last byte of the models that name themselves there
# (HDL-32E, VLP-16, Puck Hi-Res, VLP-32C, Velarray, VLS-128); an HDL-64E names none.
_PRODUCT_IDS = (0x21, 0x22, 0x24, 0x28, 0x31, 0xA1)
INSTALL_HINT = (
    "Velodyne captures are decoded by velodyne-decoder: pip install 'ehm[velodyne]' "
    "(or pip install velodyne-decoder)"
)


def decoder_module() -> ModuleType:
    """The velodyne_decoder module; ImportError with the install hint where it is missing."""
    try:
        import velodyne_decoder
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    return velodyne_decoder


class VelodyneCapture:
    """The rotations of a Velodyne capture (a .pcap) as scans; the decoder is loaded when it
    is made (ImportError naming the extra when it is missing), packets read when iterated."""

    def __init__(self, capture: str | PathLike[str]) -> None:
        self.path = Path(capture)
        self._decoder = decoder_module()
        assumed(
            f"{self.path.name}: Velodyne packets, the model and its calibration told by "
            "velodyne-decoder; frames are in the sensor's own frame"
        )

    def __iter__(self) -> Iterator[Scan]:
        decoder = self._decoder.StreamDecoder(self._config())
        found = 0
        try:
            for datagram in udp_payloads(self.path):
                if len(datagram.payload) == VELODYNE_PACKET:
                    rotation = decoder.decode(datagram.time, datagram.payload, False)
                    if rotation is not None and len(rotation[1]):
                        found += 1
                        yield _scan(*rotation)
            rotation = decoder.finish(False)
        except (RuntimeError, ValueError) as error:
            raise FileReadError(self.path, f"velodyne-decoder could not read it: {error}") from None
        if rotation is not None and len(rotation[1]):
            found += 1
            yield _scan(*rotation)
        if not found:
            raise FileReadError(self.path, "holds no Velodyne rotation the decoder could read")

    def _config(self):
        """The decoder's settings: the model from the packets, except an HDL-64E's, which with
        its calibration is read from the packets' status bytes (a first pass over the file,
        made once the capture has been read through as a valid pcap)."""
        decoder = self._decoder
        first = next(
            (d.payload for d in udp_payloads(self.path) if len(d.payload) == VELODYNE_PACKET),
            None,
        )
        if first is None or first[-1] in _PRODUCT_IDS:
            return decoder.Config()
        for _ in udp_payloads(self.path):
            pass  # the whole file is a valid capture before the decoder's own pass reads it
        try:
            model, calibration = decoder.hdl64e.detect_hdl64e(str(self.path))
        except ValueError as error:
            message = f"an HDL-64E capture without its calibration: {error}"
            raise FileReadError(self.path, message) from None
        return decoder.Config(model=model, calibration=calibration)


def _scan(stamp, cloud: np.ndarray) -> Scan:
    """The scan of one decoded rotation: (N, 3+) float32 points in the sensor frame, the host's
    time stamp."""
    return Scan(np.asarray(cloud[:, :3], dtype=np.float64), np.zeros(3), time=float(stamp.host))


class PacketDecoder:
    """Decodes the packets a ROS velodyne_msgs/VelodyneScan message bundles (one rotation)
    into points, the model told from the packets; ImportError naming the extra when
    velodyne-decoder is missing."""

    def __init__(self) -> None:
        self._decoder = decoder_module()
        self._scans = self._decoder.ScanDecoder(self._decoder.Config())

    def points(self, packets) -> np.ndarray:
        """(N, 3) float64, metres, sensor frame, of `packets` (each with `stamp`, a ROS time
        of sec and nanosec, and `data`, its 1206 bytes). InputError for packets the decoder
        cannot read (an HDL-64E's, whose calibration a bag does not carry)."""
        vector = self._decoder.PacketVector()
        for packet in packets:
            stamp = packet.stamp.sec + packet.stamp.nanosec * 1e-9
            vector.append(self._decoder.VelodynePacket(stamp, bytes(packet.data)))
        try:
            _, cloud = self._scans.decode(vector)
        except (RuntimeError, ValueError) as error:
            raise InputError(f"velodyne-decoder could not decode its packets: {error}") from None
        return np.asarray(cloud[:, :3], dtype=np.float64)
