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

import numpy as np

from ehm.core.sensor.geometry import transform_points
from ehm.core.sensor.scan import Scan
from ehm.errors import FileReadError, InputError
from ehm.io.bags import BagScans, is_bag
from ehm.io.carmen import read_carmen
from ehm.io.files import COMPRESSED_SUFFIXES, uncompressed_suffix
from ehm.io.kitti import kitti_files, kitti_frames, read_kitti_scan
from ehm.io.las import read_las
from ehm.io.octomap_graph import read_octomap_graph
from ehm.io.pcd import read_pcd
from ehm.io.ply import read_ply
from ehm.io.poses import read_poses
from ehm.io.tum import tum_scans
from ehm.io.xyz import read_xyz

FORMATS = ("xyz", "ply", "pcd", "las", "kitti", "graph", "tum", "carmen", "bag")
# Formats whose files hold each scan's sensor pose: they take neither an origin nor poses.
POSED_FORMATS = ("graph", "tum", "carmen")
_EXTENSIONS = {
    ".xyz": "xyz", ".txt": "xyz", ".dat": "xyz", ".ply": "ply", ".pcd": "pcd",
    ".las": "las", ".laz": "las", ".bin": "kitti", ".graph": "graph", ".log": "carmen",
    ".clf": "carmen", ".bag": "bag",
}  # fmt: skip


def guess_format(path: str | PathLike[str]) -> str:
    """The reader for a path: a folder holding poses.txt is TUM, one holding metadata.yaml a
    ROS 2 bag, one holding velodyne/ a KITTI sequence, otherwise by extension (the one
    before .gz, .bz2 or .xz for compressed files: x.log.gz is a CARMEN log, scan.bz2 points)."""
    path = Path(path)
    if is_bag(path):
        return "bag"
    if path.is_dir() and (path / "velodyne").is_dir():
        return "kitti"
    if path.is_dir():
        if (path / "poses.txt").exists():
            return "tum"
        raise FileReadError(path, "a folder is read as TUM depth frames and needs poses.txt")
    suffix = uncompressed_suffix(path)
    if path.suffix.lower() in COMPRESSED_SUFFIXES and suffix in ("", ".bag"):
        if suffix == ".bag":
            raise FileReadError(path, "a compressed bag is not read; decompress it first")
        return "xyz"  # a compressed point file named without its own extension
    fmt = _EXTENSIONS.get(suffix)
    if fmt is None:
        raise FileReadError(
            path, f"unknown extension {suffix!r}; give a format, one of {', '.join(FORMATS)}"
        )
    return fmt


def read_scans(
    paths: str | PathLike[str] | Sequence[str | PathLike[str]],
    format: str | None = None,
    origin: Sequence[float] | None = None,
    poses: str | PathLike[str] | None = None,
    calib: str | PathLike[str] | None = None,
    every: int = 1,
    limit: int | None = None,
    topic: str | None = None,
    frame: str | None = None,
    odometry: str | None = None,
) -> list[Scan]:
    """Scans from one or more files of one format, in world frame, all read now (see
    ScanFiles for the arguments, scan_stream for reading them one at a time)."""
    return list(
        scan_stream(paths, format, origin, poses, calib, every, limit, topic, frame, odometry)
    )


def scan_stream(
    paths: str | PathLike[str] | Sequence[str | PathLike[str]],
    format: str | None = None,
    origin: Sequence[float] | None = None,
    poses: str | PathLike[str] | None = None,
    calib: str | PathLike[str] | None = None,
    every: int = 1,
    limit: int | None = None,
    topic: str | None = None,
    frame: str | None = None,
    odometry: str | None = None,
) -> Iterator[Scan]:
    """Scans from one or more files of one format, in world frame, each read when it is asked
    for, so mapping starts with the first and memory holds one at a time (see ScanFiles for
    the arguments and the checks made before any scan is read)."""
    return iter(
        ScanFiles(paths, format, origin, poses, calib, every, limit, topic, frame, odometry)
    )


class ScanFiles:
    """The scans of one or more files of one format, in world frame, checked but not read:
    iterate to read them in order, one at a time, or `read` some by index. Small and
    picklable, so processes of a cluster can each read the scans they need.

    Everything that can be checked before reading scans is checked when it is made (files
    exist, options fit the format, poses and calibration files read); a scan that cannot be
    read raises when it is reached.

    origin: sensor position (3,), metres, world frame, for point clouds (xyz, ply, pcd, las),
        which do not record it; PCD falls back to its VIEWPOINT, the others to (0, 0, 0).
    poses: a poses file. For KITTI .bin scans the sequence's poses (line i places frame i);
        for point clouds one T_world_sensor per file, in the order given (KITTI or TUM layout,
        ehm.io.poses), each file's points in its sensor's frame (PCD: the VIEWPOINT's frame).
    calib: KITTI's calib.txt, or "identity" (ehm.io.kitti.read_kitti).
    every: take every `every`-th scan (1: all); limit: stop after this many (None: no limit).
    topic, frame, odometry: for ROS bags, the scans' topic (None: the only scan topic), the
        fixed frame they are placed in by /tf, and an odometry topic to place them by instead
        (see ehm.io.bags); `poses` gives one pose per message instead.

    Files of one scan each (xyz, ply, pcd, las, kitti) are read by index directly; logs,
    graphs, TUM folders and bags hold many scans and are read from their start.
    Raises FileReadError naming the file for anything it cannot read, InputError for options
    that do not fit the format.
    """

    def __init__(
        self,
        paths: str | PathLike[str] | Sequence[str | PathLike[str]],
        format: str | None = None,
        origin: Sequence[float] | None = None,
        poses: str | PathLike[str] | None = None,
        calib: str | PathLike[str] | None = None,
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
        if fmt != "bag" and (topic, frame, odometry) != (None, None, None):
            raise InputError(f"topic, frame and odometry are for ROS bags, not {fmt} files")
        if not (isinstance(every, int) and every >= 1):
            raise InputError(f"every must be an integer >= 1, got {every!r}")
        if limit is not None and not (isinstance(limit, int) and limit >= 0):
            raise InputError(f"limit must be an integer >= 0, got {limit!r}")
        for item in items:
            if not Path(item).exists():
                raise FileReadError(item, "no such file or folder")
        self.format = fmt
        self._every, self._limit = every, limit
        # One (path, T_world_file, origin, time) per scan for files of one scan each, else None.
        self._files: (
            list[tuple[Path, np.ndarray | None, np.ndarray | None, float | None]] | None
        ) = None
        self._streams: list = []
        if fmt == "kitti":
            bins, poses_path = kitti_files(items, poses)
            files = [(path, T, None, t) for path, T, t in kitti_frames(bins, poses_path, calib)]
        elif fmt == "bag":
            self._streams = [BagScans(item, topic, frame, odometry, poses) for item in items]
            return
        elif fmt in POSED_FORMATS:
            self._streams = items
            return
        else:
            sensor = None if origin is None else np.asarray(origin, dtype=np.float64)
            T_world_files = _file_poses(poses, len(items))
            files = [(Path(p), T, sensor, None) for p, T in zip(items, T_world_files, strict=True)]
        self._files = files[::every][:limit]

    def count(self) -> int | None:
        """How many scans there are, when that is known without reading them (files of one
        scan each), else None."""
        return None if self._files is None else len(self._files)

    def __iter__(self) -> Iterator[Scan]:
        if self._files is not None:
            return (self._read_file(i) for i in range(len(self._files)))
        if self.format == "bag":
            scans = (scan for bag in self._streams for scan in bag)
        else:
            scans = _posed_scans(self._streams, self.format)
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
        path, T_world_file, sensor, time = self._files[index]
        if self.format == "kitti":
            return read_kitti_scan(path, T_world_file, time)
        return _point_cloud_scan(path, self.format, sensor, T_world_file)


def _posed_scans(items: list[str | PathLike[str]], fmt: str) -> Iterator[Scan]:
    """The scans of graph, TUM or CARMEN files, one file after the other."""
    readers = {"graph": read_octomap_graph, "tum": tum_scans, "carmen": read_carmen}
    for item in items:
        found = 0
        for scan in readers[fmt](item):
            found += 1
            yield scan
        if not found:
            raise FileReadError(item, "no scans")


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
    if fmt in ("kitti", "bag") and origin is not None:
        raise InputError(f"{fmt} scans are placed by their poses: origin would be ignored")
    if origin is not None and poses is not None:
        raise InputError("give an origin or poses, not both: each pose places its sensor")
    if calib is not None and fmt != "kitti":
        raise InputError(f"calib is for KITTI scans, not {fmt} files")
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
    if T_world_file is not None:
        points = transform_points(T_world_file, points)
        sensor = transform_points(T_world_file, sensor[None])[0]
    try:
        return Scan(points, sensor)
    except InputError as error:
        raise FileReadError(path, str(error)) from None
