"""Soak: long runs through one map with saves along the way, and a far glitch's memory.

    python benchmarks/soak.py [--passes 10] [--scans-3d 200] [--save-every-2d 1000]
                              [--save-every-3d 20]

2D: the generated corridor (2,000 laser scans of 180 rays over 100 m) driven `passes` times,
back and forth: 20,000 scans by default. 3D: `scans_3d` LiDAR scans (16 x 512 rays) on two
laps of a loop round the warehouse's shelving. Each run is mapped twice with the defaults: once
saving the map every few scans and going on from the file just written, once without saving.
The two final maps must be equal (every cluster array and the answers at 20,000 points); the
map's memory after each pass or tenth of the run shows whether it is bounded by the scene.

Glitch: the warehouse's first full scan (89,984 rays) mapped with max_range 50 m, with and
without one extra point at 1e9 m; the peak memory traced while integrating each.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from results_file import run_recorded

import ehm
from ehm.core.sensor.scan import Scan
from ehm.eval.datasets import warehouse
from ehm.eval.datasets.simulated import corridor_2d, warehouse_drive


def soak(
    scans: list[Scan], save_every: int, checkpoints: int, folder: Path
) -> tuple[list[list[str]], bool]:
    """Map `scans` with a save and reload every `save_every` scans and without; rows of the
    memory at `checkpoints` points along the run (where both maps learn the scans waiting for
    their batch), and whether the two final maps are equal."""
    saved, plain = ehm.HilbertMap(), ehm.HilbertMap()
    path = folder / "soak.ehm"
    rows, start = [], time.perf_counter()
    every = max(len(scans) // checkpoints, 1)
    for index, scan in enumerate(scans, start=1):
        saved.integrate_scan(scan)
        plain.integrate_scan(scan)
        if index % save_every == 0:
            saved.save(path)
            saved = ehm.load(path)
        if index % every == 0 or index == len(scans):
            # Both at the same scans, so both learn the same batches.
            saved.flush()
            plain.flush()
            rows.append(
                [
                    f"{index:,}",
                    f"{plain.n_clusters:,}",
                    f"{plain.memory_bytes() / 1e6:.2f}",
                    f"{path.stat().st_size / 1e6:.2f}" if path.exists() else "",
                    f"{time.perf_counter() - start:.0f}",
                ]
            )
    return rows, maps_equal(saved, plain)


def _equal(a: np.ndarray, b: np.ndarray) -> bool:
    """Arrays of the same values, NaN equal to NaN in floating point ones."""
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


def maps_equal(a: ehm.HilbertMap, b: ehm.HilbertMap) -> bool:
    """Every cluster and memory array equal (NaN where the other has NaN: times never seen),
    and the same answers at 20,000 points."""
    a.flush()
    b.flush()
    same = all(
        _equal(array, getattr(b.clusters_, name)) for name, array in a.clusters_.arrays().items()
    )
    same &= all(
        _equal(array, b.model_.memory.arrays()[name])
        for name, array in a.model_.memory.arrays().items()
    )
    means = b.clusters_.means
    rng = np.random.default_rng(0)
    points = rng.uniform(means.min(axis=0), means.max(axis=0), (20_000, b.dim))
    return bool(same and np.array_equal(a.occupancy(points), b.occupancy(points)))


def glitch_peaks() -> tuple[float, float]:
    """Peak traced MB of integrating the warehouse's first scan, without and with a point at
    1e9 m, max_range 50 m."""
    scan = warehouse().scans[0]
    glitched = Scan(
        np.vstack([scan.points_world, [[1e9, 0.0, 1.5]]]),
        scan.origin,
        np.r_[scan.hit_mask, True],
    )
    peaks = []
    for one in (scan, glitched):
        hilbert_map = ehm.HilbertMap(max_range=50.0, batch_rays=0)
        tracemalloc.start()
        hilbert_map.integrate_scan(one)
        peaks.append(tracemalloc.get_traced_memory()[1] / 1e6)
        tracemalloc.stop()
    return peaks[0], peaks[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--passes", type=int, default=10)
    parser.add_argument("--scans-3d", type=int, default=200)
    parser.add_argument("--save-every-2d", type=int, default=1000)
    parser.add_argument("--save-every-3d", type=int, default=20)
    args = parser.parse_args()
    corridor = corridor_2d().scans
    runs = {
        "corridor_2d": (
            [s for p in range(args.passes) for s in (corridor if p % 2 == 0 else corridor[::-1])],
            args.save_every_2d,
        ),
        "warehouse_drive": (warehouse_drive(n_scans=args.scans_3d).scans, args.save_every_3d),
    }
    columns = ["scans", "clusters", "map MB", "file MB", "seconds"]
    with tempfile.TemporaryDirectory() as folder:
        for name, (scans, save_every) in runs.items():
            rows, equal = soak(scans, save_every, 10, Path(folder))
            detail = f"{len(scans):,} scans, saved and reloaded every {save_every}"
            print(heading(f"Soak: {name}", detail))
            print(markdown_table(columns, rows))
            print(f"\nfinal map equal to the one never saved: {'yes' if equal else 'NO'}\n")
    without, with_glitch = glitch_peaks()
    print(heading("A point at 1e9 m", "warehouse scan 0, max_range 50 m, peak traced memory"))
    print(f"without: {without:.1f} MB, with: {with_glitch:.1f} MB")
    peak_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident memory of this process: {peak_rss:.0f} MB")


if __name__ == "__main__":
    run_recorded(main, __file__)
