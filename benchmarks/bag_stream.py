"""Mapping a 1,000-scan ROS 2 bag: memory follows the map, not the bag.

    python benchmarks/bag_stream.py [--scans 1000]

Writes a ROS 2 bag (MCAP) of `scans` PointCloud2 messages (a 8-ring LiDAR of 256 azimuths
driven `laps` times round the warehouse, `ehm.eval.datasets.simulated.warehouse_drive`: the
bag grows with every lap, the map mostly with the first) with /tf placing each; then runs
`ehm map BAG --frame map --limit N` in a fresh process for growing N and reports its peak
resident memory against the bag's size, the decoded scans' size (what reading them all first
would hold) and the map's memory.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from results_file import run_recorded

import ehm
from ehm.eval.datasets.simulated import warehouse_drive

SECOND = 1_000_000_000


def write_bag(path: Path, n_scans: int, laps: int) -> int:
    """Write the bag; returns the bytes of its decoded points (float64 x y z and hit flags)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    t = typestore.types
    fields = [
        t["sensor_msgs/msg/PointField"](name=c, offset=4 * i, datatype=7, count=1)
        for i, c in enumerate("xyz")
    ]
    decoded = 0
    scans = warehouse_drive(n_scans=n_scans, loops=laps, rings=8, azimuths=256).scans
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        points_topic = writer.add_connection(
            "/points", "sensor_msgs/msg/PointCloud2", typestore=typestore
        )
        tf_topic = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=typestore)
        for index, scan in enumerate(scans):
            stamp = (index + 1) * SECOND // 10
            time_msg = t["builtin_interfaces/msg/Time"](sec=stamp // SECOND, nanosec=stamp % SECOND)
            transform = t["geometry_msgs/msg/TransformStamped"](
                header=t["std_msgs/msg/Header"](stamp=time_msg, frame_id="map"),
                child_frame_id="velodyne",
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](*scan.origin),
                    rotation=t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                ),
            )
            message = t["tf2_msgs/msg/TFMessage"](transforms=[transform])
            writer.write(tf_topic, stamp, typestore.serialize_cdr(message, message.__msgtype__))
            hits = (scan.points_world - scan.origin)[scan.hit_mask].astype("<f4")
            cloud = t["sensor_msgs/msg/PointCloud2"](
                header=t["std_msgs/msg/Header"](stamp=time_msg, frame_id="velodyne"),
                height=1, width=len(hits), fields=fields, is_bigendian=False, point_step=12,
                row_step=12 * len(hits), data=np.frombuffer(hits.tobytes(), np.uint8),
                is_dense=True,
            )  # fmt: skip
            writer.write(points_topic, stamp, typestore.serialize_cdr(cloud, cloud.__msgtype__))
            decoded += len(hits) * (3 * 8 + 1)
    return decoded


# Runs a command and prints the peak resident kilobytes of it alone.
PEAK_OF = (
    "import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True); "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def peak_of_map(bag: Path, limit: int, output: Path) -> tuple[float, float]:
    """Peak resident MB of `ehm map` on the first `limit` scans in a fresh process, and its
    wall-clock seconds."""
    ehm_command = Path(sys.executable).with_name("ehm")
    command = [str(ehm_command), "map", str(bag), "--frame", "map", "--limit", str(limit)]
    command += ["-o", str(output), "--force", "--quiet"]
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-c", PEAK_OF, *command], check=True, capture_output=True, text=True
    )
    return int(run.stdout.split()[-1]) / 1024, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=1000)
    parser.add_argument("--laps", type=int, default=10)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "drive"
        decoded = write_bag(bag, args.scans, args.laps)
        bag_bytes = sum(f.stat().st_size for f in bag.iterdir())
        rows = []
        for limit in (args.scans // 4, args.scans // 2, args.scans):
            peak, seconds = peak_of_map(bag, limit, Path(folder) / "map.ehm")
            map_mb = ehm.load(Path(folder) / "map.ehm").memory_bytes() / 1e6
            share = limit / args.scans
            rows.append(
                [
                    f"{limit:,}",
                    f"{share * bag_bytes / 1e6:.0f}",
                    f"{share * decoded / 1e6:.0f}",
                    f"{map_mb:.1f}",
                    f"{peak:.0f}",
                    f"{seconds:.0f}",
                ]
            )
    detail = f"{args.scans:,} PointCloud2 scans on {args.laps} laps, MCAP"
    print(heading("Streaming a ROS 2 bag", detail))
    columns = ["scans", "bag MB", "decoded scans MB", "map MB", "peak RSS MB", "seconds"]
    print(markdown_table(columns, rows))


if __name__ == "__main__":
    run_recorded(main, __file__)
