"""Stray returns in open space: how many read occupied after mapping, EHM against OctoMap.

    python benchmarks/stray_returns.py [--seeds 0,1,2] [--datasets street,hillside,...]
                                       [--share 0.01]

A LiDAR's or a depth camera's stray returns (dust, rain, the mixed pixel at an edge) are lone
hits in open space, as a wire's are: one return each, no neighbour on a surface. In every scan
of each simulated scene, a `share` of the hits is moved to a point uniform from 20 to 80 % of
the way along its ray, and the scans are mapped as they come at the scene's resolution by EHM
with its defaults (`min_hit_cluster_size` 2: one hit and its sample behind make a cluster), by
EHM with clusters of hits at the weight of every other cluster (4) and by OctoMap. Measured at
the moved points that lie in free space (the scene's exact occupancy): the share read occupied
(above 0.5) at the end, of the last scan's and of earlier scans' (which later rays may have
passed), and of the scans' other hits, the share read occupied. Mean over seeds.
"""

from __future__ import annotations

import argparse

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table
from online_mapping import SIMULATED
from peers import mapper_of, warm_up
from results_file import run_recorded

import ehm
from ehm.eval.datasets.simulated import SimulatedDataset

SCENES = ("street", "hillside", "power_lines", "dense_room", "virtual_room")
METHODS = {"ehm": {}, "ehm, min_hit_cluster_size 4": {"min_hit_cluster_size": 4}, "octomap": {}}
# Where along its ray a stray return lies, as a share of the ray's length.
ALONG = (0.2, 0.8)
# Hits of the scans read back per scene and seed (a sample, for time).
HITS_READ = 20_000
MEASURES = (
    "strays read occupied",
    "of the last scan",
    "of earlier scans",
    "other hits read occupied",
)


def with_strays(
    scans: list[ehm.Scan], share: float, rng: np.random.Generator
) -> tuple[list[ehm.Scan], np.ndarray, np.ndarray, np.ndarray]:
    """The scans with `share` of each one's hits moved along their rays (ALONG): (scans, the
    moved points (m, d) metres, world frame, the scan each came from (m,) int64, the hits left
    where they were (k, d))."""
    moved, strays, scan_of, kept = [], [], [], []
    for index, scan in enumerate(scans):
        points = scan.points_world.copy()
        picked = np.flatnonzero(scan.hit_mask & (rng.random(len(points)) < share))
        along = rng.uniform(*ALONG, len(picked))[:, None]
        points[picked] = scan.origin + (points[picked] - scan.origin) * along
        moved.append(ehm.Scan(points, scan.origin, scan.hit_mask, scan.time))
        strays.append(points[picked])
        scan_of.append(np.full(len(picked), index))
        left = scan.hit_mask.copy()
        left[picked] = False
        kept.append(points[left])
    return moved, np.concatenate(strays), np.concatenate(scan_of), np.concatenate(kept)


def measure(
    data: SimulatedDataset, resolution: float, share: float, seed: int
) -> dict[str, list[float]]:
    """Per method: strays in free space read occupied (all, the last scan's, earlier scans'),
    the other hits read occupied, for a simulated scene's `data` (scans and scene) mapped at
    `resolution` metres."""
    rng = np.random.default_rng(seed)
    scans, strays, scan_of, kept = with_strays(data.scans, share, rng)
    in_free = ~data.scene.occupied(strays)
    last = scan_of == len(scans) - 1
    hits = kept[rng.choice(len(kept), min(HITS_READ, len(kept)), replace=False)]
    found = {}
    for method, settings in METHODS.items():
        mapper = mapper_of(method.split(",")[0], resolution, seed, settings)
        mapper.build(scans)
        occupied = mapper.occupancy(strays) > 0.5
        found[method] = [
            share_of(occupied, in_free),
            share_of(occupied, in_free & last),
            share_of(occupied, in_free & ~last),
            float(np.mean(mapper.occupancy(hits) > 0.5)),
        ]
    return found


def share_of(flags: np.ndarray, rows: np.ndarray) -> float:
    """The share of `flags` (n,) bool set among `rows` (n,) bool; NaN where there are none
    (a scene of one scan has no earlier scans)."""
    return float(flags[rows].mean()) if rows.any() else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--datasets", default=",".join(SCENES))
    parser.add_argument("--share", type=float, default=0.01)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    names = args.datasets.split(",")
    unknown = sorted(set(names) - set(SIMULATED))
    if unknown:
        raise SystemExit(f"unknown scene(s) {', '.join(unknown)}; known: {', '.join(SIMULATED)}")
    print(heading("Stray returns", f"seeds {seeds}, {args.share:.0%} of each scan's hits"))
    for method, settings in METHODS.items():
        warm_up(method.split(",")[0], 3, settings)
    rows = []
    for name in names:
        data, resolution = SIMULATED[name](), RESOLUTIONS.get(name, RESOLUTION)
        runs = [measure(data, resolution, args.share, seed) for seed in seeds]
        for method in METHODS:
            means = np.mean([run[method] for run in runs], axis=0)
            rows.append([name, method, *("" if np.isnan(v) else f"{v:.3f}" for v in means)])
    print(markdown_table(["scene", "method", *MEASURES], rows, text_columns=2))


if __name__ == "__main__":
    run_recorded(main, __file__)
