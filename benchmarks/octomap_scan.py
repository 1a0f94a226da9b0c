"""EHM against OctoMap on OctoMap's sample scan (88,206 rays), in one process.

    python benchmarks/octomap_scan.py [--repeats 3]

Measures, at 0.05 m: integrate time per stage (the paper's Table 2) against OctoMap's
insertPointCloud; query time for 100,000 points against OctoMap's per-point search and its
vectorised getLabels; map memory against OctoMap's memoryUsage(); and accuracy, F1 and ROC-AUC
on the held-out-rays protocol at train fractions 0.8 / 0.6 / 0.4, for the defaults and for each
setting whose default these measurements decided, switched (benchmarks/common.py).
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np
from common import (
    RESOLUTION,
    heading,
    octomap_mapper,
    print_held_out_table,
    timed,
)
from results_file import run_recorded

import ehm
from ehm.eval.datasets.real import DataMissingError, octomap_scan
from ehm.eval.protocol import held_out_rays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    try:
        (scan,) = octomap_scan()
    except DataMissingError as missing:
        raise SystemExit(f"skipped: {missing}") from missing

    ehm.HilbertMap().integrate_scan(scan)  # compile the kernels once
    stage_runs = []

    def build_ehm():
        hilbert_map = ehm.HilbertMap().integrate_scan(scan)
        stage_runs.append(hilbert_map.timings_)
        return hilbert_map

    t_ehm, hilbert_map = timed(build_ehm, args.repeats)
    t_oct, octomap = timed(lambda: octomap_mapper(scan), args.repeats)
    tree = octomap.tree
    stages = {k: statistics.median(r[k] for r in stage_runs) for k in stage_runs[0]}

    rng = np.random.default_rng(0)
    split = held_out_rays([scan], 0.8, RESOLUTION, seed=0)
    queries = split.points[rng.choice(len(split.points), 100_000, replace=True)]
    hilbert_map.occupancy(queries[:10])
    tq_ehm, _ = timed(lambda: hilbert_map.occupancy(queries), args.repeats)
    tq_exact, _ = timed(lambda: hilbert_map.occupancy(queries, mode="exact"), args.repeats)
    tq_oct, _ = timed(lambda: octomap.occupancy(queries), args.repeats)
    tq_labels, _ = timed(lambda: tree.getLabels(queries), args.repeats)
    memory_ehm, memory_oct = hilbert_map.memory_bytes(), tree.memoryUsage()

    print(
        heading(
            "octomap_scan",
            f"{len(scan)} rays, resolution {RESOLUTION} m, median of {args.repeats}",
        )
    )
    print("| integrate stage (Table 2) | EHM ms |")
    print("|---|---:|")
    for stage, seconds in stages.items():
        print(f"| {stage} | {1000 * seconds:.0f} |")
    print(f"| **total** | **{1000 * sum(stages.values()):.0f}** |\n")
    print("| measure | EHM | OctoMap | ratio EHM/OctoMap | target |")
    print("|---|---:|---:|---:|---|")
    print(
        f"| build (integrate / insertPointCloud), s | {t_ehm:.3f} | {t_oct:.3f} | "
        f"{t_ehm / t_oct:.2f} | <= 0.5 |"
    )
    print(
        f"| query 100,000 points, s (EHM batch; OctoMap search per point) | {tq_ehm:.3f} | "
        f"{tq_oct:.3f} | {tq_ehm / tq_oct:.2f} | <= 1 |"
    )
    print(
        f"| query 100,000 points, s (EHM exact; OctoMap getLabels, labels only) | "
        f"{tq_exact:.3f} | {tq_labels:.3f} | {tq_exact / tq_labels:.2f} | |"
    )
    print(
        f"| memory, MB | {memory_ehm / 1e6:.2f} | {memory_oct / 1e6:.2f} | "
        f"{memory_ehm / memory_oct:.3f} | <= 0.1 |"
    )
    print(f"| clusters / OctoMap nodes | {hilbert_map.n_clusters} | {tree.size()} | | |\n")

    print_held_out_table([scan])


if __name__ == "__main__":
    run_recorded(main, __file__)
