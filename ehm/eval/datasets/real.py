"""The real data sets of the shared data folder, as lists of ehm.Scan.

The folder is $EHM_DATA_DIR, or ../shared/data from the working directory by default (the
project's checkout sits beside the shared folder). Each loader raises DataMissingError (a
FileNotFoundError) naming the path when its files are absent.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import AssumptionWarning
from ehm.io.carmen import read_carmen
from ehm.io.pcd import read_pcd
from ehm.io.readers import read_scans
from ehm.io.tum import FREIBURG_CAMERAS
from ehm.io.xyz import read_xyz

# The scan lines of OctoMap's sample scan meet here, 0.47 m from the file's origin.
OCTOMAP_SCAN_ORIGIN = np.array([0.035, 0.0, 0.513])
# PCL room scans: points closer than this to the sensor are the robot itself.
PCL_ROOM_MIN_RANGE = 0.3


class DataMissingError(FileNotFoundError):
    """A data set's files are not in the data folder."""


DEFAULT_DATA_DIR = Path("..") / "shared" / "data"


def data_dir() -> Path:
    """The shared data folder: $EHM_DATA_DIR, or ../shared/data from the working directory."""
    return Path(os.environ.get("EHM_DATA_DIR") or DEFAULT_DATA_DIR).resolve()


def _require(relative: str) -> Path:
    path = data_dir() / relative
    if not path.exists():
        raise DataMissingError(f"{path} not found (set EHM_DATA_DIR to the data folder)")
    return path


def octomap_scan() -> list[Scan]:
    """OctoMap's sample 3D laser scan: 88,206 rays from (0.035, 0, 0.513) m."""
    points = read_xyz(_require("octomap_scan/scan.dat.bz2"))
    return [Scan(points, OCTOMAP_SCAN_ORIGIN)]


def pcl_room() -> list[Scan]:
    """PCL's two room scans, each in its own frame with the sensor at its origin; returns
    (points closer than 0.3 m, the robot, removed)."""
    scans = []
    for name in ("room_scan1.pcd", "room_scan2.pcd"):
        points, viewpoint = read_pcd(_require(f"pcl_room/{name}"))
        ranges = np.linalg.norm(points - viewpoint, axis=1)
        scans.append(Scan(points[~(ranges < PCL_ROOM_MIN_RANGE)], viewpoint))
    return scans


def tum_fr2_pioneer_slam2() -> list[Scan]:
    """Ten Kinect depth frames of TUM fr2/pioneer_slam2 with ground-truth poses, through the
    Freiburg 2 camera."""
    camera = FREIBURG_CAMERAS[2]
    return read_scans(
        _require("tum_fr2_pioneer_slam2"),
        format="tum",
        intrinsics=camera.intrinsics,
        depth_scale=camera.depth_scale,
    )


def icl_living_room(noise_std: float = 0.0, seed: int = 0) -> list[Scan]:
    """Five depth frames rendered from the ICL-NUIM living room's mesh (Open3D's Redwood
    sample, millimetres, noise-free), through its camera file; with `noise_std` > 0, Gaussian
    noise of that many metres on each range (seeded by `seed`)."""
    with warnings.catch_warnings():  # the reader says it reads millimetres: known here
        warnings.simplefilter("ignore", AssumptionWarning)
        scans = read_scans(_require("rgbd_mm"), format="redwood")
    if noise_std <= 0.0:
        return scans
    rng = np.random.default_rng(seed)
    noisy = []
    for scan in scans:
        offsets = scan.points_world - scan.origin
        ranges = np.linalg.norm(offsets, axis=1)
        stretch = 1.0 + rng.normal(0.0, noise_std, len(ranges)) / ranges
        noisy.append(Scan(scan.origin + offsets * stretch[:, None], scan.origin))
    return noisy


def intel_lab() -> list[Scan]:
    """The Intel Research Lab 2D laser log: 910 scans, dropouts (81.83 m) removed."""
    return read_carmen(_require("intel_lab/intel.gfs.log"))


REAL_DATASETS = {
    "octomap_scan": octomap_scan,
    "pcl_room": pcl_room,
    "tum_fr2_pioneer_slam2": tum_fr2_pioneer_slam2,
    "intel_lab": intel_lab,
    "icl_living_room": icl_living_room,
    "icl_living_room_noisy": lambda: icl_living_room(noise_std=0.01),
}
