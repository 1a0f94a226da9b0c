"""OctoMap, wavemap, DUFOMap and EHM side by side on every data set, in one process.

    python benchmarks/peers.py [--seeds 0] [--fractions 0.8] [--datasets street,...]
                               [--set features=support ...]

For each data set and split (held-out rays, DESIGN.md), every method maps the training scans at
the data set's resolution (OctoMap's and wavemap's smallest cell; EHM through
`MapConfig.for_resolution`, scan by scan, `ehm-realtime` with its real-time profile) and answers
the test points; three tables: held-out F1, build seconds, memory and query seconds. Build
seconds hold everything a map learns before it can answer: EHM's last batch of scans, wavemap's
threshold and prune. Query seconds are for every test point at once; memory is each method's own
count of what it keeps. Held-out F1 of the occupied class at 0.5; on the simulated scenes also
F1 against the exact occupancy at points within 0.3 m of training hits, where a training ray
reached (benchmarks/online_mapping.py). Each method maps a small scan first, untimed, so
compilation is not timed. wavemap (../shared/peers/wavemap, built by its build.sh) is left out,
with a message, where it is not built and on 2D data. DUFOMap (`pip install dufomap`, UFOMap's
ray casting in C++; it keeps no occupancy to ask, so only its build is timed, the fastest CPU
mapper to compare with) is left out likewise. `--set` changes EHM's settings over the
resolution's defaults.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np
from common import (
    RESOLUTION,
    RESOLUTIONS,
    heading,
    markdown_table,
    settings_text,
    sweep_arguments,
)
from online_mapping import SIMULATED, loaded_datasets, near_surface_test_points
from results_file import run_recorded

from ehm.core.sensor.scan import Scan
from ehm.eval.baselines import make_mapper
from ehm.eval.metrics import f1_score
from ehm.eval.protocol import held_out_rays
from ehm.eval.runner import warm_up as warm_up_method

DATASETS = (
    "octomap_scan",
    "tum_fr2_pioneer_slam2",
    "pcl_room",
    "intel_lab",
    "icl_living_room",
    "icl_living_room_noisy",
    *SIMULATED,
)
METHODS = ("octomap", "wavemap", "dufomap", "ehm", "ehm-realtime")
# Methods timed building only: they answer no occupancy query.
BUILD_ONLY = ("dufomap",)
# Peers that map 3D scans only.
THREE_D_ONLY = ("wavemap", "dufomap")
PEERS = Path(__file__).resolve().parents[2] / "shared" / "peers" / "wavemap"


class WavemapMapper:
    """wavemap through the peer wrapper beside its archive: a Mapper of the evaluation."""

    description = "wavemap (Reijgwart et al. 2023), projective integrator"

    def __init__(self, resolution: float) -> None:
        sys.path.insert(0, str(PEERS))
        from wavemap_peer import WavemapPeer

        self.peer = WavemapPeer(resolution)

    def build(self, scans: list[Scan]) -> None:
        for scan in scans:
            self.peer.integrate(scan.points_world, scan.origin, scan.hit_mask)
        self.peer.finish()

    def occupancy(self, points: np.ndarray) -> np.ndarray:
        return self.peer.occupancy(points)

    def memory_bytes(self) -> int:
        return self.peer.memory_bytes()


class DufomapMapper:
    """DUFOMap's integration of each scan's hits from its sensor origin, at `resolution`
    metres, with the hit inflation (two voxels) and unknown inflation (one voxel) of its own
    LiDAR configuration; it answers no occupancy query."""

    def __init__(self, resolution: float) -> None:
        from dufomap import dufomap

        self.map = dufomap(resolution, 2.0 * resolution, 1, num_threads=0)

    def build(self, scans: list[Scan]) -> None:
        for scan in scans:
            T_world_sensor = np.eye(4)
            T_world_sensor[:3, 3] = scan.origin
            self.map.run(scan.points_world[scan.hit_mask], T_world_sensor, cloud_transform=False)


def mapper_of(method: str, resolution: float, seed: int, settings: dict | None = None):
    """A fresh mapper of `method` (EHM with MapConfig overrides `settings`), or the reason
    there is none."""
    if method == "dufomap":
        try:
            return DufomapMapper(resolution)
        except ImportError:
            return "not installed: pip install dufomap"
    if method != "wavemap":
        ehm_settings = settings if method.startswith("ehm") else None
        return make_mapper(method, resolution, seed, ehm_settings)
    try:
        return WavemapMapper(resolution)
    except ImportError:
        return "not built: run ../shared/peers/wavemap/build.sh .venv"


def warm_up(method: str, dim: int, settings: dict) -> None:
    """Map two small scans of `dim` dimensions once, untimed, so compiled code is ready
    (EHM with `settings`, its MapConfig overrides)."""
    if method == "octomap" or (method == "ehm" and not settings):
        warm_up_method(method, dim)
        return
    mapper = mapper_of(method, RESOLUTION, 0, settings)
    if isinstance(mapper, str) or (method in THREE_D_ONLY and dim == 2):
        return
    directions = np.random.default_rng(0).normal(size=(400, dim))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origins = (np.zeros(dim), np.full(dim, 0.5))
    mapper.build([Scan(2.0 * directions + origin, origin) for origin in origins])
    if method not in BUILD_ONLY:
        mapper.occupancy(directions)


def measure(
    name: str,
    scans: list[Scan],
    scene,
    fraction: float,
    seed: int,
    settings: dict,
    methods: tuple[str, ...] = METHODS,
) -> dict:
    """Per method of `methods`: build s, query s, memory MB, held-out F1, and near F1 on a
    scene; or the reason it was left out. settings: MapConfig overrides for EHM."""
    resolution = RESOLUTIONS.get(name, RESOLUTION)
    split = held_out_rays(scans, fraction, resolution, seed)
    near = truth = None
    if scene is not None:
        near = near_surface_test_points(split.train, 100_000, np.random.default_rng(seed))
        truth = scene.occupied(near)
    found = {}
    for method in methods:
        if method in THREE_D_ONLY and scans[0].dim == 2:
            found[method] = "3D only"
            continue
        mapper = mapper_of(method, resolution, seed, settings)
        if isinstance(mapper, str):
            found[method] = mapper
            continue
        start = time.perf_counter()
        mapper.build(split.train)
        built = time.perf_counter()
        if method in BUILD_ONLY:
            found[method] = {"build s": built - start}
            continue
        probability = mapper.occupancy(split.points)
        row = {
            "build s": built - start,
            "query s": time.perf_counter() - built,
            "memory MB": mapper.memory_bytes() / 1e6,
            "held-out F1": f1_score(split.occupied, probability > 0.5),
        }
        if near is not None:
            row["near F1 (exact)"] = f1_score(truth, mapper.occupancy(near) > 0.5)
        found[method] = row
    return found


def f1_cell(values: dict | str) -> str:
    """Held-out F1, and near F1 against the exact occupancy in brackets where measured."""
    if isinstance(values, str):
        return values
    near = values.get("near F1 (exact)")
    return f"{values['held-out F1']:.3f}" + ("" if near is None else f" ({near:.3f})")


def build_cell(values: dict | str, octomap: dict) -> str:
    """Build seconds and their ratio to OctoMap's."""
    if isinstance(values, str):
        return values
    return f"{values['build s']:.2f} ({values['build s'] / octomap['build s']:.2f}x)"


def memory_cell(values: dict | str, octomap: dict) -> str:
    """Memory MB with its ratio to OctoMap's, and the query seconds of every test point."""
    if isinstance(values, str):
        return values
    ratio = values["memory MB"] / octomap["memory MB"]
    return f"{values['memory MB']:.2f} ({ratio:.3f}x), {values['query s']:.3f} s"


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, with_settings=True)
    detail = f"seeds {sweep.seeds}, train fractions {sweep.fractions}"
    print(heading("Peers", detail + settings_text(sweep.settings)))
    for method in METHODS:
        for dim in (2, 3):
            warm_up(method, dim, sweep.settings)
    answering = [method for method in METHODS if method not in BUILD_ONLY]
    f1_rows, build_rows, memory_rows = [], [], []
    for name, scans, scene in loaded_datasets(sweep.datasets):
        for fraction in sweep.fractions:
            runs = [
                measure(name, scans, scene, fraction, seed, sweep.settings) for seed in sweep.seeds
            ]
            means = {}
            for method in METHODS:
                if isinstance(runs[0][method], str):
                    means[method] = runs[0][method]
                    continue
                keys = runs[0][method]
                means[method] = {k: statistics.fmean(r[method][k] for r in runs) for k in keys}
            octomap, key = means["octomap"], [name, f"{fraction:.0%}"]
            f1_rows.append(key + [f1_cell(means[method]) for method in answering])
            build_rows.append(key + [build_cell(means[method], octomap) for method in METHODS])
            memory_rows.append(key + [memory_cell(means[method], octomap) for method in answering])
    print("### Held-out F1 (near F1 against the exact occupancy)\n")
    print(markdown_table(["data set", "train", *answering], f1_rows, text_columns=2))
    print("### Build seconds (x OctoMap's)\n")
    print(markdown_table(["data set", "train", *METHODS], build_rows, text_columns=2))
    print("### Memory MB (x OctoMap's), query seconds\n")
    print(markdown_table(["data set", "train", *answering], memory_rows, text_columns=2))


if __name__ == "__main__":
    run_recorded(main, __file__)
