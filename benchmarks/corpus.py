"""Users' own recordings: real recordings from public repositories, checked on their own geometry.

    python benchmarks/corpus.py fetch --to CORPUS [--mirrors DIR]
    python benchmarks/corpus.py run --corpus CORPUS

`fetch` re-creates the corpus outside the repository: the recordings the shared data folder
holds are copied from it ($EHM_DATA_DIR), the others are taken from their public
repositories at a fixed commit, from local clones under `--mirrors` (OWNER+NAME/repo, as `git
clone` or a mirror lays them) or else downloaded from GitHub; every file is checked against
its SHA-256.

`run` maps each recording as a user would, a fresh `ehm map` process with the recording's own
options, and checks the map against the raw data's geometry, read back through ehm's readers:
the hits read occupied (p > 0.5 at a sample of up to 5,000 of them), the sensor poses do not
(p <= 0.5), the raw ranges lie where the recording's documentation puts them (the scale: a
depth unit or a foot read wrong moves them), and for 3D LiDAR sweeps the floor found under
the sensor lies where a plane fitted to the raw points puts it. Results go to
benchmarks/results/corpus_records.json.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from results_file import run_recorded

import ehm
from ehm.eval.datasets.real import data_dir
from ehm.grid.navigation import floor_below
from ehm.io.readers import read_scans

RESULTS = Path(__file__).parent / "results" / "corpus_records.json"
EHM = str(Path(sys.executable).with_name("ehm"))
HITS_CHECKED = 5000


@dataclass(frozen=True)
class Source:
    """A file of a public repository at a commit: its path there, its SHA-256."""

    repo: str
    commit: str
    path: str
    sha256: str
    licence: str


@dataclass(frozen=True)
class Recording:
    """One recording of the corpus: its name and kind; its files (name in the corpus folder:
    a path under the shared data folder, or a Source); the input `ehm map` is given (a file or
    folder of the corpus folder) with `options`; the range of its raw ranges, metres, that
    its documentation gives; for a 3D sweep, the height of the floor under the sensor a plane
    fit of the raw points gives (None: not a sweep over a floor). Depth cameras' ranges are
    their rays' lengths: up to 1.27 times the depth at the image's corners (a Kinect's 0.4-10
    m of depth, the Redwood frames' documented 0.96-2.70 m)."""

    name: str
    kind: str
    files: dict[str, str | Source]
    input: str
    options: list[str] = field(default_factory=list)
    ranges: tuple[float, float] = (0.0, np.inf)
    floor: float | None = None
    moving: bool = False
    refusal: str | None = None  # what its refusal names, for a recording ehm must refuse


_RUST_LIDAR = "jerry73204/rust-lidar-utils", "8b96a14c735fa30ea9e366a7dd558ba38b045e2e", "MIT"
_RADISH = "MOLAorg/mola_test_datasets", "13a2ed141116bc654e14ffca1d88fb740b3d1253", "CC BY 3.0"
_SCAN_PARSER = "btlad/ScanParser", "0e7d2ba809276b684994f5859f232b63611df628", "CC0 1.0"
# KITTI's object set frames, cut to the camera's view; KITTI's licence, the repository none.
_KITTI_OBJECT = "Kazuki-Hara/kitti", "4bf765af1e7f49aa6f566e173a733bc812d7f66c", "CC BY-NC-SA 3.0"
_CUPOCH = "neka-nat/cupoch", "1f0ece043025ac53831d7502b38b8efceef33555", "MIT"
_NEBULA = "tier4/nebula", "74b4f37c14499a7100b723d1a30ccd01ff490975", "Apache-2.0"
_NEBULA_VLP16 = "nebula_drivers/test/data/velodyne/vlp16/1673400471837873222"


def _radish(name: str, sha256: str) -> Source:
    repo, commit, licence = _RADISH
    return Source(repo, commit, f"datasets/radish/{name}", sha256, licence)


CORPUS = [
    Recording(
        "intel_lab", "2D log, FLASER", {"intel.gfs.log": "intel_lab/intel.gfs.log"},
        "intel.gfs.log", ["--limit", "300"], (0.0, 81.9), moving=True,
    ),
    Recording(
        "fr_clinic", "2D log, ROBOTLASER1",
        {"fr-clinic.clf.bz2": "radish_clinic/fr-clinic_robotlaser.clf.bz2"},
        "fr-clinic.clf.bz2", ["--limit", "300"], (0.0, 81.9), moving=True,
    ),
    Recording(
        "aces", "2D log, FLASER", {"aces.clf.bz2": _radish("aces.clf.bz2", "b663e2976ed0621c")},
        "aces.clf.bz2", ["--limit", "300"], (0.0, 81.9), moving=True,
    ),
    Recording(
        "fr079", "2D log, FLASER", {"fr079.clf.bz2": _radish("fr079.clf.bz2", "9c3930e17957889c")},
        "fr079.clf.bz2", ["--limit", "300"], (0.0, 81.9), moving=True,
    ),
    Recording(
        "mit_csail", "2D log, FLASER",
        {"mit-csail.clf.bz2": _radish("mit-csail.clf.bz2", "e010703e450a20e7")},
        "mit-csail.clf.bz2", ["--limit", "300"], (0.0, 81.9), moving=True,
    ),
    Recording(
        "stage_2d_bag", "ROS 1 bag, LaserScan placed by odometry (Stage)",
        {"Mapping1.bag": Source(*_CUPOCH[:2], "examples/testdata/Mapping1.bag", "b8995459d9a41727",
                                _CUPOCH[2])},
        "Mapping1.bag",
        ["--topic", "/base_scan", "--odometry", "/base_pose_ground_truth", "--frame", "odom",
         "--limit", "300"],
        (0.0, 5.0), moving=True,
    ),
    Recording(
        "ros2_vlp16_packets", "ROS 2 bag (sqlite3, format 4), VLP-16 packets, no /tf",
        {
            "vlp16_bag/1673400471837873222_0.db3": Source(
                *_NEBULA[:2], f"{_NEBULA_VLP16}/1673400471837873222_0.db3", "71262f490f04456a",
                _NEBULA[2],
            ),
            "vlp16_bag/metadata.yaml": Source(
                *_NEBULA[:2], f"{_NEBULA_VLP16}/metadata.yaml", "068a9e1cc8b3990a", _NEBULA[2]
            ),
        },
        "vlp16_bag", ["--origin", "0,0,0", "--resolution", "0.2"], (0.1, 100.0),
    ),
    Recording(
        "tum_fr2_pioneer", "RGB-D, TUM layout",
        {"rgbd_dataset_freiburg2_pioneer_slam2": "tum_fr2_pioneer_slam2"},
        "rgbd_dataset_freiburg2_pioneer_slam2", [], (0.4, 12.5), moving=True,
    ),
    Recording(
        "redwood_living_room", "RGB-D, Redwood layout, millimetres", {"rgbd_mm": "rgbd_mm"},
        "rgbd_mm", [], (0.96, 3.43), moving=True,
    ),
    Recording(
        "las_state_plane", "airborne LAS, US survey feet",
        {"4_6_crop.las": "las_georeferenced/4_6_crop.las"},
        "4_6_crop.las", ["--origin", "499781.6,443363.0,2500", "--resolution", "0.5"],
        (320.0, 390.0),  # from the origin above: the tile's 61 x 61 x 19 m under 2500 m
    ),
    Recording(
        "las_without_origin", "airborne LAS, no sensor position given",
        {"4_6_crop.las": "las_georeferenced/4_6_crop.las"}, "4_6_crop.las",
        refusal="give the sensor's position (--origin X,Y,Z",
    ),
    Recording(
        "ouster_os0_128", "Ouster pcap, RNG15 profile",
        {
            "os0.pcap": "ouster_pcap/OS-0-128-U1_v2.3.0_1024x10.pcap",
            "os0.json": "ouster_pcap/OS-0-128-U1_v2.3.0_1024x10.json",
        },
        "os0.pcap", ["--resolution", "0.2"], (0.24, 128.6), floor=-1.96,
    ),
    Recording(
        "ouster_os1_64", "Ouster pcap, LEGACY profile, early firmware",
        {
            "os1.pcap": Source(*_RUST_LIDAR[:2], "ouster-lidar/test_files/ouster_example.pcap",
                               "d0c3507e0d29fe39", _RUST_LIDAR[2]),
            "os1.json": Source(*_RUST_LIDAR[:2], "ouster-lidar/test_files/ouster_example.json",
                               "8cfc1b613cb330d0", _RUST_LIDAR[2]),
        },
        "os1.pcap", ["--resolution", "0.2"], (0.5, 150.0),
    ),
    Recording(
        "ouster_without_metadata", "Ouster pcap without its metadata JSON",
        {"alone/os1.pcap": Source(*_RUST_LIDAR[:2], "ouster-lidar/test_files/ouster_example.pcap",
                                  "d0c3507e0d29fe39", _RUST_LIDAR[2])},
        "alone/os1.pcap", refusal="whose metadata JSON would lie beside it (os1.json)",
    ),
    Recording(
        "velodyne_hdl32e_a", "Velodyne pcap, HDL-32E",
        {"hdl32e_a.pcap": Source(*_RUST_LIDAR[:2], "velodyne-test/test_files/velodyne_vlp16.pcap",
                                 "285e6408802ff628", _RUST_LIDAR[2])},
        "hdl32e_a.pcap", ["--resolution", "0.2"], (0.1, 130.0),
    ),
    Recording(
        "velodyne_hdl32e_b", "Velodyne pcap, HDL-32E",
        {"hdl32e_b.pcap": Source(*_RUST_LIDAR[:2], "velodyne-test/test_files/velodyne_vlp32.pcap",
                                 "1ecbd133a86f266b", _RUST_LIDAR[2])},
        "hdl32e_b.pcap", ["--resolution", "0.2"], (0.1, 130.0),
    ),
    Recording(
        "velodyne_vlp16", "Velodyne pcap, VLP-16",
        {"vlp16.pcap": Source(*_SCAN_PARSER[:2], "data/my.pcap", "f7b70ee87910cc02",
                              _SCAN_PARSER[2])},
        "vlp16.pcap", [], (0.1, 100.0),
    ),
    Recording(
        # Cut to the camera's view, the frame holds no ground within 5.7 m: no floor below.
        "kitti_frame", "KITTI frame alone, HDL-64E (the camera's view)",
        {"kitti/000000.bin": Source(*_KITTI_OBJECT[:2], "velodyne/000000.bin",
                                    "77392e8cbd2f1ff9", _KITTI_OBJECT[2])},
        "kitti/000000.bin", ["--origin", "0,0,0", "--resolution", "0.2"], (5.0, 120.0),
    ),
    Recording(
        "octomap_scan", "3D points, text", {"scan.dat.bz2": "octomap_scan/scan.dat.bz2"},
        "scan.dat.bz2", ["--origin", "0.035,0,0.513"], (0.4, 29.5),
    ),
    Recording(
        "pcl_room", "3D points, PCD (LZF)", {"room_scan1.pcd": "pcl_room/room_scan1.pcd"},
        "room_scan1.pcd", [], (0.0, 20.0),
    ),
]  # fmt: skip


def fetch(destination: Path, mirrors: Path | None) -> None:
    """Re-create the corpus in `destination` (see the module)."""
    destination.mkdir(parents=True, exist_ok=True)
    for recording in CORPUS:
        for name, source in recording.files.items():
            target = destination / name
            target.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(source, str):
                shared = data_dir() / source
                if not shared.exists():
                    print(f"missing: {shared} (the shared data folder, EHM_DATA_DIR)")
                    continue
                if shared.is_dir():
                    shutil.copytree(shared, target, dirs_exist_ok=True)
                else:
                    shutil.copy(shared, target)
                continue
            data = _repository_file(source, mirrors)
            digest = hashlib.sha256(data).hexdigest()
            if not digest.startswith(source.sha256):
                raise SystemExit(
                    f"{source.repo}:{source.path}: SHA-256 {digest[:16]} is not {source.sha256}"
                )
            target.write_bytes(data)
        print(f"fetched {recording.name}")


def _repository_file(source: Source, mirrors: Path | None) -> bytes:
    """A file of a public repository at its commit: from a local clone, else from GitHub."""
    if mirrors is not None:
        clone = mirrors / source.repo.replace("/", "+") / "repo"
        if clone.exists():
            return subprocess.run(
                ["git", "-C", str(clone), "show", f"{source.commit}:{source.path}"],
                check=True, capture_output=True,
            ).stdout  # fmt: skip
    url = f"https://raw.githubusercontent.com/{source.repo}/{source.commit}/{source.path}"
    with urllib.request.urlopen(url, timeout=60) as response:
        return response.read()


def check(recording: Recording, corpus: Path, folder: Path) -> dict:
    """Map one recording through the CLI and check it against its raw geometry."""
    map_path = folder / f"{recording.name}.ehm"
    args = [EHM, "map", str(corpus / recording.input), "-o", str(map_path), "--quiet"]
    start = time.perf_counter()
    done = subprocess.run([*args, *recording.options], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    notes = [line for line in done.stderr.splitlines() if line.startswith("note:")]
    record = {"name": recording.name, "kind": recording.kind, "seconds": seconds, "notes": notes}
    if done.returncode != 0 or recording.refusal is not None:
        record["refused"] = done.stderr.strip().splitlines()[-1] if done.returncode else None
        record["exit"] = done.returncode
        record["refused_as_expected"] = bool(
            recording.refusal is not None
            and done.returncode == 2
            and recording.refusal in " ".join(done.stderr.split())
        )
        return record
    hilbert_map = ehm.load(map_path)
    options = _reader_options(recording.options)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scans = read_scans(corpus / recording.input, **options)
    hits = np.concatenate([scan.points_world[scan.hit_mask] for scan in scans])
    ranges = np.concatenate(
        [np.linalg.norm(s.points_world[s.hit_mask] - s.origin, axis=1) for s in scans]
    )
    rng = np.random.default_rng(0)
    sample = hits[rng.choice(len(hits), min(HITS_CHECKED, len(hits)), replace=False)]
    poses = np.stack([scan.origin for scan in scans])
    record.update(
        scans=len(scans),
        hits=len(hits),
        range_m=[float(np.percentile(ranges, 0.1)), float(np.percentile(ranges, 99.9))],
        hits_occupied=float(np.mean(hilbert_map.occupancy(sample) > 0.5)),
        poses_not_occupied=float(np.mean(hilbert_map.occupancy(poses) <= 0.5)),
    )
    low, high = recording.ranges
    record["scale_ok"] = bool(low * 0.95 <= ranges.min() and ranges.max() <= high * 1.05)
    if recording.floor is not None:
        found = floor_below(hilbert_map, poses[0], hilbert_map.config.resolution)
        record["floor_m"] = found
        record["floor_expected_m"] = recording.floor
        record["floor_ok"] = found is not None and abs(found - recording.floor) < 0.3
    return record


def _reader_options(options: list[str]) -> dict:
    """read_scans keywords of the `ehm map` options a recording takes (--origin, --limit,
    and a bag's --topic, --frame and --odometry)."""
    found: dict = {}
    for flag, value in zip(options[::2], options[1::2], strict=True):
        if flag == "--origin":
            found["origin"] = [float(v) for v in value.split(",")]
        elif flag == "--limit":
            found["limit"] = int(value)
        elif flag in ("--topic", "--frame", "--odometry"):
            found[flag[2:]] = value
    return found


def run(corpus: Path) -> None:
    print(heading("Users' own recordings", f"{len(CORPUS)} recordings through `ehm map`"))
    records = []
    with tempfile.TemporaryDirectory() as folder:
        for recording in CORPUS:
            if not (corpus / recording.input).exists():
                print(f"skipped {recording.name}: {corpus / recording.input} not found (fetch it)")
                continue
            records.append(check(recording, corpus, Path(folder)))
            print(f"  {records[-1]}", file=sys.stderr)  # progress
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(records, indent=1) + "\n")
    rows = []
    for r in records:
        if "refused" in r:
            outcome = "refused, naming the fix" if r["refused_as_expected"] else "FAILED"
            rows.append([r["name"], r["kind"], f"{outcome} (exit {r['exit']})", "", "", "", "", ""])
            continue
        floor = ""
        if "floor_ok" in r:
            found = "none" if r["floor_m"] is None else f"{r['floor_m']:.2f}"
            floor = f"{found} ({r['floor_expected_m']:.2f})"
        rows.append([
            r["name"], r["kind"], f"{r['scans']} / {r['hits']:,}",
            f"{r['range_m'][0]:.2f}-{r['range_m'][1]:.1f}" + ("" if r["scale_ok"] else " (off)"),
            f"{r['hits_occupied']:.3f}", f"{r['poses_not_occupied']:.2f}", floor,
            f"{r['seconds']:.1f}",
        ])  # fmt: skip
    header = [
        "recording", "kind", "scans / hits", "raw ranges m, 0.1-99.9 %", "hits occupied",
        "poses not occupied", "floor m (raw fit)", "ehm map s",
    ]  # fmt: skip
    print(markdown_table(header, rows, 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    getting = commands.add_parser("fetch", help="re-create the corpus in a folder")
    getting.add_argument("--to", type=Path, required=True)
    getting.add_argument("--mirrors", type=Path, help="local clones, OWNER+NAME/repo")
    running = commands.add_parser("run", help="map every recording and check it")
    running.add_argument("--corpus", type=Path, required=True)
    args = parser.parse_args()
    if args.command == "fetch":
        fetch(args.to, args.mirrors)
    else:
        run(args.corpus)


if __name__ == "__main__":
    run_recorded(main, __file__)
