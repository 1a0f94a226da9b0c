"""Shared pieces of the benchmark scripts: OctoMap as the reference, timing, EHM variants."""

from __future__ import annotations

import platform
import statistics
import time
from collections.abc import Callable
from datetime import date
from typing import Any

import numpy as np

import ehm

RESOLUTION = 0.05

# EHM settings whose defaults were decided by these benchmarks, each against the default.
VARIANTS: dict[str, dict[str, Any]] = {
    "EHM": {},
    "EHM, intercept in queries": {"query_intercept": True},
    "EHM, no coarse neighbours": {"coarse_neighbours": 0},
    "EHM, occupied_depth=0.05": {"occupied_depth": 0.05},
    "EHM, balance_classes=True": {"balance_classes": True},
    "EHM, samples clustered together": {"cluster_free_apart": False},
}
# Merge rules only act between scans: these variants learn the training rays as two scans.
MERGE_VARIANTS: dict[str, dict[str, Any]] = {
    "EHM, paper's average merge (2 halves)": {"merge_rule": "average"},
    "EHM, pooled merge (2 halves)": {"merge_rule": "pooled"},
}


def octomap_tree(scan: ehm.Scan, resolution: float = RESOLUTION):
    """An OcTree with `scan` inserted (hits only; no-return rays are left out)."""
    try:
        import octomap
    except ImportError as error:
        raise SystemExit("OctoMap bindings missing: pip install 'ehm[octomap]'") from error
    tree = octomap.OcTree(resolution)
    tree.insertPointCloud(scan.points_world[scan.hit_mask], scan.origin)
    return tree


def octomap_probabilities(tree, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Occupancy of each point's voxel; unknown voxels are 0.5 (and flagged)."""
    import octomap

    probability = np.full(len(points), 0.5)
    unknown = np.ones(len(points), dtype=bool)
    for i, point in enumerate(points):
        try:
            probability[i] = tree.search(point).getOccupancy()
            unknown[i] = False
        except octomap.NullPointerException:
            pass
    return probability, unknown


def timed(function: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Median seconds over `repeats` runs, and the last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def build_variant(overrides: dict[str, Any], train: ehm.Scan, halves: bool) -> ehm.HilbertMap:
    """An EHM with `overrides` learned from `train`, as one scan or as two halves."""
    hilbert_map = ehm.HilbertMap(**overrides)
    if halves:
        rays = np.arange(len(train))
        hilbert_map.integrate_scan(train.subset(rays % 2 == 0))
        hilbert_map.integrate_scan(train.subset(rays % 2 == 1))
    else:
        hilbert_map.integrate_scan(train)
    return hilbert_map


def heading(name: str, detail: str) -> str:
    return f"## {name}, {date.today()}, {platform.processor() or platform.machine()}, {detail}\n"
