"""Occupancy grids and meshes (Sec. 3.5): speed, incremental updates and mesh quality.

    python benchmarks/grids.py [--repeats 3]

1. Grid reconstruction from local grids against `occupancy()` at every voxel centre (batch
   queries, Alg. 3) and against OctoMap's vectorised getLabels on the same centres; the
   paper's Table 2 rows "calc. grid features" and "grid inference".
2. One more scan: updating a grid incrementally against rebuilding it. The virtual room and
   OctoMap's scan are split into 8 azimuth sectors of equal ray counts, learned one after the
   other (a sensor
   sweeping round); TUM fr2/pioneer_slam2 learns its 10 frames in order.
3. Mesh quality on the virtual room, at full and at a quarter of its ray density: distance of
   mesh vertices to the exact surface, and completeness, the share of the observed surface (the
   noise-free hits of a scan 4x denser from the same pose) within 2 voxels of a mesh vertex;
   OctoMap's occupied voxel centres at the same resolution are scored the same way.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import RESOLUTION, heading, octomap_mapper, timed
from results_file import run_recorded
from scipy.spatial import cKDTree

import ehm
from ehm.eval.datasets import virtual_room
from ehm.eval.datasets.real import DataMissingError, octomap_scan, tum_fr2_pioneer_slam2
from ehm.pipeline import MappingPipeline


def sectors(scan: ehm.Scan, parts: int) -> list[ehm.Scan]:
    """The scan split into `parts` azimuth sectors of equal ray counts around its origin."""
    offsets = scan.points_world - scan.origin
    order = np.argsort(np.arctan2(offsets[:, 1], offsets[:, 0]), kind="stable")
    return [scan.subset(np.sort(rays)) for rays in np.array_split(order, parts)]


def hit_bounds(scans: list[ehm.Scan]) -> np.ndarray:
    """(2, 3) box around every hit, metres."""
    hits = np.vstack([s.points_world[s.hit_mask] for s in scans])
    return np.stack([hits.min(axis=0), hits.max(axis=0)])


def reconstruction_rows(name: str, scans: list[ehm.Scan], resolution: float, repeats: int):
    """Grid reconstruction against per-voxel queries and OctoMap, and Table 2's grid rows."""
    hilbert_map = ehm.HilbertMap().fit(scans)
    bounds = hit_bounds(scans)
    grid_s, grid = timed(lambda: hilbert_map.grid(bounds, resolution), repeats)
    inference_s, _ = timed(lambda: 1.0 / (1.0 + np.exp(-grid.scores)), repeats)
    centres = grid.centers()
    query_s, probability = timed(lambda: hilbert_map.occupancy(centres), 1)
    tree = octomap_mapper(scans[0], RESOLUTION).tree
    for scan in scans[1:]:
        tree.insertPointCloud(scan.points_world[scan.hit_mask], scan.origin)
    octomap_s, _ = timed(lambda: tree.getLabels(centres), 1)
    local_voxels = grid.update(hilbert_map.snapshot()).rebuild_voxels  # up to date: counts only
    difference = np.abs(probability - grid.probability.ravel())
    voxels = grid.probability.size
    shape = " x ".join(map(str, grid.shape))
    print(
        f"| {name} | {shape} at {resolution} m | {1000 * (grid_s + inference_s):.0f} | "
        f"{1000 * query_s:.0f} | {query_s / (grid_s + inference_s):.1f}x | "
        f"{1000 * octomap_s:.0f} | {octomap_s / (grid_s + inference_s):.1f}x | "
        f"{difference.mean():.4f} / {np.quantile(difference, 0.99):.3f} |"
    )
    return (
        f"| {name} | {1000 * grid_s:.0f} | {1e6 * grid_s / local_voxels:.4f} per local-grid "
        f"voxel ({local_voxels / 1e6:.1f} M) | {1000 * inference_s:.0f} | "
        f"{1e6 * inference_s / voxels:.4f} per voxel ({voxels / 1e6:.1f} M) |"
    )


def incremental_row(name: str, scans: list[ehm.Scan], resolution: float, repeats: int) -> None:
    """Time of one incremental update after the last scan against a rebuild."""
    hilbert_map = MappingPipeline(scans[:-1]).run().hilbert_map
    bounds = hit_bounds(scans)
    grid = hilbert_map.grid(bounds, resolution)
    snapshot = hilbert_map.integrate_scan(scans[-1]).snapshot()  # learns a waiting batch too
    start = time.perf_counter()
    update = grid.update(snapshot)
    update_s = time.perf_counter() - start
    rebuild_s, rebuilt = timed(lambda: hilbert_map.grid(bounds, resolution), repeats)
    error = np.abs(grid.scores - rebuilt.scores).max()
    print(
        f"| {name} | {resolution} | {update.kind} | {update.local_grids} of "
        f"{hilbert_map.n_clusters} | {update.voxels / update.rebuild_voxels:.2f} | "
        f"{1000 * update_s:.0f} | {1000 * rebuild_s:.0f} | {rebuild_s / update_s:.1f}x | "
        f"{error:.1e} |"
    )


def surface_scores(points: np.ndarray, scene, observed: np.ndarray) -> str:
    """Distance of `points` to the exact surface, and completeness of the observed surface."""
    distance = scene.surface_distance(points)
    gap, _ = cKDTree(points).query(observed, distance_upper_bound=2 * RESOLUTION)
    return (
        f"{len(points)} | {100 * distance.mean():.1f} | {100 * np.quantile(distance, 0.95):.1f} | "
        f"{np.mean(np.isfinite(gap)):.3f}"
    )


def mesh_quality_rows() -> None:
    dense = virtual_room(rings=128, azimuths=2812, noise_std=0.0)
    observed = dense.scans[0].points_world[dense.scans[0].hit_mask]
    scene = dense.scene
    for label, rings, azimuths in (("full", 64, 1406), ("quarter", 32, 703)):
        (scan,) = virtual_room(rings=rings, azimuths=azimuths).scans
        hilbert_map = ehm.HilbertMap().integrate_scan(scan)
        vertices, _ = hilbert_map.grid(hit_bounds([scan]), RESOLUTION).mesh()
        occupied, _ = octomap_mapper(scan).tree.extractPointCloud()
        surfaces = {
            "EHM mesh vertices": vertices,
            "OctoMap occupied voxel centres": np.asarray(occupied, dtype=np.float64),
        }
        for method, points in surfaces.items():
            scores = surface_scores(points, scene, observed)
            print(f"| {label}, {len(scan)} rays | {method} | {scores} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    room = virtual_room().scans
    datasets: dict[str, tuple[list[ehm.Scan], float]] = {"virtual_room": (room, RESOLUTION)}
    try:
        # At 0.05 m the 27 x 32 x 11 m box would take 1.2 GiB; 0.1 m keeps it at 150 MB.
        datasets["octomap_scan"] = (octomap_scan(), 0.1)
    except DataMissingError as missing:
        print(f"octomap_scan skipped: {missing}")
    ehm.HilbertMap().fit(room).grid(resolution=0.2)  # compile the kernels once

    print(heading("grids", f"median of {args.repeats} unless stated"))
    print(
        "| data | grid | grid reconstruction ms | occupancy() per voxel ms | speed-up | "
        "OctoMap getLabels ms | speed-up | abs. difference to occupancy(), mean / 99 % |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---|")
    table2 = [reconstruction_rows(n, s, r, args.repeats) for n, (s, r) in datasets.items()]
    print("\nTable 2 rows (kernel values are recomputed, so grid features and the weighted sum")
    print("of Eq. 17 are one pass; inference is the logistic of Eq. 18):\n")
    print("| data | calc. grid features ms | us | grid inference ms | us |")
    print("|---|---:|---|---:|---|")
    print("\n".join(table2))

    print("\nOne more scan: incremental update against a rebuild (update timed once):\n")
    print(
        "| data | resolution m | update | local grids recomputed | their voxels / a rebuild's | "
        "update ms | rebuild ms | speed-up | max. score difference |"
    )
    print("|---|---:|---|---|---:|---:|---:|---:|---:|")
    sequences = {"virtual_room, 8 sectors": (sectors(room[0], 8), RESOLUTION)}
    if "octomap_scan" in datasets:
        scans, resolution = datasets["octomap_scan"]
        sequences["octomap_scan, 8 sectors"] = (sectors(scans[0], 8), resolution)
    try:
        sequences["tum_fr2_pioneer_slam2, 10 frames"] = (tum_fr2_pioneer_slam2(), RESOLUTION)
    except DataMissingError as missing:
        print(f"tum_fr2_pioneer_slam2 skipped: {missing}")
    for name, (scans, resolution) in sequences.items():
        incremental_row(name, scans, resolution, args.repeats)

    print(f"\nMesh quality on the virtual room at {RESOLUTION} m (distances in cm):\n")
    print("| scan | surface from | points | mean distance | 95 % distance | completeness |")
    print("|---|---|---:|---:|---:|---:|")
    mesh_quality_rows()


if __name__ == "__main__":
    run_recorded(main, __file__)
