"""Kernel selection and hierarchy switched on and off (Sec. 3.1, 3.2, 3.4), in one process.

    python benchmarks/kernel_selection.py [--datasets virtual_room,warehouse,tum]

For each switch (planar_kernel, merge_coplanar; with 'nearest' features, whose search they
change, anisotropic_search and anchor_layers) against the defaults, on the held-out-rays
protocol at train fraction 0.8 (seed 0): the map learns the training rays scan by scan, and the
table gives clusters, map memory, total integrate time, query time for every test point, and
accuracy / F1 / ROC-AUC. On the synthetic scenes the same maps are also scored against the exact
occupancy, at points scattered 10 cm around the hits ("near") and uniform points where some ray
reached ("uniform"), as the held-out test rewards a boundary pushed in front of surfaces.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import RESOLUTION, heading
from results_file import run_recorded

import ehm
from ehm.eval.datasets import virtual_room, warehouse
from ehm.eval.datasets.real import DataMissingError, tum_fr2_pioneer_slam2
from ehm.eval.metrics import score
from ehm.eval.protocol import exact_test_points, held_out_rays
from ehm.pipeline import MappingPipeline

SWITCHES = {
    "defaults": {},
    "planar_kernel=True": {"planar_kernel": True},
    "merge_coplanar=True": {"merge_coplanar": True},
    "planar_kernel + merge_coplanar": {"planar_kernel": True, "merge_coplanar": True},
    # The nearest clusters' search (Sec. 3.4) serves the 'nearest' features alone.
    "features='nearest'": {"features": "nearest"},
    "nearest, anisotropic_search=True": {"features": "nearest", "anisotropic_search": True},
    "nearest, anchor_layers=2": {"features": "nearest", "anchor_layers": 2},
    "nearest, anchor_layers=3": {"features": "nearest", "anchor_layers": 3},
}


def datasets(names: list[str]):
    for name in names:
        if name == "virtual_room":
            yield name, virtual_room()
        elif name == "warehouse":
            yield name, warehouse()
        elif name == "tum":
            try:
                yield "tum_fr2_pioneer_slam2", tum_fr2_pioneer_slam2()
            except DataMissingError as missing:
                print(f"tum_fr2_pioneer_slam2 skipped: {missing}\n")
        else:
            raise SystemExit(f"unknown data set {name!r}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default="virtual_room,warehouse,tum")
    args = parser.parse_args()
    for features in ("support", "nearest"):  # compile
        ehm.HilbertMap(
            features=features,
            planar_kernel=True,
            merge_coplanar=True,
            anisotropic_search=True,
            anchor_layers=3,
        ).fit(virtual_room(rings=8, azimuths=100).scans)
    for name, data in datasets(args.datasets.split(",")):
        scans = data if isinstance(data, list) else data.scans
        split = held_out_rays(scans, 0.8, RESOLUTION, seed=0)
        rays = sum(len(s) for s in scans)
        print(heading(name, f"{len(scans)} scans, {rays} rays, train fraction 0.8, seed 0"))
        exact = None
        if not isinstance(data, list):
            scene = data.scene
            low, high = scene.box_min.min(axis=0), scene.box_max.max(axis=0)
            near, uniform = exact_test_points(
                split.train, low, high, 0.3, 100_000, 0.05, np.random.default_rng(5)
            )
            exact = (near, scene.occupied(near), uniform, scene.occupied(uniform))
        columns = (
            "| switch | clusters | memory MB | integrate s | query s | accuracy | F1 | ROC-AUC |"
        )
        rule = "|---|---:|---:|---:|---:|---:|---:|---:|"
        if exact is not None:
            columns += " near acc. | near AUC | uniform acc. | uniform AUC |"
            rule += "---:|---:|---:|---:|"
        print(f"{len(split.points)} held-out test points.\n")
        print(columns)
        print(rule)
        for switch, overrides in SWITCHES.items():
            run = MappingPipeline(split.train, ehm.HilbertMap(**overrides)).run()
            hilbert_map, build = run.hilbert_map, run.seconds
            start = time.perf_counter()
            probability = hilbert_map.occupancy(split.points)
            query = time.perf_counter() - start
            s = score(split.occupied, probability)
            row = (
                f"| {switch} | {hilbert_map.n_clusters} | {hilbert_map.memory_bytes() / 1e6:.2f} "
                f"| {build:.2f} | {query:.3f} | {s.accuracy:.3f} | {s.f1:.3f} | {s.auc:.3f} |"
            )
            if exact is not None:
                near, near_truth, uniform, uniform_truth = exact
                s_near = score(near_truth, hilbert_map.occupancy(near))
                s_uniform = score(uniform_truth, hilbert_map.occupancy(uniform))
                row += (
                    f" {s_near.accuracy:.3f} | {s_near.auc:.3f} | {s_uniform.accuracy:.3f} "
                    f"| {s_uniform.auc:.3f} |"
                )
            print(row, flush=True)
        print()


if __name__ == "__main__":
    run_recorded(main, __file__)
