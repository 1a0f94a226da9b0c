"""Tiled maps: accuracy and seams against one map, Dask speed-up, memory, a 10 km drive.

    python benchmarks/tiles.py                       # everything (about 20 minutes)
    python benchmarks/tiles.py --part accuracy       # held-out F1 and seams, every data set
    python benchmarks/tiles.py --part speed --length 1000 --scans 500

Accuracy: each data set's scans, 80 % of the rays of each (seed 0), learned scan by scan by
one HilbertMap and by a TiledMap (in one process: a Dask build learns the same tiles, see
tests/tiles/test_build.py); held-out F1 of both. Seams: pairs of points resolution / 2 apart
across every tile border plane inside the scans' box (2000 pairs per plane, at random places
on it), and as many across the planes through the tile centres: the largest change of
occupancy within a pair, and the 99th percentile, of the tiled map across borders and across
centres, and of the one map across the same borders.

Speed: CityDrive(length, scans) built on a LocalCluster of 1 and of 2 single-threaded
workers, block 2, same process; then a drive half as long on 2 workers, for the peak
resident memory per worker. Simulation: the 1-worker run's task costs, drawn again for as many
tasks as a 10 km drive has, scheduled largest first on 8, 32 and 128 workers, with binning
spread over the workers and the client receiving and writing each tile in turn.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table
from results_file import run_recorded

from ehm.config import MapConfig
from ehm.eval.datasets import DataMissingError, floor_plan_2d, load_dataset
from ehm.eval.datasets.simulated import CityDrive, city_drive, corridor_2d
from ehm.eval.metrics import f1_score
from ehm.eval.protocol import held_out_rays
from ehm.hilbert_map import HilbertMap
from ehm.io.files import write_atomically
from ehm.tiles import TiledMap

# Each data set's tile side, metres: a few tiles across the scene, so borders cross it.
TILE_SIZES = {
    "virtual_room": 3.0,
    "warehouse": 10.0,
    "street": 25.0,
    "floor_plan_2d": 4.0,
    "corridor_2d": 25.0,
    "city_drive_200m": 25.0,
    "octomap_scan": 10.0,
    "intel_lab": 10.0,
    "tum_fr2_pioneer_slam2": 4.0,
    "pcl_room": 8.0,
}
OUTDOOR = {"street", "city_drive_200m"}
DRIVE_METRES = 10_000.0
# The client's network link in the simulation: 1 Gbit/s.
LINK_BYTES_PER_SECOND = 125e6
CLUSTER_SIZES = (1, 2, 8, 32, 128)


def scans_of(name: str) -> list:
    if name == "floor_plan_2d":
        return floor_plan_2d().scans
    if name == "corridor_2d":
        return corridor_2d().scans
    if name == "city_drive_200m":
        return city_drive(length=200.0, n_scans=100).scans
    return load_dataset(name)


def seam_jumps(
    maps: list, tiled: TiledMap, scans: list, resolution: float, rng: np.random.Generator
) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each of `maps`: the change of occupancy between pairs of points resolution / 2
    apart across tile borders, and across the planes through tile centres (the same count
    of pairs, at random places in the scans' box, across every axis' planes)."""
    hits = np.concatenate([scan.points_world[scan.hit_mask] for scan in scans])
    low, high = np.quantile(hits, 0.01, axis=0), np.quantile(hits, 0.99, axis=0)
    size, step = tiled.tile_size, resolution / 2.0
    pairs = {"border": [], "centre": []}
    for axis in range(hits.shape[1]):
        first, last = np.floor(low[axis] / size), np.ceil(high[axis] / size)
        for kind, offset in (("border", 0.5), ("centre", 0.0)):
            for plane in (np.arange(first, last + 1) + offset) * size:
                if not low[axis] < plane < high[axis]:
                    continue
                points = rng.uniform(low, high, (2000, len(low)))
                before, after = points.copy(), points.copy()
                before[:, axis], after[:, axis] = plane - step / 2.0, plane + step / 2.0
                pairs[kind].append((before, after))
    found = []
    for hilbert_map in maps:
        jumps = {
            kind: np.concatenate(
                [np.abs(hilbert_map.occupancy(a) - hilbert_map.occupancy(b)) for a, b in chosen]
            )
            for kind, chosen in pairs.items()
        }
        found.append((jumps["border"], jumps["centre"]))
    return found


def accuracy_rows() -> list[list[str]]:
    rows = []
    for name, tile_size in TILE_SIZES.items():
        try:
            scans = scans_of(name)
        except DataMissingError as missing:
            print(f"skipped {name}: {missing}")
            continue
        resolution = 0.2 if name in OUTDOOR else RESOLUTIONS.get(name, RESOLUTION)
        config = MapConfig.for_resolution(resolution)
        split = held_out_rays(scans, 0.8, resolution, seed=0)
        one, tiled = HilbertMap(config), TiledMap(tile_size, config=config)
        start = time.perf_counter()
        for scan in split.train:
            one.integrate_scan(scan)
        one.flush()
        one_seconds = time.perf_counter() - start
        start = time.perf_counter()
        for scan in split.train:
            tiled.integrate_scan(scan)
        tiled.flush()
        tiled_seconds = time.perf_counter() - start
        one_f1 = f1_score(split.occupied, one.occupancy(split.points) > 0.5)
        tiled_f1 = f1_score(split.occupied, tiled.occupancy(split.points) > 0.5)
        (tiled_border, tiled_centre), (one_border, _) = seam_jumps(
            [tiled, one], tiled, split.train, resolution, np.random.default_rng(0)
        )
        rows.append(
            [
                name,
                f"{tile_size:g} / {tiled.overlap:g}",
                str(tiled.n_tiles),
                f"{one_f1:.3f}",
                f"{tiled_f1:.3f}",
                f"{tiled_f1 - one_f1:+.3f}",
                _max_and_99(tiled_border),
                _max_and_99(tiled_centre),
                _max_and_99(one_border),
                f"{one_seconds:.1f} / {tiled_seconds:.1f}",
            ]
        )
        print(" | ".join(rows[-1]), file=sys.stderr, flush=True)  # progress
    return rows


def _max_and_99(jumps: np.ndarray) -> str:
    return f"{jumps.max():.3f} / {np.quantile(jumps, 0.99):.3f}"


def build_run(drive: CityDrive, workers: int, config: MapConfig):
    tiled = TiledMap(25.0, config=config)
    start = time.perf_counter()
    report = tiled.build(drive, workers=workers)
    return time.perf_counter() - start, report, tiled


def simulated_seconds(
    task_costs: np.ndarray, bin_costs: np.ndarray, write_seconds: float, workers: int
) -> float:
    """Wall-clock seconds of binning then learning on `workers`, tasks largest first, each
    task's tiles written by the client one at a time (write_seconds each task)."""
    binned = list_schedule(bin_costs, workers)
    learned = list_schedule(np.sort(task_costs)[::-1], workers)
    return binned + max(learned, write_seconds * len(task_costs))


def list_schedule(costs: np.ndarray, workers: int) -> float:
    """Finish time of `costs` given in order to whichever of `workers` is free first."""
    free = np.zeros(workers)
    for cost in costs:
        free[np.argmin(free)] += cost
    return float(free.max())


def speed_section(length: float, n_scans: int) -> str:
    config = MapConfig.for_resolution(0.2)
    drive = CityDrive(length=length, n_scans=n_scans)
    runs = {workers: build_run(drive, workers, config) for workers in (1, 2)}
    half = CityDrive(length=length / 2.0, n_scans=n_scans // 2)
    _, half_report, _ = build_run(half, 2, config)
    rows = []
    for workers, (seconds, report, _) in runs.items():
        tasks = report.tasks
        rows.append(
            [
                f"{length:g} m, {n_scans} scans, {workers} worker(s)",
                f"{seconds:.1f}",
                f"{report.binning_seconds:.1f}",
                f"{report.learning_seconds:.1f}",
                f"{sum(t.seconds for t in tasks):.1f}",
                f"{sum(t.read_seconds for t in tasks):.1f}",
                f"{runs[1][0] / seconds:.2f}",
                f"{max(t.worker_peak_bytes for t in tasks) / 1e6:.0f}",
            ]
        )
    rows.append(
        [
            f"{length / 2:g} m, {n_scans // 2} scans, 2 workers",
            f"{half_report.seconds:.1f}",
            f"{half_report.binning_seconds:.1f}",
            f"{half_report.learning_seconds:.1f}",
            f"{sum(t.seconds for t in half_report.tasks):.1f}",
            f"{sum(t.read_seconds for t in half_report.tasks):.1f}",
            "",
            f"{max(t.worker_peak_bytes for t in half_report.tasks) / 1e6:.0f}",
        ]
    )
    text = markdown_table(
        [
            "build",
            "wall s",
            "binning s",
            "learning s",
            "task s summed",
            "reading s summed",
            "speed-up",
            "peak MB per worker",
        ],
        rows,
    )
    _, one_report, tiled = runs[1]
    costs = np.array([task.seconds for task in one_report.tasks])
    tiles_per_task = np.mean([len(task.tiles) for task in one_report.tasks])
    text += "\n" + markdown_table(
        ["task seconds (1 worker)", "min", "median", "mean", "90 %", "max", "tasks", "tiles"],
        [
            [
                f"{length:g} m drive, blocks of 2 x 2 x 2 tiles",
                *(
                    f"{v:.2f}"
                    for v in (
                        costs.min(),
                        np.median(costs),
                        costs.mean(),
                        np.quantile(costs, 0.9),
                        costs.max(),
                    )
                ),
                str(len(costs)),
                str(tiled.n_tiles),
            ]
        ],
    )
    # The client receives each learned tile over the network and writes it: the write timed
    # on this disk, the transfer at LINK_BYTES_PER_SECOND, per task's tiles.
    tile_bytes = np.mean([tile.record.n_bytes for tile in one_report.tiles])
    start = time.perf_counter()
    for i in range(20):
        write_atomically(f"/tmp/ehm-tile-write-{i}.bin", bytes(int(tile_bytes)))
    write_seconds = (time.perf_counter() - start) / 20 * tiles_per_task
    write_seconds += tile_bytes * tiles_per_task / LINK_BYTES_PER_SECOND
    scale = DRIVE_METRES / length
    rng = np.random.default_rng(0)
    drive_costs = rng.choice(costs, size=round(len(costs) * scale))
    bin_costs = np.full(round(n_scans * scale / 16), one_report.binning_seconds / (n_scans / 16))
    serial = simulated_seconds(drive_costs, bin_costs, write_seconds, 1)
    sim_rows = []
    for workers in CLUSTER_SIZES:
        seconds = simulated_seconds(drive_costs, bin_costs, write_seconds, workers)
        bound = max(costs.max(), drive_costs.sum() / workers)
        sim_rows.append(
            [
                str(workers),
                f"{seconds / 60:.1f}",
                f"{serial / seconds:.1f}",
                f"{serial / seconds / workers:.2f}",
                f"{list_schedule(bin_costs, workers) / seconds:.2f}",
                f"{bound / 60:.1f}",
            ]
        )
    text += (
        f"\nSimulated {DRIVE_METRES / 1000:g} km drive: {len(drive_costs)} tasks "
        f"(task costs drawn from the run above), {len(bin_costs)} binning tasks; the client "
        f"receives and writes {tile_bytes / 1e6:.2f} MB per tile, {write_seconds * 1000:.0f} ms "
        f"per task (1 Gbit/s, this disk), {write_seconds * len(drive_costs) / 60:.1f} minutes "
        "in all.\n\n"
    )
    text += markdown_table(
        ["workers", "minutes", "speed-up", "efficiency", "binning share", "bound: minutes"],
        sim_rows,
    )
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("accuracy", "speed", "all"), default="all")
    parser.add_argument("--length", type=float, default=1000.0)
    parser.add_argument("--scans", type=int, default=500)
    args = parser.parse_args()
    if args.part in ("accuracy", "all"):
        print(heading("Tiled maps against one map", "held-out F1 at 80 %, seams"))
        header = [
            "data set",
            "tile / overlap m",
            "tiles",
            "F1 one map",
            "F1 tiled",
            "difference",
            "tiled, across borders: max / 99 %",
            "tiled, across tile centres",
            "one map, across borders",
            "learn s: one / tiled",
        ]
        print(markdown_table(header, accuracy_rows()))
    if args.part in ("speed", "all"):
        print(heading("Tiled builds on Dask", f"CityDrive {args.length:g} m, {args.scans} scans"))
        print(speed_section(args.length, args.scans))


if __name__ == "__main__":
    run_recorded(main, __file__)
