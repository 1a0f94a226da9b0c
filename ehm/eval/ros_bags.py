"""ROS bags of a ROS distribution's message types, written by the rosbags library's writers:
the guides' example bag (ehm.eval.guide_files) and the tests' bags."""

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ehm.io.bags import VELODYNE_TYPES

SECOND = 1_000_000_000  # nanoseconds
QUARTER_TURN = (0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5))  # x y z w: 90 degrees about z


class Messages:
    """Builds messages of one ROS distribution's types."""

    def __init__(self, store: Stores) -> None:
        self.typestore = get_typestore(store)
        if "tf2_msgs/msg/TFMessage" not in self.typestore.types:  # not in ROS 1's store
            definition = "geometry_msgs/TransformStamped[] transforms"
            self.typestore.register(get_types_from_msg(definition, "tf2_msgs/msg/TFMessage"))
        self.types = self.typestore.types
        self.ros1 = store == Stores.ROS1_NOETIC

    def header(self, stamp: int, frame: str) -> Any:
        time = self.types["builtin_interfaces/msg/Time"](
            sec=stamp // SECOND, nanosec=stamp % SECOND
        )
        if self.ros1:
            return self.types["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)
        return self.types["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def transform(
        self,
        stamp: int,
        parent: str,
        child: str,
        xyz: Sequence[float],
        quaternion: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
    ) -> Any:
        """A tf2_msgs/TFMessage placing `child` in `parent`: xyz metres, quaternion x y z w."""
        t = self.types
        transform = t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](*xyz),
            rotation=t["geometry_msgs/msg/Quaternion"](*quaternion),
        )
        stamped = t["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent), child_frame_id=child, transform=transform
        )
        return t["tf2_msgs/msg/TFMessage"](transforms=[stamped])

    def cloud(self, stamp: int, frame: str, points: np.ndarray) -> Any:
        """A sensor_msgs/PointCloud2 of (n, 3) points, metres, in `frame`."""
        t = self.types
        fields = [
            t["sensor_msgs/msg/PointField"](name=c, offset=4 * i, datatype=7, count=1)
            for i, c in enumerate("xyz")
        ]
        # 16 bytes a point: x y z and 4 bytes of padding.
        records = np.zeros((len(points), 4), dtype="<f4")
        records[:, :3] = points
        data = np.frombuffer(records.tobytes(), dtype=np.uint8)
        return t["sensor_msgs/msg/PointCloud2"](
            header=self.header(stamp, frame), height=1, width=len(points), fields=fields,
            is_bigendian=False, point_step=16, row_step=16 * len(points), data=data,
            is_dense=True,
        )  # fmt: skip

    def depth_image(self, stamp: int, frame: str, depth: np.ndarray) -> Any:
        """A sensor_msgs/Image of a (H, W) depth array: uint16 as 16UC1, float32 as 32FC1."""
        depth = np.ascontiguousarray(depth)
        encoding = "16UC1" if depth.dtype == np.uint16 else "32FC1"
        return self.types["sensor_msgs/msg/Image"](
            header=self.header(stamp, frame), height=depth.shape[0], width=depth.shape[1],
            encoding=encoding, is_bigendian=0, step=depth.shape[1] * depth.itemsize,
            data=np.frombuffer(depth.astype(depth.dtype.newbyteorder("<")).tobytes(), np.uint8),
        )  # fmt: skip

    def camera_info(
        self,
        stamp: int,
        frame: str,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        size: tuple[int, int],
    ) -> Any:
        """A sensor_msgs/CameraInfo of a pinhole camera of `size` (width, height) pixels."""
        k = np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=float)
        fields = {"K": k, "R": np.eye(3).ravel(), "P": np.zeros(12), "D": np.zeros(0)}
        if not self.ros1:
            fields = {name.lower(): value for name, value in fields.items()}
        t = self.types
        roi = t["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        return t["sensor_msgs/msg/CameraInfo"](
            header=self.header(stamp, frame), height=size[1], width=size[0],
            distortion_model="plumb_bob", binning_x=0, binning_y=0, roi=roi, **fields,
        )  # fmt: skip

    def laser(self, stamp: int, frame: str, ranges: Sequence[float]) -> Any:
        """A sensor_msgs/LaserScan of beams a quarter turn apart from angle 0."""
        return self.types["sensor_msgs/msg/LaserScan"](
            header=self.header(stamp, frame), angle_min=0.0, angle_max=np.pi,
            angle_increment=np.pi / 2, time_increment=0.0, scan_time=0.1, range_min=0.1,
            range_max=10.0, ranges=np.array(ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32),
        )  # fmt: skip

    def odometry(
        self,
        stamp: int,
        parent: str,
        child: str,
        xyz: Sequence[float],
        quaternion: Sequence[float],
    ) -> Any:
        """A nav_msgs/Odometry pose of `child` in `parent`, at rest."""
        t = self.types
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](*xyz),
            orientation=t["geometry_msgs/msg/Quaternion"](*quaternion),
        )
        zero = t["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.0)
        return t["nav_msgs/msg/Odometry"](
            header=self.header(stamp, parent), child_frame_id=child,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                covariance=np.zeros(36),
            ),
        )  # fmt: skip

    def velodyne_scan(self, stamp: int, frame: str, packets: list[tuple[int, bytes]]) -> Any:
        """A velodyne_msgs/VelodyneScan of (time in nanoseconds, 1206 bytes) packets."""
        t = self.types
        if "velodyne_msgs/msg/VelodyneScan" not in t:
            for name, definition in VELODYNE_TYPES.items():
                self.typestore.register(get_types_from_msg(definition, name))
        time, packet = t["builtin_interfaces/msg/Time"], t["velodyne_msgs/msg/VelodynePacket"]
        return t["velodyne_msgs/msg/VelodyneScan"](
            header=self.header(stamp, frame),
            packets=[
                packet(stamp=time(sec=ns // SECOND, nanosec=ns % SECOND),
                       data=np.frombuffer(data, dtype=np.uint8))
                for ns, data in packets
            ],
        )  # fmt: skip

    def serialize(self, message: Any) -> bytes:
        """The message's bytes as the distribution's bags hold them."""
        if self.ros1:
            return self.typestore.serialize_ros1(message, message.__msgtype__)
        return self.typestore.serialize_cdr(message, message.__msgtype__)


def write_bag(
    path: Path,
    store: Stores,
    messages: Iterable[tuple[str, int, Callable[[Messages], Any]]],
    storage: Any = None,
    compression: Any = None,
    version: int = 9,
) -> Path:
    """Write (topic, stamp, message) triples, in order, to a ROS 1 bag (its chunks compressed
    with `compression`, a Writer1.CompressionFormat, or not) or a ROS 2 folder of rosbag2's
    format `version` (before 8, without the messages' type definitions)."""
    build = Messages(store)
    writer = Writer1(path) if build.ros1 else Writer2(path, version=version, storage_plugin=storage)
    if compression is not None:
        writer.set_compression(compression)
    with writer:
        connections = {}
        for topic, stamp, make in messages:
            message = make(build)
            if topic not in connections:
                connections[topic] = writer.add_connection(
                    topic, message.__msgtype__, typestore=build.typestore
                )
            writer.write(connections[topic], stamp, build.serialize(message))
    return path
