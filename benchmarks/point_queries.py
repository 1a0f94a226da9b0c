"""Point queries against OctoMap's getLabels, in one process, on the same points.

    python benchmarks/point_queries.py [--points 100000] [--repeats 7] [--datasets a,b]

Each data set is mapped scan by scan at its own resolution (EHM through `MapConfig.for_resolution`,
once with each way of finding a point's kernels: 'nearest', the real-time profile's, and 'support',
the default's; OctoMap with every scan's hits inserted). Then `points` points are asked, drawn two
ways: around the hits (a hit picked at random plus Gaussian noise of 0.2 m per axis: where planners
ask most) and uniformly in the box of the hits. EHM answers with `occupancy` (default query mode),
OctoMap with `getLabels` (one C++ call for all points; 2D maps in the plane z = 0). Times are the
median of `repeats` calls, JIT warm, the slowest call beside it; OctoMap's calls and each EHM
map's take turns, so that all meet the machine in the same moments.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from common import RESOLUTION, RESOLUTIONS, markdown_table
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset, virtual_room, warehouse

DATA_SETS: dict[str, Callable[[], list[ehm.Scan]]] = {
    "octomap_scan": lambda: load_dataset("octomap_scan"),
    "virtual_room": lambda: virtual_room().scans,
    "warehouse": lambda: warehouse().scans,
    "tum_fr2_pioneer_slam2": lambda: load_dataset("tum_fr2_pioneer_slam2"),
    "intel_lab": lambda: load_dataset("intel_lab"),
}
FEATURES = ("nearest", "support")
# Spread of the points asked around hits, metres per axis.
NEAR_HITS_STD = 0.2


def seconds(function: Callable[[], object]) -> float:
    """Seconds of one call."""
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def query_points(hits: np.ndarray, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """(n, d) points around the (m, d) hits and uniformly in their box, metres."""
    near = hits[rng.integers(0, len(hits), n)] + rng.normal(0.0, NEAR_HITS_STD, (n, hits.shape[1]))
    box = rng.uniform(hits.min(axis=0), hits.max(axis=0), (n, hits.shape[1]))
    return {"around hits": near, "in the box": box}


def in_3d(points: np.ndarray) -> np.ndarray:
    """OctoMap's (n, 3) points: 2D ones in the plane z = 0."""
    if points.shape[1] == 3:
        return np.ascontiguousarray(points)
    return np.column_stack([points, np.zeros(len(points))])


def measure(name: str, scans: list[ehm.Scan], n: int, repeats: int) -> list[list[str]]:
    resolution = RESOLUTIONS.get(name, RESOLUTION)
    octomap = OctoMapMapper(resolution)
    octomap.build(scans)
    maps = {}
    for features in FEATURES:
        hilbert_map = ehm.HilbertMap(ehm.MapConfig.for_resolution(resolution, features=features))
        for scan in scans:
            hilbert_map.integrate_scan(scan)
        maps[features] = hilbert_map.flush()
    hits = np.concatenate([scan.points_world[scan.hit_mask] for scan in scans])
    rows = []
    for drawn, points in query_points(hits, n, np.random.default_rng(0)).items():
        octomap_points = in_3d(points)
        calls = {"OctoMap": lambda p=octomap_points: octomap.tree.getLabels(p)}
        for features, hilbert_map in maps.items():
            calls[features] = lambda m=hilbert_map, p=points: m.occupancy(p)
        times: dict[str, list[float]] = {method: [] for method in calls}
        for call in calls.values():
            call()
        for _ in range(repeats):
            for method, call in calls.items():
                times[method].append(seconds(call))
        reference = float(np.median(times["OctoMap"]))
        row = [name, drawn, f"{reference * 1e3:.1f}", f"{max(times['OctoMap']) * 1e3:.1f}"]
        for features in FEATURES:
            median = float(np.median(times[features]))
            row += [
                f"{median * 1e3:.1f}",
                f"{max(times[features]) * 1e3:.1f}",
                f"{median / reference:.2f}x",
            ]
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--datasets", default=",".join(DATA_SETS))
    args = parser.parse_args()
    rows = []
    for name in args.datasets.split(","):
        try:
            scans = DATA_SETS[name]()
        except DataMissingError as missing:
            print(f"skipping {name}: {missing}")
            continue
        rows += measure(name, scans, args.points, args.repeats)
    header = ["data set", "points", "OctoMap getLabels, median ms", "worst ms"]
    for features in FEATURES:
        header += [f"EHM '{features}', median ms", "worst ms", "/ OctoMap"]
    print(markdown_table(header, rows, text_columns=2))


if __name__ == "__main__":
    run_recorded(main, __file__)
