"""EHM against OctoMap on the simulated virtual room, scored against its exact occupancy.

    python benchmarks/virtual_room.py

One simulated scan (89,984 rays). Test points are scored against the scene's exact
occupancy where some ray reached (up to 5 cm past a ray's end): points scattered 10 cm around
the hits ("near surfaces") and uniform points in the room ("uniform"). The held-out-rays
protocol at 0.8 / 0.6 / 0.4 is reported beside it: the design brief asks for both, since
held-out hits reward a boundary pushed in front of surfaces and exact occupancy punishes it.
"""

from __future__ import annotations

import time

import numpy as np
from common import (
    RESOLUTION,
    VARIANTS,
    build_variant,
    heading,
    octomap_mapper,
    print_held_out_table,
)
from results_file import run_recorded

from ehm.eval.datasets import virtual_room
from ehm.eval.metrics import score
from ehm.eval.protocol import exact_test_points


def main() -> None:
    data = virtual_room()
    (scan,) = data.scans
    low, high = data.scene.box_min.min(axis=0), data.scene.box_max.max(axis=0)
    near, uniform = exact_test_points(
        data.scans, low, high, 0.3, 60_000, 0.05, np.random.default_rng(5)
    )
    truth = {"near": data.scene.occupied(near), "uniform": data.scene.occupied(uniform)}
    print(heading("virtual_room", f"{len(scan)} rays, resolution {RESOLUTION} m"))
    print(
        f"Exact occupancy: {len(near)} points near surfaces "
        f"({truth['near'].mean():.0%} occupied), {len(uniform)} uniform "
        f"({truth['uniform'].mean():.1%} occupied).\n"
    )
    print(
        "| method | near accuracy | near F1 | near ROC-AUC | uniform accuracy | "
        "uniform ROC-AUC | build s |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")

    def exact_row(name: str, occupancy, build: float) -> None:
        s_near = score(truth["near"], occupancy(near))
        s_uniform = score(truth["uniform"], occupancy(uniform))
        print(
            f"| {name} | {s_near.accuracy:.3f} | {s_near.f1:.3f} | {s_near.auc:.3f} | "
            f"{s_uniform.accuracy:.3f} | {s_uniform.auc:.3f} | {build:.2f} |"
        )

    start = time.perf_counter()
    octomap = octomap_mapper(scan)
    exact_row("OctoMap", octomap.occupancy, time.perf_counter() - start)
    build_variant({}, scan, halves=False)  # compile the kernels once
    for name, overrides in VARIANTS.items():
        start = time.perf_counter()
        hilbert_map = build_variant(overrides, scan, halves=False)
        exact_row(name, hilbert_map.occupancy, time.perf_counter() - start)

    print()
    print_held_out_table(data.scans)


if __name__ == "__main__":
    run_recorded(main, __file__)
