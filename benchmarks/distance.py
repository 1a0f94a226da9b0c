"""Distances to obstacles against the exact scene, the field's cost per update, and its speed.

    python benchmarks/distance.py [--points 200000]

Each simulated scene (the virtual room, the warehouse, the street) is mapped scan by scan at
its own resolution (`MapConfig.for_resolution`). After the first scan a distance query makes
the field; every later update keeps it up to date (the update's stage 'grids'), timed beside
the rest of the update. After the last scan, `points` points drawn in the scene's box are
asked their distance (the field kept, JIT warm); their error is measured against the exact
distance to the scene's surfaces, signed, where the map is known: points some kernel reaches
(occupancy other than 0.5: the inside of a building, behind its facade, is unknown to any
scan), whose nearest surface the scans saw (the nearest hit lies within two resolutions of
that distance), nearer to it than the field's reach. Unknown space is free here
(unknown="free"): the error is to the scene's surfaces, not to the edge of what was seen.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table
from results_file import run_recorded
from scipy.spatial import cKDTree

import ehm
from ehm.eval.datasets import street, virtual_room, warehouse

SCENES = {"virtual_room": virtual_room, "warehouse": warehouse, "street": street}


def signed_truth(dataset, points: np.ndarray, resolution: float):
    """Exact signed distances of `points` to the scene and which points' nearest surface the
    scans saw."""
    scene = dataset.scene
    exact = scene.surface_distance(points)
    signed = np.where(scene.occupied(points), -exact, exact)
    hits = np.vstack([scan.points_world[scan.hit_mask] for scan in dataset.scans])
    nearest_hit, _ = cKDTree(hits).query(points, workers=-1)
    return signed, np.abs(nearest_hit - exact) < 2 * resolution


def measure(name: str, n_points: int, rng: np.random.Generator) -> list[str]:
    dataset = SCENES[name]()
    resolution = RESOLUTIONS.get(name, RESOLUTION)
    hilbert_map = ehm.HilbertMap(ehm.MapConfig.for_resolution(resolution))
    hits = np.vstack([scan.points_world[scan.hit_mask] for scan in dataset.scans])
    low, high = hits.min(axis=0), hits.max(axis=0)
    points = rng.uniform(low, high, (n_points, 3))
    learn, keep = [], []
    for index, scan in enumerate(dataset.scans):
        start = time.perf_counter()
        hilbert_map.integrate_scan(scan)
        seconds = time.perf_counter() - start
        if index == 0:
            start = time.perf_counter()
            hilbert_map.distance(points[:1], unknown="free")  # makes the field
            made = time.perf_counter() - start
            continue
        grids = hilbert_map.timings_.get("grids", 0.0)
        learn.append(seconds - grids)
        keep.append(grids)
    hilbert_map.distance(points, unknown="free")
    start = time.perf_counter()
    distance = hilbert_map.distance(points, return_gradient=True, unknown="free")[0]
    query = time.perf_counter() - start
    signed, seen = signed_truth(dataset, points, resolution)
    reach = hilbert_map.config.distance_reach
    known = np.abs(hilbert_map.occupancy(points) - 0.5) > 1e-9
    judged = seen & known & (np.abs(signed) < reach)
    error = np.abs(distance - signed)[judged]
    return [
        f"{name} ({len(dataset.scans)} scans, {resolution} m)",
        f"{judged.sum():,}",
        f"{np.median(error) / resolution:.2f}",
        f"{np.percentile(error, 95) / resolution:.2f}",
        f"{np.median(error):.3f}",
        f"{made:.2f}",
        f"{np.median(learn):.2f}" if learn else "",
        f"{np.median(keep):.2f}" if keep else "",
        f"{n_points / query / 1e6:.2f}",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200_000)
    parser.add_argument("--scenes", default=",".join(SCENES))
    args = parser.parse_args()
    print(heading("Distances to obstacles", f"{args.points:,} points, scan by scan"))
    rng = np.random.default_rng(0)
    warm = ehm.HilbertMap().integrate_scan(virtual_room().scans[0])
    warm.distance(rng.uniform(-1, 1, (10, 3)), return_gradient=True, unknown="free")
    rows = [measure(name, args.points, rng) for name in args.scenes.split(",")]
    header = [
        "scene",
        "points judged",
        "median error, resolutions",
        "95th pct, resolutions",
        "median error, m",
        "field made, s",
        "update without field, s",
        "keeping the field, s",
        "queries, M points/s",
    ]
    print(markdown_table(header, rows))


if __name__ == "__main__":
    run_recorded(main, __file__)
