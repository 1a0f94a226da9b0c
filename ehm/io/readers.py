"""Read any supported input into a list of ehm.Scan, choosing the reader by file extension.

scans = read_scans("scan.dat.bz2", origin=[0.035, 0, 0.513])
scans = read_scans(["velodyne/000000.bin", ...], poses="poses.txt")
scans = read_scans("tum_sequence/")                 # folder with poses.txt and depth/
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.core.scan import Scan
from ehm.io.carmen import read_carmen
from ehm.io.kitti import read_kitti
from ehm.io.octomap_graph import read_octomap_graph
from ehm.io.pcd import read_pcd
from ehm.io.ply import read_ply
from ehm.io.tum import read_tum
from ehm.io.xyz import read_xyz

FORMATS = ("xyz", "ply", "pcd", "kitti", "graph", "tum", "carmen")
_EXTENSIONS = {
    ".xyz": "xyz", ".txt": "xyz", ".dat": "xyz", ".bz2": "xyz", ".ply": "ply", ".pcd": "pcd",
    ".bin": "kitti", ".graph": "graph", ".log": "carmen", ".clf": "carmen",
}  # fmt: skip


def guess_format(path: str | PathLike[str]) -> str:
    """The reader for a path: a folder holding poses.txt is TUM, otherwise by extension."""
    path = Path(path)
    if path.is_dir():
        if (path / "poses.txt").exists():
            return "tum"
        raise ValueError(f"{path}: a folder is read as TUM depth frames and needs poses.txt")
    fmt = _EXTENSIONS.get(path.suffix.lower())
    if fmt is None:
        raise ValueError(
            f"{path}: unknown extension {path.suffix!r}; pass a format, one of {', '.join(FORMATS)}"
        )
    return fmt


def read_scans(
    paths: str | PathLike[str] | Sequence[str | PathLike[str]],
    format: str | None = None,
    origin: Sequence[float] | None = None,
    poses: str | PathLike[str] | None = None,
) -> list[Scan]:
    """Scans from one or more files of one format.

    origin: sensor position, metres, for single point clouds (xyz, ply, pcd), which do not
    record it; PCD falls back to its VIEWPOINT, the others to (0, 0, 0).
    poses: the poses file of KITTI .bin scans.
    """
    items = [paths] if isinstance(paths, str | PathLike) else list(paths)
    if not items:
        raise ValueError("no input files given")
    fmt = format or guess_format(items[0])
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
    for item in items:
        if not Path(item).exists():
            raise ValueError(f"{item}: no such file or folder")
    if fmt == "kitti":
        if poses is None:
            raise ValueError("KITTI .bin scans need a poses file (poses=...)")
        return read_kitti(items, poses)
    scans: list[Scan] = []
    for item in items:
        if fmt == "graph":
            scans += read_octomap_graph(item)
        elif fmt == "tum":
            scans += read_tum(item)
        elif fmt == "carmen":
            scans += read_carmen(item)
        else:
            scans.append(_point_cloud_scan(Path(item), fmt, origin))
    return scans


def _point_cloud_scan(path: Path, fmt: str, origin: Sequence[float] | None) -> Scan:
    if fmt == "pcd":
        points, viewpoint = read_pcd(path)
        sensor = viewpoint if origin is None else origin
    else:
        points = read_xyz(path) if fmt == "xyz" else read_ply(path)
        sensor = np.zeros(3) if origin is None else origin
    return Scan(points, np.asarray(sensor, dtype=np.float64))
