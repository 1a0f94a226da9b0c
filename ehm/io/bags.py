"""ROS 1 bags (.bag) and ROS 2 bag folders (.db3 or .mcap), read with the `rosbags` library,
no ROS install needed: sensor_msgs/PointCloud2 (3D scans), sensor_msgs/LaserScan (2D scans,
in the fixed frame's x-y plane) or velodyne_msgs/VelodyneScan (a rotation's raw packets,
decoded by velodyne-decoder, ehm.io.velodyne) of one topic, placed in a fixed frame by /tf
and /tf_static (the transform at each message's stamp, interpolated), by a
nav_msgs/Odometry topic (with /tf_static from its child frame to the sensor's), or by a
poses file (one T_world_sensor per message, in order).

    bag = BagScans("run.bag", "/velodyne_points", frame="map")
    for scan in bag: ...
    bag.skipped            # messages without a transform at their stamp

Transforms and odometry are read first, in one pass (they are small); the scans are read as
they are asked for, so memory holds one at a time.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix, transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError, assumed
from ehm.io.bag_chunks import ChunkReader
from ehm.io.depth import DepthCamera
from ehm.io.frames import FrameTree
from ehm.io.poses import read_poses
from ehm.io.velodyne import PacketDecoder

INSTALL_HINT = "ROS bags need the rosbags library: pip install 'ehm[ros]'"
VELODYNE_SCAN = "velodyne_msgs/msg/VelodyneScan"
# velodyne_msgs' types, which ROS 2 bags before rosbag2's version 8 do not carry and the
# distributions' type stores do not hold: a packet of 1206 bytes and its time, a scan of them.
VELODYNE_TYPES = {
    "velodyne_msgs/msg/VelodynePacket": "builtin_interfaces/Time stamp\nuint8[1206] data",
    VELODYNE_SCAN: "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets",
}
IMAGE, CAMERA_INFO = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo"
SCAN_TYPES = ("sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/LaserScan", VELODYNE_SCAN, IMAGE)
# Depth image encodings, and the raw units a metre each holds (REP 118: 16-bit millimetres,
# 32-bit float metres).
DEPTH_ENCODINGS = {"16UC1": ("u2", 1000.0), "mono16": ("u2", 1000.0), "32FC1": ("f4", 1.0)}
# Raw packets of sensors whose packets are not decoded from bags, and what to do instead.
UNDECODED_PACKETS = {
    "ouster_sensor_msgs/msg/PacketMsg": "Ouster",
    "ouster_ros/msg/PacketMsg": "Ouster",
    "ouster_msgs/msg/PacketMsg": "Ouster",
}
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
TF_TOPICS = ("/tf", "/tf_static")
# numpy codes of sensor_msgs/PointField datatypes 1 to 8.
FIELD_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


# The files a ROS 2 bag folder keeps its messages in.
ROS2_SUFFIXES = (".db3", ".mcap")


def is_bag(path: str | PathLike[str]) -> bool:
    """A ROS 1 .bag file, or a ROS 2 bag: its folder (holding metadata.yaml) or one of its
    .db3 or .mcap files."""
    path = Path(path)
    return path.suffix == ".bag" or (bag_folder(path) / "metadata.yaml").exists()


def bag_folder(path: Path) -> Path:
    """The folder of a ROS 2 bag that `path` names: itself, or the folder of a .db3 or .mcap
    file; FileReadError for such a file outside a bag folder."""
    if path.suffix.lower() not in ROS2_SUFFIXES:
        return path
    if not (path.parent / "metadata.yaml").exists():
        raise FileReadError(
            path,
            "a ROS 2 bag is the folder holding metadata.yaml beside its .db3 or .mcap files, and "
            "there is none here: give the bag's folder, or make one with `ros2 bag reindex`",
        )
    return path.parent


class BagScans:
    """The scans of `topic` in a bag, in world frame `frame` (see the module). Opening checks
    the topic, its type and the source of poses; iterating reads the scans."""

    def __init__(
        self,
        path: str | PathLike[str],
        topic: str | None,
        frame: str | None = None,
        odometry: str | None = None,
        poses: str | PathLike[str] | None = None,
        intrinsics: Sequence[float] | None = None,
        depth_scale: float | None = None,
        origin: Sequence[float] | None = None,
    ) -> None:
        self.path = bag_folder(Path(path))
        self.skipped = 0
        self._frame, self._odometry = frame, odometry
        with self._reader() as reader:
            topics = {c.topic: c.msgtype for c in reader.connections}
            self.topic = self._scan_topic(topic, topics)
            # Scans at most (messages without a pose at their stamp are skipped); None where
            # the bag's index is broken and its connections were read from its chunks.
            mine = [
                getattr(c, "msgcount", None) for c in reader.connections if c.topic == self.topic
            ]
            self.messages = None if None in mine else sum(mine)
        self.dim = 2 if topics[self.topic] == SCAN_TYPES[1] else 3
        self._packets = PacketDecoder() if topics[self.topic] == VELODYNE_SCAN else None
        self._camera = None
        if topics[self.topic] == IMAGE:
            self._camera = self._depth_camera(topics, intrinsics, depth_scale)
        elif (intrinsics, depth_scale) != (None, None):
            raise InputError("intrinsics and depth_scale are for depth images (Image topics)")
        self._poses = read_poses(poses) if poses is not None else None
        # A sensor that stood still: every scan placed at `origin`, the world's axes its own.
        self._fixed = None
        if origin is not None:
            if (frame, odometry) != (None, None):
                raise InputError(
                    "an origin places every scan: --frame and --odometry would be ignored"
                )
            self._fixed = np.eye(4)
            self._fixed[:3, 3] = origin
        if self._poses is None and self._fixed is None:
            if odometry is None and "/tf" not in topics and "/tf_static" not in topics:
                raise InputError(
                    f"{self.path}: no /tf in the bag: give an odometry topic (--odometry), a "
                    "poses file (--poses), or the origin of a sensor that stood still (--origin)"
                )
            if frame is None:
                raise InputError(
                    f"{self.path}: give the fixed frame the scans are placed in (--frame)"
                )
            if odometry is not None and topics.get(odometry) != ODOMETRY_TYPE:
                raise InputError(
                    f"{self.path}: {odometry!r} is not a {ODOMETRY_TYPE} topic "
                    f"({', '.join(t for t, k in topics.items() if k == ODOMETRY_TYPE) or 'none'})"
                )
            self._frames = self._read_frames()

    def __iter__(self) -> Iterator[Scan]:
        with self._reader() as reader:
            connections = [c for c in reader.connections if c.topic == self.topic]
            for index, (connection, _, raw) in enumerate(reader.messages(connections=connections)):
                try:
                    message = reader.deserialize(raw, connection.msgtype)
                except Exception as error:
                    # rosbags reports undecodable messages in its own exception types.
                    raise FileReadError(
                        self.path, f"message {index} on {self.topic} cannot be decoded ({error})"
                    ) from None
                scan = self._scan(message, index)
                if scan is None:
                    self.skipped += 1
                else:
                    yield scan

    def _scan(self, message, index: int) -> Scan | None:
        """The message as a Scan in world frame, at its header's stamp, or None without a
        transform at that stamp."""
        stamp = _nanoseconds(message.header.stamp)
        if self._fixed is not None:
            T_world_sensor = self._fixed
        elif self._poses is not None:
            if index >= len(self._poses):
                raise InputError(f"{len(self._poses)} poses for more messages on {self.topic}")
            T_world_sensor = self._poses[index]
        else:
            T_world_sensor = self._frames.lookup(self._frame, message.header.frame_id, stamp)
            if T_world_sensor is None:
                return None
        try:
            if self._packets is not None:
                points, hits = self._packets.points(message.packets), None
            elif self._camera is not None:
                points, hits = self._camera.points(depth_image(message)), None
            elif self.dim == 3:
                points, hits = point_cloud_points(message), None
            else:
                points, hits = laser_scan_points(message)
            world = transform_points(T_world_sensor, points)
            origin = T_world_sensor[:3, 3]
            time = stamp * 1e-9
            if self.dim == 2:
                return Scan(world[:, :2], origin[:2].copy(), hits, time)
            return Scan(world, origin.copy(), time=time)
        except InputError as error:
            raise FileReadError(self.path, f"message {index} on {self.topic}: {error}") from None

    def _depth_camera(
        self,
        topics: dict[str, str],
        intrinsics: Sequence[float] | None,
        depth_scale: float | None,
    ) -> DepthCamera:
        """The camera of the depth image topic: its CameraInfo (the topic's namespace's
        camera_info, else the bag's only CameraInfo topic) or `intrinsics`; the depth unit of
        its first image's encoding or `depth_scale`."""
        with self._reader() as reader:
            images = [c for c in reader.connections if c.topic == self.topic]
            first = next(reader.messages(connections=images), None)
            if first is None:
                raise FileReadError(self.path, f"{self.topic} holds no image")
            image = reader.deserialize(first[2], first[0].msgtype)
            if intrinsics is None:
                intrinsics = self._camera_info(reader, topics)
        if image.encoding not in DEPTH_ENCODINGS and depth_scale is None:
            raise FileReadError(
                self.path,
                f"{self.topic} holds {image.encoding!r} images, not depth ("
                f"{', '.join(DEPTH_ENCODINGS)}); give --depth-scale for another encoding",
            )
        if depth_scale is None:
            depth_scale = DEPTH_ENCODINGS[image.encoding][1]
            unit = "millimetres" if depth_scale == 1000.0 else "metres"
            assumed(f"{self.topic}: {image.encoding} depth read as {unit} (REP 118)")
        # 0 is no reading in either encoding; a float image's NaN the scan drops.
        return DepthCamera(*intrinsics, depth_scale=depth_scale)

    def _camera_info(self, reader, topics: dict[str, str]) -> tuple[float, ...]:
        """(fx, fy, cx, cy) of the depth topic's CameraInfo; InputError naming the option when
        the bag has none for it."""
        namespace = self.topic.rsplit("/", 1)[0]
        infos = [t for t, kind in topics.items() if kind == CAMERA_INFO]
        ours = f"{namespace}/camera_info"
        topic = ours if ours in infos else (infos[0] if len(infos) == 1 else None)
        if topic is None:
            raise InputError(
                f"{self.path}: no CameraInfo for {self.topic} ({', '.join(infos) or 'none'}): "
                "give the camera with --intrinsics FX,FY,CX,CY"
            )
        connections = [c for c in reader.connections if c.topic == topic]
        found = next(reader.messages(connections=connections), None)
        if found is None:
            raise FileReadError(self.path, f"{topic} holds no CameraInfo")
        info = reader.deserialize(found[2], found[0].msgtype)
        k = np.asarray(info.k if hasattr(info, "k") else info.K, dtype=float)  # ROS 2, ROS 1
        return (k[0], k[4], k[2], k[5])

    def _read_frames(self) -> FrameTree:
        """Every /tf and /tf_static transform, and the odometry topic's poses."""
        frames = FrameTree()
        with self._reader() as reader:
            # An odometry without child frame (Stage's ground truth) places the scans' frame.
            unnamed = self._scan_frame(reader) if self._odometry else ""
            noted = False
            topics = [*TF_TOPICS, *([self._odometry] if self._odometry else [])]
            connections = [c for c in reader.connections if c.topic in topics]
            for connection, _, raw in reader.messages(connections=connections):
                message = reader.deserialize(raw, connection.msgtype)
                if connection.msgtype == ODOMETRY_TYPE:
                    stamp = _nanoseconds(message.header.stamp)
                    pose = message.pose.pose
                    T = _pose_matrix(pose.position, pose.orientation)
                    if not message.child_frame_id and not noted:
                        assumed(
                            f"{self.path}: {self._odometry} names no child frame: its poses "
                            f"are taken as those of the scans' frame, {unnamed!r}"
                        )
                        noted = True
                    child = message.child_frame_id or unnamed
                    frames.add(message.header.frame_id, child, stamp, T)
                    continue
                for transform in message.transforms:
                    t = transform.transform
                    T = _pose_matrix(t.translation, t.rotation)
                    parent, child = transform.header.frame_id, transform.child_frame_id
                    if connection.topic == "/tf_static":
                        frames.add_static(parent, child, T)
                    else:
                        frames.add(parent, child, _nanoseconds(transform.header.stamp), T)
        return frames

    def _scan_frame(self, reader) -> str:
        """The frame of the first message on the scan topic."""
        connections = [c for c in reader.connections if c.topic == self.topic]
        for connection, _, raw in reader.messages(connections=connections):
            return reader.deserialize(raw, connection.msgtype).header.frame_id
        return ""

    def _scan_topic(self, topic: str | None, topics: dict[str, str]) -> str:
        found = [t for t, kind in topics.items() if kind in SCAN_TYPES]
        listing = ", ".join(f"{t} ({topics[t].rsplit('/', 1)[-1]})" for t in found) or "none"
        packets = [t for t, kind in topics.items() if kind in UNDECODED_PACKETS]
        if packets and (topic in packets or (topic is None and not found)):
            sensor = UNDECODED_PACKETS[topics[topic or packets[0]]]
            raise InputError(
                f"{self.path}: {topic or packets[0]} carries raw {sensor} packets, which are "
                "not decoded from bags: record the driver's point clouds (PointCloud2), or the "
                "sensor's packets as a pcap with its metadata JSON, which ehm reads"
            )
        if topic is None:
            if len(found) != 1:
                raise InputError(f"{self.path}: give the topic of the scans (--topic): {listing}")
            return found[0]
        if topics.get(topic) not in SCAN_TYPES:
            raise InputError(
                f"{self.path}: {topic!r} is not a PointCloud2, LaserScan or VelodyneScan topic: "
                f"{listing}"
            )
        return topic

    def _reader(self):
        try:
            from rosbags.highlevel import AnyReader
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
        except ImportError as error:
            raise ImportError(INSTALL_HINT) from error
        store = get_typestore(Stores.ROS2_HUMBLE)
        for name, definition in VELODYNE_TYPES.items():
            store.register(get_types_from_msg(definition, name))
        reader = AnyReader([self.path], default_typestore=store)
        return _Opened(reader, self.path)


class _Opened:
    """An AnyReader opened as a context, its errors naming the bag. A ROS 1 bag it refuses
    is read from its chunks alone (ehm.io.bag_chunks): old bags whose index records are
    broken have intact chunks."""

    def __init__(self, reader, path: Path) -> None:
        self._reader, self._path = reader, path

    def __enter__(self):
        try:
            self._reader.open()
        except Exception as error:
            # rosbags reports unreadable bags in its own exception types, some without a text.
            reason = str(error) or type(error).__name__
            if self._path.is_dir():
                raise FileReadError(self._path, f"not a readable ROS bag ({reason})") from None
            self._reader = ChunkReader(self._path)
            try:
                self._reader.open()
            except Exception as chunk_error:
                if isinstance(chunk_error, FileReadError):
                    chunks = str(chunk_error).removeprefix(f"{self._path}")
                else:
                    chunks = f": {str(chunk_error) or type(chunk_error).__name__}"
                raise FileReadError(
                    self._path, f"not a readable ROS bag ({reason}; chunk by chunk{chunks})"
                ) from None
        return self._reader

    def __exit__(self, *exc) -> None:
        self._reader.close()


def depth_image(message) -> np.ndarray:
    """(H, W) raw depth values of a sensor_msgs/Image of a DEPTH_ENCODINGS encoding."""
    kind, _ = DEPTH_ENCODINGS.get(message.encoding, ("u2", None))
    dtype = np.dtype(kind).newbyteorder(">" if message.is_bigendian else "<")
    data = np.asarray(message.data, dtype=np.uint8)
    if message.step * message.height > len(data) or message.step < message.width * dtype.itemsize:
        raise InputError(
            f"Image of {message.height} x {message.width} ({message.step} bytes a row) holds "
            f"{len(data)} bytes"
        )
    rows = data[: message.step * message.height].reshape(message.height, message.step)
    pixels = rows[:, : message.width * dtype.itemsize].copy().view(dtype)
    return pixels.astype(np.float64) if kind == "f4" else pixels


def point_cloud_points(message) -> np.ndarray:
    """(n, 3) float64 x, y, z of a sensor_msgs/PointCloud2, sensor frame, metres."""
    fields = {f.name: f for f in message.fields}
    missing = [c for c in "xyz" if c not in fields]
    if missing:
        raise InputError(f"PointCloud2 without {', '.join(missing)} fields")
    for c in "xyz":
        kind = FIELD_TYPES.get(fields[c].datatype)
        if kind is None or fields[c].offset + int(kind[1]) > message.point_step:
            raise InputError(f"PointCloud2 field {c} of datatype {fields[c].datatype} does not fit")
    if message.row_step < message.width * message.point_step or len(message.data) < (
        message.height * message.row_step
    ):
        raise InputError(
            f"PointCloud2 of {message.height} x {message.width} points of {message.point_step} "
            f"bytes in rows of {message.row_step} holds {len(message.data)} bytes"
        )
    order = ">" if message.is_bigendian else "<"
    dtype = np.dtype(
        {
            "names": list("xyz"),
            "formats": [order + FIELD_TYPES[fields[c].datatype] for c in "xyz"],
            "offsets": [fields[c].offset for c in "xyz"],
            "itemsize": message.point_step,
        }
    )
    data = np.asarray(message.data, dtype=np.uint8)[: message.height * message.row_step]
    rows = data.reshape(message.height, message.row_step)[:, : message.width * message.point_step]
    records = np.frombuffer(np.ascontiguousarray(rows).tobytes(), dtype=dtype)
    with np.errstate(invalid="ignore"):
        return np.column_stack([records[c].astype(np.float64) for c in "xyz"])


def laser_scan_points(message) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) float64 ray ends of a sensor_msgs/LaserScan in its frame (z = 0), metres, and
    (n,) which returned: readings under range_min or NaN are left out; readings at range_max
    or beyond (or infinite) are rays without return, ending at range_max, as gmapping and
    slam_toolbox read them (simulators and many drivers report no return as range_max)."""
    ranges = np.asarray(message.ranges, dtype=np.float64)
    angles = message.angle_min + np.arange(len(ranges)) * message.angle_increment
    kept = ~np.isnan(ranges) & (ranges >= message.range_min)
    ranges, angles = ranges[kept], angles[kept]
    hits = ranges < message.range_max
    ranges = np.where(hits, ranges, message.range_max)
    points = np.column_stack(
        [ranges * np.cos(angles), ranges * np.sin(angles), np.zeros(len(ranges))]
    )
    return points, hits


def _pose_matrix(translation, rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = quaternion_to_matrix(rotation.w, rotation.x, rotation.y, rotation.z)
    T[:3, 3] = (translation.x, translation.y, translation.z)
    return T


def _nanoseconds(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
