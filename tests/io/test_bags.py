"""ROS bags written by the rosbags library's writers, read back as scans in the fixed frame."""

import struct

import numpy as np
import pytest

from ehm.errors import FileReadError, InputError
from ehm.io.bags import BagScans
from ehm.io.frames import FrameTree, interpolate_pose
from ehm.io.readers import read_scans

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.typesys import Stores  # noqa: E402

from ehm.eval.ros_bags import QUARTER_TURN, SECOND, write_bag  # noqa: E402


def lidar_messages(cloud):
    """base_link moves from the origin (0 s) to (2, 0, 0) turned a quarter about z (2 s); the
    Velodyne sits 1 m above base_link; clouds at 1 s and 3 s."""
    return [
        ("/tf_static", 0, lambda m: m.transform(0, "base_link", "velodyne", (0, 0, 1))),
        ("/tf", 0, lambda m: m.transform(0, "map", "base_link", (0, 0, 0))),
        ("/points", SECOND, lambda m: m.cloud(SECOND, "velodyne", cloud)),
        ("/tf", 2 * SECOND, lambda m: m.transform(
            2 * SECOND, "map", "base_link", (2, 0, 0), QUARTER_TURN)),
        ("/points", 3 * SECOND, lambda m: m.cloud(3 * SECOND, "velodyne", cloud)),
    ]  # fmt: skip


@pytest.fixture
def lidar_bag(tmp_path, cloud):
    """A ROS 1 bag of lidar_messages."""
    return write_bag(tmp_path / "lidar.bag", Stores.ROS1_NOETIC, lidar_messages(cloud))


def break_index_counts(path):
    """Make every index record of the ROS 1 bag at `path` announce two entries more than it
    holds, as in old bags whose index the bag library refuses (with an empty AssertionError)
    while their chunks are intact."""
    data = bytearray(path.read_bytes())
    position = len(b"#ROSBAG V2.0\n")
    while position < len(data):
        (header_length,) = struct.unpack_from("<I", data, position)
        header = bytes(data[position + 4 : position + 4 + header_length])
        (data_length,) = struct.unpack_from("<I", data, position + 4 + header_length)
        if b"op=\x04" in header:
            at = header.index(b"count=") + len(b"count=")
            (count,) = struct.unpack_from("<I", header, at)
            struct.pack_into("<I", data, position + 4 + at, count + 2)
        position += 8 + header_length + data_length
    path.write_bytes(bytes(data))


def test_clouds_are_placed_by_tf_at_their_stamp(lidar_bag, cloud):
    bag = BagScans(lidar_bag, "/points", frame="map")
    scans = list(bag)
    assert len(scans) == 1 and bag.skipped == 1  # the cloud at 3 s is past the last /tf
    eighth = np.pi / 4  # halfway through the quarter turn
    R = np.array(
        [[np.cos(eighth), -np.sin(eighth), 0], [np.sin(eighth), np.cos(eighth), 0], [0, 0, 1]]
    )
    expected = (cloud + np.array([0, 0, 1])) @ R.T + [1, 0, 0]
    np.testing.assert_allclose(scans[0].points_world, expected, atol=1e-5)
    np.testing.assert_allclose(scans[0].origin, [1, 0, 1], atol=1e-12)
    assert scans[0].time == 1.0  # its header's stamp, seconds
    (read,) = read_scans(lidar_bag, topic="/points", frame="map")
    np.testing.assert_array_equal(read.points_world, scans[0].points_world)


def test_a_poses_file_places_each_message(lidar_bag, cloud, tmp_path):
    (tmp_path / "poses.txt").write_text("1 0 0 5 0 1 0 0 0 0 1 0\n1 0 0 6 0 1 0 0 0 0 1 0\n")
    scans = list(BagScans(lidar_bag, "/points", poses=tmp_path / "poses.txt"))
    np.testing.assert_allclose(scans[1].points_world, cloud + np.array([6, 0, 0]), atol=1e-5)
    assert [scan.time for scan in scans] == [1.0, 3.0]


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_laser_scans_placed_by_odometry_in_ros2_bags(tmp_path, storage):
    """A ROS 2 bag of LaserScans (beams at 0, 90 and 180 degrees; one beyond range_max, one
    under range_min) placed by /odom and the laser's static offset."""
    bag = write_bag(
        tmp_path / "run",
        Stores.ROS2_HUMBLE,
        [
            ("/tf_static", 0, lambda m: m.transform(0, "base_link", "laser", (0.5, 0, 0))),
            ("/odom", 0, lambda m: m.odometry(0, "odom", "base_link", (1, 2, 0), QUARTER_TURN)),
            ("/scan", SECOND, lambda m: m.laser(SECOND, "laser", [2.0, 30.0, 0.05])),
            ("/odom", 2 * SECOND, lambda m: m.odometry(
                2 * SECOND, "odom", "base_link", (1, 2, 0), QUARTER_TURN)),
        ],
        storage,
    )  # fmt: skip
    (scan,) = list(BagScans(bag, "/scan", frame="odom", odometry="/odom"))
    # The laser at (1, 2.5) facing +y: its 0-degree beam hits 2 m ahead; its 90-degree beam
    # is a ray without return to range_max, 10 m toward -x; the 0.05 m reading is dropped.
    np.testing.assert_allclose(scan.origin, [1.0, 2.5], atol=1e-12)
    # (float32 angles: to 1e-6 m)
    np.testing.assert_allclose(scan.points_world, [[1.0, 4.5], [-9.0, 2.5]], atol=1e-6)
    np.testing.assert_array_equal(scan.hit_mask, [True, False])
    # The bag's own .db3 or .mcap file, given by path, reads as its folder.
    (data,) = [p for p in bag.iterdir() if p.suffix in (".db3", ".mcap")]
    (by_file,) = read_scans(data, topic="/scan", frame="odom", odometry="/odom")
    np.testing.assert_array_equal(by_file.points_world, scan.points_world)
    (bag / "metadata.yaml").unlink()
    with pytest.raises(FileReadError, match=r"a ROS 2 bag is the folder holding metadata\.yaml"):
        read_scans(data, topic="/scan")


def test_bag_mistakes_are_named(lidar_bag, tmp_path):
    with pytest.raises(InputError, match="intrinsics and depth_scale are for depth images"):
        read_scans(lidar_bag, frame="map", intrinsics=[1, 1, 0, 0])
    with pytest.raises(
        InputError,
        match=r"'/nothing' is not a PointCloud2, LaserScan or VelodyneScan topic: /points \(Poi",
    ):
        BagScans(lidar_bag, "/nothing", frame="map")
    with pytest.raises(InputError, match="give the fixed frame"):
        BagScans(lidar_bag, "/points")
    with pytest.raises(InputError, match="no transforms involve frame 'world'"):
        list(BagScans(lidar_bag, "/points", frame="world"))
    with pytest.raises(InputError, match="'/tf' is not a nav_msgs/msg/Odometry topic"):
        BagScans(lidar_bag, "/points", frame="map", odometry="/tf")
    (tmp_path / "junk.bag").write_bytes(b"#ROSBAG V2.0\n garbage")
    with pytest.raises(FileReadError, match=r"junk\.bag: not a readable ROS bag"):
        BagScans(tmp_path / "junk.bag", "/points", frame="map")


@pytest.mark.parametrize("compression", [None, *Writer1.CompressionFormat])
def test_a_bag_with_a_broken_index_is_read_from_its_chunks(tmp_path, cloud, compression):
    intact = write_bag(tmp_path / "intact.bag", Stores.ROS1_NOETIC, lidar_messages(cloud))
    broken = write_bag(
        tmp_path / "broken.bag", Stores.ROS1_NOETIC, lidar_messages(cloud), None, compression
    )
    break_index_counts(broken)
    want = list(BagScans(intact, "/points", frame="map"))
    got = list(BagScans(broken, "/points", frame="map"))
    assert len(got) == len(want) == 1
    np.testing.assert_array_equal(got[0].points_world, want[0].points_world)
    np.testing.assert_array_equal(got[0].origin, want[0].origin)
    # A bag whose chunks are cut short too: both reasons are named.
    broken.write_bytes(broken.read_bytes()[:5000])
    message = r"not a readable ROS bag \(.+; chunk by chunk, byte \d+: a record cut short\)"
    with pytest.raises(FileReadError, match=message):
        BagScans(broken, "/points", frame="map")


def test_frame_trees_chain_invert_and_interpolate():
    frames = FrameTree()
    turn = np.eye(4)
    turn[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    frames.add("map", "odom", 0, np.eye(4))
    frames.add("map", "odom", 10, turn)
    shift = np.eye(4)
    shift[:3, 3] = [1, 0, 0]
    frames.add_static("odom", "base", shift)
    np.testing.assert_allclose(frames.lookup("map", "base", 10), turn @ shift)
    np.testing.assert_allclose(frames.lookup("/map", "/base", 10), turn @ shift)  # ROS 1 names
    np.testing.assert_allclose(frames.lookup("base", "map", 10), np.linalg.inv(turn @ shift))
    np.testing.assert_allclose(
        frames.lookup("map", "base", 5), interpolate_pose(np.eye(4), turn, 0.5) @ shift
    )
    half = interpolate_pose(np.eye(4), turn, 0.5)
    np.testing.assert_allclose(
        half[:3, :3] @ [1, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0], atol=1e-12
    )
    assert frames.lookup("map", "base", 11) is None
    frames.add_static("elsewhere", "island", np.eye(4))
    with pytest.raises(InputError, match="no chain of transforms joins frame 'map' to 'island'"):
        frames.lookup("map", "island", 0)


def test_ehm_map_reads_a_bag(lidar_bag, tmp_path):
    from typer.testing import CliRunner

    import ehm
    from ehm.cli import app

    output = tmp_path / "lidar.ehm"
    args = ["map", str(lidar_bag), "--topic", "/points", "--frame", "map", "-o", str(output)]
    result = CliRunner().invoke(app, [*args, "--set", "min_cluster_size=1"])
    assert result.exit_code == 0, result.output
    assert ehm.load(output).n_scans_ == 1
    result = CliRunner().invoke(app, [*args[:2], "--frame", "map", "-o", str(tmp_path / "x.ehm")])
    assert result.exit_code == 0, result.output  # /points is the only scan topic
    result = CliRunner().invoke(app, ["map", str(lidar_bag), "-o", str(tmp_path / "y.ehm")])
    assert result.exit_code == 2 and "give the fixed frame" in result.stderr


def test_a_cloud_whose_layout_does_not_fit_is_named(tmp_path, cloud):
    def short_cloud(m):
        message = m.cloud(SECOND, "velodyne", cloud)
        message.data = message.data[:100]
        return message

    bag = write_bag(
        tmp_path / "short.bag",
        Stores.ROS1_NOETIC,
        [
            ("/tf_static", 0, lambda m: m.transform(0, "map", "velodyne", (0, 0, 0))),
            ("/points", SECOND, short_cloud),
        ],
    )
    with pytest.raises(FileReadError, match=r"message 0 on /points: PointCloud2 of 1 x 50 points"):
        list(BagScans(bag, "/points", frame="map"))


@pytest.mark.parametrize(
    ("store", "storage"),
    [(Stores.ROS1_NOETIC, None), (Stores.ROS2_HUMBLE, StoragePlugin.MCAP)],
)
def test_velodyne_packet_bags_decode_as_the_capture_does(tmp_path, store, storage):
    """A real HDL-32E rotation's packets (tests/io/data/hdl32e.pcap) bundled in one
    velodyne_msgs/VelodyneScan, the sensor 2 m above the map's origin: the same points as the
    capture, moved by the transform."""
    pytest.importorskip("velodyne_decoder")
    from pathlib import Path

    from ehm.io.pcap import udp_payloads

    capture = Path(__file__).parent / "data" / "hdl32e.pcap"
    packets = [
        (int(d.time * SECOND), d.payload) for d in udp_payloads(capture) if len(d.payload) == 1206
    ]
    stamp = packets[-1][0]
    messages = [
        ("/tf_static", stamp, lambda m: m.transform(stamp, "map", "velodyne", (0, 0, 2))),
        ("/velodyne_packets", stamp, lambda m: m.velodyne_scan(stamp, "velodyne", packets)),
    ]
    bag = write_bag(tmp_path / ("packets.bag" if storage is None else "packets"), store,
                    messages, storage)  # fmt: skip
    (scan,) = read_scans(bag, frame="map")
    with pytest.warns(UserWarning):
        rotations = read_scans(capture)
    expected = np.concatenate([r.points_world for r in rotations]) + np.array([0, 0, 2])
    assert len(scan) == len(expected) == 19_579
    key = np.lexsort(expected.T)
    np.testing.assert_allclose(scan.points_world[np.lexsort(scan.points_world.T)],
                               expected[key], atol=1e-5)  # fmt: skip
    np.testing.assert_allclose(scan.origin, [0, 0, 2])


def test_a_ros2_bag_without_type_definitions_or_transforms_maps_from_an_origin(tmp_path):
    """Bags of rosbag2's formats before 8 carry no type definitions (here a format 8 bag with
    them taken out): velodyne_msgs' are ehm's own. Without /tf, a sensor that stood still is
    placed by --origin."""
    pytest.importorskip("velodyne_decoder")
    import sqlite3
    from pathlib import Path

    from ehm.io.pcap import udp_payloads

    capture = Path(__file__).parent / "data" / "hdl32e.pcap"
    packets = [
        (int(d.time * SECOND), d.payload) for d in udp_payloads(capture) if len(d.payload) == 1206
    ]
    stamp = packets[-1][0]
    messages = [("/packets", stamp, lambda m: m.velodyne_scan(stamp, "velodyne", packets))]
    bag = write_bag(
        tmp_path / "old", Stores.ROS2_HUMBLE, messages, StoragePlugin.SQLITE3, version=8
    )
    with sqlite3.connect(next(bag.glob("*.db3"))) as database:
        database.execute("DELETE FROM message_definitions")
    with pytest.raises(
        InputError, match=r"or the origin of a sensor that stood still \(--origin\)"
    ):
        read_scans(bag)
    (scan,) = read_scans(bag, origin=(1.0, 0.0, 2.0))
    with pytest.warns(UserWarning):
        rotations = read_scans(capture)
    expected = np.concatenate([r.points_world for r in rotations]) + np.array([1.0, 0.0, 2.0])
    np.testing.assert_allclose(
        np.sort(scan.points_world, axis=0), np.sort(expected, axis=0), atol=1e-5
    )
    np.testing.assert_allclose(scan.origin, [1.0, 0.0, 2.0])
    with pytest.raises(InputError, match="--frame and --odometry would be ignored"):
        read_scans(bag, origin=(0, 0, 0), frame="map")


def test_raw_ouster_packets_in_bags_are_refused_naming_what_to_record(tmp_path):
    from rosbags.typesys import get_types_from_msg

    from ehm.eval.ros_bags import Messages

    def packet(m: Messages):
        name = "ouster_sensor_msgs/msg/PacketMsg"
        if name not in m.types:
            m.typestore.register(get_types_from_msg("uint8[] buf", name))
        return m.types[name](buf=np.zeros(16, dtype=np.uint8))

    bag = write_bag(
        tmp_path / "os.bag", Stores.ROS1_NOETIC, [("/os_node/lidar_packets", 0, packet)]
    )
    with pytest.raises(InputError, match=r"lidar_packets carries raw Ouster packets, .* as a pcap"):
        read_scans(bag, frame="map")


@pytest.mark.parametrize(
    ("store", "storage", "dtype"),
    [
        (Stores.ROS1_NOETIC, None, np.uint16),
        (Stores.ROS2_HUMBLE, StoragePlugin.SQLITE3, np.uint16),
        (Stores.ROS2_HUMBLE, StoragePlugin.MCAP, np.float32),
    ],
)
def test_depth_images_in_bags_take_their_camera_info(tmp_path, store, storage, dtype):
    """A 16UC1 (millimetres) or 32FC1 (metres) depth image of a wall 2 m ahead, its camera
    from the topic's camera_info, the optical frame placed 1 m above the map's origin."""
    from ehm.errors import AssumptionWarning
    from ehm.io.depth import DepthCamera

    depth = np.full((48, 64), 2000, dtype=np.uint16)
    depth[0, :] = 0  # no reading
    image = depth if dtype == np.uint16 else (depth / 1000.0).astype(np.float32)
    messages = [
        ("/tf_static", 0, lambda m: m.transform(0, "map", "camera_optical", (0, 0, 1))),
        ("/camera/depth/camera_info", SECOND,
         lambda m: m.camera_info(SECOND, "camera_optical", 50.0, 50.0, 32.0, 24.0, (64, 48))),
        ("/camera/depth/image_raw", SECOND,
         lambda m: m.depth_image(SECOND, "camera_optical", image)),
    ]  # fmt: skip
    bag = write_bag(tmp_path / ("d.bag" if storage is None else "d"), store, messages, storage)
    unit = "millimetres" if dtype == np.uint16 else "metres"
    with pytest.warns(AssumptionWarning, match=f"image_raw: .* depth read as {unit}"):
        (scan,) = read_scans(bag, frame="map")
    expected = DepthCamera(50.0, 50.0, 32.0, 24.0, 1000.0).points(depth) + np.array([0, 0, 1])
    np.testing.assert_allclose(scan.points_world, expected, atol=1e-6)
    assert np.allclose(scan.points_world[:, 2], 3.0)  # the wall, 2 m along the optical axis


def test_depth_image_bags_without_a_camera_name_the_option(tmp_path):
    image = np.full((4, 4), 1000, dtype=np.uint16)
    messages = [
        ("/tf_static", 0, lambda m: m.transform(0, "map", "cam", (0, 0, 0))),
        ("/depth", SECOND, lambda m: m.depth_image(SECOND, "cam", image)),
    ]
    bag = write_bag(tmp_path / "d.bag", Stores.ROS1_NOETIC, messages)
    with pytest.raises(InputError, match=r"no CameraInfo for /depth \(none\): give the camera"):
        read_scans(bag, frame="map")
    with pytest.warns(UserWarning):
        (scan,) = read_scans(bag, frame="map", intrinsics=[2, 2, 2, 2])
    assert len(scan) == 4 and np.allclose(scan.points_world[:, 2], 1.0)


def test_laser_readings_at_range_max_are_rays_without_return():
    from types import SimpleNamespace

    from ehm.io.bags import laser_scan_points

    message = SimpleNamespace(
        ranges=[1.0, 5.0, np.inf, 4.999, 0.01], angle_min=0.0, angle_increment=np.pi / 2,
        range_min=0.1, range_max=5.0,
    )  # fmt: skip
    points, hits = laser_scan_points(message)
    np.testing.assert_array_equal(hits, [True, False, False, True])
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), [1.0, 5.0, 5.0, 4.999])


def test_an_odometry_without_child_frame_places_the_scans_frame(tmp_path):
    """Stage's ground-truth odometry names no child frame: its poses are the laser's, said in
    a note."""
    bag = write_bag(
        tmp_path / "stage.bag",
        Stores.ROS1_NOETIC,
        [
            ("/truth", 0, lambda m: m.odometry(0, "odom", "", (1, 2, 0), QUARTER_TURN)),
            ("/scan", SECOND, lambda m: m.laser(SECOND, "base_laser_link", [2.0, 10.0, 3.0])),
            ("/truth", 2 * SECOND, lambda m: m.odometry(
                2 * SECOND, "odom", "", (1, 2, 0), QUARTER_TURN)),
        ],
    )  # fmt: skip
    with pytest.warns(UserWarning, match="names no child frame: its poses are taken as those of "
                                         "the scans' frame, 'base_laser_link'"):  # fmt: skip
        (scan,) = read_scans(bag, topic="/scan", frame="odom", odometry="/truth")
    # The laser at (1, 2) facing +y: 2 m ahead a hit, the beam at range_max no return, 3 m
    # toward -y a hit.
    np.testing.assert_allclose(scan.origin, [1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(scan.points_world, [[1.0, 4.0], [-9.0, 2.0], [1.0, -1.0]],
                               atol=1e-6)  # fmt: skip
    np.testing.assert_array_equal(scan.hit_mask, [True, False, True])
