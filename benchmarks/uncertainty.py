"""The occupancy's std (`return_std`): calibrated, high where unseen, low at surfaces; its cost.

    python benchmarks/uncertainty.py [--seeds 0,1,2] [--fractions 0.8,0.4] [--datasets ...]

For each data set, train fraction and seed, the map is learned scan by scan from the training
rays of one held-out-rays split (DESIGN.md), at the data set's resolution (0.05 m, on the
street 0.2 m). Then:
- calibration: the held-out test points in four groups by predicted std (quartiles), and the
  error rate of the occupancy at p = 0.5 in each (a point the map knows nothing of, p exactly
  0.5, counts as half an error: a guess): it should rise with the std;
- observed surfaces: mean std at the training hits;
- never observed: mean std at points uniform in the box of the training hits (grown by 10 %
  on each side) that no training ray reached (0.05 m past its end);
- cost: query time of the held-out points with the std against without it.
Prints one markdown table, mean over seeds.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table, sweep_arguments
from results_file import run_recorded

import ehm
from ehm.eval.datasets import DataMissingError, load_dataset
from ehm.eval.protocol import held_out_rays, observed_mask
from ehm.pipeline import MappingPipeline

DATASETS = (
    "virtual_room",
    "warehouse",
    "street",
    "tum_fr2_pioneer_slam2",
    "pcl_room",
    "intel_lab",
)
COLUMNS = (
    "error by std quartile",
    "std at surfaces",
    "std never observed",
    "ratio",
    "query s",
    "with std s",
)


def never_observed_points(scans: list[ehm.Scan], n: int, rng: np.random.Generator) -> np.ndarray:
    """Points uniform in the box of the hits of `scans` (10 % larger on each side) that no ray
    of `scans` reached."""
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    low, high = hits.min(axis=0), hits.max(axis=0)
    margin = 0.1 * (high - low)
    points = rng.uniform(low - margin, high + margin, (n, hits.shape[1]))
    return points[~observed_mask(scans, points, 0.05)]


def measure(
    scans: list[ehm.Scan], resolution: float, fraction: float, seed: int
) -> dict[str, object]:
    """The measures of COLUMNS for one split."""
    split = held_out_rays(scans, fraction, resolution, seed)
    config = ehm.MapConfig.for_resolution(resolution, seed=seed)
    hilbert_map = MappingPipeline(split.train, ehm.HilbertMap(config)).run().hilbert_map
    start = time.perf_counter()
    hilbert_map.occupancy(split.points)
    query_s = time.perf_counter() - start
    start = time.perf_counter()
    p, std = hilbert_map.occupancy(split.points, return_std=True)
    with_std_s = time.perf_counter() - start
    wrong = np.where(p == 0.5, 0.5, (p > 0.5) != split.occupied)
    quartile = np.digitize(std, np.quantile(std, [0.25, 0.5, 0.75]))
    hits = np.concatenate([s.points_world[s.hit_mask] for s in split.train])
    _, std_hits = hilbert_map.occupancy(hits, return_std=True)
    never = never_observed_points(split.train, 50_000, np.random.default_rng(seed))
    _, std_never = hilbert_map.occupancy(never, return_std=True)
    return {
        "error by std quartile": np.array([wrong[quartile == q].mean() for q in range(4)]),
        "std at surfaces": float(std_hits.mean()),
        "std never observed": float(std_never.mean()),
        "ratio": float(std_never.mean() / std_hits.mean()),
        "query s": query_s,
        "with std s": with_std_s,
    }


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS)
    seeds, fractions, names = sweep.seeds, sweep.fractions, sweep.datasets
    rows = []
    for name in names:
        try:
            scans = load_dataset(name)
        except DataMissingError as missing:
            print(f"skipped {name}: {missing}")
            continue
        for fraction in fractions:
            resolution = RESOLUTIONS.get(name, RESOLUTION)
            runs = [measure(scans, resolution, fraction, seed) for seed in seeds]
            mean = {c: np.mean([run[c] for run in runs], axis=0) for c in COLUMNS}
            rows.append(
                [
                    name,
                    f"{fraction:.0%}",
                    " / ".join(f"{e:.3f}" for e in mean["error by std quartile"]),
                    *(f"{mean[c]:.3f}" for c in COLUMNS[1:4]),
                    f"{mean['query s']:.2f}",
                    f"{mean['with std s']:.2f}",
                ]
            )
            print(" | ".join(rows[-1]), file=sys.stderr, flush=True)  # progress
    print(heading("Uncertainty", f"seeds {seeds}, train fractions {fractions}, scan by scan"))
    print(markdown_table(["data set", "train", *COLUMNS], rows, text_columns=3))


if __name__ == "__main__":
    run_recorded(main, __file__)
