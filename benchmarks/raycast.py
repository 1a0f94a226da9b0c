"""Ray casting: EHM's `raycast` against OctoMap's `castRay`, on the same rays, in one process.

    python benchmarks/raycast.py [--rays 100000] [--set features=support ...]

Each data set is mapped whole by both (EHM with the defaults or the `--set` overrides,
OctoMap at 0.05 m with every hit inserted); then up to `rays` of its own rays are cast from
their sensor origins, out to 30 m, twice by EHM: the first call makes the grid of log-odds
rays march first, the second finds it kept (a planner casting rays again between map
updates). A third cast comes right after the map learned its last scan (a map learned scan
by scan, a lone scan in two halves): the grid made by a cast before that update followed it.
The distance each returns is compared with the exact surface (the simulated warehouse) or
with the range the sensor measured (OctoMap's sample scan). EHM's rays stop where the map has
no evidence (its default) and, once more, pass through it (`unknown="free"`). OctoMap is
called once per ray through octomap-python, the way a Python planner would, twice: stopping
at unknown voxels (`ignoreUnknownCells=False`, its default) and passing through them.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import (
    RESOLUTION,
    add_settings_argument,
    heading,
    markdown_table,
    octomap_mapper,
    settings_of,
    settings_text,
)
from results_file import run_recorded

import ehm
from ehm.core.sensor.scan import Scan
from ehm.eval.datasets import DataMissingError, load_dataset, virtual_room, warehouse

MAX_RANGE = 30.0


def sample_rays(scans: list[Scan], n: int, rng: np.random.Generator):
    """Origins (n, 3), unit directions (n, 3) and the measured ranges (n,) of up to `n` of
    the scans' hit rays."""
    origins = np.concatenate([np.broadcast_to(s.origin, (int(s.hit_mask.sum()), 3)) for s in scans])
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    chosen = rng.choice(len(hits), min(n, len(hits)), replace=False)
    offsets = hits[chosen] - origins[chosen]
    ranges = np.linalg.norm(offsets, axis=1)
    return origins[chosen], offsets / ranges[:, None], ranges


def octomap_cast(tree, origins, directions, ignore_unknown: bool) -> np.ndarray:
    """(n,) distance to the voxel castRay stops at (inf where it returns False)."""
    end = np.zeros(3)
    distance = np.full(len(origins), np.inf)
    for i in range(len(origins)):
        if tree.castRay(origins[i], directions[i], end, ignore_unknown, MAX_RANGE):
            distance[i] = np.linalg.norm(end - origins[i])
    return distance


def row(name: str, distance: np.ndarray, reference: np.ndarray, seconds: float, base: float):
    hit = np.isfinite(distance)
    error = np.abs(distance - reference)[hit]
    return [
        name,
        f"{hit.mean():.3f}",
        f"{np.median(error):.3f}" if len(error) else "",
        f"{np.percentile(error, 90):.3f}" if len(error) else "",
        f"{seconds:.2f}",
        f"{seconds / base:.2f}",
    ]


def halves(scan: Scan) -> list[Scan]:
    """A lone scan as two, its rays alternately in one and the other."""
    return [
        Scan(scan.points_world[part::2], scan.origin, scan.hit_mask[part::2]) for part in (0, 1)
    ]


def after_update(
    scans: list[Scan], origins, directions, settings: dict
) -> tuple[np.ndarray, float, float, float]:
    """Rays cast right after the map learned its last scan, with the grid made before it:
    (distances, seconds of the cast, seconds the update spent bringing the grid up to date,
    seconds of the same cast again, nothing changed since). The map (MapConfig overrides
    `settings`) learns scan by scan (a lone scan in two halves)."""
    parts = scans if len(scans) > 1 else halves(scans[0])
    hilbert_map = ehm.HilbertMap(**settings, batch_rays=0)
    for scan in parts[:-1]:
        hilbert_map.integrate_scan(scan)
    hilbert_map.raycast(origins, directions, MAX_RANGE)  # the planner's earlier cast
    hilbert_map.integrate_scan(parts[-1])
    seconds = []
    for _ in range(2):
        start = time.perf_counter()
        distance = hilbert_map.raycast(origins, directions, MAX_RANGE)
        seconds.append(time.perf_counter() - start)
    return distance, seconds[0], hilbert_map.timings_["grids"], seconds[1]


def compile_kernels(settings: dict) -> None:
    """Cast a few rays through a small map, so that no timing below includes compiling."""
    room = ehm.HilbertMap(**settings).fit(virtual_room().scans)
    room.raycast(np.zeros(3), np.eye(3), 5.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=100_000)
    add_settings_argument(parser)
    args = parser.parse_args()
    settings = settings_of(args)
    rng = np.random.default_rng(0)
    compile_kernels(settings)
    data_sets = {"warehouse": lambda: warehouse()}
    data_sets["octomap_scan"] = lambda: load_dataset("octomap_scan")
    for name, load in data_sets.items():
        try:
            loaded = load()
        except DataMissingError as missing:
            print(f"skipped {name}: {missing}")
            continue
        scans = loaded.scans if hasattr(loaded, "scans") else loaded
        origins, directions, measured = sample_rays(scans, args.rays, rng)
        reference, against = measured, "measured range"
        if hasattr(loaded, "scene"):
            reference = np.array(
                [
                    loaded.scene.raycast(o, d[None])[0]
                    for o, d in zip(origins, directions, strict=True)
                ]
            )
            against = "exact surface"
        hilbert_map = ehm.HilbertMap(**settings).fit(scans)
        octomap = octomap_mapper(scans[0], RESOLUTION)
        for scan in scans[1:]:
            octomap.insert(scan)
        first_s, ours_s = [], []
        for timings in (first_s, ours_s):
            start = time.perf_counter()
            ours = hilbert_map.raycast(origins, directions, MAX_RANGE)
            timings.append(time.perf_counter() - start)
        rows = []
        timings = {}
        for ignore in (False, True):
            start = time.perf_counter()
            cast = octomap_cast(octomap.tree, origins, directions, ignore)
            timings[ignore] = (cast, time.perf_counter() - start)
        base = timings[False][1]
        rows.append(
            row("EHM raycast, first call (makes the grid)", ours, reference, first_s[0], base)
        )
        rows.append(row("EHM raycast, grid kept", ours, reference, ours_s[0], base))
        start = time.perf_counter()
        passing = hilbert_map.raycast(origins, directions, MAX_RANGE, unknown="free")
        passing_s = time.perf_counter() - start
        rows.append(
            row("EHM raycast, grid kept, passing unknown", passing, reference, passing_s, base)
        )
        after, after_s, grids_s, again_s = after_update(scans, origins, directions, settings)
        rows.append(
            row(
                f"EHM scan by scan: raycast right after an update (that kept the grid in "
                f"{grids_s:.2f} s)", after, reference, after_s, base,
            )
        )  # fmt: skip
        rows.append(row("EHM scan by scan: the same cast again", after, reference, again_s, base))
        for ignore, (cast, seconds) in timings.items():
            label = "passing unknown" if ignore else "stopping at unknown"
            rows.append(row(f"OctoMap castRay, {label}", cast, reference, seconds, base))
        detail = f"{len(origins):,} of its rays, errors against the {against}"
        detail += settings_text(settings)
        print(heading(f"Ray casting: {name}", detail))
        columns = ["method", "rays that hit", "median error m", "90 % error m", "seconds"]
        print(markdown_table([*columns, "time / OctoMap's"], rows))


if __name__ == "__main__":
    run_recorded(main, __file__)
