"""Read any supported input into a list of ehm.Scan, choosing the reader by file extension.

scans = read_scans("scan.dat.bz2", origin=[0.035, 0, 0.513])
scans = read_scans(["a.pcd", "b.pcd"], poses="poses.txt")  # one T_world_sensor per file
scans = read_scans(sorted(glob("sequences/00/velodyne/*.bin")), poses="poses/00.txt")
scans = read_scans("tum_sequence/")                 # folder with poses.txt and depth/
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from itertools import islice
from os import PathLike
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ehm.core.sensor.geometry import transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError, assumed
from ehm.io.bags import BagScans, is_bag
from ehm.io.carmen import read_carmen
from ehm.io.depth import DepthCamera, check_depth_options, depth_scan
from ehm.io.files import COMPRESSED_SUFFIXES, uncompressed_suffix
from ehm.io.kitti import kitti_files, kitti_frames, read_kitti_scan, sequence_poses
from ehm.io.las import read_las
from ehm.io.octomap_graph import read_octomap_graph
from ehm.io.ouster import OusterCapture, metadata_path
from ehm.io.pcap import udp_payloads
from ehm.io.pcd import read_pcd
from ehm.io.ply import read_ply
from ehm.io.poses import read_poses
from ehm.io.redwood import is_redwood, redwood_frames
from ehm.io.seven_scenes import is_seven_scenes, seven_scenes_frames
from ehm.io.tum import is_tum, tum_frames
from ehm.io.velodyne import VELODYNE_PACKET, VelodyneCapture
from ehm.io.xyz import read_xyz

FORMATS = (
    "xyz", "ply", "pcd", "las", "kitti", "graph", "tum", "7scenes", "redwood", "carmen", "bag",
    "ouster", "velodyne",
)  # fmt: skip
# Folders of depth images, each with its camera and poses: the reader of each layout, and
# what tells a folder of it.
DEPTH_FORMATS = {"tum": tum_frames, "7scenes": seven_scenes_frames, "redwood": redwood_frames}
_IS_DEPTH_LAYOUT = {"tum": is_tum, "7scenes": is_seven_scenes, "redwood": is_redwood}
# LiDAR packet captures (.pcap), one scan per frame, and their readers.
CAPTURES = {"ouster": OusterCapture, "velodyne": VelodyneCapture}
# Formats whose files hold each scan's sensor pose: they take neither an origin nor poses.
POSED_FORMATS = ("graph", "carmen", *DEPTH_FORMATS)
# A point cloud none of whose points lies within this of where its sensor is taken to stand,
# metres, is refused: its rays would be that long (georeferenced coordinates without --origin).
FAR_FROM_SENSOR = 10_000.0
_DEPTH_LAYOUTS = (
    "tum: depth.txt and groundtruth.txt, or poses.txt; 7scenes: frame-*.depth.png and "
    "frame-*.pose.txt; redwood: depth/ and a .log trajectory"
)
_EXTENSIONS = {
    ".xyz": "xyz", ".txt": "xyz", ".dat": "xyz", ".ply": "ply", ".pcd": "pcd",
    ".las": "las", ".laz": "las", ".bin": "kitti", ".graph": "graph", ".log": "carmen",
    ".clf": "carmen", ".bag": "bag",
}  # fmt: skip


def guess_format(path: str | PathLike[str]) -> str:
    """The reader for a path: a folder holding metadata.yaml is a ROS 2 bag, one holding
    velodyne/ a KITTI sequence, others depth frames in their layout (ehm.io.tum,
    ehm.io.seven_scenes, ehm.io.redwood); a file by its extension (the one
    before .gz, .bz2 or .xz for compressed files: x.log.gz is a CARMEN log, scan.bz2 points)."""
    path = Path(path)
    if is_bag(path):
        return "bag"
    if path.is_dir() and (path / "velodyne").is_dir():
        return "kitti"
    if path.is_dir():
        for fmt, is_layout in _IS_DEPTH_LAYOUT.items():
            if is_layout(path):
                return fmt
        raise FileReadError(
            path,
            "a folder of scans is a KITTI sequence (velodyne/), a ROS 2 bag (metadata.yaml) "
            f"or depth frames: {_DEPTH_LAYOUTS}",
        )
    suffix = uncompressed_suffix(path)
    if suffix == ".pcap" and path.suffix.lower() == ".pcap":
        return _capture_format(path)
    if path.suffix.lower() in COMPRESSED_SUFFIXES and suffix in ("", ".bag", ".pcap"):
        if suffix in (".bag", ".pcap"):
            kind = "bag" if suffix == ".bag" else "packet capture"
            raise FileReadError(path, f"a compressed {kind} is not read; decompress it first")
        return "xyz"  # a compressed point file named without its own extension
    fmt = _EXTENSIONS.get(suffix)
    if fmt is None:
        raise FileReadError(
            path, f"unknown extension {suffix!r}; give a format, one of {', '.join(FORMATS)}"
        )
    return fmt


def _capture_format(path: Path) -> str:
    """The sensor of a .pcap: Velodyne where its first datagrams are Velodyne data packets,
    else Ouster where its metadata JSON is found (or the file is missing, which ScanFiles
    names); FileReadError naming both otherwise."""
    if not path.is_file():
        return "ouster"
    if VELODYNE_PACKET in {len(datagram.payload) for datagram in islice(udp_payloads(path), 20)}:
        return "velodyne"
    try:
        metadata_path(path)
    except FileReadError:
        raise FileReadError(
            path,
            "is a packet capture of neither an Ouster LiDAR, whose metadata JSON would lie "
            f"beside it ({path.with_suffix('.json').name}), nor a Velodyne (1206-byte data "
            "packets)",
        ) from None
    return "ouster"


def read_scans(
    paths: str | PathLike[str] | Sequence[str | PathLike[str]], **options: Any
) -> list[Scan]:
    """Scans from one or more files of one format, in world frame, all read now (`options`:
    those of ScanFiles; scan_stream reads them one at a time)."""
    return list(ScanFiles(paths, **options))


def scan_stream(
    paths: str | PathLike[str] | Sequence[str | PathLike[str]], **options: Any
) -> Iterator[Scan]:
    """Scans from one or more files of one format, in world frame, each read when it is asked
    for, so mapping starts with the first and memory holds one at a time (`options`: those of
    ScanFiles, which checks everything it can before any scan is read)."""
    return iter(ScanFiles(paths, **options))


class _FileScan(NamedTuple):
    """A scan that is one file: its path, the (4, 4) pose placing its points in world frame
    (None: they are), its sensor origin in that file's frame (None: the format's own), its
    time (seconds; None: unknown) and, for a depth image, the camera that took it."""

    path: Path
    T_world_file: np.ndarray | None
    sensor: np.ndarray | None = None
    time: float | None = None
    camera: DepthCamera | None = None


class ScanFiles:
    """The scans of one or more files of one format, in world frame, checked but not read:
    iterate to read them in order, one at a time, or `read` some by index. Small and
    picklable, so processes of a cluster can each read the scans they need.

    Everything that can be checked before reading scans is checked when it is made (files
    exist, options fit the format, poses, calibration and cameras read); a scan that cannot
    be read raises when it is reached. What a reader has to assume (a depth camera, units)
    it says in an ehm.AssumptionWarning, when it is made.

    format: one of FORMATS (None: guessed from the names, guess_format).
    origin: sensor position (3,), metres, world frame, for point clouds (xyz, ply, pcd, las),
        which do not record it; PCD falls back to its VIEWPOINT, the others to (0, 0, 0).
        For KITTI .bin scans without poses, LiDAR captures (Ouster, Velodyne) and bags
        without transforms, where the sensor's own frame is placed (a sensor that stood still).
    poses: a poses file. For KITTI .bin scans the sequence's poses (line i places frame i);
        for LiDAR captures one T_world_sensor per frame, over all captures in order;
        for point clouds one T_world_sensor per file, in the order given (KITTI or TUM layout,
        ehm.io.poses), each file's points in its sensor's frame (PCD: the VIEWPOINT's frame).
    calib: KITTI's calib.txt (default: the sequence's), or "identity" for poses that already
        place the LiDAR (ehm.io.kitti).
    intrinsics, depth_scale: for folders of depth images (tum, 7scenes, redwood), the camera
        (fx, fy, cx, cy, pixels) and the raw depth units a metre, in place of the layout's own.
    fov: for CARMEN logs, the field of view of FLASER lines, radians (None: pi).
    every: take every `every`-th scan (1: all); limit: stop after this many (None: no limit).
    topic, frame, odometry: for ROS bags, the scans' topic (None: the only scan topic), the
        fixed frame they are placed in by /tf, and an odometry topic to place them by instead
        (see ehm.io.bags); `poses` gives one pose per message instead.

    Files of one scan each (point clouds, KITTI scans, depth images) are read by index
    directly; logs, graphs and bags hold many scans and are read from their start.
    Raises FileReadError naming the file for anything it cannot read, InputError for options
    that do not fit the format.
    """

    def __init__(
        self,
        paths: str | PathLike[str] | Sequence[str | PathLike[str]],
        format: str | None = None,
        *,
        origin: Sequence[float] | None = None,
        poses: str | PathLike[str] | None = None,
        calib: str | PathLike[str] | None = None,
        intrinsics: Sequence[float] | None = None,
        depth_scale: float | None = None,
        fov: float | None = None,
        every: int = 1,
        limit: int | None = None,
        topic: str | None = None,
        frame: str | None = None,
        odometry: str | None = None,
    ) -> None:
        items = [paths] if isinstance(paths, str | PathLike) else list(paths)
        if not items:
            raise InputError("no input files given")
        fmt = format or _one_format(items)
        if fmt not in FORMATS:
            raise InputError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
        _check_options(fmt, origin, poses, calib)
        unused = {
            "topic, frame and odometry are for ROS bags": fmt != "bag"
            and (topic, frame, odometry) != (None, None, None),
            "intrinsics and depth_scale are for depth frames": fmt not in (*DEPTH_FORMATS, "bag")
            and (intrinsics, depth_scale) != (None, None),
            "fov is for CARMEN logs": fmt != "carmen" and fov is not None,
        }
        for message, wrong in unused.items():
            if wrong:
                raise InputError(f"{message}, not {fmt} files")
        check_depth_options(intrinsics, depth_scale)
        if not (isinstance(every, int) and every >= 1):
            raise InputError(f"every must be an integer >= 1, got {every!r}")
        if limit is not None and not (isinstance(limit, int) and limit >= 0):
            raise InputError(f"limit must be an integer >= 0, got {limit!r}")
        for item in items:
            if not Path(item).exists():
                raise FileReadError(item, "no such file or folder")
            _check_fits(Path(item), fmt)
        self.format = fmt
        self._every, self._limit, self._fov = every, limit, fov
        self._files: list[_FileScan] | None = None  # None: files of many scans each
        self._streams: list = []
        self._logs: list[list[Scan]] = []  # the logs' scans, once __length_hint__ read them
        if fmt == "kitti":
            poses_path = sequence_poses(items, poses)
            if origin is not None and poses_path is not None:
                raise InputError(
                    f"the sequence's poses are at {poses_path}: an origin would put every scan "
                    "at one place; leave out origin"
                )
            frames = kitti_frames(kitti_files(items), poses_path, calib, origin)
            files = [_FileScan(path, T, None, time) for path, T, time in frames]
        elif fmt in DEPTH_FORMATS:
            files = []
            for item in items:
                camera, frames = DEPTH_FORMATS[fmt](item, intrinsics, depth_scale)
                files += [
                    _FileScan(f.image, f.T_world_camera, None, f.time, camera) for f in frames
                ]
        elif fmt == "bag":
            self._streams = [
                BagScans(item, topic, frame, odometry, poses, intrinsics, depth_scale, origin)
                for item in items
            ]
            return
        elif fmt in POSED_FORMATS:
            self._streams = items
            return
        elif fmt in CAPTURES:
            self._streams = [CAPTURES[fmt](item) for item in items]
            self._T_world_sensors = _capture_poses(self._streams, origin, poses)
            return
        else:
            sensor = None if origin is None else np.asarray(origin, dtype=np.float64)
            T_world_files = _file_poses(poses, len(items))
            files = [
                _FileScan(Path(p), T, sensor) for p, T in zip(items, T_world_files, strict=True)
            ]
        self._files = files[::every][:limit]

    def count(self) -> int | None:
        """How many scans there are, when that is known without reading them (files of one
        scan each), else None."""
        return None if self._files is None else len(self._files)

    def __length_hint__(self) -> int:
        """How many scans are expected, for progress bars (operator.length_hint): files of
        one scan each counted, logs read (once: iterating then reuses them), bags' messages on
        the topic counted (at most: messages without a pose are skipped); NotImplemented for
        LiDAR captures, whose frames are known only by decoding them, and bags whose index is
        broken."""
        if self._files is not None:
            return len(self._files)
        if self.format == "bag":
            counts = [bag.messages for bag in self._streams]
            if None in counts:
                return NotImplemented
            found = sum(counts)
        elif self.format in POSED_FORMATS:
            if not self._logs:
                self._logs = [
                    list(_posed_scans([item], self.format, self._fov)) for item in self._streams
                ]
            found = sum(map(len, self._logs))
        else:
            return NotImplemented
        chosen = -(-found // self._every)
        return chosen if self._limit is None else min(chosen, self._limit)

    def __iter__(self) -> Iterator[Scan]:
        if self._files is not None:
            return (self._read_file(i) for i in range(len(self._files)))
        if self.format == "bag":
            scans = (scan for bag in self._streams for scan in bag)
        elif self.format in CAPTURES:
            scans = _capture_scans(self._streams, self._T_world_sensors)
        elif self._logs:
            scans = (scan for log in self._logs for scan in log)
        else:
            scans = _posed_scans(self._streams, self.format, self._fov)
        stop = None if self._limit is None else self._limit * self._every
        return islice(scans, 0, stop, self._every)

    def read(self, indices: Iterable[int] | None = None) -> Iterator[tuple[int, Scan]]:
        """(index, scan) for each of `indices` (0-based, after every and limit; None: every
        scan), in ascending order: read directly from files of one scan each, else by reading
        the files from the start."""
        if indices is None:
            return enumerate(self)
        wanted = sorted(set(indices))
        if self._files is not None:
            return ((i, self._read_file(i)) for i in wanted)
        chosen = set(wanted)
        return ((i, scan) for i, scan in enumerate(self) if i in chosen)

    def _read_file(self, index: int) -> Scan:
        scan = self._files[index]
        if self.format == "kitti":
            return read_kitti_scan(scan.path, scan.T_world_file, scan.time)
        if scan.camera is not None:
            return depth_scan(scan.path, scan.T_world_file, scan.camera, scan.time)
        return _point_cloud_scan(scan.path, self.format, scan.sensor, scan.T_world_file)


def _posed_scans(items: list[str | PathLike[str]], fmt: str, fov: float | None) -> Iterator[Scan]:
    """The scans of graph or CARMEN files, one file after the other."""
    for item in items:
        found = 0
        scans = read_octomap_graph(item) if fmt == "graph" else read_carmen(item, fov)
        for scan in scans:
            found += 1
            yield scan
        if not found:
            raise FileReadError(item, "no scans")


def _capture_poses(
    captures: list[Iterable[Scan]],
    origin: Sequence[float] | None,
    poses: str | PathLike[str] | None,
) -> list[np.ndarray] | None:
    """T_world_sensor of each frame of LiDAR captures (CAPTURES): one per frame
    from `poses` (the frames are counted first), or one placing every frame at `origin`;
    None: the sensor's frame."""
    if origin is not None:
        T_world_sensor = np.eye(4)
        T_world_sensor[:3, 3] = origin
        return [T_world_sensor]
    if poses is None:
        return None
    T_world_sensors = read_poses(poses)
    frames = sum(1 for capture in captures for _ in capture)
    if len(T_world_sensors) != frames:
        raise FileReadError(poses, f"{len(T_world_sensors)} poses for {frames} frames")
    return T_world_sensors


def _capture_scans(
    captures: list[Iterable[Scan]],
    T_world_sensors: list[np.ndarray] | None,
) -> Iterator[Scan]:
    """The frames of LiDAR captures (CAPTURES), each placed by its pose (one pose:
    all frames; None: left in the sensor's frame, said once a second frame shows the sensor
    may have moved)."""
    for index, scan in enumerate(scan for capture in captures for scan in capture):
        if index == 1 and (T_world_sensors is None or len(T_world_sensors) == 1):
            assumed(
                "the capture's frames are all mapped from one sensor pose (no poses given): "
                "right for a sensor standing still; give poses, one per frame, if it moved"
            )
        if T_world_sensors is None:
            yield scan
        else:
            yield _placed(scan, T_world_sensors[min(index, len(T_world_sensors) - 1)])


def _placed(scan: Scan, T_world_sensor: np.ndarray) -> Scan:
    """`scan`, given in its sensor's frame, moved into world frame by its (4, 4) pose."""
    return Scan(
        transform_points(T_world_sensor, scan.points_world),
        transform_points(T_world_sensor, scan.origin[None])[0],
        scan.hit_mask,
        scan.time,
    )


def _check_fits(path: Path, fmt: str) -> None:
    """FileReadError for an input that cannot be of `fmt` whatever it holds: a file given as a
    folder format, a folder as a file format, a bag that is no bag."""
    if fmt == "bag" and not is_bag(path):
        raise FileReadError(
            path, "is not a ROS bag (a .bag file, or a ROS 2 bag folder holding metadata.yaml)"
        )
    if fmt in _IS_DEPTH_LAYOUT and not (path.is_dir() and _IS_DEPTH_LAYOUT[fmt](path)):
        raise FileReadError(path, f"is not a folder of {fmt} depth frames ({_DEPTH_LAYOUTS})")
    if fmt not in (*DEPTH_FORMATS, "bag", "kitti") and path.is_dir():
        raise FileReadError(path, f"is a folder; {fmt} scans are files")


def _one_format(items: list[str | PathLike[str]]) -> str:
    """The format all `items` share by their names; InputError when they differ."""
    formats = {Path(item).name: guess_format(item) for item in items}
    first = formats[Path(items[0]).name]
    other = next((name for name, fmt in formats.items() if fmt != first), None)
    if other is not None:
        raise InputError(
            f"{other} is {formats[other]}, {Path(items[0]).name} is {first}: give files of one "
            "format"
        )
    return first


def _check_options(
    fmt: str,
    origin: Sequence[float] | None,
    poses: str | PathLike[str] | None,
    calib: str | PathLike[str] | None,
) -> None:
    """InputError for an option the format would ignore or that contradicts another."""
    given = [name for name, value in (("origin", origin), ("poses", poses)) if value is not None]
    if fmt in POSED_FORMATS and given:
        raise InputError(
            f"{fmt} files hold each scan's sensor pose: {' and '.join(given)} would be ignored"
        )
    if origin is not None and poses is not None:
        raise InputError("give an origin or poses, not both: each pose places its sensor")
    if calib is not None and fmt != "kitti":
        raise InputError(f"calib is for KITTI scans, not {fmt} files")
    if calib is not None and origin is not None:
        raise InputError("calib places the LiDAR in a sequence's poses, not at an origin")
    if origin is not None:
        values = np.asarray(origin, dtype=np.float64)
        if values.shape != (3,) or not np.all(np.isfinite(values)):
            raise InputError(f"origin must be 3 finite numbers x, y, z, got {list(origin)}")


def _file_poses(poses: str | PathLike[str] | None, n_files: int) -> list[np.ndarray | None]:
    """T_world_file of each point-cloud file: from the poses file, or None for each."""
    if poses is None:
        return [None] * n_files
    T_world_files = read_poses(poses)
    if len(T_world_files) != n_files:
        raise FileReadError(poses, f"{len(T_world_files)} poses for {n_files} files")
    return T_world_files


def _point_cloud_scan(
    path: Path, fmt: str, origin: np.ndarray | None, T_world_file: np.ndarray | None
) -> Scan:
    if fmt == "pcd":
        points, viewpoint = read_pcd(path)
    else:
        points = {"xyz": read_xyz, "ply": read_ply, "las": read_las}[fmt](path)
        viewpoint = np.zeros(3)
    sensor = viewpoint if origin is None else origin
    if origin is None and T_world_file is None and len(points):
        nearest = float(np.min(np.linalg.norm(points - sensor, axis=1)))
        if nearest > FAR_FROM_SENSOR:
            raise FileReadError(
                path,
                f"its points lie {nearest / 1000:.0f} km or more from {sensor.tolist()}, where "
                "its sensor is taken to stand as the file does not say: give the sensor's "
                "position (--origin X,Y,Z; for an airborne tile, a point above it) or --poses",
            )
    try:
        scan = Scan(points, sensor)
    except InputError as error:
        raise FileReadError(path, str(error)) from None
    return scan if T_world_file is None else _placed(scan, T_world_file)
