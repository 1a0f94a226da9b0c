"""Time per scan as the map grows: EHM scan by scan and OctoMap's insertPointCloud, same scans.

    python benchmarks/scan_times.py [--datasets corridor_2d,intel_lab,...] [--set name=value]

corridor_2d is a generated 100 m office floor scanned 2,000 times by a 2D laser of 180 rays
as a robot drives along it: a map that keeps growing. warehouse_drive is 200 LiDAR scans of
16 x 512 rays on two laps round the warehouse's shelving: a map whose places are passed
again. EHM learns each batch of `MapConfig.batch_rays` rays as one, shared by its scans.
Prints a markdown table and draws benchmarks/figures/scan_times.png (with --set, not
drawn).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from common import (
    RESOLUTION,
    add_settings_argument,
    heading,
    markdown_table,
    settings_of,
    settings_text,
)
from results_file import run_recorded

import ehm
from ehm.core.sensor.scan import Scan
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset, warehouse
from ehm.eval.datasets.simulated import corridor_2d, warehouse_drive
from ehm.eval.plots import scan_time_plot
from ehm.pipeline import MappingPipeline

HERE = Path(__file__).resolve().parent
LOADERS = {
    "corridor_2d": lambda: corridor_2d().scans,
    "intel_lab": lambda: load_dataset("intel_lab"),
    "tum_fr2_pioneer_slam2": lambda: load_dataset("tum_fr2_pioneer_slam2"),
    "warehouse": lambda: warehouse().scans,
    "warehouse_drive": lambda: warehouse_drive().scans,
}


def octomap_scan_seconds(scans: list[Scan]) -> np.ndarray:
    """(n,) seconds of each scan's insertPointCloud into one OcTree at RESOLUTION."""
    mapper = OctoMapMapper(RESOLUTION)
    mapper.build([])
    seconds = []
    for scan in scans:
        start = time.perf_counter()
        mapper.insert(scan)
        seconds.append(time.perf_counter() - start)
    return np.array(seconds)


def tenth_means(seconds: np.ndarray) -> tuple[float, float]:
    """Mean milliseconds of the second and the last tenth of the scans (the first tenth
    holds EHM's first batch, which has no past samples to replay)."""
    tenth = max(1, len(seconds) // 10)
    return 1e3 * seconds[tenth : 2 * tenth].mean(), 1e3 * seconds[-tenth:].mean()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=",".join(LOADERS))
    add_settings_argument(parser)
    args = parser.parse_args()
    settings = settings_of(args)
    # Compile every kernel before timing.
    MappingPipeline(corridor_2d(n_scans=20, length=10.0).scans, ehm.HilbertMap()).run()
    seconds, rows = {}, []
    for name in args.datasets.split(","):
        try:
            scans = LOADERS[name]()
        except DataMissingError as error:
            print(f"Left out {name}: {error}\n")
            continue
        run = MappingPipeline(scans, ehm.HilbertMap(**settings)).run()
        ours = run.amortized_scan_seconds()
        theirs = octomap_scan_seconds(scans)
        seconds[name] = {"EHM (batch time shared by its scans)": ours, "OctoMap": theirs}
        ours_first, ours_last = tenth_means(ours)
        theirs_first, theirs_last = tenth_means(theirs)
        rows.append(
            [
                name,
                f"{len(scans):,}",
                f"{run.n_rays // len(scans):,}",
                f"{len(run.batch_scans):,}",
                f"{1e3 * ours[: run.batch_scans[0]].mean():.2f}",
                f"{ours_first:.2f} / {ours_last:.2f} ({ours_last / ours_first:.2f}x)",
                f"{theirs_first:.2f} / {theirs_last:.2f} ({theirs_last / theirs_first:.2f}x)",
                f"{ours.sum():.2f} / {theirs.sum():.2f} ({ours.sum() / theirs.sum():.2f})",
            ]
        )
    print(heading("Time per scan", f"EHM and OctoMap in one process{settings_text(settings)}"))
    header = ["sequence", "scans", "rays per scan", "EHM batches", "EHM ms, first batch"]
    header += ["EHM ms, second / last 10 %", "OctoMap ms, second / last 10 %"]
    header += ["total s, EHM / OctoMap"]
    print(markdown_table(header, rows))
    if not settings:
        scan_time_plot(seconds, HERE / "figures" / "scan_times.png")


if __name__ == "__main__":
    run_recorded(main, __file__)
