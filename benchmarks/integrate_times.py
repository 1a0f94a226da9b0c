"""One integrate, stage by stage, in both profiles, beside OctoMap's insertPointCloud.

    python benchmarks/integrate_times.py [--repeats 5] [--set features=support ...]

The scans: OctoMap's sample scan (88,206 rays, 0.05 m), a TUM depth frame (0.05 m) and a sweep
of the simulated street's 32-ring LiDAR (0.2 m), in both profiles of MapConfig.for_resolution,
each against its own targets.

A scan of a sequence is learned into the map of the scans before it, as a robot's would be:
each scan after the first is timed once (the sequence `repeats` times over, in fresh maps);
the sample scan, alone, is learned `repeats` times into a fresh map. Kernels are compiled
before any timing. Prints one markdown table of milliseconds: the median integrate with its
stages, and the worst one (a scan late in a sequence, or a slow moment of the machine);
OctoMap's insertPointCloud of the same scans is given by its median too. Each integrate is
timed again on one thread (ONE_THREAD_REPEATS times over): its median against the median on
all of Numba's threads is the speed-up the machine's cores give.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numba
from common import add_settings_argument, heading, markdown_table, settings_of, settings_text
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset, street

STAGES = (
    "samples", "memory_lookup", "forgetting", "clustering", "merging", "features", "sgd",
    "memory_insert",
)  # fmt: skip


@dataclass(frozen=True)
class Case:
    """A data set, the map detail it is learned at (metres) and the target time of each
    profile (ms; none where a profile has none)."""

    name: str
    scans: Callable[[], list[ehm.Scan]]
    resolution: float
    target_ms: dict[str, float]


PROFILES = ("default", "realtime")
# Repeats of each integrate on one thread, for the speed-up the machine's threads give.
ONE_THREAD_REPEATS = 3
CASES = (
    Case(
        "octomap_scan",
        lambda: load_dataset("octomap_scan"),
        0.05,
        {"default": 250.0, "realtime": 100.0},
    ),
    Case(
        "tum_fr2_pioneer_slam2",
        lambda: load_dataset("tum_fr2_pioneer_slam2"),
        0.05,
        {"realtime": 100.0},
    ),
    Case("street", lambda: street().scans, 0.2, {"realtime": 50.0}),
)


def ehm_times(scans: list[ehm.Scan], config: ehm.MapConfig, repeats: int) -> list[dict[str, float]]:
    """Seconds of each timed integrate: 'total' and the map's stage timings."""
    runs = []
    if len(scans) == 1:
        for _ in range(repeats):
            hilbert_map = ehm.HilbertMap(config)
            start = time.perf_counter()
            hilbert_map.integrate_scan(scans[0])
            runs.append({"total": time.perf_counter() - start, **hilbert_map.timings_})
        return runs
    for _ in range(repeats):
        hilbert_map = ehm.HilbertMap(config).integrate_scan(scans[0])
        for scan in scans[1:]:
            start = time.perf_counter()
            hilbert_map.integrate_scan(scan)
            runs.append({"total": time.perf_counter() - start, **hilbert_map.timings_})
    return runs


def one_thread_times(scans: list[ehm.Scan], config: ehm.MapConfig) -> list[dict[str, float]]:
    """ehm_times with every parallel loop, thread pool and tree search on one thread,
    ONE_THREAD_REPEATS repeats (the threads are set back after)."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return ehm_times(scans, config, ONE_THREAD_REPEATS)
    finally:
        numba.set_num_threads(threads)


def octomap_times(scans: list[ehm.Scan], resolution: float, repeats: int) -> list[float]:
    """Seconds of OctoMap's insertPointCloud of the scans ehm_times times, into the same
    maps (a fresh tree for a lone scan, the tree of the scans before for a sequence)."""
    seconds = []
    for _ in range(repeats):
        mapper = OctoMapMapper(resolution)
        mapper.build(scans[:1] if len(scans) > 1 else [])
        for scan in scans[1:] if len(scans) > 1 else scans:
            start = time.perf_counter()
            mapper.insert(scan)
            seconds.append(time.perf_counter() - start)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    add_settings_argument(parser)
    args = parser.parse_args()
    settings = settings_of(args)
    rows = []
    for case in CASES:
        try:
            scans = case.scans()
        except DataMissingError as missing:
            print(f"skipped {case.name}: {missing}")
            continue
        octomap = 1e3 * statistics.median(octomap_times(scans, case.resolution, args.repeats))
        for profile in PROFILES:
            config = ehm.MapConfig.for_resolution(case.resolution, profile, **settings)
            # Compile: a second scan meets the first's evidence, so the memory's and the
            # passes' kernels compile too (a lone scan is learned twice).
            ehm.HilbertMap(config).integrate_scan(scans[0]).integrate_scan(scans[-1]).flush()
            runs = sorted(ehm_times(scans, config, args.repeats), key=lambda run: run["total"])
            median = {key: 1e3 * value for key, value in runs[(len(runs) - 1) // 2].items()}
            one = 1e3 * statistics.median(run["total"] for run in one_thread_times(scans, config))
            rest = median["total"] - sum(median.get(stage, 0.0) for stage in STAGES)
            target = case.target_ms.get(profile)
            rows.append(
                [
                    case.name,
                    profile,
                    f"{len(scans[-1]):,}",
                    f"{median['total']:.0f}",
                    f"{1e3 * runs[-1]['total']:.0f}",
                    "" if target is None else f"{target:.0f}",
                    f"{octomap:.0f}",
                    f"{median['total'] / octomap:.2f}",
                    f"{one:.0f}",
                    f"{one / median['total']:.2f}x",
                    *(f"{median.get(stage, 0.0):.0f}" for stage in STAGES),
                    f"{rest:.0f}",
                ]
            )
    header = [
        "data set",
        "profile",
        "rays",
        "median ms",
        "worst ms",
        "target ms",
        "OctoMap ms",
        "/ OctoMap",
        "one thread ms",
        f"{numba.get_num_threads()} threads' speed-up",
    ]
    detail = f"median of {args.repeats} repeats and its stages, the worst{settings_text(settings)}"
    print(heading("Integrate times", detail))
    print(markdown_table([*header, *STAGES, "other"], rows, text_columns=2))


if __name__ == "__main__":
    run_recorded(main, __file__)
