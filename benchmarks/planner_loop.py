"""A planner in the loop: learn a scan, then cast rays, ask points and distances; EHM, OctoMap.

    python benchmarks/planner_loop.py [--rays 5000] [--points 10000] [--features nearest]

For each data set (TUM, the warehouse, the street; each at its own resolution, EHM through
`MapConfig.for_resolution`), scan by scan:

- the learning part: EHM's `integrate_scan` and `flush` (so no scan waits for its batch inside
  the queries), with its stage 'grids' (keeping what rays march and the distance field) shown
  apart; OctoMap's `insertPointCloud` of the scan's hits;
- the query part: `rays` rays of the scan, from its origin out to 30 m, and `points` points drawn
  in the box of every hit so far. EHM: `raycast`, `occupancy` and `distance` with its gradient.
  OctoMap: `castRay` per ray and `search` per point, from Python as a planner would; it has no
  distances.

The first scan's EHM queries make what rays march and the distance field; after that every
update keeps them, in its stage 'grids'. The ratio compares the query parts.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table
from raycast import octomap_cast
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset, street, warehouse

MAX_RANGE = 30.0
DATA_SETS = {
    "tum_fr2_pioneer_slam2": lambda: load_dataset("tum_fr2_pioneer_slam2"),
    "warehouse": lambda: warehouse().scans,
    "street": lambda: street().scans,
}


def seconds(function, *args, **kwargs) -> float:
    """Seconds `function(*args, **kwargs)` takes."""
    start = time.perf_counter()
    function(*args, **kwargs)
    return time.perf_counter() - start


def learn(hilbert_map: ehm.HilbertMap, scan: ehm.Scan) -> None:
    """Integrate `scan` and learn it, whether or not its batch is full."""
    hilbert_map.integrate_scan(scan).flush()


def rays_of(scan: ehm.Scan, n: int, rng: np.random.Generator):
    """Origins (n, 3) and unit directions (n, 3) of up to `n` of the scan's hit rays."""
    hits = scan.points_world[scan.hit_mask]
    chosen = hits[rng.choice(len(hits), min(n, len(hits)), replace=False)]
    offsets = chosen - scan.origin
    directions = offsets / np.linalg.norm(offsets, axis=1)[:, None]
    return np.broadcast_to(scan.origin, directions.shape).copy(), directions


def loop(
    name: str, scans: list[ehm.Scan], n_rays: int, n_points: int, features: str
) -> list[list[str]]:
    resolution = RESOLUTIONS.get(name, RESOLUTION)
    hilbert_map = ehm.HilbertMap(ehm.MapConfig.for_resolution(resolution, features=features))
    octomap = OctoMapMapper(resolution)
    octomap.build([])
    rng = np.random.default_rng(0)
    low, high = np.full(3, np.inf), np.full(3, -np.inf)
    rows = []
    for index, scan in enumerate(scans):
        learning = seconds(learn, hilbert_map, scan)
        grids = hilbert_map.timings_.get("grids", 0.0)
        insert = seconds(octomap.insert, scan)
        hits = scan.points_world[scan.hit_mask]
        low, high = np.minimum(low, hits.min(axis=0)), np.maximum(high, hits.max(axis=0))
        origins, directions = rays_of(scan, n_rays, rng)
        points = rng.uniform(low, high, (n_points, 3))
        cast = seconds(hilbert_map.raycast, origins, directions, MAX_RANGE)
        ask = seconds(hilbert_map.occupancy, points)
        far = seconds(hilbert_map.distance, points, return_gradient=True)
        their_cast = seconds(octomap_cast, octomap.tree, origins, directions, False)
        their_ask = seconds(octomap.occupancy, points)
        ours, theirs = cast + ask + far, their_cast + their_ask
        rows.append(
            [
                f"{name} {index + 1}",
                f"{learning:.2f}",
                f"{grids:.2f}",
                f"{insert:.2f}",
                f"{cast:.3f} / {ask:.3f} / {far:.3f}",
                f"{their_cast:.3f} / {their_ask:.3f}",
                f"{ours / theirs:.2f}",
            ]
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=5000)
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--datasets", default=",".join(DATA_SETS))
    parser.add_argument("--features", choices=("nearest", "support"), default="support")
    args = parser.parse_args()
    detail = f"{args.rays:,} rays, {args.points:,} points a scan, features '{args.features}'"
    print(heading("A planner in the loop", detail))
    # Compiles every kernel.
    warm = ehm.HilbertMap(features=args.features).integrate_scan(warehouse().scans[0])
    warm.raycast(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), 5.0)
    warm.distance(np.zeros((1, 3)), return_gradient=True)
    rows = []
    for name in args.datasets.split(","):
        try:
            scans = DATA_SETS[name]()
        except DataMissingError as missing:
            print(f"skipped {name}: {missing}")
            continue
        rows += loop(name, scans, args.rays, args.points, args.features)
    header = [
        "scan",
        "EHM learns, s",
        "of it 'grids', s",
        "OctoMap inserts, s",
        "EHM rays / points / distances, s",
        "OctoMap castRay / search, s",
        "queries, EHM / OctoMap",
    ]
    print(markdown_table(header, rows))


if __name__ == "__main__":
    run_recorded(main, __file__)
