"""The small recordings the guides use, simulated: a CARMEN 2D laser log of the floor plan
(`floor.log`), a ROS 1 bag of three LiDAR sweeps of the virtual room placed by /tf
(`room.bag`), TUM depth frames of the room (`tum_fr2/`) and a KITTI odometry sequence of the
same sweeps (`kitti/sequences/00`, `kitti/poses/00.txt`). `ehm demo --data DIR` writes them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError
from ehm.eval.datasets import floor_plan_2d
from ehm.eval.datasets.simulated import lidar_directions, simulate_scan, virtual_room_scene
from ehm.io.frames import matrix_to_quaternion

# Where the three LiDAR sweeps are taken, metres, world frame (1.2 m above the floor).
SWEEP_ORIGINS = np.array([[-1.0, 0.0, 1.2], [0.0, 0.0, 1.2], [1.0, 0.2, 1.2]])
# A CARMEN beam that saw nothing reads the laser's maximum range, metres.
CARMEN_NO_RETURN = 81.83
# TUM's depth images: 640 x 480 pixels, 5000 units a metre; returns beyond 8 m are dropped.
TUM_SIZE = (640, 480)
TUM_UNITS_PER_METRE = 5000
TUM_MAX_DEPTH = 8.0


def write_guide_files(folder: Path, report: Callable[[str], None] | None = None) -> list[Path]:
    """Write the guides' recordings into `folder` (made when missing), saying each with
    `report(line)`. The bag needs the `ros` extra (rosbags): without it, it is left out, said
    so, and the others written. Returns the paths written; refuses a folder that holds any of
    them already, before writing."""
    names = ("floor.log", "tum_fr2", "kitti", "room.bag")
    taken = [name for name in names if (folder / name).exists()]
    if taken:
        raise InputError(f"{folder} already holds {', '.join(taken)}: give a new or empty folder")
    folder.mkdir(parents=True, exist_ok=True)
    say = report or (lambda line: None)
    scene, rng = virtual_room_scene(), np.random.default_rng(0)
    directions = lidar_directions(32, 512, 30.0)
    sweeps = [simulate_scan(scene, o, directions, 20.0, 0.01, rng) for o in SWEEP_ORIGINS]
    writers = [
        lambda path: write_carmen_log(floor_plan_2d(seed=0).scans, path),
        lambda path: write_tum_sequence(path, scene, SWEEP_ORIGINS),
        lambda path: write_kitti_sequence(path, sweeps),
        lambda path: write_room_bag(path, sweeps),
    ]
    written = []
    for name, write in zip(names, writers, strict=True):
        try:
            write(folder / name)
        except ImportError:  # only the bag has a missing extra to fall over
            say(f"left out {folder / name}: ROS bags need pip install 'ehm[ros]'")
            continue
        say(f"wrote {folder / name}")
        written.append(folder / name)
    return written


def write_carmen_log(scans: list[Scan], path: Path) -> None:
    """2D scans as a CARMEN log (FLASER lines) of 180 beams each, one a degree from -90 to
    +89 degrees of the sensor's heading (+x), no return read as CARMEN_NO_RETURN."""
    lines = []
    for scan in scans:
        offsets = scan.points_world[scan.hit_mask] - scan.origin
        ranges = np.linalg.norm(offsets, axis=1)
        angles = np.arctan2(offsets[:, 1], offsets[:, 0])
        beams = np.full(180, CARMEN_NO_RETURN)
        index = np.round(np.rad2deg(angles) + 90).astype(int)
        inside = (index >= 0) & (index < 180)
        beams[index[inside]] = ranges[inside]
        values = " ".join(f"{r:.4f}" for r in beams)
        lines.append(f"FLASER 180 {values} {scan.origin[0]} {scan.origin[1]} 0.0 0 0 0 0 h 0")
    path.write_text("\n".join(lines) + "\n")


def write_room_bag(path: Path, sweeps: list[Scan]) -> None:
    """A ROS 1 bag of the sweeps as PointCloud2 on /velodyne_points in the frame `velodyne`,
    placed in `map` by /tf (and /tf_static), one a second."""
    from rosbags.typesys import Stores

    from ehm.eval.ros_bags import SECOND, write_bag

    messages = [("/tf_static", 0, lambda m: m.transform(0, "base_link", "velodyne", (0, 0, 0)))]
    for i, sweep in enumerate(sweeps):
        stamp, origin = (i + 1) * SECOND, tuple(sweep.origin)
        points = sweep.points_world[sweep.hit_mask] - sweep.origin
        messages += [
            ("/tf", stamp, lambda m, s=stamp, o=origin: m.transform(s, "map", "base_link", o)),
            ("/velodyne_points", stamp, lambda m, s=stamp, p=points: m.cloud(s, "velodyne", p)),
        ]
    write_bag(path, Stores.ROS1_NOETIC, messages)


def write_tum_sequence(folder: Path, scene, origins: np.ndarray) -> None:
    """640 x 480 depth frames of `scene` from `origins` ((n, 3) metres) looking along +x (the
    camera's z), in TUM's layout (depth/*.png and the folder's poses.txt), through Freiburg 2's
    intrinsics (the folder's name names them). Only the pixels the reader takes (every
    PIXEL_STRIDE-th row and column) are rendered; the rest read 0, no depth."""
    from PIL import Image

    from ehm.io.depth import PIXEL_STRIDE
    from ehm.io.tum import FREIBURG_CAMERAS

    fx, fy, cx, cy = FREIBURG_CAMERAS[2].intrinsics
    width, height = TUM_SIZE
    (folder / "depth").mkdir(parents=True)
    v, u = np.mgrid[0:height:PIXEL_STRIDE, 0:width:PIXEL_STRIDE]
    rays_camera = np.column_stack([(u.ravel() - cx) / fx, (v.ravel() - cy) / fy, np.ones(u.size)])
    # Camera: x right, y down, z forward -> world: x forward, y left, z up.
    R_world_camera = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    directions = rays_camera @ R_world_camera.T
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    w, x, y, z = matrix_to_quaternion(R_world_camera)
    lines = []
    for i, origin in enumerate(origins):
        ranges = scene.raycast(origin, directions)
        depth = ranges * (directions @ R_world_camera[:, 2])
        units = np.where(ranges < TUM_MAX_DEPTH, np.round(depth * TUM_UNITS_PER_METRE), 0)
        image = np.zeros((height, width), dtype=np.uint16)
        image[::PIXEL_STRIDE, ::PIXEL_STRIDE] = units.reshape(v.shape)
        Image.fromarray(image).save(folder / "depth" / f"{i}.png")
        position = " ".join(map(str, origin))
        lines.append(f"depth/{i}.png {position} {x} {y} {z} {w}")  # TUM's x y z w order
    (folder / "poses.txt").write_text("\n".join(lines) + "\n")


def write_kitti_sequence(folder: Path, sweeps: list[Scan]) -> None:
    """The sweeps in KITTI's odometry layout, sequence 00, with poses of the Velodyne itself
    (calib.txt's Tr the identity) and a frame every 0.1 s."""
    sequence = folder / "sequences" / "00"
    (sequence / "velodyne").mkdir(parents=True)
    (folder / "poses").mkdir()
    poses = []
    for i, sweep in enumerate(sweeps):
        points = sweep.points_world[sweep.hit_mask] - sweep.origin
        raw = np.column_stack([points, np.ones(len(points))]).astype("<f4")
        raw.tofile(sequence / "velodyne" / f"{i:06d}.bin")
        pose = np.hstack([np.eye(3), sweep.origin[:, None]])
        poses.append(" ".join(f"{x:g}" for x in pose.ravel()))
    (sequence / "calib.txt").write_text("Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n")
    (sequence / "times.txt").write_text("".join(f"{0.1 * i:f}\n" for i in range(len(sweeps))))
    (folder / "poses" / "00.txt").write_text("\n".join(poses) + "\n")
