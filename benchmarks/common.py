"""Shared pieces of the benchmark scripts: OctoMap as the reference, timing, EHM variants."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np

import ehm
from ehm.cli.app import parse_settings
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.metrics import score
from ehm.eval.protocol import held_out_rays
from ehm.pipeline import MappingPipeline

# The shared data folder beside the project's checkout, wherever the scripts run from.
os.environ.setdefault("EHM_DATA_DIR", str(Path(__file__).resolve().parents[2] / "shared" / "data"))

RESOLUTION = 0.05
# Map detail per data set where it is not RESOLUTION, metres: OctoMap's voxel side, EHM's
# MapConfig.for_resolution and the held-out split's margin. Outdoor LiDAR out to 40 m is
# mapped at 0.2 m (at 0.05 m OctoMap's held-out F1 on the street is 0.27: voxels that far out
# are seldom hit twice); the long-range scans to 30 m, the hillside and the power lines (to
# 40 m) at 0.1 m.
RESOLUTIONS = {"street": 0.2, "outdoor_lidar": 0.1, "hillside": 0.1, "power_lines": 0.1}

# EHM settings whose defaults were decided by these benchmarks, each against the default.
VARIANTS: dict[str, dict[str, Any]] = {
    "EHM": {},
    "EHM, intercept in queries": {"query_intercept": True},
    "EHM, nearest kernels (Alg. 3)": {"features": "nearest"},
    "EHM, nearest, no coarse neighbours": {"features": "nearest", "coarse_neighbours": 0},
    "EHM, nearest, coarse_neighbours=8": {"features": "nearest", "coarse_neighbours": 8},
    "EHM, occupied_depth=0.05": {"occupied_depth": 0.05},
    "EHM, balance_classes=True": {"balance_classes": True},
    "EHM, samples clustered together": {"cluster_free_apart": False},
}
# Merge rules only act between scans: these variants learn the training rays as two scans,
# each as it comes.
MERGE_VARIANTS: dict[str, dict[str, Any]] = {
    "EHM, paper's average merge (2 halves)": {"merge_rule": "average", "batch_rays": 0},
    "EHM, pooled merge (2 halves)": {"merge_rule": "pooled", "batch_rays": 0},
}


def octomap_mapper(scan: ehm.Scan, resolution: float = RESOLUTION) -> OctoMapMapper:
    """OctoMap with `scan`'s hits inserted (no-return rays are left out); `.tree` is the
    OcTree, `.occupancy(points)` reads 0.5 in unknown voxels."""
    try:
        mapper = OctoMapMapper(resolution)
    except ImportError as error:
        raise SystemExit(str(error)) from error
    mapper.build([scan])
    return mapper


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
    rays = np.arange(len(train))
    scans = [train.subset(rays % 2 == part) for part in (0, 1)] if halves else [train]
    return MappingPipeline(scans, ehm.HilbertMap(**overrides)).run().hilbert_map


def heading(name: str, detail: str) -> str:
    return f"## {name}, {date.today()}, {platform.processor() or platform.machine()}, {detail}\n"


# Train fractions of the held-out table, the first also scored by ROC-AUC, time and size.
HELD_OUT_FRACTIONS = (0.8, 0.6, 0.4)


def print_held_out_table(scans: list[ehm.Scan]) -> None:
    """Markdown table of the held-out-rays protocol (seed 0), OctoMap and every EHM variant on
    the same splits, one row each: F1 at each of HELD_OUT_FRACTIONS, and at the first also
    ROC-AUC, the share of test points left unknown, build seconds and clusters. The variants
    learn the training rays of the first scan only, as one scan or as two halves."""
    f1: dict[str, list[str]] = {}
    at_first: dict[str, list[str]] = {}
    for fraction in HELD_OUT_FRACTIONS:
        split = held_out_rays(scans, fraction, RESOLUTION, seed=0)
        train = split.train[0]
        start = time.perf_counter()
        octomap = octomap_mapper(train)
        build = time.perf_counter() - start
        built = {"OctoMap": (octomap.occupancy(split.points), build, "")}
        for name, overrides in {**VARIANTS, **MERGE_VARIANTS}.items():
            start = time.perf_counter()
            hilbert_map = build_variant(overrides, train, halves=name in MERGE_VARIANTS)
            build = time.perf_counter() - start
            built[name] = (hilbert_map.occupancy(split.points), build, hilbert_map.n_clusters)
        for name, (probability, build, clusters) in built.items():
            unknown = probability == 0.5 if name == "OctoMap" else None
            s = score(split.occupied, probability, unknown)
            f1.setdefault(name, []).append(f"{s.f1:.3f}")
            if fraction == HELD_OUT_FRACTIONS[0]:
                at_first[name] = [f"{s.auc:.3f}", f"{s.unknown:.3f}", f"{build:.2f}", str(clusters)]
    first = f"{HELD_OUT_FRACTIONS[0]:.0%}"
    header = [
        "method",
        *(f"F1 at {fraction:.0%}" for fraction in HELD_OUT_FRACTIONS),
        f"ROC-AUC at {first}",
        f"unknown at {first}",
        f"build s at {first}",
        f"clusters at {first}",
    ]
    print(markdown_table(header, [[name, *f1[name], *at_first[name]] for name in f1]))


def markdown_table(
    header: Sequence[str], rows: Sequence[Sequence[str]], text_columns: int = 1
) -> str:
    """Markdown table, the first `text_columns` left-aligned and the others right."""
    align = ["---" if i < text_columns else "---:" for i in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Sweep:
    """What a benchmark sweep runs: seeds, train fractions, data sets and methods."""

    seeds: list[int]
    fractions: list[float]
    datasets: list[str]
    methods: list[str]
    settings: dict[str, Any]
    """MapConfig overrides for the EHM methods, over MapConfig.for_resolution's."""
    extra: dict[str, str] = field(default_factory=dict)
    """The values of a script's own options (sweep_arguments' `extra`), as given."""


def add_settings_argument(parser: argparse.ArgumentParser) -> None:
    """--set name=value, as often as wanted: MapConfig overrides for EHM (`settings_of`)."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="MapConfig override for EHM, over the resolution's defaults (repeatable).",
    )


def settings_of(args: argparse.Namespace) -> dict[str, Any]:
    """The MapConfig overrides of `--set` (add_settings_argument), typed like the defaults."""
    return parse_settings(args.set)


def settings_text(settings: dict[str, Any]) -> str:
    """', name=value' for each MapConfig override, for a heading ('' for none)."""
    return "".join(f", {name}={value}" for name, value in settings.items())


def sweep_arguments(
    description: str,
    datasets: Sequence[str],
    methods: Sequence[str] = (),
    with_settings: bool = False,
    fractions: str = "0.8,0.4",
    extra: dict[str, str] | None = None,
) -> Sweep:
    """The sweep asked for on the command line (--seeds 0,1,2 --fractions `fractions`
    --datasets a,b --methods m,n, with_settings --set name=value, and --name value for each of
    `extra`'s names; the defaults: those, `datasets`, `methods`, no overrides and `extra`'s
    values)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--fractions", default=fractions)
    parser.add_argument("--datasets", default=",".join(datasets))
    if methods:
        parser.add_argument("--methods", default=",".join(methods))
    if with_settings:
        add_settings_argument(parser)
    for name, default in (extra or {}).items():
        parser.add_argument(f"--{name}", default=default)
    args = parser.parse_args()
    return Sweep(
        [int(s) for s in args.seeds.split(",")],
        [float(f) for f in args.fractions.split(",")],
        args.datasets.split(","),
        args.methods.split(",") if methods else [],
        settings_of(args) if with_settings else {},
        {name: getattr(args, name) for name in extra or {}},
    )
